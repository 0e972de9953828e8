#pragma once
//! \file
//! What a decoded mesh must be, for the targets that decode meshes (mesh_parse, draco_decode):
//! finite positions, colours for every vertex or none, indices in range.

#include "fuzz/fuzz_check.h"
#include "zipfusion/core/mesh.h"

namespace zipfusion::fuzz {

inline void check_valid_mesh(const TriangleMesh& mesh) {
  for (const Eigen::Vector3f& p : mesh.positions) {
    if (!p.allFinite()) fail("a position that is not finite");
  }
  if (mesh.has_colors() && mesh.colors.size() != mesh.vertex_count()) fail("colours for some vertices only");
  const int vertices = static_cast<int>(mesh.vertex_count());
  for (const Eigen::Vector3i& t : mesh.triangles) {
    if ((t.array() < 0).any() || (t.array() >= vertices).any()) fail("an index outside the vertices");
  }
}

}  // namespace zipfusion::fuzz
