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

}  // namespace zipfusion
