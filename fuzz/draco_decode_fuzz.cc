// libFuzzer target: Draco meshes (io/draco_codec.h), which `decode_draco` reads from any source it
// is given (the stream's own frames, in tests and tools). A decoded mesh must be valid (finite
// positions, colours for every vertex or none, indices in range), and encoding it again must give
// bytes that decode to a valid mesh of no more triangles: Draco quantises positions and reorders
// vertices, so the round trip is not exact, but it must not fail or grow. The encoder is checked
// too, as `serve` runs it on every frame: it may refuse only a box it cannot quantise in floats.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "fuzz/fuzz_check.h"
#include "fuzz/mesh_check.h"
#include "zipfusion/io/draco_codec.h"

namespace zipfusion::fuzz {
namespace {

void check_draco(const std::string& bytes) {
  const auto mesh = decoded_or_error("draco", [&] { return decode_draco(bytes, kSource); });
  if (!mesh) return;
  check_valid_mesh(*mesh);
  const QuantizationBox box = quantization_box(*mesh, std::nullopt);
  // The level from the last byte, so that both of Draco's methods (sequential at 0) are run.
  const DracoOptions options{.compression_level = bytes.empty() ? 4 : static_cast<unsigned char>(bytes.back()) % 11};
  std::string again;
  try {
    again = encode_draco(*mesh, box, options);
  } catch (const InvalidInput& e) {
    // The one refusal allowed: a box Draco cannot quantise in floats (positions finite each).
    if (draco_can_quantise(box)) fail(std::string("Draco encoding refused a decoded mesh: ") + e.what());
    return;
  } catch (const IoError& e) {
    fail(std::string("Draco failed to encode a decoded mesh: ") + e.what());
  }
  const TriangleMesh round_trip = must_decode([&] { return decode_draco(again, kSource); }, "Draco");
  check_valid_mesh(round_trip);
  if (round_trip.triangles.size() > mesh->triangles.size()) fail("Draco round trip added triangles");
  if (!round_trip.positions.empty() && round_trip.has_colors() != mesh->has_colors()) fail("Draco round trip changed whether there are colours");
}

}  // namespace
}  // namespace zipfusion::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  zipfusion::fuzz::check_draco(std::string(reinterpret_cast<const char*>(data), size));
  return 0;
}
