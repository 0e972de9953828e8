// libFuzzer target: rig.json (io/rig.h), the file every capture, outside tool and calibration
// writes. A parsed rig must be written back by format_rig as text that parses to the same rig.

#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz/fuzz_check.h"
#include "zipfusion/io/rig.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace zipfusion;
  using namespace zipfusion::fuzz;
  const auto rig = decoded_or_error([&] { return parse_rig(std::string(reinterpret_cast<const char*>(data), size), kSource); });
  if (!rig) return 0;
  if (rig->cameras.empty()) fail("a rig without cameras");
  const std::string text = format_rig(*rig);
  const Rig again = must_decode([&] { return parse_rig(text, kSource); }, "rig.json");
  if (format_rig(again) != text) fail("rig.json round trip changed the rig");
  return 0;
}
