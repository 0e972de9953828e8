// libFuzzer target: fakenect dumps (live/fakenect_dump.h), which `record --replay` and
// `serve --live --replay` read: INDEX.txt and the PGM depth / PPM colour frames. Whatever is
// accepted must come back unchanged from the writers.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "fuzz/fuzz_check.h"
#include "zipfusion/live/fakenect_dump.h"

namespace zipfusion::fuzz {
namespace {

void check_index(const std::string& text) {
  const auto entries = decoded_or_error([&] { return parse_fakenect_index(text, kSource); });
  if (!entries) return;
  std::string written;
  for (const FakenectIndexEntry& e : *entries) {
    if (!std::isfinite(e.time_s) || e.time_s < 0) fail("an entry time that is not a time: " + e.file);
    written += e.file + "\n";  // as write_fakenect_index writes it
  }
  const auto again = must_decode([&] { return parse_fakenect_index(written, kSource); }, "INDEX.txt");
  if (again.size() != entries->size()) fail("INDEX.txt round trip changed the entry count");
  for (size_t i = 0; i < again.size(); ++i) {
    const FakenectIndexEntry &a = again[i], &b = (*entries)[i];
    if (a.type != b.type || a.time_s != b.time_s || a.timestamp != b.timestamp || a.file != b.file) fail("INDEX.txt round trip changed " + b.file);
  }
}

void check_depth(std::span<const std::uint8_t> bytes) {
  const auto raw = decoded_or_error([&] { return decode_fakenect_depth(bytes, kSource); });
  if (!raw) return;
  for (const std::uint16_t d : raw->data) {
    if (d > 2047) fail("a depth value wider than the Kinect's 11 bits");
  }
  const RawDepthImage again = must_decode([&] { return decode_fakenect_depth(encode_fakenect_depth(*raw), kSource); }, "PGM");
  if (!(again == *raw)) fail("PGM round trip changed the image");
}

void check_rgb(std::span<const std::uint8_t> bytes) {
  const auto color = decoded_or_error([&] { return decode_fakenect_rgb(bytes, kSource); });
  if (!color) return;
  const ColorImage again = must_decode([&] { return decode_fakenect_rgb(encode_fakenect_rgb(*color), kSource); }, "PPM");
  if (!(again == *color)) fail("PPM round trip changed the image");
}

}  // namespace
}  // namespace zipfusion::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  zipfusion::fuzz::check_index(std::string(reinterpret_cast<const char*>(data), size));
  zipfusion::fuzz::check_depth(bytes);
  zipfusion::fuzz::check_rgb(bytes);
  return 0;
}
