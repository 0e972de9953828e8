#pragma once
//! \file
//! TriangleMesh: structure of arrays (positions, optional per-vertex colours, triangles).

#include <Eigen/Core>
#include <vector>

#include "zipfusion/core/image.h"

namespace zipfusion {

struct TriangleMesh {
  std::vector<Eigen::Vector3f> positions;  // metres
  std::vector<Rgb8> colors;                // empty, or one per position
  std::vector<Eigen::Vector3i> triangles;  // indices into positions, counter-clockwise = outward

  bool has_colors() const { return !colors.empty(); }
  size_t vertex_count() const { return positions.size(); }
  size_t triangle_count() const { return triangles.size(); }

  //! Appends `other`, shifting its indices. Both must agree on having colours, or this is empty.
  void append(const TriangleMesh& other);
};

//! Asserts (debug builds) what every mesh function assumes: colours empty or one per position,
//! triangle indices in range.
void assert_well_formed(const TriangleMesh& mesh);

//! Drops the vertices no triangle uses, keeping the others' order, and renumbers the triangles;
//! returns how many went. Precondition: assert_well_formed. `remap` is scratch (kept by the caller: no allocation once it has grown).
//! Zippering leaves a few such vertices: seam points whose triangles were all dropped.
int remove_unreferenced_vertices(TriangleMesh& mesh, std::vector<int>& remap);

//! Connected components of a mesh: triangles that share a vertex index belong together.
struct MeshComponents {
  std::vector<int> triangle_component;  // per triangle: component id, numbered by first triangle
  std::vector<int> triangle_counts;     // per component: its number of triangles
  std::vector<int> parent, root_component;  // scratch: the union-find over vertices, each root's id
  int count() const { return static_cast<int>(triangle_counts.size()); }
};
//! Fills `out` (its vectors reused: no allocation once they have grown).
void connected_components(const TriangleMesh& mesh, MeshComponents& out);
MeshComponents connected_components(const TriangleMesh& mesh);

//! Drops the triangles of every connected component with fewer than `min_triangles` triangles
//! (specks: noise at silhouettes, bits of floor through the volume's crop), keeping the others'
//! order; returns how many went. Their vertices stay (remove_unreferenced_vertices).
int remove_small_components(TriangleMesh& mesh, int min_triangles, MeshComponents& scratch);

}  // namespace zipfusion
