#include "zipfusion/fusion/clipping.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <limits>
#include <span>

#include "zipfusion/fusion/seam_triangulation.h"
#include "zipfusion/fusion/surface_fit.h"

namespace zipfusion {
namespace {

// Short names for the seam's triangulations (seam_triangulation.h).
using Kernel = SeamKernel;
using Delaunay = SeamTriangulation;
using PlainDelaunay = SeamPointTriangulation;

// The seeds of a pair's seams in one mesh: its boundary triangles inside the mask. Both
// meshes' seeds are chosen once per pair, before either's seam is found (the bit matrices do not
// change until both are), and each seam reads both lists. Every triangle of `s.boundary` that
// still exists is a boundary triangle (it was one when collected, or it is next to a taken one,
// and the mesh only loses triangles): only existence is tested.
void select_seeds(const MeshView& view, const OverlapMask& mask, SeamScratch& s) {
  const DepthMesh& mesh = *view.mesh;
  s.seeds.clear();
  for (int id : s.boundary) {
    if ((mesh.triangles[cell_of(id)] & bit_of(id)) && mask.covers(cell_of(id), mesh.width, view.level)) {
      assert(is_boundary_triangle(mesh.triangles.data(), cell_of(id), mesh.width, bit_of(id)));
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
      if (first_visit(id)) test(id, project_camera_point(b, transform_point(b_from_a_camera, camera_triangle_centre(a, under, bit))));
    }
  }
  for (int id : s.visited) s.marks.clear(id);
}

// The centres of `view`'s seeds projected into `other`: each is needed twice, to test the seed
// and to find the other mesh's triangles under it.
void project_seeds(const MeshView& view, const MeshView& other, SeamScratch& s) {
  const Rigid3f other_from_view = b_from_a(view, other);
  s.seeds_in_other.clear();
  // A block of seeds at a time, through FRBR's row kernel.
  TriangleTestBlock block;
  for (size_t first = 0; first < s.seeds.size(); first += TriangleTestBlock::kCapacity) {
    block.count = 0;
    for (size_t k = first; k < std::min(s.seeds.size(), first + TriangleTestBlock::kCapacity); ++k) {
      const int cell = cell_of(s.seeds[k]);
      block.add(s.seeds[k], cell % view.mesh->width, cell / view.mesh->width);
    }
    project_triangle_centres(view, other, other_from_view, block);
    for (int i = 0; i < block.count; ++i) s.seeds_in_other.push_back(block.centre(i));
  }
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
                    std::vector<std::pair<int, int>>& edges, std::vector<KeptSide>& sides, std::vector<std::array<int, 3>>& kept_triangles) {
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
    // Each grid edge from p with the two grid triangles on its sides (upper triangle of cell (u, v):
    // pixels (u, v), (u, v + 1), (u + 1, v) in that order; lower: (u + 1, v), (u, v + 1), (u + 1, v + 1)):
    // whether the mesh has each, its third corner, and whether it runs from p to the edge's other end.
    struct Side {
      bool kept;
      int third;
      bool forward;
    };
    const struct {
      int other;
      Side sides[2];
    } grid_edges[6] = {
        {p + 1, {{(here & kUpperTriangle) != 0, p + width, false}, {(up & kLowerTriangle) != 0, p - width + 1, true}}},        // right
        {p - 1, {{(left & kUpperTriangle) != 0, p + width - 1, true}, {(up_left & kLowerTriangle) != 0, p - width, false}}},   // left
        {p + width, {{(here & kUpperTriangle) != 0, p + 1, true}, {(left & kLowerTriangle) != 0, p + width - 1, false}}},      // down
        {p - width, {{(up & kUpperTriangle) != 0, p - width + 1, false}, {(up_left & kLowerTriangle) != 0, p - 1, true}}},     // up
        {p + width - 1, {{(left & kUpperTriangle) != 0, p - 1, false}, {(left & kLowerTriangle) != 0, p + width, true}}},      // down and left
        {p - width + 1, {{(up & kUpperTriangle) != 0, p - width, true}, {(up & kLowerTriangle) != 0, p + 1, false}}},          // up and right
    };
    for (const auto& edge : grid_edges) {
      if (!edge.sides[0].kept && !edge.sides[1].kept) continue;
      const int j = seam_vertex(edge.other);
      if (j <= index) continue;
      edges.emplace_back(index, j);
      // A kept triangle with every corner in the seam is listed once: from the edge between its two
      // lowest seam indices, with the third corner the highest.
      for (const Side& side : edge.sides) {
        const int third = side.kept ? seam_vertex(side.third) : -1;
        if (third > j) kept_triangles.push_back({index, j, third});
      }
      // Where both sides are kept the edge is inside the kept mesh: no seam face borders it.
      if (edge.sides[0].kept && edge.sides[1].kept) {
        sides.push_back({});
        continue;
      }
      const Side& side = edge.sides[0].kept ? edge.sides[0] : edge.sides[1];
      sides.push_back({.third_pixel = side.third, .third_vertex = seam_vertex(side.third), .forward = side.forward});
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

// Sets a face's info: whether it is output (`output(i0, i1, i2)` of its seam vertices; never at
// a crossing of two constraints, where `constrain` made a vertex) and its normal in 3-D, its vertices
// taken in their (counter-clockwise) order.
template <typename Output>
void set_face_info(Delaunay::Face_handle f, const std::vector<Eigen::Vector3f>& positions, Output&& output) {
  const int i0 = f->vertex(0)->info().index, i1 = f->vertex(1)->info().index, i2 = f->vertex(2)->info().index;
  SeamFaceInfo& info = f->info();
  info.output = i0 >= 0 && i1 >= 0 && i2 >= 0 && output(i0, i1, i2);
  if (info.output) info.normal = (positions[i1] - positions[i0]).cross(positions[i2] - positions[i0]).normalized();
}

// Twice the signed area of the 2-D triangle (p0, p1, p2), positive counter-clockwise; in double,
// where the differences of the float coordinates are exact.
double signed_area2(const Eigen::Vector2f& p0, const Eigen::Vector2f& p1, const Eigen::Vector2f& p2) {
  const Eigen::Vector2d e1 = p1.cast<double>() - p0.cast<double>(), e2 = p2.cast<double>() - p0.cast<double>();
  return e1.x() * e2.y() - e1.y() * e2.x();
}

// Whether two signed areas (signed_area2) have the same sign, neither zero: a face keeps its
// orientation in the layout.
bool same_orientation(double before, double after) { return (before > 0 && after > 0) || (before < 0 && after < 0); }

// Two output faces whose normals' cosine is below this meet at a crease sharper than 60°, a fold
// (eval's count_folded_edges).
constexpr float kCreaseCosine = -0.5f;

// A seam's kept edges (its constraints), each listed under its lower end with the kept triangle
// beside it. A seam face on the kept triangle's side of one overlaps it: the output test refuses
// such faces (a face whose centroid lies more than d_c from the kept triangle's surface, as the
// layout's consensus and fairing can move it, slipped past covered_by_triangle, and assembly then
// dropped it: 6–7 % of the unfiltered seams' faces on samba-4cam frames 0, 10, 20 and 30, whose neighbours the creases
// had weighed against it instead of against the kept triangle). The creases read the kept
// triangle's normal.
class KeptEdges {
 public:
  struct Kept {
    int i, j;  // the edge's ends, i < j
    KeptSide side;
    Eigen::Vector3f third;  // where side.third_vertex is −1 (and the edge has a single kept side)
  };

  // Its arrays, reused across seams.
  struct Storage {
    std::vector<int> first, next;
    std::vector<Kept> kept;
  };

  KeptEdges(const MeshView& a, const MeshView& b, const TakenSeam& taken, Storage& storage) : first_(storage.first), kept_(storage.kept) {
    first_.assign(taken.seam.vertices.size() + 1, 0);
    for (const auto& [i, j] : taken.constraints) ++first_[i + 1];
    for (size_t i = 1; i < first_.size(); ++i) first_[i] += first_[i - 1];
    kept_.resize(first_.back());
    std::vector<int>& next = storage.next;
    next.assign(first_.begin(), first_.end() - 1);
    for (size_t k = 0; k < taken.constraints.size(); ++k) {
      const KeptSide& side = taken.kept_sides[k];
      const auto [i, j] = taken.constraints[k];
      const MeshView& view = taken.seam.vertices[i].camera == a.camera ? a : b;
      const bool needs_third = side.third_pixel >= 0 && side.third_vertex < 0;
      kept_[next[i]++] = {i, j, side, needs_third ? view.mesh->point(side.third_pixel) : Eigen::Vector3f::Zero()};
    }
  }

  // The kept edge (u, v), in either order; nullptr where it is none.
  const Kept* find(int u, int v) const {
    const int lower = std::min(u, v), higher = std::max(u, v);
    for (int k = first_[lower]; k < first_[lower + 1]; ++k) {
      if (kept_[k].j == higher) return &kept_[k];
    }
    return nullptr;
  }

  // Does a face with the counter-clockwise edge p → q in the layout lie on a kept triangle's side
  // of it? Its output runs q → p (stitch_seam flips the faces), as does the kept triangle beside
  // it on that side; an edge inside the kept mesh (kept on both sides) has no free side.
  bool on_kept_side(int p, int q) const {
    const Kept* kept = find(p, q);
    if (kept == nullptr) return false;
    if (kept->side.third_pixel < 0) return true;
    return kept->side.forward == (q < p);  // forward: the kept triangle runs from the lower end to the higher
  }

  const std::vector<Kept>& all() const { return kept_; }

 private:
  std::vector<int>& first_;  // per seam vertex: where its kept edges to higher vertices begin in kept_
  std::vector<Kept>& kept_;
};

// The creases of a seam's output faces, as the cosines between unit normals (1: no crease): between
// two output faces, and between an output face and the kept triangle beyond a kept edge (a
// constrained edge with no output face on its other side). The kept triangle shares the edge's
// corners, which the seam moves, so its normal is taken from their positions as they are; a
// corner that is not this seam's vertex stays where it was measured, as the output has it (or,
// beside another seam's vertex, near enough). The faces' info must be set (set_face_info).
class Creases {
 public:
  Creases(const Delaunay& triangulation, const std::vector<Eigen::Vector3f>& positions, const KeptEdges& kept_edges)
      : triangulation_(triangulation), positions_(positions), kept_edges_(kept_edges) {}

  float cosine(Delaunay::Face_handle f, int i) const {
    const Delaunay::Face_handle g = f->neighbor(i);
    // An infinite face is never output (set_face_info is given finite faces only).
    const bool f_output = f->info().output, g_output = g->info().output;
    if (f_output && g_output) return f->info().normal.dot(g->info().normal);
    if (f_output == g_output || !f->is_constrained(i)) return 1.0f;
    const int u = f->vertex(Delaunay::cw(i))->info().index, v = f->vertex(Delaunay::ccw(i))->info().index;
    if (u < 0 || v < 0) return 1.0f;
    const Eigen::Vector3f kept = kept_normal(u, v);
    return kept.isZero() ? 1.0f : (f_output ? f : g)->info().normal.dot(kept);
  }

  // The face of edge (f, i) that is output, and its index of the edge; f where neither is.
  std::pair<Delaunay::Face_handle, int> output_side(Delaunay::Face_handle f, int i) const {
    const Delaunay::Face_handle g = f->neighbor(i);
    if (!f->info().output && g->info().output) {
      return {g, triangulation_.mirror_index(f, i)};
    }
    return {f, i};
  }

 private:
  // The unit normal of the kept triangle beside seam edge (u, v), turned as set_face_info turns a
  // seam face's (the output flips the seam's faces: stitch_seam); zero where there is none.
  Eigen::Vector3f kept_normal(int u, int v) const {
    const KeptEdges::Kept* kept = kept_edges_.find(u, v);
    if (kept == nullptr || kept->side.third_pixel < 0) return Eigen::Vector3f::Zero();
    const Eigen::Vector3f& third = kept->side.third_vertex >= 0 ? positions_[kept->side.third_vertex] : kept->third;
    const Eigen::Vector3f &from = positions_[kept->side.forward ? kept->i : kept->j], &to = positions_[kept->side.forward ? kept->j : kept->i];
    return -(to - from).cross(third - from).normalized();
  }

  const Delaunay& triangulation_;
  const std::vector<Eigen::Vector3f>& positions_;
  const KeptEdges& kept_edges_;
};

// Where the seam's creases (Creases) may be, so that each step after the first looks at those
// edges instead of every edge of the triangulation (a look at every edge cost about as much as
// the step's own work, four times a seam): the creased edges found by the last look, and every
// edge of the faces around the points whose faces have changed since (flipped, made anew, a
// corner moved) or whose kept triangle has (its third corner moved). An edge's crease depends on
// its two faces and, beyond a kept edge, on the kept triangle's corners only.
class CreaseWatch {
 public:
  using VertexPair = std::pair<Delaunay::Vertex_handle, Delaunay::Vertex_handle>;

  // Its arrays, reused across seams.
  struct Storage {
    // Per seam point, where its kept edges (by their lower end) begin in edge_end_by_third: those
    // whose kept triangle has it as third corner.
    std::vector<int> first_with_third, edge_end_by_third, next;
    std::vector<VertexPair> creased_pairs;         // the creased edges the last look found
    std::vector<Delaunay::Vertex_handle> changed;  // the points whose faces changed since
    std::vector<VertexPair> candidates;            // scratch of creased()
    std::vector<Delaunay::Edge> creased;           // what creased() returns
    std::vector<Delaunay::Vertex_handle> removed;  // scratch of forget()
  };

  // `handle`: each seam point's vertex, as inserted. `everywhere`: every look is at every edge
  // (the reference the watch must match).
  CreaseWatch(const Delaunay& triangulation, const Creases& creases, const KeptEdges& kept_edges, size_t points,
              const std::vector<Delaunay::Vertex_handle>& handle, bool everywhere, Storage& storage)
      : triangulation_(triangulation), creases_(creases), handle_(handle), s_(storage), always_everywhere_(everywhere) {
    std::vector<int>&first_with_third = s_.first_with_third, &edge_end_by_third = s_.edge_end_by_third;
    s_.creased_pairs.clear();
    s_.changed.clear();
    // The kept edges' lower ends by their kept triangle's third corner, where that is a seam point.
    first_with_third.assign(points + 1, 0);
    for (const KeptEdges::Kept& kept : kept_edges.all()) {
      if (kept.side.third_vertex >= 0) ++first_with_third[kept.side.third_vertex + 1];
    }
    for (size_t i = 1; i < first_with_third.size(); ++i) first_with_third[i] += first_with_third[i - 1];
    std::vector<int>& next = s_.next;
    next.assign(first_with_third.begin(), first_with_third.end() - 1);
    edge_end_by_third.resize(first_with_third.back());
    for (const KeptEdges::Kept& kept : kept_edges.all()) {
      if (kept.side.third_vertex >= 0) edge_end_by_third[next[kept.side.third_vertex]++] = kept.i;
    }
  }

  // The faces around v have changed.
  void faces_changed(Delaunay::Vertex_handle v) {
    if (!everywhere_) s_.changed.push_back(v);
  }

  // Point v has moved: its faces, and the kept triangles it is the third corner of, have changed.
  // Points move only before any is dropped (relax_creases, then drop_crease_points), so the kept
  // edges' ends are all still in the triangulation.
  void point_moved(Delaunay::Vertex_handle v) {
    faces_changed(v);
    const int i = v->info().index;
    for (int k = s_.first_with_third[i]; k < s_.first_with_third[i + 1]; ++k) faces_changed(handle_[s_.edge_end_by_third[k]]);
  }

  // These vertices are about to leave the triangulation.
  void forget(const std::vector<Delaunay::Vertex_handle>& vertices) {
    std::vector<Delaunay::Vertex_handle>& removed_by_address = s_.removed;
    removed_by_address.assign(vertices.begin(), vertices.end());
    std::sort(removed_by_address.begin(), removed_by_address.end());
    auto removed = [&](Delaunay::Vertex_handle v) { return std::binary_search(removed_by_address.begin(), removed_by_address.end(), v); };
    std::erase_if(s_.creased_pairs, [&](const VertexPair& pair) { return removed(pair.first) || removed(pair.second); });
    std::erase_if(s_.changed, removed);
  }

  // The edges that may be creased now, each once: every edge whose cosine (Creases) is not at
  // least kCreaseCosine (NaN included, as relax_creases counts it). Valid until the next change.
  const std::vector<Delaunay::Edge>& creased() {
    std::vector<Delaunay::Edge>& creased = s_.creased;
    std::vector<Delaunay::Vertex_handle>& changed = s_.changed;
    creased.clear();
    if (triangulation_.dimension() != 2) return creased;  // no faces (all points on a line)
    auto consider = [&](Delaunay::Face_handle f, int i) {
      if (!(creases_.cosine(f, i) >= kCreaseCosine)) creased.emplace_back(f, i);
    };
    if (everywhere_) {
      for (auto edge = triangulation_.finite_edges_begin(); edge != triangulation_.finite_edges_end(); ++edge) consider(edge->first, edge->second);
      everywhere_ = always_everywhere_;
    } else {
      // The last look's creased edges, and every edge of the faces around the changed points.
      std::vector<VertexPair>& pairs = s_.candidates;
      pairs.assign(s_.creased_pairs.begin(), s_.creased_pairs.end());
      std::sort(changed.begin(), changed.end());
      changed.erase(std::unique(changed.begin(), changed.end()), changed.end());
      for (const Delaunay::Vertex_handle v : changed) {
        Delaunay::Face_circulator f = triangulation_.incident_faces(v), first = f;
        do {
          if (triangulation_.is_infinite(f)) continue;
          for (int i = 0; i < 3; ++i) pairs.push_back(ordered(f->vertex(Delaunay::cw(i)), f->vertex(Delaunay::ccw(i))));
        } while (++f != first);
      }
      changed.clear();
      std::sort(pairs.begin(), pairs.end());
      pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
      for (const auto& [u, v] : pairs) {
        Delaunay::Face_handle f;
        int i = 0;
        if (triangulation_.is_edge(u, v, f, i)) consider(f, i);
      }
    }
    s_.creased_pairs.clear();
    for (const auto& [f, i] : creased) s_.creased_pairs.push_back(ordered(f->vertex(Delaunay::cw(i)), f->vertex(Delaunay::ccw(i))));
    return creased;
  }

 private:
  static VertexPair ordered(Delaunay::Vertex_handle u, Delaunay::Vertex_handle v) { return u < v ? VertexPair{u, v} : VertexPair{v, u}; }

  const Delaunay& triangulation_;
  const Creases& creases_;
  const std::vector<Delaunay::Vertex_handle>& handle_;
  Storage& s_;
  bool always_everywhere_;
  bool everywhere_ = true;  // nothing looked at yet, or always_everywhere_
};

// Flips the seam's creases out where a flip makes the surface smoother (after Dyn, Levin and
// Rippa's data-dependent triangulations). Delaunay in 2-D chooses each quadrilateral's diagonal
// by the layout alone; where the two meshes' points lie a few millimetres apart in depth, the
// diagonal it chose can make two output triangles, both facing the virtual camera, meet at a
// crease sharper than 60° (normals more than 120° apart, eval's count_folded_edges), where the
// other diagonal makes them one slope. An unconstrained edge between two output faces is flipped,
// where a crease (Creases: also one against the kept triangle beyond a kept edge) lies on it or,
// for a crease on a kept edge, on its face's other edges, when its quadrilateral is strictly convex in 2-D (so both new faces are still
// counter-clockwise in the layout: they face the virtual camera), the new diagonal is no longer
// than max_edge, and the sharpest crease over the quadrilateral's five edges becomes less sharp;
// otherwise it is flipped back. A flip takes its two faces over (CGAL's data structure reuses
// them), so only theirs needs setting again. Every finite face's info must be set
// (set_face_info) and is kept so. `flat`: the points' layout, which after fairing is no longer
// CGAL's (fair_seam). The creases looked for first are those on the edges of `faces`, or every
// crease the watch knows where it is empty. `candidates` is scratch.
template <typename Output>
void flip_out_creases(Delaunay& triangulation, const std::vector<Eigen::Vector3f>& positions, const std::vector<Eigen::Vector2f>& flat,
                      float max_edge2, Output&& output, const Creases& creases, const std::vector<Delaunay::Face_handle>& faces,
                      CreaseWatch& watch, std::vector<std::pair<Delaunay::Vertex_handle, Delaunay::Vertex_handle>>& candidates) {
  if (triangulation.dimension() != 2) return;
  // The sharpest crease over edge (f, i) and the four outer edges of its quadrilateral.
  auto sharpest = [&](Delaunay::Face_handle f, int i) {
    const Delaunay::Face_handle g = f->neighbor(i);
    const int j = triangulation.mirror_index(f, i);
    return std::min({creases.cosine(f, i), creases.cosine(f, Delaunay::cw(i)), creases.cosine(f, Delaunay::ccw(i)),
                     creases.cosine(g, Delaunay::cw(j)), creases.cosine(g, Delaunay::ccw(j))});
  };
  auto edge_vertices = [](Delaunay::Face_handle f, int i) { return std::pair{f->vertex(Delaunay::cw(i)), f->vertex(Delaunay::ccw(i))}; };
  // A creased edge is a candidate itself; a constrained one (a kept edge, mostly against the kept
  // triangle beyond it) stays, and the other two edges of its output face are the candidates:
  // flipping one gives the face another third corner.
  auto queue_if_creased = [&](Delaunay::Face_handle f, int i) {
    if (!(creases.cosine(f, i) < kCreaseCosine)) return;
    if (!f->is_constrained(i)) {
      candidates.push_back(edge_vertices(f, i));
      return;
    }
    const Delaunay::Face_handle g = f->neighbor(i);
    for (const auto& [face, edge] : {std::pair{f, i}, std::pair{g, triangulation.mirror_index(f, i)}}) {
      if (triangulation.is_infinite(face) || !face->info().output) continue;
      for (const int other : {Delaunay::cw(edge), Delaunay::ccw(edge)}) {
        if (!face->is_constrained(other)) candidates.push_back(edge_vertices(face, other));
      }
    }
  };
  candidates.clear();
  if (faces.empty()) {
    for (const auto& [f, i] : watch.creased()) queue_if_creased(f, i);
  }
  for (const Delaunay::Face_handle f : faces) {
    for (int i = 0; i < 3; ++i) queue_if_creased(f, i);
  }
  // In the seam's order of points, each edge from its lower-numbered end: CGAL's edge iterator
  // gives an edge from whichever of its two faces lies at the lower address, which differs from
  // run to run, and the flips' result depends on their order. (Every candidate has two output
  // faces or borders one, so both ends are seam vertices.)
  auto index_pair = [](const std::pair<Delaunay::Vertex_handle, Delaunay::Vertex_handle>& edge) {
    return std::pair{edge.first->info().index, edge.second->info().index};
  };
  for (auto& [u, v] : candidates) {
    if (u->info().index > v->info().index) std::swap(u, v);
  }
  std::sort(candidates.begin(), candidates.end(), [&](const auto& x, const auto& y) { return index_pair(x) < index_pair(y); });
  candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
  // A flip changes only its quadrilateral: creases left on its outer edges are queued in turn, up
  // to a bound that ends the pass whatever happens.
  const size_t most = 8 * candidates.size();
  for (size_t k = 0; k < candidates.size() && k < most; ++k) {
    const auto [u, v] = candidates[k];
    Delaunay::Face_handle f;
    int i = 0;
    if (!triangulation.is_edge(u, v, f, i) || f->is_constrained(i)) continue;
    const Delaunay::Face_handle g = f->neighbor(i);
    // Only between two output faces (so every corner is a seam vertex), where a crease is left.
    if (triangulation.is_infinite(f) || triangulation.is_infinite(g) || !f->info().output || !g->info().output) continue;
    const float before = sharpest(f, i);
    if (!(before < kCreaseCosine)) continue;
    const Delaunay::Vertex_handle w = f->vertex(i), x = g->vertex(triangulation.mirror_index(f, i));
    const Eigen::Vector2f &flat_w = flat[w->info().index], &flat_x = flat[x->info().index];
    const double side_u = signed_area2(flat_w, flat_x, flat[u->info().index]), side_v = signed_area2(flat_w, flat_x, flat[v->info().index]);
    if (!same_orientation(side_u, -side_v)) continue;
    // Convex where CGAL has the points too: fairing and relaxing move the layout (flat), not
    // CGAL's points, and a flip across a quadrilateral that is concave there leaves CGAL an
    // invalid triangulation, in which removing a point (drop_crease_points) crashed or never
    // ended (a synthetic 1280x960 ring, frame 8).
    const CGAL::Orientation cgal_side_u = triangulation.orientation(w->point(), x->point(), u->point());
    const CGAL::Orientation cgal_side_v = triangulation.orientation(w->point(), x->point(), v->point());
    if (cgal_side_u == CGAL::COLLINEAR || cgal_side_u != -cgal_side_v) continue;
    if ((positions[w->info().index] - positions[x->info().index]).squaredNorm() > max_edge2) continue;
    triangulation.flip(f, i);  // f and g now hold the faces of edge (w, x)
    for (const Delaunay::Vertex_handle corner : {u, v, w, x}) watch.faces_changed(corner);
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
        queue_if_creased(face, index);
      }
    } else {
      triangulation.flip(h, e);  // back: the same two triangles as before, in the faces f and g again
      set_face_info(f, positions, output);
      set_face_info(g, positions, output);
    }
  }
}

// Below this cosine between a point's ray and its surface normal the ray grazes the surface: a
// small step along the normal is a long one along the ray, so the seam does not move the point.
constexpr float kGrazingCosine = 0.25f;

// One mesh's surface as its seam reads it: each pixel on its ray at the mean depth of its surface
// over the seam's smoothing window (SeamOptions::smoothing_radius; 0: as measured). Unfiltered,
// noise moves a point along its camera's ray, which a view from another direction sees as a
// sideways shift larger than the pixel spacing (about 7 mm for the Kinect's 1 cm at 2.5 m, seen
// from 45°): laid out as measured, the seam's grid would fold over and the kept edges cross. The
// mean keeps the layout as regular as the pixel grid.
struct SeamSurface {
  const MeshView& view;
  Rigid3f world_from_view;
  Eigen::Vector3f centre;  // the camera's centre, world
  int radius = 0;

  // The plane fitted for a point's normal: without smoothing (radius 0) over the 3×3 pixels two
  // apart around it, the cheapest; where the seam smooths, over 5×5 pixels every (1 + radius / 2)th.
  // On unfiltered depth (radius 2) the Kinect's noise (about 1 cm at 2.5 m) tilts a plane over
  // ±2 pixels by tens of degrees (samba-4cam frames 0, 10, 20 and 30 unfiltered: 170 folded
  // edges in the seams with a plane over the 5×5 pixels around, 142 over the 9×9, 140 over every
  // second of those, 167 over 3×3 pixels four apart, 212 two apart). On filtered depth (radius
  // 1, ReconstructOptions::seam_smoothing_px) frames 0–39 had 118 folded edges without
  // smoothing, 103 with only this plane over the 5×5, 103 with only the 3×3 mean, 89 with both.
  int normal_radius() const { return radius == 0 ? 1 : 2; }
  int normal_spacing() const { return radius == 0 ? 2 : 1 + radius / 2; }

  // The fits for the normals (fit_surface over normal_radius() and normal_spacing()) and the depths
  // (smoothed_depth over `radius`; as measured for 0) of `pixels`, all at once (surface_fit.h).
  void read_points(std::span<const int> pixels, SurfaceFit* fits, float* depths) const {
    fit_surfaces(view, pixels, normal_radius(), normal_spacing(), fits);
    if (radius == 0) {
      for (size_t k = 0; k < pixels.size(); ++k) depths[k] = view.mesh->depth[pixels[k]];
    } else {
      smoothed_depths(view, pixels, radius, depths);
    }
  }

  // The world point of `pixel` at `depth` (read_points') and the unit normal of its surface there
  // from `fit` (either sign; zero where the window's pixels lie on one line).
  void point_and_normal(int pixel, const SurfaceFit& fit, float depth, Eigen::Vector3f& point, Eigen::Vector3f& normal) const {
    const DepthMesh& mesh = *view.mesh;
    const float x = static_cast<float>(pixel % mesh.width), y = static_cast<float>(pixel / mesh.width);
    const Eigen::Vector3f in_camera = unproject(view.intrinsics, x, y, depth);
    point = radius == 0 ? mesh.point(pixel) : world_from_view * in_camera;
    normal.setZero();
    if (!fit.sloped) return;
    // The surface's tangents along the image axes: P(x, y) = z(x, y)·r(x, y), r the ray scaled to
    // depth 1, whose derivatives are (1/fx, 0, 0) and (0, 1/fy, 0).
    const Eigen::Vector3f ray = in_camera / depth;
    const Eigen::Vector3f along_x = fit.du * ray + Eigen::Vector3f(depth * view.inv_fx, 0, 0);
    const Eigen::Vector3f along_y = fit.dv * ray + Eigen::Vector3f(0, depth * view.inv_fy, 0);
    normal = (world_from_view.linear() * along_x.cross(along_y)).normalized();
  }

  // Where the surface lies around pixel coordinates q (in the image, with the pixel `cell` at its
  // integer part), read as the seam reads its own points, in two steps. near_pixel looks at the
  // pixels of `cell`'s 2×2 within `same_surface` of `near_depth` as measured: the nearest of them
  // (none where none is) and, for radius 0, their depth interpolated bilinearly. Otherwise
  // depth_from_fit reads the depth from the plane fitted over the window of that nearest pixel
  // (fit_surface over `radius`); 0 stands for no depth.
  struct NearPixel {
    int corner = -1;  // the nearest pixel's place in the 2×2 (bit 0: right, bit 1: below); −1: none
    int pixel = 0;
    float fu = 0, fv = 0;  // q's offset from the 2×2's top left pixel
    float depth = 0;       // radius 0: the bilinear depth
  };
  NearPixel near_pixel(const ViewPoint& q, float near_depth, float same_surface) const {
    const DepthMesh& mesh = *view.mesh;
    NearPixel near;
    // q lies in the image (its cell is valid), so the floor is a truncation.
    near.fu = q.x - static_cast<float>(static_cast<int>(q.x)), near.fv = q.y - static_cast<float>(static_cast<int>(q.y));
    const float fu = near.fu, fv = near.fv;
    const int pixels[4] = {q.cell, q.cell + 1, q.cell + mesh.width, q.cell + mesh.width + 1};
    const float w[4] = {(1 - fu) * (1 - fv), fu * (1 - fv), (1 - fu) * fv, fu * fv};
    float sum = 0, weight = 0;
    for (int k = 0; k < 4; ++k) {
      const float z = mesh.depth[pixels[k]];
      if (!(z > 0 && std::abs(z - near_depth) < same_surface)) continue;
      sum += w[k] * z;
      weight += w[k];
      if (near.corner < 0 || w[k] > w[near.corner]) near.corner = k;
    }
    if (near.corner < 0) return near;
    near.pixel = pixels[near.corner];
    if (radius == 0) near.depth = weight > 0 ? sum / weight : 0.0f;
    return near;
  }
  static float depth_from_fit(const NearPixel& near, const SurfaceFit& fit) {
    return fit.depth_at(near.fu - static_cast<float>(near.corner & 1), near.fv - static_cast<float>(near.corner >> 1));
  }
};

// Where the seam puts point p (world) of one mesh, whose surface normal there is `normal` (zero:
// unknown) and whose camera's ray through it is `ray` (unit), given the other mesh's surface
// `other` (after Turk and Levoy's consensus geometry): on p's own ray, where it meets the surface
// halfway between the two meshes' layers. The other layer's point is the other camera's surface
// point on its ray through p, its depth read around p's projection on the same surface (within
// `same_surface` of p's depth there) as the seam reads its own points (SeamSurface::near_pixel);
// the two layers are taken as parallel, at the distance of the two points along the normal. p
// itself where the other camera has no depth on that surface or the ray grazes the surface; the
// move is at most `same_surface`, and at most the width of p's pixel at its distance
// (`pixel_footprint`, distance from the camera / f): p's kept neighbours do not move, and a step of several pixels
// between them folds the grid where the pixels are small (cameras 0.9 m from a person, or
// 1280×960: a zippering review's 21–39 folded edges a frame against none in the separate meshes;
// with this bound 0–1, and on samba-4cam 0.90 → 0.68 a frame set filtered). Moving along the
// own ray keeps the point on its pixel, so its kept triangles do not turn over in its own camera.
// Laid out side by side in the seam, points of two layers a few millimetres apart in depth made
// its triangles zigzag between them, at creases sharper than 60°. Before 2026-12-03 the point
// moved to the place on its ray nearest the midpoint of the two points: cos α of halfway, α the
// angle between the two cameras' rays, which on a ring of four cameras is near 90° over most of
// a seam, so it hardly moved (docs/design.md).
// In two steps, so that the other surface's depths are read for many points at once:
// consensus_projection gives p's projection q into the other camera (cell −1 where p stays);
// consensus_move then moves p given the other surface's depth on q's ray (0: none).
ViewPoint consensus_projection(const Eigen::Vector3f& p, const Eigen::Vector3f& normal, const Eigen::Vector3f& ray,
                               const SeamSurface& other) {
  if (!(std::abs(ray.dot(normal)) > kGrazingCosine)) return {};
  return project_into(other.view, p);
}
Eigen::Vector3f consensus_move(const Eigen::Vector3f& p, const Eigen::Vector3f& normal, const Eigen::Vector3f& ray,
                               const SeamSurface& other, const ViewPoint& q, float depth, float same_surface, float pixel_footprint) {
  if (!(depth > 0)) return p;
  const float ray_along_normal = ray.dot(normal);
  const Eigen::Vector3f on_other = other.world_from_view * (q.in_camera * (depth / q.in_camera.z()));
  const float limit = std::min(same_surface, pixel_footprint);
  const float step = std::clamp(0.5f * normal.dot(on_other - p) / ray_along_normal, -limit, limit);
  return p + step * ray;
}

// How the seam is laid out in 2-D: through the virtual camera halfway between the two cameras,
// or (where a point lies behind it) onto the seam's PCA plane.
struct SeamLayout {
  bool pca = false;
  Eigen::Matrix3f world_from_virtual = Eigen::Matrix3f::Identity();
  Eigen::Vector3f viewpoint = Eigen::Vector3f::Zero();
  Eigen::Vector3f mean = Eigen::Vector3f::Zero(), e1 = Eigen::Vector3f::UnitX(), e2 = Eigen::Vector3f::UnitY();

  // World point p in the virtual camera's frame.
  Eigen::Vector3f in_virtual(const Eigen::Vector3f& p) const { return world_from_virtual.transpose() * (p - viewpoint); }
  // The unit direction along which p moves without moving in the layout: the virtual camera's
  // ray through it, or the PCA plane's normal.
  Eigen::Vector3f depth_direction(const Eigen::Vector3f& p) const { return pca ? e1.cross(e2) : (p - viewpoint).normalized(); }
  Eigen::Vector2f operator()(const Eigen::Vector3f& p) const {
    if (pca) return {(p - mean).dot(e1), (p - mean).dot(e2)};
    const Eigen::Vector3f q = in_virtual(p);
    return {q.x() / q.z(), q.y() / q.z()};
  }
};

// Scratch of the steps against creases: flip_out_creases, relax_creases, drop_crease_points and
// drop_creased_faces.
struct CreaseStepScratch {
  std::vector<std::pair<Delaunay::Vertex_handle, Delaunay::Vertex_handle>> flip_candidates;
  std::vector<Delaunay::Vertex_handle> corners, moved, dropped, around;
  std::vector<Delaunay::Face_handle> faces;
  RemovalScratch removal;
};

// Scratch of fair_seam.
struct FairingScratch {
  std::vector<std::array<int, 3>> faces;
  std::vector<Eigen::Vector3f> sum, next;
  std::vector<int> count;
  std::vector<Eigen::Vector2f> flat_next;
  std::vector<std::uint8_t> moved;
};

// Fairs the seam's points along their own rays (a Laplacian "umbrella" step restricted to the
// ray): each moves by half the distance, along its surface normal, to the mean of its neighbours in
// the triangulation no farther than max_edge (each counted once for every face the two share), for
// `iterations` Jacobi rounds, by at most `most` a round. The consensus leaves the two meshes'
// points a millimetre or so apart in depth (sensor noise, layers not quite parallel); between
// points 3–6 mm apart that is still a crease. A point that is a vertex of two seams (`fixed`),
// whose ray grazes its surface or whose normal is unknown stays, as does one with fewer than three
// such neighbour entries (two faces). A move that would turn a face over in the layout is undone, so every face keeps
// facing the virtual camera; `flat` holds the points' layout and is kept up to date.
void fair_seam(const Delaunay& triangulation, const std::vector<Eigen::Vector3f>& normals, const std::vector<Eigen::Vector3f>& rays,
               const std::vector<std::uint8_t>& fixed, const SeamLayout& layout, float max_edge2, float most, int iterations,
               std::vector<Eigen::Vector3f>& positions, std::vector<Eigen::Vector2f>& flat, FairingScratch& s) {
  if (triangulation.dimension() != 2 || iterations == 0) return;
  // The faces as plain index triples: CGAL's iterators cost more than the work done per face.
  s.faces.clear();
  for (auto f = triangulation.finite_faces_begin(); f != triangulation.finite_faces_end(); ++f) {
    const int i0 = f->vertex(0)->info().index, i1 = f->vertex(1)->info().index, i2 = f->vertex(2)->info().index;
    if (i0 >= 0 && i1 >= 0 && i2 >= 0) s.faces.push_back({i0, i1, i2});
  }
  const size_t n = positions.size();
  for (int iteration = 0; iteration < iterations; ++iteration) {
    s.sum.assign(n, Eigen::Vector3f::Zero());
    s.count.assign(n, 0);
    for (const auto& face : s.faces) {
      for (int k = 0; k < 3; ++k) {
        const int i = face[k], j = face[(k + 1) % 3];
        if ((positions[i] - positions[j]).squaredNorm() > max_edge2) continue;
        s.sum[i] += positions[j], s.sum[j] += positions[i];
        ++s.count[i], ++s.count[j];
      }
    }
    s.next = positions;
    s.flat_next = flat;
    s.moved.assign(n, 0);
    for (size_t i = 0; i < n; ++i) {
      const float ray_along_normal = rays[i].dot(normals[i]);
      if (s.count[i] < 3 || (!fixed.empty() && fixed[i]) || !(std::abs(ray_along_normal) > kGrazingCosine)) continue;
      const Eigen::Vector3f mean = s.sum[i] / static_cast<float>(s.count[i]);
      const float step = std::clamp(0.5f * normals[i].dot(mean - positions[i]) / ray_along_normal, -most, most);
      s.next[i] = positions[i] + step * rays[i];
      s.flat_next[i] = layout(s.next[i]);
      s.moved[i] = 1;
    }
    // Undo the moves of any face turned over, until none is (each pass only undoes, so it ends).
    for (bool undone = true; undone;) {
      undone = false;
      for (const auto& [i0, i1, i2] : s.faces) {
        if (!(s.moved[i0] | s.moved[i1] | s.moved[i2])) continue;
        const double before = signed_area2(flat[i0], flat[i1], flat[i2]), after = signed_area2(s.flat_next[i0], s.flat_next[i1], s.flat_next[i2]);
        if (same_orientation(before, after)) continue;
        for (const int i : {i0, i1, i2}) s.next[i] = positions[i], s.flat_next[i] = flat[i], s.moved[i] = 0;
        undone = true;
      }
    }
    positions.swap(s.next);
    flat.swap(s.flat_next);
  }
}

// Rounds of relax_creases: on samba-4cam frames 0, 10, 20 and 30 the folded edges with a seam
// face on either side went 23 → 10 filtered with one round, 9 with two, 8 with three or four
// (unfiltered 140 → 118, 116, 116, 117); on frames 0–39 filtered, the zippered meshes' seam folds
// (a seam face on either side) were 85 with two rounds, 79 with three.
constexpr int kCreaseRelaxRounds = 3;

// Relaxes the creases that fairing and flipping left (fair_seam, flip_out_creases): where an
// output face still meets another, or the kept triangle beyond a kept edge (Creases), at a crease
// sharper than 60°, each corner of the two faces (of the output face and the kept edge's far
// corner, where that is a seam vertex) moves to the plane
// through the mean of its triangulation neighbours (no farther than max_edge) along its normal,
// the full umbrella step that fair_seam takes half of, by at most `most`. It moves along the
// layout's own line of sight (SeamLayout::depth_direction), so its place in the layout stays and
// no face turns over there (along its camera's ray, as fair_seam moves, 211 of the 571 moves
// tried on samba-4cam frames 0, 10, 20 and 30 would have turned one over: these creases are often
// slivers, between points a few millimetres apart in depth across edges of a few millimetres).
// That takes it off its pixel's ray: `grid_unfolded(i, p)` says whether point i at p leaves the
// pixel grid around it unfolded in its camera (keeps_pixel_grid_unfolded). A move it refuses, or
// one that would change whether a face around the point is output (a longer edge, a face over a
// kept triangle), is halved, twice, then given up, so the seam keeps its faces. The first of
// `rounds` rounds takes the corners of every crease, each later one those of the creases around
// the points that moved. `fixed`, normals as in fair_seam; faces' info as in flip_out_creases,
// kept up to date. On those frames the seams' folds went 23 → 8 filtered, 140 → 116 unfiltered
// (10 and 118 with every point held within 0.35 pixel of its pixel, as keeps_pixel_grid_unfolded
// holds only those beside another seam's points).
template <typename Output, typename GridUnfolded>
void relax_creases(Delaunay& triangulation, const std::vector<Eigen::Vector3f>& normals, const std::vector<std::uint8_t>& fixed,
                   GridUnfolded&& grid_unfolded, const SeamLayout& layout, float max_edge2, float most, int rounds,
                   std::vector<Eigen::Vector3f>& positions, std::vector<Eigen::Vector2f>& flat, Output&& output, const Creases& creases,
                   CreaseWatch& watch, CreaseStepScratch& s) {
  if (triangulation.dimension() != 2 || rounds == 0) return;
  auto is_seam_face = [](Delaunay::Face_handle f) {
    return f->vertex(0)->info().index >= 0 && f->vertex(1)->info().index >= 0 && f->vertex(2)->info().index >= 0;
  };
  std::vector<Delaunay::Vertex_handle>& corners = s.corners;
  corners.clear();
  // Queues the four corners of the quadrilateral of edge (f, i): f's, then the one across the edge
  // (beyond a kept edge it is not a seam vertex, or not this seam's to move).
  auto queue_quadrilateral = [&](Delaunay::Face_handle f, int i) {
    corners.insert(corners.end(), {f->vertex(0), f->vertex(1), f->vertex(2), f->neighbor(i)->vertex(triangulation.mirror_index(f, i))});
  };
  // Queues the quadrilateral of each creased edge of output face f.
  auto queue_creases_of = [&](Delaunay::Face_handle f) {
    if (!f->info().output) return;
    for (int i = 0; i < 3; ++i) {
      if (!(creases.cosine(f, i) >= kCreaseCosine)) queue_quadrilateral(f, i);
    }
  };
  // Every crease, seen from either of its faces: a crease has one output face, and the cosine is
  // the same from both.
  for (const auto& [f, i] : watch.creased()) queue_quadrilateral(f, i);
  // The faces around the point being moved, with their signed areas and output before the move
  // (a Delaunay vertex rarely has more than 16 faces; one with more stays).
  constexpr size_t kMostFaces = 16;
  std::array<Delaunay::Face_handle, kMostFaces> around;
  std::array<double, kMostFaces> area_before;
  std::array<bool, kMostFaces> output_before;
  auto area2 = [&](Delaunay::Face_handle f) {
    return signed_area2(flat[f->vertex(0)->info().index], flat[f->vertex(1)->info().index], flat[f->vertex(2)->info().index]);
  };
  std::vector<Delaunay::Vertex_handle>& moved = s.moved;
  for (int round = 0; round < rounds && !corners.empty(); ++round) {
    // In the seam's order of points (the moves are Gauss–Seidel, so the result depends on the
    // order, and the handles' addresses differ from run to run).
    std::sort(corners.begin(), corners.end(), [](Delaunay::Vertex_handle x, Delaunay::Vertex_handle y) { return x->info().index < y->info().index; });
    corners.erase(std::unique(corners.begin(), corners.end()), corners.end());
    moved.clear();
    for (const Delaunay::Vertex_handle v : corners) {
      const int i = v->info().index;
      if (i < 0 || (!fixed.empty() && fixed[i])) continue;
      const Eigen::Vector3f direction = layout.depth_direction(positions[i]);
      const float along_normal = direction.dot(normals[i]);
      if (!(std::abs(along_normal) > kGrazingCosine)) continue;
      size_t faces = 0;
      bool too_many = false;
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      int count = 0;
      Delaunay::Face_circulator f = triangulation.incident_faces(v), first = f;
      do {
        if (triangulation.is_infinite(f)) continue;
        if (is_seam_face(f)) {
          too_many = too_many || faces == kMostFaces;
          if (!too_many) around[faces++] = f;
        }
        const int k = f->index(v);
        for (const int j : {f->vertex(Delaunay::cw(k))->info().index, f->vertex(Delaunay::ccw(k))->info().index}) {
          if (j >= 0 && (positions[j] - positions[i]).squaredNorm() <= max_edge2) sum += positions[j], ++count;
        }
      } while (++f != first);
      // Each neighbour counts once for every face the two share: at least two faces.
      if (too_many || count < 4) continue;
      const float step = std::clamp(normals[i].dot(sum / static_cast<float>(count) - positions[i]) / along_normal, -most, most);
      for (size_t k = 0; k < faces; ++k) area_before[k] = area2(around[k]), output_before[k] = around[k]->info().output;
      const Eigen::Vector3f start = positions[i];
      const Eigen::Vector2f flat_start = flat[i];
      bool keeps = false;
      for (float part = 1.0f; part > 0.2f && !keeps; part *= 0.5f) {
        positions[i] = start + part * step * direction;
        flat[i] = layout(positions[i]);
        keeps = grid_unfolded(i, positions[i]);
        for (size_t k = 0; k < faces && keeps; ++k) {
          const double area = area2(around[k]);
          const Delaunay::Face_handle g = around[k];
          keeps = same_orientation(area_before[k], area) &&
                  output(g->vertex(0)->info().index, g->vertex(1)->info().index, g->vertex(2)->info().index) == output_before[k];
        }
      }
      if (!keeps) {
        positions[i] = start, flat[i] = flat_start;
        continue;
      }
      for (size_t k = 0; k < faces; ++k) set_face_info(around[k], positions, output);
      watch.point_moved(v);
      moved.push_back(v);
    }
    corners.clear();
    for (const Delaunay::Vertex_handle v : moved) {
      Delaunay::Face_circulator f = triangulation.incident_faces(v), first = f;
      do queue_creases_of(f);
      while (++f != first);
    }
  }
}

// Rounds of drop_crease_points (samba-4cam frames 0–39 filtered: the folded edges with a seam
// face on either side went 48 → 9 with one round, 7 with two).
constexpr int kCreaseDropRounds = 2;

// Drops the seam points at the creases that flipping and relaxing left (flip_out_creases,
// relax_creases): for each crease sharper than 60°, between two output faces or between one and
// the kept triangle beyond a kept edge, the first of its corners that may go (the edge's ends,
// then the output face's third corner, then the other face's) leaves the triangulation, which
// fills the hole by Delaunay; the new faces' creases are then flipped out where they can be.
// Most of those creases are slivers on a concave quadrilateral, which no flip mends (samba-4cam
// frames 0–39 filtered: 68 of the 104 left after relaxing, and 22 more on a kept edge): the
// point is one of two layers' points a millimetre or so apart, and the surface is whole without
// it. A point on a kept edge (a constraint) stays, as does a point of two seams (`fixed`): its
// pixel is used by the output either way. A dropped point's pixel is still a seam vertex, in no
// face of it. Faces' info as in flip_out_creases, kept up to date.
template <typename Output>
void drop_crease_points(Delaunay& triangulation, const std::vector<std::uint8_t>& fixed, const std::vector<Eigen::Vector3f>& positions,
                        const std::vector<Eigen::Vector2f>& flat, float max_edge2, Output&& output, const Creases& creases, int rounds,
                        CreaseWatch& watch, CreaseStepScratch& s) {
  if (triangulation.dimension() != 2) return;
  auto may_go = [&](Delaunay::Vertex_handle v) {
    const int i = v->info().index;
    return !triangulation.is_infinite(v) && i >= 0 && (fixed.empty() || !fixed[i]) && !triangulation.are_there_incident_constraints(v);
  };
  std::vector<Delaunay::Vertex_handle>&dropped = s.dropped, &around = s.around;
  std::vector<Delaunay::Face_handle>& faces = s.faces;
  faces.clear();
  // The first of the corners of crease (f, i) that may go, into `dropped`.
  auto consider = [&](Delaunay::Face_handle face, int edge) {
    if (!(creases.cosine(face, edge) < kCreaseCosine)) return;
    const auto [f, i] = creases.output_side(face, edge);
    const Delaunay::Face_handle g = f->neighbor(i);
    // Each pair in the seam's order of points (which of an edge's faces CGAL's iterator gives it
    // from depends on their addresses).
    auto ordered = [](Delaunay::Vertex_handle x, Delaunay::Vertex_handle y) {
      return x->info().index <= y->info().index ? std::array{x, y} : std::array{y, x};
    };
    const auto ends = ordered(f->vertex(Delaunay::cw(i)), f->vertex(Delaunay::ccw(i)));
    const auto far = ordered(f->vertex(i), g->vertex(triangulation.mirror_index(f, i)));
    for (const Delaunay::Vertex_handle v : {ends[0], ends[1], far[0], far[1]}) {
      if (may_go(v)) {
        dropped.push_back(v);
        return;
      }
    }
  };
  for (int round = 0; round < rounds; ++round) {
    dropped.clear();
    // Every crease the first time; then those on the faces the last round made or flipped.
    if (round == 0) {
      for (const auto& [f, i] : watch.creased()) consider(f, i);
    } else {
      for (const Delaunay::Face_handle f : faces) {
        for (int i = 0; i < 3; ++i) consider(f, i);
      }
    }
    if (dropped.empty()) return;
    // In the seam's order of points (the handles' addresses differ from run to run).
    auto by_index = [](Delaunay::Vertex_handle x, Delaunay::Vertex_handle y) { return x->info().index < y->info().index; };
    std::sort(dropped.begin(), dropped.end(), by_index);
    dropped.erase(std::unique(dropped.begin(), dropped.end()), dropped.end());
    // The points around the holes: every new face has one as a corner.
    around.clear();
    for (const Delaunay::Vertex_handle v : dropped) {
      Delaunay::Vertex_circulator w = triangulation.incident_vertices(v), first = w;
      do {
        if (!triangulation.is_infinite(w)) around.push_back(w);
      } while (++w != first);
    }
    std::sort(around.begin(), around.end(), by_index);
    around.erase(std::unique(around.begin(), around.end()), around.end());
    around.erase(std::remove_if(around.begin(), around.end(),
                                [&](Delaunay::Vertex_handle w) { return std::binary_search(dropped.begin(), dropped.end(), w, by_index); }),
                 around.end());
    watch.forget(dropped);
    for (const Delaunay::Vertex_handle v : dropped) remove_point(triangulation, v, s.removal);
    // Every new face has its corners among the points around.
    for (const Delaunay::Vertex_handle w : around) watch.faces_changed(w);
    if (triangulation.dimension() != 2) return;
    faces.clear();
    for (const Delaunay::Vertex_handle w : around) {
      Delaunay::Face_circulator f = triangulation.incident_faces(w), first = f;
      do {
        if (!triangulation.is_infinite(f)) faces.push_back(f);
      } while (++f != first);
    }
    for (const Delaunay::Face_handle f : faces) set_face_info(f, positions, output);
    flip_out_creases(triangulation, positions, flat, max_edge2, output, creases, faces, watch, s.flip_candidates);
  }
}

// The last resort: an output face still at a crease sharper than 60° after the flips, the
// relaxation and the dropped points (flip_out_creases, relax_creases, drop_crease_points) is not
// output, and leaves a gap of one triangle; a fold is the worse defect (the surface turns back on
// itself). What is left is a face against the kept triangle beyond a kept edge, nearly always
// with all three corners on kept edges, so that none may go (samba-4cam frames 0–39 with the
// true poses: 5–22 faces a frame set without the filter, of 6 000–8 000 seam faces; 2 in the 40
// filtered). Returns how many.
int drop_creased_faces(const Creases& creases, CreaseWatch& watch, CreaseStepScratch& s) {
  std::vector<Delaunay::Face_handle>& creased = s.faces;
  creased.clear();
  for (const auto& [f, i] : watch.creased()) {
    if (!(creases.cosine(f, i) < kCreaseCosine)) continue;
    for (const Delaunay::Face_handle face : {f, f->neighbor(i)}) {
      if (face->info().output) creased.push_back(face);  // an infinite face never is
    }
  }
  std::sort(creased.begin(), creased.end());
  creased.erase(std::unique(creased.begin(), creased.end()), creased.end());
  // Both faces of a crease between two output faces go (which one is wrong is not known).
  for (const Delaunay::Face_handle f : creased) f->info().output = false;
  return static_cast<int>(creased.size());
}

}  // namespace

bool keeps_pixel_grid_unfolded(const MeshView& view, const SeamPixelMap& map, std::uint16_t own, int pixel, const Eigen::Vector3f& p,
                               const Eigen::Vector3f* positions) {
  const DepthMesh& mesh = *view.mesh;
  const int width = mesh.width, u = pixel % width, v = pixel / width;
  const ViewPoint moved = project_into(view, p);
  if (!(moved.in_camera.z() > 0)) return false;
  auto grid_point = [&](int q) { return Eigen::Vector2f(static_cast<float>(q % width), static_cast<float>(q / width)); };
  // Every triangle of the pixel grid with the pixel as a corner, kept or not: while none turns
  // over, the point stays inside the polygon of its neighbours, so it cannot move over a kept
  // triangle it is not a corner of either.
  bool beside_other_seam = map.seam == nullptr, turns_over = false;
  if (map.seam != nullptr) {
    for_each_grid_triangle_at_pixel(pixel, width, mesh.height, [&](int, TriangleBit, const int* corners, int) {
      Eigen::Vector2f grid[3], image[3];
      for (int k = 0; k < 3; ++k) {
        const int q = corners[k];
        grid[k] = grid_point(q);
        const std::uint16_t seam = map.seam[q];
        if (q == pixel) {
          image[k] = Eigen::Vector2f(moved.x, moved.y);
        } else if (seam == SeamPixelMap::kNoSeam || seam == SeamPixelMap::kManySeams) {
          image[k] = grid[k];  // on its pixel's ray: a point of several seams stays there
        } else if (seam == own) {
          const ViewPoint seen = project_into(view, positions[map.vertex[q]]);
          image[k] = Eigen::Vector2f(seen.x, seen.y);
        } else {
          beside_other_seam = true;
          return;
        }
      }
      turns_over = turns_over || !same_orientation(signed_area2(grid[0], grid[1], grid[2]), signed_area2(image[0], image[1], image[2]));
    });
  }
  if (turns_over) return false;
  const float du = moved.x - static_cast<float>(u), dv = moved.y - static_cast<float>(v);
  const float most = beside_other_seam ? kMostPixelShiftBesideOtherSeam : kMostPixelShift;
  return du * du + dv * dv <= most * most;
}

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

void take_seam(const MeshView& a, const MeshView& b, const SeamOptions& options, const OverlapMask& mask_a, const OverlapMask& mask_b,
               SeamScratch& scratch_a, SeamScratch& scratch_b, TakenSeam& taken) {
  taken.clear();
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
  add_kept_edges(a, scratch_a, 0, a_end, seam, taken.constraints, taken.kept_sides, taken.kept_triangles);
  add_kept_edges(b, scratch_b, a_end, static_cast<int>(seam.vertices.size()), seam, taken.constraints, taken.kept_sides, taken.kept_triangles);
  clear_pixel_marks(a, scratch_a);
  clear_pixel_marks(b, scratch_b);
  taken.taken_a.assign(scratch_a.taken.begin(), scratch_a.taken.end());
  taken.taken_b.assign(scratch_b.taken.begin(), scratch_b.taken.end());
}

// stitch_seam's arrays, kept between frames.
struct StitchScratch::Buffers {
  std::vector<Eigen::Vector3f> normals, rays;
  std::vector<int> own_points, own_pixels, near_index, near_pixels;
  std::vector<SurfaceFit> fits;
  std::vector<float> depths;
  std::vector<ViewPoint> projections;
  std::vector<SeamSurface::NearPixel> near;
  std::vector<Eigen::Vector2f> flat;
  std::vector<SeamPoint> points;
  std::vector<Delaunay::Vertex_handle> handle;
  InsertionScratch insertion;
  PlainDelaunay points_only;  // kept with their containers' blocks (clear_keeping_memory)
  Delaunay triangulation;
  std::vector<std::array<int, 3>> kept_triangles;
  std::vector<std::uint8_t> kept_triangle_corner;
  ConstraintScratch constraints;
  FairingScratch fairing;
  KeptEdges::Storage kept_edges;
  CreaseWatch::Storage crease_watch;
  CreaseStepScratch crease_steps;
};

StitchScratch::StitchScratch() : buffers_(std::make_unique<Buffers>()) {}
StitchScratch::~StitchScratch() = default;
StitchScratch::StitchScratch(StitchScratch&&) noexcept = default;
StitchScratch& StitchScratch::operator=(StitchScratch&&) noexcept = default;

void stitch_seam(const MeshView& a, const Eigen::Vector3f& centre_a, const MeshView& b, const Eigen::Vector3f& centre_b,
                 const SeamOptions& options, const KeptAt& kept_a, const KeptAt& kept_b, const SeamPixels& pixels, TakenSeam& taken,
                 StitchScratch& scratch) {
  StitchScratch::Buffers& buffers = scratch.buffers();
  Seam& seam = taken.seam;
  const std::vector<std::pair<int, int>>& constraints = taken.constraints;
  if (seam.vertices.size() < 3) return;

  // Where the seam puts its points, formed once (each face reads three): each on its own pixel's
  // ray as its seam reads its surface (SeamSurface), then moved to halfway between the two meshes'
  // layers (consensus_projection, consensus_move), so that the two meshes' points lie close
  // together; after the triangulation they are faired (fair_seam). The output takes the same
  // positions: where it kept the measured ones, a face the layout saw from the front could face
  // away in 3-D, folded over its neighbours.
  const size_t count = seam.vertices.size();
  std::vector<Eigen::Vector3f>& positions = seam.positions;
  positions.resize(count);
  std::vector<Eigen::Vector3f>&normals = buffers.normals, &rays = buffers.rays;
  normals.resize(count);  // every point's is set below
  rays.resize(count);
  const SeamSurface surface_a{a, a.depth_from_world.inverse(Eigen::Isometry), centre_a, options.smoothing_radius};
  const SeamSurface surface_b{b, b.depth_from_world.inverse(Eigen::Isometry), centre_b, options.smoothing_radius};
  // Each camera's points read their own surface together (SeamSurface::read_points), then the
  // other camera's near their projections, also together (SeamSurface::near_pixel, then the fits
  // at the pixels it found).
  std::vector<int>&own_points = buffers.own_points, &own_pixels = buffers.own_pixels, &near_index = buffers.near_index,
                   &near_pixels = buffers.near_pixels;
  std::vector<SurfaceFit>& fits = buffers.fits;
  std::vector<float>& depths = buffers.depths;
  std::vector<ViewPoint>& projections = buffers.projections;
  projections.assign(count, ViewPoint{});
  std::vector<SeamSurface::NearPixel>& near = buffers.near;
  near.assign(count, SeamSurface::NearPixel{});
  for (const SeamSurface* own : {&surface_a, &surface_b}) {
    const SeamSurface& other = own == &surface_a ? surface_b : surface_a;
    own_points.clear();
    own_pixels.clear();
    for (size_t i = 0; i < count; ++i) {
      if (seam.vertices[i].camera != own->view.camera) continue;
      own_points.push_back(static_cast<int>(i));
      own_pixels.push_back(seam.vertices[i].pixel);
    }
    fits.resize(own_pixels.size());
    depths.resize(own_pixels.size());
    own->read_points(own_pixels, fits.data(), depths.data());
    near_index.clear();
    near_pixels.clear();
    for (size_t k = 0; k < own_points.size(); ++k) {
      const int i = own_points[k];
      own->point_and_normal(own_pixels[k], fits[k], depths[k], positions[i], normals[i]);
      rays[i] = (positions[i] - own->centre).normalized();
      // A pixel that is a vertex of two seams keeps its measured place.
      if (!taken.shared.empty() && taken.shared[i]) continue;
      const ViewPoint& q = projections[i] = consensus_projection(positions[i], normals[i], rays[i], other);
      if (q.cell < 0) continue;
      near[i] = other.near_pixel(q, q.in_camera.z(), options.ownership_distance);
      if (near[i].corner >= 0 && other.radius > 0) {
        near_index.push_back(i);
        near_pixels.push_back(near[i].pixel);
      }
    }
    fits.resize(near_pixels.size());
    fit_surfaces(other.view, near_pixels, other.radius, 1, fits.data());
    for (size_t k = 0; k < near_index.size(); ++k) near[near_index[k]].depth = SeamSurface::depth_from_fit(near[near_index[k]], fits[k]);
    for (const int i : own_points) {
      if (near[i].corner >= 0) {
        const float pixel_footprint = (positions[i] - own->centre).norm() * std::max(own->view.inv_fx, own->view.inv_fy);
        positions[i] = consensus_move(positions[i], normals[i], rays[i], other, projections[i], near[i].depth, options.ownership_distance,
                                      pixel_footprint);
      }
    }
  }

  // The virtual camera halfway between the two.
  SeamLayout layout;
  const Eigen::Quaternionf rotation_a(a.depth_from_world.linear().transpose());
  const Eigen::Quaternionf rotation_b(b.depth_from_world.linear().transpose());
  layout.world_from_virtual = rotation_a.slerp(0.5f, rotation_b).toRotationMatrix();
  layout.viewpoint = 0.5f * (centre_a + centre_b);
  for (const Eigen::Vector3f& p : positions) {
    if (layout.in_virtual(p).z() < 0.05f) {
      layout.pca = true;
      break;
    }
  }
  if (layout.pca) {
    // PCA plane of the seam (the paper's projection).
    for (const Eigen::Vector3f& p : positions) layout.mean += p;
    layout.mean /= static_cast<float>(positions.size());
    Eigen::Matrix3f covariance = Eigen::Matrix3f::Zero();
    for (const Eigen::Vector3f& p : positions) {
      const Eigen::Vector3f d = p - layout.mean;
      covariance += d * d.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> pca(covariance);
    layout.e1 = pca.eigenvectors().col(2);
    layout.e2 = pca.eigenvectors().col(1);
    // Make (e1, e2) a frame seen from behind by the cameras, like image axes (x right, y down):
    // then the faces' order is flipped below exactly as for the virtual camera.
    if (layout.e1.cross(layout.e2).dot(layout.viewpoint - layout.mean) > 0) layout.e1 = -layout.e1;
    seam.used_pca = true;
  }
  std::vector<Eigen::Vector2f>& flat = buffers.flat;
  flat.resize(seam.vertices.size());  // every point's is set here
  std::vector<SeamPoint>& points = buffers.points;
  points.clear();
  for (size_t i = 0; i < seam.vertices.size(); ++i) {
    flat[i] = layout(positions[i]);
    points.emplace_back(Kernel::Point_2(flat[i].x(), flat[i].y()), SeamVertexInfo{static_cast<int>(i)});
  }

  // The seam vertices come in the order their triangles were collected, along the boundaries, so
  // each lies next to the one before: inserted one by one, each from the face of the previous,
  // the point location walks a step or two. CGAL's range insertion sorts the points along a
  // Hilbert curve first, which cost more than it saved here (samba-4cam frame 0, one thread:
  // 6.4–7.1 ms against 5.8–6.2 ms for the insertion, the same triangulation). insert_points puts
  // the hull in first, then a skeleton of the seam, then the rest. The triangulation is kept
  // between seams and frames (clear_keeping_memory), for the blocks of its containers, and
  // swapped into the constrained one for the seam.
  PlainDelaunay& points_only = buffers.points_only;
  clear_keeping_memory(points_only);
  std::vector<Delaunay::Vertex_handle>& handle = buffers.handle;
  insert_points(points_only, points, handle, buffers.insertion);
  Delaunay& triangulation = buffers.triangulation;
  triangulation.swap(points_only);
  // Every kept edge becomes a constraint (constrain). With the seam laid out at locally averaged
  // depth (the default; filtered depth laid out as measured is about as regular), about 90 % of
  // them are already edges of the triangulation and are only marked; the others are flipped into
  // place.
  for (const auto& [i, j] : constraints) constrain(triangulation, handle[i], handle[j], buffers.constraints);
  const float max_edge2 = options.max_edge * options.max_edge;
  fair_seam(triangulation, normals, rays, taken.shared, layout, max_edge2, options.ownership_distance, options.fairing_iterations, positions, flat,
            buffers.fairing);
  // The kept triangles whose three corners are all seam vertices (take_seam lists them), each as
  // its sorted corners: the triangulation has a face on exactly those corners (its three edges
  // are constraints), which would double the kept triangle. covered_by_triangle below misses it
  // where the seam has moved the corners so far that the centroid projects beside the triangle's
  // cell (samba-4cam frame 31 filtered: one such face, turned over against its kept twin). The
  // corners are taken as the triangulation numbers them (a point at the 2-D position of a
  // lower-numbered one has that one's index), and flagged, so that most faces are cleared by three
  // loads (the output test runs for every face the flips, the relaxation and the dropping touch).
  std::vector<std::array<int, 3>>& kept_triangles = buffers.kept_triangles;
  kept_triangles.clear();
  std::vector<std::uint8_t>& kept_triangle_corner = buffers.kept_triangle_corner;
  kept_triangle_corner.assign(seam.vertices.size(), 0);
  for (const std::array<int, 3>& triangle : taken.kept_triangles) {
    std::array<int, 3> corners;
    for (int k = 0; k < 3; ++k) {
      corners[k] = handle[triangle[k]]->info().index;
      kept_triangle_corner[corners[k]] = 1;
    }
    std::sort(corners.begin(), corners.end());
    kept_triangles.push_back(corners);
  }
  std::sort(kept_triangles.begin(), kept_triangles.end());
  auto is_kept_triangle = [&](int i0, int i1, int i2) {
    if (!(kept_triangle_corner[i0] & kept_triangle_corner[i1] & kept_triangle_corner[i2])) return false;
    std::array<int, 3> corners{i0, i1, i2};
    std::sort(corners.begin(), corners.end());
    return std::binary_search(kept_triangles.begin(), kept_triangles.end(), corners);
  };
  const KeptEdges kept_edges(a, b, taken, buffers.kept_edges);
  // Is the seam triangle of these vertices (counter-clockwise in the layout) output? Not with an
  // edge longer than max_edge, nor over a kept triangle of either mesh (the seam would double the
  // surface there): beside a kept edge on the kept triangle's side, or elsewhere over it.
  auto output = [&](int i0, int i1, int i2) {
    if (is_kept_triangle(i0, i1, i2)) return false;
    if (kept_edges.on_kept_side(i0, i1) || kept_edges.on_kept_side(i1, i2) || kept_edges.on_kept_side(i2, i0)) return false;
    const Eigen::Vector3f &p0 = positions[i0], &p1 = positions[i1], &p2 = positions[i2];
    if ((p0 - p1).squaredNorm() > max_edge2 || (p1 - p2).squaredNorm() > max_edge2 || (p0 - p2).squaredNorm() > max_edge2) return false;
    const Eigen::Vector3f centroid = (p0 + p1 + p2) / 3.0f;
    return !covered_by_triangle(a, project_into(a, centroid), options.clipping_distance, kept_a) &&
           !covered_by_triangle(b, project_into(b, centroid), options.clipping_distance, kept_b);
  };
  for (auto face = triangulation.finite_faces_begin(); face != triangulation.finite_faces_end(); ++face) set_face_info(face, positions, output);
  const Creases creases(triangulation, positions, kept_edges);
  CreaseWatch crease_watch(triangulation, creases, kept_edges, positions.size(), handle, !options.crease_watch, buffers.crease_watch);
  CreaseStepScratch& crease_steps = buffers.crease_steps;
  crease_steps.faces.clear();  // flip_out_creases looks at every crease the watch knows
  flip_out_creases(triangulation, positions, flat, max_edge2, output, creases, crease_steps.faces, crease_watch, crease_steps.flip_candidates);
  if (options.fairing_iterations > 0) {
    // Does point i at p leave the pixel grid around it unfolded in its camera?
    auto grid_unfolded = [&](int i, const Eigen::Vector3f& p) {
      const bool in_a = seam.vertices[i].camera == a.camera;
      return keeps_pixel_grid_unfolded(in_a ? a : b, in_a ? pixels.a : pixels.b, pixels.own, seam.vertices[i].pixel, p, positions.data());
    };
    relax_creases(triangulation, normals, taken.shared, grid_unfolded, layout, max_edge2, options.ownership_distance, kCreaseRelaxRounds,
                  positions, flat, output, creases, crease_watch, crease_steps);
  }
  drop_crease_points(triangulation, taken.shared, positions, flat, max_edge2, output, creases, kCreaseDropRounds, crease_watch, crease_steps);
  seam.creased_faces_dropped = drop_creased_faces(creases, crease_watch, crease_steps);
  for (auto face = triangulation.finite_faces_begin(); face != triangulation.finite_faces_end(); ++face) {
    if (!face->info().output) continue;
    int index[3];
    for (int k = 0; k < 3; ++k) index[k] = face->vertex(k)->info().index;
    // CGAL's faces are counter-clockwise in the 2-D coordinates; with image-like axes (y down) a
    // face towards the viewer is clockwise there, like the SDC triangles. Flipping every face
    // orients the whole seam consistently, slivers included (a 3-D normal test would not).
    seam.triangles.emplace_back(index[0], index[2], index[1]);
  }
  // Back to points_only, so that one triangulation takes every seam's points, and its blocks grow
  // to the largest seam once: taking turns, each would grow again to the largest of every other.
  triangulation.swap(points_only);
}

}  // namespace zipfusion
