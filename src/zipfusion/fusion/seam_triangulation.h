#pragma once
//! The triangulation of a seam (clipping.h; the paper's Section III-D): the seam's points laid
//! out in 2-D, triangulated by CGAL's Delaunay triangulation, with the kept edges between seam
//! points as constraints; and `constrain`, which inserts a constraint as CGAL does without the
//! lists CGAL's insertion allocates.

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <Eigen/Core>
#include <utility>
#include <vector>

namespace zipfusion {

using SeamKernel = CGAL::Exact_predicates_inexact_constructions_kernel;
//! Vertex info: the seam vertex index; −1 for a vertex made where two constraints cross.
struct SeamVertexInfo {
  int index = -1;
};
//! Face info: set before the seam's output is chosen (clipping.cc's set_face_info).
struct SeamFaceInfo {
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();
  bool output = false;
};
using SeamTriangulationData =
    CGAL::Triangulation_data_structure_2<CGAL::Triangulation_vertex_base_with_info_2<SeamVertexInfo, SeamKernel>,
                                         CGAL::Constrained_triangulation_face_base_2<
                                             SeamKernel, CGAL::Triangulation_face_base_with_info_2<SeamFaceInfo, SeamKernel>>>;
//! Constraints from two meshes may cross where their borders overlap; Exact_predicates_tag lets
//! them be split at an approximate intersection instead of failing.
using SeamTriangulation = CGAL::Constrained_Delaunay_triangulation_2<SeamKernel, SeamTriangulationData, CGAL::Exact_predicates_tag>;
//! The points go into a plain Delaunay triangulation of the same data structure, which then
//! becomes the constrained one (`swap`; a Delaunay triangulation without constraints is one): the
//! constrained triangulation's flips also restore the constraint flags of the four faces around,
//! and test for them and for infinite faces, to the same result while there are none.
using SeamPointTriangulation = CGAL::Delaunay_triangulation_2<SeamKernel, SeamTriangulationData>;

//! Work space of `constrain`, reused across calls: edges as their two vertices, since a flip
//! replaces the faces' handles around it.
struct ConstraintScratch {
  using VertexPair = std::pair<SeamTriangulation::Vertex_handle, SeamTriangulation::Vertex_handle>;
  std::vector<VertexPair> crossing;  //!< a queue: the edges that cross the constraint
  std::vector<VertexPair> created;   //!< the edges flips made beside it, to be made Delaunay again
  long left_to_cgal = 0;             //!< segments (or their rests) given to CGAL's insertion, counted up
};

//! Makes the segment between two vertices a constrained edge of the triangulation, which stays
//! constrained Delaunay: the triangulation CGAL's `insert_constraint(from, to)` makes, up to the
//! choice among co-circular points. An edge that is already there is only marked; one that
//! crosses edges is flipped into place (Sloan's insertion, 1993), then the edges the flips made
//! are flipped until Delaunay (Lawson). Where the segment crosses a constrained edge, both are
//! split at a vertex made where they cross (its info has index −1), the point constructed and
//! snapped to a nearby end as CGAL's insertion does, so that it is CGAL's to the bit. Allocates
//! nothing once `scratch` has grown (CGAL's containers aside, when a crossing's vertex needs a new
//! block), except where it leaves the segment, or what is left of it, to CGAL's insertion
//! (`scratch.left_to_cgal` counts those): a vertex on the segment, a crossing whose point lies
//! outside the two triangles beside the crossed edge (CGAL then constructs it more exactly) or
//! on one of their corners other than the crossed edge's ends, more than eight nested crossings,
//! an infinite face on the way, flips that take more than 64 steps a crossed edge (a guard:
//! Sloan's take a few), or a triangulation of dimension below 2. Precondition: both vertices
//! belong to `triangulation`.
void constrain(SeamTriangulation& triangulation, SeamTriangulation::Vertex_handle from, SeamTriangulation::Vertex_handle to,
               ConstraintScratch& scratch);

}  // namespace zipfusion
