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

}  // namespace zipfusion
