#include "zipfusion/core/mesh.h"

#include <algorithm>
#include <cassert>
#include <numeric>

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

namespace {

int find_root(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];  // path halving
    i = parent[i];
  }
  return i;
}

}  // namespace

void connected_components(const TriangleMesh& mesh, MeshComponents& out) {
  std::vector<int>& parent = out.parent;
  parent.resize(mesh.positions.size());
  std::iota(parent.begin(), parent.end(), 0);
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 1; k < 3; ++k) {
      const int a = find_root(parent, t[0]), b = find_root(parent, t[k]);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  }
  out.triangle_component.resize(mesh.triangles.size());
  out.triangle_counts.clear();
  out.root_component.assign(mesh.positions.size(), -1);
  for (size_t i = 0; i < mesh.triangles.size(); ++i) {
    int& component = out.root_component[find_root(parent, mesh.triangles[i][0])];
    if (component < 0) {
      component = out.count();
      out.triangle_counts.push_back(0);
    }
    out.triangle_component[i] = component;
    out.triangle_counts[component]++;
  }
}

MeshComponents connected_components(const TriangleMesh& mesh) {
  MeshComponents out;
  connected_components(mesh, out);
  return out;
}

int remove_small_components(TriangleMesh& mesh, int min_triangles, MeshComponents& scratch) {
  if (min_triangles <= 1 || mesh.triangles.empty()) return 0;
  connected_components(mesh, scratch);
  size_t kept = 0;
  for (size_t i = 0; i < mesh.triangles.size(); ++i) {
    if (scratch.triangle_counts[scratch.triangle_component[i]] >= min_triangles) mesh.triangles[kept++] = mesh.triangles[i];
  }
  const int removed = static_cast<int>(mesh.triangles.size() - kept);
  mesh.triangles.resize(kept);
  return removed;
}

}  // namespace zipfusion
