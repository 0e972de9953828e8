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

//! What the two share: their data structure, and what CGAL's Triangulation_2 does with it.
using SeamTriangulationBase = CGAL::Triangulation_2<SeamKernel, SeamTriangulationData>;
//! A seam point in the plane, with its info; its index is its place in the list of points.
using SeamPoint = std::pair<SeamKernel::Point_2, SeamVertexInfo>;

//! Empties `triangulation` as CGAL's `clear` does, but keeps its containers' blocks for the next
//! seam (`clear` frees them, and a new triangulation allocates them again a block at a time).
//! The containers then hand out their slots in the order a new triangulation's would, so that a
//! reused triangulation lays its faces out in memory as a new one does: their order is the order
//! of the seam's float sums (fairing), and a reused scratch gives the seam a new one gives, to
//! the bit (the same order of iteration; addresses in different blocks still come from malloc).
//! Allocates nothing.
void clear_keeping_memory(SeamTriangulationBase& triangulation);

//! Work space of `insert_points`, reused across calls.
struct InsertionScratch {
  struct Place {
    double x, y;
    int index;
  };
  std::vector<Place> by_position;  //!< the points in lexicographic order, with their indices
  std::vector<int> hull;         //!< the convex hull's corners, counter-clockwise
};

//! Inserts every point into `triangulation`, which must be empty (new or cleared), and sets
//! handle[k] to point k's vertex; a point at the position of another shares its vertex, whose
//! info is that of the lower index. The triangulation is CGAL's Delaunay triangulation of the
//! points (unique: CGAL perturbs co-circular points symbolically), whatever the order of
//! insertion; the order only sets where its faces lie in memory. The convex hull's corners go in
//! first, counter-clockwise, the first three as one triangle built directly: so no point extends
//! the hull over more than one edge and no insertion changes the dimension, the two cases where
//! CGAL's insertion allocates (lists of the faces it changes). Then every 16th point, every 4th,
//! and the rest, each located from the face of the one before (points in the seam's order lie
//! next to each other). Allocates nothing once `scratch` and `handle` have grown, CGAL's
//! containers aside (clear_keeping_memory), unless the points all lie on one line or a cascade of
//! flips runs deeper than CGAL's recursion (100 flips; then it takes a std::stack): a seam's hull
//! of 200 corners took none, a band whose hull had 1 001 took 38.
void insert_points(SeamPointTriangulation& triangulation, const std::vector<SeamPoint>& points,
                   std::vector<SeamPointTriangulation::Vertex_handle>& handle, InsertionScratch& scratch);

//! Work space of `constrain`, reused across calls: edges as their two vertices, since a flip
//! replaces the faces' handles around it.
struct ConstraintScratch {
  using VertexPair = std::pair<SeamTriangulation::Vertex_handle, SeamTriangulation::Vertex_handle>;
  std::vector<VertexPair> crossing;  //!< a queue: the edges that cross the constraint
  std::vector<VertexPair> created;   //!< the edges flips made beside it, to be made Delaunay again
  long left_to_cgal = 0;             //!< segments (or their rests) given to CGAL's insertion, counted up
};

//! Work space of `remove_point`, reused across calls.
struct RemovalScratch {
  std::vector<SeamTriangulation::Vertex_handle> link;  //!< the point's neighbours, counter-clockwise
  std::vector<SeamTriangulation::Vertex_handle> polygon;  //!< the link as ears are cut off it
  struct Ear {
    SeamTriangulation::Vertex_handle before, tip, after;  //!< counter-clockwise; before–after becomes an edge
  };
  std::vector<Ear> ears;  //!< the link's corners cut off in turn, with their neighbours then
  std::vector<ConstraintScratch::VertexPair> created;  //!< the hole's edges, to be made Delaunay
  std::vector<SeamTriangulation::Face_handle> faces;    //!< a point's faces, on the hull
  long left_to_cgal = 0;  //!< points removed by CGAL's `remove`, counted up
};

//! Removes vertex `v`, which no constrained edge touches, from `triangulation`, which stays
//! constrained Delaunay: the triangulation CGAL's `remove(v)` makes (the hole's triangulation is
//! unique, CGAL perturbing co-circular points symbolically in both), with these faces' info for
//! the caller to set: the faces of the hole are v's old faces, flipped, with their old info (CGAL
//! makes new ones), but for those that become infinite, whose info is reset. The hole is cut into ears by
//! flips of v's edges until v has three neighbours, v goes with its three faces, and the hole's
//! edges are then flipped until Delaunay (Lawson). On the convex hull, ears are cut off the chain
//! of v's finite neighbours until it turns right at every corner, and v's faces then become the
//! infinite faces of the new hull. Allocates nothing once `scratch` has grown, where CGAL's
//! removal lists the hole's edges twice and its sub-holes. A point of more than 64 neighbours,
//! one on the hull whose chain keeps a left turn (a guard: v's finite neighbours lie within a
//! straight angle of it, so every strictly convex corner is an ear), one whose removal leaves no
//! finite face, or one in a triangulation of dimension below 2 goes to CGAL's `remove`
//! (`scratch.left_to_cgal` counts those).
void remove_point(SeamTriangulation& triangulation, SeamTriangulation::Vertex_handle v, RemovalScratch& scratch);

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
