// libFuzzer target: PLY (ascii and binary) and OBJ meshes (io/mesh_io.h), which `eval` and the
// ground truth of a capture read. A parsed mesh must be valid (finite positions, colours for
// every vertex or none, indices in range) and come back unchanged from the writers.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "fuzz/fuzz_check.h"
#include "fuzz/mesh_check.h"
#include "zipfusion/io/mesh_io.h"

namespace zipfusion::fuzz {
namespace {

bool same_mesh(const TriangleMesh& a, const TriangleMesh& b) {
  return a.positions == b.positions && a.colors == b.colors && a.triangles == b.triangles;
}

void check_ply(const std::vector<std::uint8_t>& bytes) {
  const auto mesh = decoded_or_error("ply", [&] { return parse_ply(bytes, kSource); });
  if (!mesh) return;
  check_valid_mesh(*mesh);
  const TriangleMesh again = must_decode([&] { return parse_ply(encode_ply(*mesh), kSource); }, "PLY");
  if (!same_mesh(again, *mesh)) fail("PLY round trip changed the mesh");
}

void check_obj(const std::string& text) {
  const auto mesh = decoded_or_error("obj", [&] { return parse_obj(text, kSource); });
  if (!mesh) return;
  check_valid_mesh(*mesh);
  const TriangleMesh again = must_decode([&] { return parse_obj(encode_obj(*mesh), kSource); }, "OBJ");
  if (!same_mesh(again, *mesh)) fail("OBJ round trip changed the mesh");
}

}  // namespace
}  // namespace zipfusion::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  zipfusion::fuzz::check_ply(std::vector<std::uint8_t>(data, data + size));
  zipfusion::fuzz::check_obj(std::string(reinterpret_cast<const char*>(data), size));
  return 0;
}
