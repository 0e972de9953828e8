#include "zipfusion/fusion/clipping.h"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <Eigen/Eigenvalues>
#include <cmath>

namespace zipfusion {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
// Vertex info: the seam vertex index; −1 for a vertex CGAL made where two constraints cross.
struct SeamInfo {
  int index = -1;
};
using VertexBase = CGAL::Triangulation_vertex_base_with_info_2<SeamInfo, Kernel>;
// Face info: set before the seam's output is chosen (set_face_info).
struct SeamFace {
  Eigen::Vector3f normal = Eigen::Vector3f::Zero();
  bool output = false;
};
using FaceBase = CGAL::Constrained_triangulation_face_base_2<Kernel, CGAL::Triangulation_face_base_with_info_2<SeamFace, Kernel>>;
using TriangulationData = CGAL::Triangulation_data_structure_2<VertexBase, FaceBase>;
// Constraints from two meshes may cross where their borders overlap; Exact_predicates_tag lets
// CGAL split them at an approximate intersection instead of failing.
using Delaunay = CGAL::Constrained_Delaunay_triangulation_2<Kernel, TriangulationData, CGAL::Exact_predicates_tag>;

// The seeds of a pair's seams in one mesh: its boundary triangles inside the mask. Both
// meshes' seeds are chosen once per pair, before either's seam is found (the bit matrices do not
// change until both are), and each seam reads both lists.
void select_seeds(const MeshView& view, const OverlapMask& mask, SeamScratch& s) {
  const DepthMesh& mesh = *view.mesh;
  s.seeds.clear();
  for (int id : s.boundary) {
    if (mask.covers(cell_of(id), mesh.width, view.level) && is_boundary_triangle(mesh.triangles.data(), cell_of(id), mesh.width, bit_of(id))) {
      s.seeds.push_back(id);
    }
  }
}

// The triangles of `a` within d_c of `b` that border the seam: a's boundary triangles with a
// triangle of b that near, and a's triangles under b's boundary. The second matter where `b`
// lost the overlap and ends on top of a's surface: there `a` has no boundary, yet its triangles
// under b's border must join the seam for the two to be stitched. After ownership-based
// redundancy removal the two meshes meet, so the triangles within d_c of the other mesh are this
// one ring: growing it through every triangle within d_c (a flood fill) took 1.7 times the
// triangles on samba-4cam and changed no quality figure (docs/design.md). `b_seeds`: b's
// boundary triangles inside its mask (select_seeds); a's are in `s.seeds`. `s.seeds_in_other`,
// `b.seeds_in_other`: the seeds' centres projected into the other camera (project_seeds).
void find_seam_triangles(const MeshView& a, const MeshView& b, const SeamScratch& b_scratch, float distance, SeamScratch& s) {
  const DepthMesh& mesh = *a.mesh;
  const Rigid3f b_from_a_camera = b_from_a(a, b);
  s.marks.reserve(mesh.triangles.size() * 2);
  s.taken.clear();
  s.visited.clear();
  auto test = [&](int id, const ViewPoint& centre) {
    if (!may_see_point(b, centre, 2 * distance) || !seam_window_has_triangle(*b.mesh, centre) ||
        !has_triangle_near(b, centre, distance, kSeamWindow)) {
      return;
    }
    s.taken.push_back(id);
  };
  auto first_visit = [&](int id) {
    if (s.marks.test_and_set(id)) return false;
    s.visited.push_back(id);
    return (mesh.triangles[cell_of(id)] & bit_of(id)) != 0;
  };
  for (size_t k = 0; k < s.seeds.size(); ++k) {
    if (first_visit(s.seeds[k])) test(s.seeds[k], s.seeds_in_other[k]);
  }
  for (const ViewPoint& b_centre : b_scratch.seeds_in_other) {
    const int under = b_centre.cell;
    if (under < 0 || !mesh.triangles[under]) continue;
    for (TriangleBit bit : {kUpperTriangle, kLowerTriangle}) {
      const int id = triangle_id(under, bit);
      if (first_visit(id)) test(id, project_camera_point(b, b_from_a_camera * camera_triangle_centre(a, under, bit)));
    }
  }
  for (int id : s.visited) s.marks.clear(id);
}

// The centres of `view`'s seeds projected into `other`: each is needed twice, to test the seed
// and to find the other mesh's triangles under it.
void project_seeds(const MeshView& view, const MeshView& other, SeamScratch& s) {
  const Rigid3f other_from_view = b_from_a(view, other);
  s.seeds_in_other.clear();
  for (int id : s.seeds) s.seeds_in_other.push_back(project_camera_point(other, other_from_view * camera_triangle_centre(view, cell_of(id), bit_of(id))));
}

// The triangle bits of cell (cu, cv) of `mesh`, 0 for a cell outside it.
std::uint8_t cell_bits(const DepthMesh& mesh, int cu, int cv) {
  return cu >= 0 && cv >= 0 && cu < mesh.width - 1 && cv < mesh.height - 1 ? mesh.triangles[cv * mesh.width + cu] : 0;
}

// Does any triangle of `mesh` use pixel p as a vertex?
bool pixel_has_triangle(const DepthMesh& mesh, int p) {
  const int u = p % mesh.width, v = p / mesh.width;
  return pixel_used(cell_bits(mesh, u, v), cell_bits(mesh, u - 1, v), cell_bits(mesh, u, v - 1), cell_bits(mesh, u - 1, v - 1));
}

// Adds the pixels of the taken triangles (already cleared from the mesh) to the seam's vertex
// list, each once. A pixel that no kept triangle uses any more is left out when the other mesh owns the
// surface there (as in FRBR): inside the seam, where the two meshes' boundaries overlap by a
// triangle or two, only one layer of points is triangulated, so the seam does not zigzag between
// two noisy layers.
void take_triangles(const MeshView& view, const MeshView& other, float distance, SeamScratch& s, Seam& seam) {
  const DepthMesh& mesh = *view.mesh;
  if (s.seam_index.size() < mesh.triangles.size()) s.seam_index.resize(mesh.triangles.size());
  for (int id : s.taken) {
    int pixels[3];
    triangle_pixels(cell_of(id), mesh.width, bit_of(id), pixels);
    for (int p : pixels) {
      if (s.marks.test_and_set(p)) continue;
      if (!pixel_has_triangle(mesh, p)) {
        const int u = p % mesh.width, v = p / mesh.width;
        const ViewPoint point = project_into(other, mesh.point(u, v));
        const float x = static_cast<float>(u), y = static_cast<float>(v);
        if (owner_is_other(view, x, y, other, point, 2 * distance) && has_triangle_near(other, point, distance)) continue;
      }
      s.seam_index[p] = static_cast<int>(seam.vertices.size());
      seam.vertices.push_back({view.camera, p});
    }
  }
  seam.triangles_taken += static_cast<int>(s.taken.size());
  // The triangles next to the taken ones are boundary now: candidates for later pairs' seams.
  for (int id : s.taken) {
    int neighbours[3];
    const int n = triangle_neighbours(id, mesh.width, neighbours);
    s.boundary.insert(s.boundary.end(), neighbours, neighbours + n);
  }
}

// The edges of kept triangles between two seam vertices of the same mesh: the seam must contain
// them exactly, or its triangles would cut across the kept triangles they border. Each edge once,
// as (lower index, higher index): a constraint that CGAL split where it crossed another, inserted
// a second time, can be split again at a slightly different point (one seam triangle of 12 000
// differed on samba-4cam frame 20 when edges shared by two kept triangles came twice).
void add_kept_edges(const MeshView& view, const SeamScratch& s, int first_vertex, int end_vertex, const Seam& seam,
                    std::vector<std::pair<int, int>>& edges) {
  const DepthMesh& mesh = *view.mesh;
  const int width = mesh.width;
  auto seam_vertex = [&](int pixel) {
    if (!s.marks.test(pixel)) return -1;
    const int index = s.seam_index[pixel];
    return index >= first_vertex && index < end_vertex && seam.vertices[index].pixel == pixel ? index : -1;
  };
  for (int index = first_vertex; index < end_vertex; ++index) {
    const int p = seam.vertices[index].pixel;
    const int u = p % width, v = p / width;
    // The six grid edges from p and the triangles on either side of each (upper triangle of
    // cell (u, v): (u, v), (u, v + 1), (u + 1, v); lower: (u + 1, v), (u, v + 1), (u + 1, v + 1)).
    const unsigned here = cell_bits(mesh, u, v), left = cell_bits(mesh, u - 1, v), up = cell_bits(mesh, u, v - 1),
                   up_left = cell_bits(mesh, u - 1, v - 1);
    const struct {
      bool kept;
      int other;
    } grid_edges[6] = {
        {((here & kUpperTriangle) | (up & kLowerTriangle)) != 0, p + 1},          // right
        {((left & kUpperTriangle) | (up_left & kLowerTriangle)) != 0, p - 1},     // left
        {((here & kUpperTriangle) | (left & kLowerTriangle)) != 0, p + width},    // down
        {((up & kUpperTriangle) | (up_left & kLowerTriangle)) != 0, p - width},   // up
        {left != 0, p + width - 1},                                               // down and left
        {up != 0, p - width + 1},                                                 // up and right
    };
    for (const auto& edge : grid_edges) {
      if (!edge.kept) continue;
      const int j = seam_vertex(edge.other);
      if (j > index) edges.emplace_back(index, j);
    }
  }
}

// Clears the marks take_triangles set: the pixels of the taken triangles.
void clear_pixel_marks(const MeshView& view, SeamScratch& s) {
  for (int id : s.taken) {
    int pixels[3];
    triangle_pixels(cell_of(id), view.mesh->width, bit_of(id), pixels);
    for (int p : pixels) s.marks.clear(p);
  }
}

// Makes the kept edge (from, to) an edge of the triangulation by one flip, where it crosses exactly
// one edge, the diagonal of the quadrilateral of the two triangles that have `from` and `to` as
// their far corners (mostly the pixel grid's other diagonal); false where it does not, or where
// that diagonal is constrained or a corner lies on the kept edge. CGAL's constraint insertion
// would give the same triangulation (each side of the kept edge is one triangle, constrained
// Delaunay as it is) after walking the segment and re-triangulating the hole with lists it
// allocates, about 3 000 instructions more a constraint (stitching 5 % fewer without the filter).
bool flip_into_edge(Delaunay& triangulation, Delaunay::Vertex_handle from, Delaunay::Vertex_handle to) {
  Delaunay::Face_circulator face = triangulation.incident_faces(from), first = face;
  if (face == nullptr) return false;
  do {
    if (triangulation.is_infinite(face)) continue;
    const int i = face->index(from);
    const Delaunay::Face_handle across = face->neighbor(i);
    if (triangulation.is_infinite(across) || across->vertex(triangulation.mirror_index(face, i)) != to) continue;
    if (face->is_constrained(i)) return false;
    const Kernel::Point_2 &a = face->vertex(Delaunay::cw(i))->point(), &b = face->vertex(Delaunay::ccw(i))->point();
    const CGAL::Orientation side_a = triangulation.orientation(from->point(), to->point(), a);
    const CGAL::Orientation side_b = triangulation.orientation(from->point(), to->point(), b);
    if (side_a == CGAL::COLLINEAR || side_b == CGAL::COLLINEAR || side_a == side_b) return false;
    Delaunay::Face_handle flipped = face;
    triangulation.flip(flipped, i);
    return true;
  } while (++face != first);
  return false;
}

// Marks the triangulation edge (from, to) as constrained on both its sides; false when it is not an edge.
bool mark_constrained(Delaunay& triangulation, Delaunay::Vertex_handle from, Delaunay::Vertex_handle to) {
  Delaunay::Face_handle face;
  int edge;
  if (triangulation.dimension() != 2 || !triangulation.is_edge(from, to, face, edge)) return false;
  face->set_constraint(edge, true);
  face->neighbor(edge)->set_constraint(triangulation.mirror_index(face, edge), true);
  return true;
}

// Sets a face's info: whether it is output (`output(i0, i1, i2)` of its seam vertices; never at
// a crossing of two constraints, where CGAL made a vertex) and its normal in 3-D, its vertices
// taken in their (counter-clockwise) order.
template <typename Output>
void set_face_info(Delaunay::Face_handle f, const std::vector<Eigen::Vector3f>& positions, Output&& output) {
  const int i0 = f->vertex(0)->info().index, i1 = f->vertex(1)->info().index, i2 = f->vertex(2)->info().index;
  SeamFace& info = f->info();
  info.output = i0 >= 0 && i1 >= 0 && i2 >= 0 && output(i0, i1, i2);
  if (info.output) info.normal = (positions[i1] - positions[i0]).cross(positions[i2] - positions[i0]).normalized();
}

// Flips the seam's creases out where a flip makes the surface smoother (after Dyn, Levin and
// Rippa's data-dependent triangulations). Delaunay in 2-D chooses each quadrilateral's diagonal
// by the layout alone; where the two meshes' points lie a few millimetres apart in depth, the
// diagonal it chose can make two output triangles, both facing the virtual camera, meet at a
// crease sharper than 60° (normals more than 120° apart, eval's count_folded_edges), where the
// other diagonal makes them one slope. An unconstrained edge between two creased output faces is
// flipped when its quadrilateral is strictly convex in 2-D (so both new faces are still
// counter-clockwise in the layout: they face the virtual camera), the new diagonal is no longer
// than max_edge, and the sharpest crease over the quadrilateral's five edges becomes less sharp;
// otherwise it is flipped back. A flip takes its two faces over (CGAL's data structure reuses
// them), so only theirs needs setting again. Every finite face's info must be set
// (set_face_info) and is kept so. `candidates` is scratch.
template <typename Output>
void flip_out_creases(Delaunay& triangulation, const std::vector<Eigen::Vector3f>& positions, float max_edge2, Output&& output,
                      std::vector<std::pair<Delaunay::Vertex_handle, Delaunay::Vertex_handle>>& candidates) {
  if (triangulation.dimension() != 2) return;
  constexpr float kCreaseCosine = -0.5f;
  // The cosine between the normals of edge (f, i)'s two faces; 1 (no crease) where either is not
  // output.
  auto edge_cosine = [&](Delaunay::Face_handle f, int i) {
    const Delaunay::Face_handle g = f->neighbor(i);
    return !triangulation.is_infinite(f) && !triangulation.is_infinite(g) && f->info().output && g->info().output
               ? f->info().normal.dot(g->info().normal)
               : 1.0f;
  };
  // The sharpest crease over edge (f, i) and the four outer edges of its quadrilateral.
  auto sharpest = [&](Delaunay::Face_handle f, int i) {
    const Delaunay::Face_handle g = f->neighbor(i);
    const int j = triangulation.mirror_index(f, i);
    return std::min({edge_cosine(f, i), edge_cosine(f, Delaunay::cw(i)), edge_cosine(f, Delaunay::ccw(i)), edge_cosine(g, Delaunay::cw(j)),
                     edge_cosine(g, Delaunay::ccw(j))});
  };
  auto creased = [&](Delaunay::Face_handle f, int i) { return !f->is_constrained(i) && edge_cosine(f, i) < kCreaseCosine; };
  auto edge_vertices = [](Delaunay::Face_handle f, int i) { return std::pair{f->vertex(Delaunay::cw(i)), f->vertex(Delaunay::ccw(i))}; };
  candidates.clear();
  for (auto edge = triangulation.finite_edges_begin(); edge != triangulation.finite_edges_end(); ++edge) {
    if (creased(edge->first, edge->second)) candidates.push_back(edge_vertices(edge->first, edge->second));
  }
  // A flip changes only its quadrilateral: creases left on its outer edges are queued in turn, up
  // to a bound that ends the pass whatever happens.
  const size_t most = 8 * candidates.size();
  for (size_t k = 0; k < candidates.size() && k < most; ++k) {
    const auto [u, v] = candidates[k];
    Delaunay::Face_handle f;
    int i = 0;
    if (!triangulation.is_edge(u, v, f, i) || !creased(f, i)) continue;
    const Delaunay::Face_handle g = f->neighbor(i);
    const Delaunay::Vertex_handle w = f->vertex(i), x = g->vertex(triangulation.mirror_index(f, i));
    const CGAL::Orientation side_u = triangulation.orientation(w->point(), x->point(), u->point());
    const CGAL::Orientation side_v = triangulation.orientation(w->point(), x->point(), v->point());
    if (side_u == CGAL::COLLINEAR || side_v == CGAL::COLLINEAR || side_u == side_v) continue;
    if ((positions[w->info().index] - positions[x->info().index]).squaredNorm() > max_edge2) continue;
    const float before = sharpest(f, i);
    triangulation.flip(f, i);  // f and g now hold the faces of edge (w, x)
    set_face_info(f, positions, output);
    set_face_info(g, positions, output);
    Delaunay::Face_handle h;
    int e = 0;
    triangulation.is_edge(w, x, h, e);
    // Both new faces must be output: a face dropped would count as no crease, and leave a hole.
    if (f->info().output && g->info().output && sharpest(h, e) > before) {
      const Delaunay::Face_handle n = h->neighbor(e);
      const int j = triangulation.mirror_index(h, e);
      for (const auto& [face, index] : {std::pair{h, Delaunay::cw(e)}, std::pair{h, Delaunay::ccw(e)}, std::pair{n, Delaunay::cw(j)},
                                        std::pair{n, Delaunay::ccw(j)}}) {
        if (creased(face, index)) candidates.push_back(edge_vertices(face, index));
      }
    } else {
      triangulation.flip(h, e);  // back: the same two triangles as before, in the faces f and g again
      set_face_info(f, positions, output);
      set_face_info(g, positions, output);
    }
  }
}

// Element function: the point of `view`'s pixel at the mean depth of the pixels around it (a
// (2·radius + 1)² window) on the same surface (within the view's SDC threshold), in the camera
// frame.
Eigen::Vector3f smoothed_camera_point(const MeshView& view, int pixel, int radius) {
  const float same_surface = view.same_surface;
  const DepthMesh& mesh = *view.mesh;
  const int u = pixel % mesh.width, v = pixel / mesh.width;
  const float centre = mesh.depth[pixel];
  float sum = 0;
  int count = 0;
  // Without branches (which pixels belong is unpredictable at a border): a pixel left out adds
  // exactly 0, so the sum is the same as adding only the others, in the same order.
  auto add = [&](float z) {
    const bool same = z > 0 && std::abs(z - centre) < same_surface;
    sum += same ? z : 0.0f;
    count += same;
  };
  if (u >= radius && v >= radius && u + radius < mesh.width && v + radius < mesh.height) {
    const float* row = mesh.depth.data() + pixel - radius * mesh.width - radius;
    for (int y = 0; y <= 2 * radius; ++y, row += mesh.width) {
      for (int x = 0; x <= 2 * radius; ++x) add(row[x]);
    }
  } else {
    for (int y = std::max(0, v - radius); y <= std::min(mesh.height - 1, v + radius); ++y) {
      const float* row = mesh.depth.data() + y * mesh.width;
      for (int x = std::max(0, u - radius); x <= std::min(mesh.width - 1, u + radius); ++x) add(row[x]);
    }
  }
  return unproject(view.intrinsics, static_cast<float>(u), static_cast<float>(v), sum / static_cast<float>(count));
}

// Element function: where the seam puts point p (world) of one mesh, whose camera's centre is
// `centre`, given the other mesh's view `other` (after Turk and Levoy's consensus geometry): on
// p's own ray, at the point nearest the midpoint of p and the other camera's surface point on
// its ray through p, its depth interpolated bilinearly over the pixels around p's projection on
// the same surface (within `same_surface` of p's depth there); p itself where the other camera
// has no depth on that surface, or where α, the angle between the two cameras' rays, is 90° or
// more. Moving along the own ray keeps the point on its pixel, so its kept triangles do not turn
// over in its camera; it moves cos α of halfway, and both meshes' points end up close together
// between their layers.
// Laid out side by side in the seam, points of two layers a few millimetres apart in depth made
// its triangles zigzag between them, at creases sharper than 60°. Tried, no fewer creases on
// samba-4cam nor on zipper_test's offset wall: a secant step to where p's ray meets the halfway
// surface; the other's depth as the window mean of its nearest pixel, as the seam lays out its
// own points without the filter (the wall's creases rose from 0, 2, 4 to 6, 6, 6).
Eigen::Vector3f consensus_point(const Eigen::Vector3f& p, const Eigen::Vector3f& centre, const MeshView& other,
                                const Rigid3f& world_from_other, float same_surface) {
  const ViewPoint q = project_into(other, p);
  if (q.cell < 0) return p;
  const DepthMesh& mesh = *other.mesh;
  // q lies in the image (its cell is valid), so the floor is a truncation.
  const float fu = q.x - static_cast<float>(static_cast<int>(q.x)), fv = q.y - static_cast<float>(static_cast<int>(q.y));
  const float* depth = mesh.depth.data() + q.cell;
  const float z[4] = {depth[0], depth[1], depth[mesh.width], depth[mesh.width + 1]};
  const float w[4] = {(1 - fu) * (1 - fv), fu * (1 - fv), (1 - fu) * fv, fu * fv};
  float sum = 0, weight = 0;
  for (int k = 0; k < 4; ++k) {
    const bool same = z[k] > 0 && std::abs(z[k] - q.in_camera.z()) < same_surface;
    sum += same ? w[k] * z[k] : 0.0f;
    weight += same ? w[k] : 0.0f;
  }
  if (!(weight > 0)) return p;
  const Eigen::Vector3f on_other = world_from_other * (q.in_camera * (sum / weight / q.in_camera.z()));
  const Eigen::Vector3f ray = (p - centre).normalized();
  // Where the two cameras' rays meet at 90° or more (cos α ≤ 0: grazing overlaps, as of three
  // cameras 120° apart), the nearest point to the midpoint lies on the far side of p from the
  // other layer, and moving there pulled the layers apart.
  if (!(ray.dot(world_from_other.linear() * q.in_camera.normalized()) > 0)) return p;
  return centre + ray * ray.dot(0.5f * (p + on_other) - centre);
}

}  // namespace

bool covered_by_triangle(const MeshView& view, const ViewPoint& p, float tolerance, const KeptAt& kept) {
  if (p.cell < 0) return false;
  const DepthMesh& mesh = *view.mesh;
  // p lies in the image (its cell is valid), so the floor is a truncation.
  const float fu = p.x - static_cast<float>(static_cast<int>(p.x)), fv = p.y - static_cast<float>(static_cast<int>(p.y));
  const TriangleBit bit = fu + fv < 1.0f ? kUpperTriangle : kLowerTriangle;
  if (!(mesh.triangles[p.cell] & bit) && !kept.taken_later(triangle_id(p.cell, bit))) return false;
  int pixels[3];
  triangle_pixels(p.cell, mesh.width, bit, pixels);
  const float mean_depth = (mesh.depth[pixels[0]] + mesh.depth[pixels[1]] + mesh.depth[pixels[2]]) / 3.0f;
  return std::abs(mean_depth - p.in_camera.z()) < tolerance;
}

TakenSeam take_seam(const MeshView& a, const MeshView& b, const SeamOptions& options, const OverlapMask& mask_a, const OverlapMask& mask_b,
                    SeamScratch& scratch_a, SeamScratch& scratch_b) {
  TakenSeam taken;
  Seam& seam = taken.seam;
  // Both seams are found against the meshes as FRBR left them, then taken out together.
  select_seeds(a, mask_a, scratch_a);
  select_seeds(b, mask_b, scratch_b);
  project_seeds(a, b, scratch_a);
  project_seeds(b, a, scratch_b);
  find_seam_triangles(a, b, scratch_b, options.clipping_distance, scratch_a);
  find_seam_triangles(b, a, scratch_a, options.clipping_distance, scratch_b);
  // Both meshes lose their seam triangles before either's points are chosen, so "kept" means
  // kept after clipping.
  for (int id : scratch_a.taken) a.mesh->triangles[cell_of(id)] &= static_cast<std::uint8_t>(~bit_of(id));
  for (int id : scratch_b.taken) b.mesh->triangles[cell_of(id)] &= static_cast<std::uint8_t>(~bit_of(id));
  take_triangles(a, b, options.ownership_distance, scratch_a, seam);
  const int a_end = static_cast<int>(seam.vertices.size());
  take_triangles(b, a, options.ownership_distance, scratch_b, seam);
  add_kept_edges(a, scratch_a, 0, a_end, seam, taken.constraints);
  add_kept_edges(b, scratch_b, a_end, static_cast<int>(seam.vertices.size()), seam, taken.constraints);
  clear_pixel_marks(a, scratch_a);
  clear_pixel_marks(b, scratch_b);
  taken.taken_a = scratch_a.taken;
  taken.taken_b = scratch_b.taken;
  return taken;
}

void stitch_seam(const MeshView& a, const Eigen::Vector3f& centre_a, const MeshView& b, const Eigen::Vector3f& centre_b,
                 const SeamOptions& options, const KeptAt& kept_a, const KeptAt& kept_b, TakenSeam& taken) {
  Seam& seam = taken.seam;
  const std::vector<std::pair<int, int>>& constraints = taken.constraints;
  if (seam.vertices.size() < 3) return;

  // Where the seam puts its points, formed once (each face reads three): each on its own pixel's
  // ray at the mean depth of the surface around it. Unfiltered, noise moves a point along its
  // camera's ray, which a view from another direction sees as a sideways shift larger than the
  // pixel spacing (about 7 mm for the Kinect's 1 cm at 2.5 m, seen from 45°): the grid would fold
  // over and the kept edges cross. The mean keeps the layout as regular as the pixel grid. Each
  // point then moves towards the other mesh's layer (consensus_point), so the two meshes' points
  // lie close together between their layers. The output takes the same positions: where it kept
  // the measured ones, a face the layout saw from the front could face away in 3-D, folded over
  // its neighbours.
  std::vector<Eigen::Vector3f>& positions = seam.positions;
  positions.resize(seam.vertices.size());
  const Rigid3f world_from_a = a.depth_from_world.inverse(Eigen::Isometry), world_from_b = b.depth_from_world.inverse(Eigen::Isometry);
  for (size_t i = 0; i < seam.vertices.size(); ++i) {
    const PixelVertex& v = seam.vertices[i];
    const bool in_a = v.camera == a.camera;
    const Eigen::Vector3f measured = options.smoothing_radius == 0
                                         ? (in_a ? a.mesh : b.mesh)->point(v.pixel)
                                         : (in_a ? world_from_a : world_from_b) * smoothed_camera_point(in_a ? a : b, v.pixel, options.smoothing_radius);
    positions[i] = !taken.shared.empty() && taken.shared[i] ? measured
                   : in_a ? consensus_point(measured, centre_a, b, world_from_b, options.ownership_distance)
                          : consensus_point(measured, centre_b, a, world_from_a, options.ownership_distance);
  }

  // The virtual camera halfway between the two.
  const Eigen::Quaternionf rotation_a(a.depth_from_world.linear().transpose());
  const Eigen::Quaternionf rotation_b(b.depth_from_world.linear().transpose());
  const Eigen::Matrix3f world_from_virtual = rotation_a.slerp(0.5f, rotation_b).toRotationMatrix();
  const Eigen::Vector3f viewpoint = 0.5f * (centre_a + centre_b);

  std::vector<std::pair<Kernel::Point_2, SeamInfo>> points;
  points.reserve(seam.vertices.size());
  bool behind = false;
  for (size_t i = 0; i < seam.vertices.size(); ++i) {
    const Eigen::Vector3f q = world_from_virtual.transpose() * (positions[i] - viewpoint);
    if (q.z() < 0.05f) {
      behind = true;
      break;
    }
    points.emplace_back(Kernel::Point_2(q.x() / q.z(), q.y() / q.z()), SeamInfo{static_cast<int>(i)});
  }
  if (behind) {
    // PCA plane of the seam (the paper's projection).
    Eigen::Vector3f mean = Eigen::Vector3f::Zero();
    for (const Eigen::Vector3f& p : positions) mean += p;
    mean /= static_cast<float>(positions.size());
    Eigen::Matrix3f covariance = Eigen::Matrix3f::Zero();
    for (const Eigen::Vector3f& p : positions) {
      const Eigen::Vector3f d = p - mean;
      covariance += d * d.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> pca(covariance);
    Eigen::Vector3f e1 = pca.eigenvectors().col(2);
    const Eigen::Vector3f e2 = pca.eigenvectors().col(1);
    // Make (e1, e2) a frame seen from behind by the cameras, like image axes (x right, y down):
    // then the faces' order is flipped below exactly as for the virtual camera.
    if (e1.cross(e2).dot(viewpoint - mean) > 0) e1 = -e1;
    points.clear();
    for (size_t i = 0; i < seam.vertices.size(); ++i) {
      const Eigen::Vector3f d = positions[i] - mean;
      points.emplace_back(Kernel::Point_2(d.dot(e1), d.dot(e2)), SeamInfo{static_cast<int>(i)});
    }
    seam.used_pca = true;
  }

  // The seam vertices come in the order their triangles were collected, along the boundaries, so
  // each lies next to the one before: inserted one by one, each from the face of the previous,
  // the point location walks a step or two. CGAL's range insertion sorts the points along a
  // Hilbert curve first, which cost more than it saved here (samba-4cam frame 0, one thread:
  // 6.4–7.1 ms against 5.8–6.2 ms for the insertion, the same triangulation). A skeleton of the
  // whole seam goes in first, every 16th point and then every 4th, so that the others mostly fall
  // inside the hull rather than extend it, which costs CGAL more flips (every 8th point alone:
  // clipping 3 % fewer instructions, about 0.4 ms of 16 on one thread, and every 4th, 16th or
  // 32nd did less; 16 then 4 another 1.4 %, better than 8 then 2, 32 then 8, 64, 16 then 4).
  constexpr size_t kSkeletonStrides[] = {16, 4};
  Delaunay triangulation;
  std::vector<Delaunay::Vertex_handle> handle(seam.vertices.size());
  Delaunay::Face_handle hint;
  auto insert_point = [&](const std::pair<Kernel::Point_2, SeamInfo>& point) {
    if (handle[point.second.index] != Delaunay::Vertex_handle()) return;  // in the skeleton
    const Delaunay::Vertex_handle v = triangulation.insert(point.first, hint);
    // A seam vertex at the 2-D position of an earlier one shares that vertex and its index.
    if (v->info().index < 0) v->info() = point.second;
    handle[point.second.index] = v;
    hint = v->face();
  };
  for (const size_t stride : kSkeletonStrides) {
    for (size_t k = 0; k < points.size(); k += stride) insert_point(points[k]);
  }
  for (const auto& point : points) insert_point(point);
  // With the seam laid out at locally averaged depth (unfiltered; filtered depth is laid out as
  // measured, as regular), about 90 % of the kept edges are already edges of the triangulation:
  // those are marked as constrained in place (which keeps it constrained Delaunay), without
  // CGAL's general insertion, which first looks for vertices on the segment and allocates a work
  // stack per call (clipping 9 % fewer instructions).
  // Of the others, most cross one edge and take one flip (flip_into_edge).
  for (const auto& [i, j] : constraints) {
    if (handle[i] == handle[j] || mark_constrained(triangulation, handle[i], handle[j])) continue;
    if (triangulation.dimension() == 2 && flip_into_edge(triangulation, handle[i], handle[j]) && mark_constrained(triangulation, handle[i], handle[j])) {
      continue;
    }
    triangulation.insert_constraint(handle[i], handle[j]);
  }
  const float max_edge2 = options.max_edge * options.max_edge;
  // Is the seam triangle of these vertices output? Not with an edge longer than max_edge, nor over
  // a kept triangle of either mesh (the seam would double the surface there).
  auto output = [&](int i0, int i1, int i2) {
    const Eigen::Vector3f &p0 = positions[i0], &p1 = positions[i1], &p2 = positions[i2];
    if ((p0 - p1).squaredNorm() > max_edge2 || (p1 - p2).squaredNorm() > max_edge2 || (p0 - p2).squaredNorm() > max_edge2) return false;
    const Eigen::Vector3f centroid = (p0 + p1 + p2) / 3.0f;
    return !covered_by_triangle(a, project_into(a, centroid), options.clipping_distance, kept_a) &&
           !covered_by_triangle(b, project_into(b, centroid), options.clipping_distance, kept_b);
  };
  for (auto face = triangulation.finite_faces_begin(); face != triangulation.finite_faces_end(); ++face) set_face_info(face, positions, output);
  std::vector<std::pair<Delaunay::Vertex_handle, Delaunay::Vertex_handle>> crease_candidates;
  flip_out_creases(triangulation, positions, max_edge2, output, crease_candidates);
  for (auto face = triangulation.finite_faces_begin(); face != triangulation.finite_faces_end(); ++face) {
    if (!face->info().output) continue;
    int index[3];
    for (int k = 0; k < 3; ++k) index[k] = face->vertex(k)->info().index;
    // CGAL's faces are counter-clockwise in the 2-D coordinates; with image-like axes (y down) a
    // face towards the viewer is clockwise there, like the SDC triangles. Flipping every face
    // orients the whole seam consistently, slivers included (a 3-D normal test would not).
    seam.triangles.emplace_back(index[0], index[2], index[1]);
  }
}

}  // namespace zipfusion
