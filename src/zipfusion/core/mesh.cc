#include "zipfusion/core/mesh.h"

#include <cassert>

namespace zipfusion {

void TriangleMesh::append(const TriangleMesh& other) {
  const bool was_empty = positions.empty();
  assert(was_empty || has_colors() == other.has_colors());
  const int offset = static_cast<int>(positions.size());
  positions.insert(positions.end(), other.positions.begin(), other.positions.end());
  if (was_empty || has_colors()) colors.insert(colors.end(), other.colors.begin(), other.colors.end());
  triangles.reserve(triangles.size() + other.triangles.size());
  for (const Eigen::Vector3i& t : other.triangles) triangles.push_back(t.array() + offset);
}

void assert_well_formed(const TriangleMesh& mesh) {
  assert(mesh.colors.empty() || mesh.colors.size() == mesh.positions.size());
#ifndef NDEBUG
  for (const Eigen::Vector3i& t : mesh.triangles) {
    assert((t.array() >= 0).all() && (t.array() < static_cast<int>(mesh.positions.size())).all());
  }
#endif
  (void)mesh;
}

int remove_unreferenced_vertices(TriangleMesh& mesh, std::vector<int>& remap) {
  assert_well_formed(mesh);
  const int count = static_cast<int>(mesh.positions.size());
  remap.assign(count, -1);
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) remap[t[k]] = 0;
  }
  int kept = 0;
  for (int v = 0; v < count; ++v) {
    if (remap[v] < 0) continue;
    remap[v] = kept;
    mesh.positions[kept] = mesh.positions[v];
    if (mesh.has_colors()) mesh.colors[kept] = mesh.colors[v];
    ++kept;
  }
  if (kept == count) return 0;
  for (Eigen::Vector3i& t : mesh.triangles) t = Eigen::Vector3i(remap[t[0]], remap[t[1]], remap[t[2]]);
  mesh.positions.resize(kept);
  if (mesh.has_colors()) mesh.colors.resize(kept);
  return count - kept;
}

}  // namespace zipfusion
