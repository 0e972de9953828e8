#include "zipfusion/fusion/seam_triangulation.h"

#include <CGAL/intersections.h>

#include <algorithm>
#include <array>
#include <cassert>
#include <cstddef>
#include <iterator>
#include <optional>

namespace zipfusion {
namespace {

using Vertex = SeamTriangulation::Vertex_handle;
using Face = SeamTriangulation::Face_handle;
using Edge = SeamTriangulation::Edge;
using Point = SeamKernel::Point_2;
// A face's corners after corner i, counter-clockwise and clockwise.
int ccw(int i) { return SeamTriangulation::ccw(i); }
int cw(int i) { return SeamTriangulation::cw(i); }

// Marks the triangulation edge (from, to) as constrained on both its sides; false when it is not an edge.
bool mark_constrained(SeamTriangulation& triangulation, Vertex from, Vertex to) {
  Face face;
  int edge;
  if (triangulation.dimension() != 2 || !triangulation.is_edge(from, to, face, edge)) return false;
  face->set_constraint(edge, true);
  face->neighbor(edge)->set_constraint(triangulation.mirror_index(face, edge), true);
  return true;
}

// Flips the edges the constraint's flips made, and those around each flip, until each is
// constrained Delaunay (Lawson's flips; CGAL's test, with its perturbation of co-circular points).
void restore_delaunay(SeamTriangulation& triangulation, std::vector<ConstraintScratch::VertexPair>& created) {
  while (!created.empty()) {
    const auto [u, w] = created.back();
    created.pop_back();
    Face f;
    int e;
    if (!triangulation.is_edge(u, w, f, e) || !triangulation.is_flipable(f, e)) continue;
    const Vertex p = f->vertex(e), q = f->neighbor(e)->vertex(triangulation.mirror_index(f, e));
    triangulation.flip(f, e);
    for (const Vertex corner : {u, w}) {
      created.emplace_back(p, corner);
      created.emplace_back(q, corner);
    }
  }
}

// What constrain_by_flips did with a segment.
enum class Flipped {
  kDone,        // it is a constrained edge now
  kSplit,       // it crossed a constraint: its part up to the crossing is done, the rest is left
  kLeftToCgal,  // nothing, or flips that stopped short: CGAL's insertion is to finish it
};

Flipped constrain_by_flips(SeamTriangulation& triangulation, Vertex from, Vertex to, ConstraintScratch& s, int depth, Vertex& rest_from);

// `constrain` below `depth` nested crossings: by flips, each crossing it meets on the way split
// off in turn, and what flips cannot do by CGAL's insertion.
void constrain_at_depth(SeamTriangulation& triangulation, Vertex from, Vertex to, ConstraintScratch& s, int depth) {
  for (;;) {
    Vertex rest_from;
    switch (constrain_by_flips(triangulation, from, to, s, depth, rest_from)) {
      case Flipped::kDone:
        return;
      case Flipped::kSplit:
        from = rest_from;
        continue;
      case Flipped::kLeftToCgal:
        ++s.left_to_cgal;
        triangulation.insert_constraint(from, to);
        restore_delaunay(triangulation, s.created);  // after flips that stopped short, if any
        return;
    }
  }
}

// The point where segment (a, b) crosses the constrained edge (c, d), as CGAL's insertion finds it
// (its Exact_predicates_tag path: the kernel's intersection of the two segments, taken with the
// crossed edge's ends in CGAL's order, then snapped to an end within 4 units in the last place),
// so that the vertex made there is CGAL's to the bit; none where the kernel finds no single point.
std::optional<Point> crossing_point(const Point& a, const Point& b, const Point& c, const Point& d) {
  const auto crossing = CGAL::intersection(SeamKernel::Segment_2(a, b), SeamKernel::Segment_2(c, d));
  if (!crossing) return std::nullopt;
#if CGAL_VERSION_MAJOR >= 6
  const Point* found = std::get_if<Point>(&*crossing);
#else
  const Point* found = boost::get<Point>(&*crossing);
#endif
  if (found == nullptr) return std::nullopt;
  Point x = *found;
  if (x == a || x == b || x == c || x == d) return x;
  CGAL::Bbox_2 around = x.bbox();
  around.dilate(4);
  for (const Point* end : {&a, &b, &c, &d}) {
    if (CGAL::do_overlap(around, end->bbox())) x = *end;
  }
  return x;
}

// The segment (from, to) crosses the constrained edge `crossed` of its walk's face: makes the
// crossing a vertex v, as CGAL's insertion does where two constraints cross (where it snapped to
// an end of the crossed edge, that end), constrains the crossed edge's two halves and (from, v),
// and returns v, from which the rest of the segment goes on; a null handle, with nothing changed,
// where CGAL's insertion must decide (the point outside the two triangles beside the crossed
// edge, where CGAL constructs it again more exactly, or on one of the segment's ends or the far
// corners of those triangles).
Vertex split_at_crossing(SeamTriangulation& triangulation, Vertex from, Vertex to, Edge crossed, ConstraintScratch& s, int depth) {
  const auto [face, i] = crossed;
  // CGAL's names: the crossed edge from c (clockwise of the far corner in the walk's face) to d.
  const Vertex c = face->vertex(cw(i)), d = face->vertex(ccw(i));
  const Face beyond = face->neighbor(i);
  const Vertex near_corner = face->vertex(i), far_corner = beyond->vertex(triangulation.mirror_index(face, i));
  const std::optional<Point> crossing = crossing_point(from->point(), to->point(), c->point(), d->point());
  if (!crossing) return {};
  const Point& x = *crossing;
  auto inside_or_on = [&](Face f) {
    for (int k = 0; k < 3; ++k) {
      if (triangulation.orientation(f->vertex(k)->point(), f->vertex(ccw(k))->point(), x) == CGAL::RIGHT_TURN) return false;
    }
    return true;
  };
  if (!(inside_or_on(face) || inside_or_on(beyond))) return {};
  for (const Vertex corner : {from, to, near_corner, far_corner}) {
    if (x == corner->point()) return {};
  }
  if (x == c->point()) return c;  // the crossed constraint stays whole; the segment bends through c
  if (x == d->point()) return d;
  face->set_constraint(i, false);
  beyond->set_constraint(triangulation.mirror_index(face, i), false);
  const Vertex v = triangulation.insert(x, face);  // a new vertex: x is no corner of the two triangles it lies in
  constrain_at_depth(triangulation, c, v, s, depth + 1);
  constrain_at_depth(triangulation, v, d, s, depth + 1);
  return v;
}

// Constrains (from, to) by flipping the edges it crosses (Sloan's insertion of a constraint,
// 1993): an edge whose two triangles form a convex quadrilateral is flipped, one that still
// crosses goes back into the queue, and one that does not waits for the Delaunay test
// (restore_delaunay). That gives the constrained Delaunay triangulation that CGAL's insertion
// gives (up to the choice among co-circular points). Where it crosses a constrained edge, the
// segment is split where they cross (split_at_crossing), its part up to there constrained, and the
// rest left to the caller (kSplit, rest_from). Left to CGAL: a vertex on the segment, a crossing
// split_at_crossing leaves to it, more than eight nested crossings, an infinite face on the way,
// or a queue that does not empty in a generous number of steps. Most kept edges cross nothing
// (they are marked in place) or one diagonal (one flip).
Flipped constrain_by_flips(SeamTriangulation& triangulation, Vertex from, Vertex to, ConstraintScratch& s, int depth, Vertex& rest_from) {
  if (from == to || mark_constrained(triangulation, from, to)) return Flipped::kDone;
  if (triangulation.dimension() != 2 || depth > 8) return Flipped::kLeftToCgal;
  const Point &p_from = from->point(), &p_to = to->point();
  auto side_of = [&](Vertex v) { return triangulation.orientation(p_from, p_to, v->point()); };
  // The face around `from` that the segment leaves through: its corner after `from` (counter-
  // clockwise) on the segment's right, the next on its left.
  Face face;
  int i = -1;
  SeamTriangulation::Face_circulator around = triangulation.incident_faces(from), first = around;
  if (around == nullptr) return Flipped::kLeftToCgal;
  do {
    if (triangulation.is_infinite(around)) continue;
    const int k = around->index(from);
    if (side_of(around->vertex(ccw(k))) == CGAL::RIGHT_TURN && side_of(around->vertex(cw(k))) == CGAL::LEFT_TURN) {
      face = around;
      i = k;
      break;
    }
  } while (++around != first);
  if (i < 0) return Flipped::kLeftToCgal;  // a vertex next to `from` lies on the segment
  // Walk to `to`, listing the crossed edges as (right corner, left corner).
  s.crossing.clear();
  for (;;) {
    if (face->is_constrained(i)) {
      const Vertex v = split_at_crossing(triangulation, from, to, {face, i}, s, depth);
      if (v == Vertex()) return Flipped::kLeftToCgal;
      constrain_at_depth(triangulation, from, v, s, depth + 1);
      rest_from = v;
      return Flipped::kSplit;
    }
    const Vertex right = face->vertex(ccw(i)), left = face->vertex(cw(i));
    s.crossing.emplace_back(right, left);
    const Face next = face->neighbor(i);
    if (triangulation.is_infinite(next)) return Flipped::kLeftToCgal;
    const int j = triangulation.mirror_index(face, i);
    const Vertex far = next->vertex(j);  // next's corners, counter-clockwise: far, left, right
    if (far == to) break;
    const CGAL::Orientation side = side_of(far);
    if (side == CGAL::COLLINEAR) return Flipped::kLeftToCgal;
    face = next;
    i = side == CGAL::LEFT_TURN ? ccw(j) : cw(j);  // the corner opposite the next crossed edge
  }
  // Flip. Each step either removes a crossing or moves a non-convex one to the back; the queue
  // always holds a convex one (Sloan), so the bound only guards against the unforeseen.
  s.created.clear();
  size_t head = 0, steps_left = 64 * s.crossing.size() + 64;
  while (head < s.crossing.size()) {
    if (steps_left-- == 0) return Flipped::kLeftToCgal;
    const auto [u, w] = s.crossing[head++];
    Face f;
    int e;
    if (!triangulation.is_edge(u, w, f, e)) return Flipped::kLeftToCgal;
    const Vertex p = f->vertex(e), q = f->neighbor(e)->vertex(triangulation.mirror_index(f, e));
    const CGAL::Orientation side_u = triangulation.orientation(p->point(), q->point(), u->point());
    const CGAL::Orientation side_w = triangulation.orientation(p->point(), q->point(), w->point());
    if (side_u == CGAL::COLLINEAR || side_u != -side_w) {
      s.crossing.emplace_back(u, w);
      continue;
    }
    triangulation.flip(f, e);
    if ((p == from && q == to) || (p == to && q == from)) continue;
    const CGAL::Orientation side_p = side_of(p), side_q = side_of(q);
    if (side_p != CGAL::COLLINEAR && side_p == -side_q) {
      s.crossing.emplace_back(p, q);
    } else {
      s.created.emplace_back(p, q);
    }
    if (head > 256 && 2 * head > s.crossing.size()) {
      s.crossing.erase(s.crossing.begin(), s.crossing.begin() + static_cast<std::ptrdiff_t>(head));
      head = 0;
    }
  }
  if (!mark_constrained(triangulation, from, to)) return Flipped::kLeftToCgal;
  restore_delaunay(triangulation, s.created);
  return Flipped::kDone;
}

// Empties a container of CGAL's triangulation as Compact_container::clear does, but keeps its
// blocks. Its free list hands out first the slot put on it last: erased as they lie, the slots
// would come back in the order the last seam left them. So the free slots are taken too, and
// then every slot is put back from the last to the first, and the list hands them out from the
// first block's first slot on, as a new container does with the blocks it allocates.
template <typename Slots>
void free_in_block_order(Slots& slots) {
  for (size_t k = slots.size(); k < slots.capacity(); ++k) slots.emplace();
  if (slots.empty()) return;
  for (auto it = std::prev(slots.end());;) {
    const auto slot = it;
    const bool first = it == slots.begin();
    if (!first) --it;
    slots.erase(slot);
    if (first) return;
  }
}

// The corners of the points' convex hull, counter-clockwise, into s.hull (Andrew's monotone
// chain, with the kernel's exact orientation: collinear points and repeated ones are no corners);
// empty when the points all lie on one line.
void find_hull(const std::vector<SeamPoint>& points, InsertionScratch& s) {
  std::vector<InsertionScratch::Place>& places = s.by_position;
  std::vector<int>& hull = s.hull;
  hull.clear();
  if (points.size() < 3) return;
  places.resize(points.size());
  for (size_t k = 0; k < points.size(); ++k) places[k] = {points[k].first.x(), points[k].first.y(), static_cast<int>(k)};
  std::sort(places.begin(), places.end(), [](const InsertionScratch::Place& p, const InsertionScratch::Place& q) {
    return p.x < q.x || (p.x == q.x && (p.y < q.y || (p.y == q.y && p.index < q.index)));
  });
  auto turns_left = [&](int a, int b, int c) {
    return CGAL::orientation(points[a].first, points[b].first, points[c].first) == CGAL::LEFT_TURN;
  };
  auto extend = [&](int k, size_t keep) {
    while (hull.size() >= keep + 2 && !turns_left(hull[hull.size() - 2], hull.back(), k)) hull.pop_back();
    hull.push_back(k);
  };
  for (const InsertionScratch::Place& p : places) extend(p.index, 0);  // the lower chain, left to right
  const size_t lower = hull.size() - 1;
  for (auto it = places.rbegin() + 1; it != places.rend(); ++it) extend(it->index, lower);  // the upper, back
  hull.pop_back();  // the first point again
  if (hull.size() < 3) hull.clear();
}

// Makes empty `triangulation` the triangle (a, b, c), counter-clockwise, and its three infinite
// faces, directly in its data structure: CGAL's insertion of the first three points raises the
// dimension twice, and lists the faces each time.
std::array<Vertex, 3> start_with_triangle(SeamTriangulationBase& triangulation, const Point& a, const Point& b, const Point& c) {
  SeamTriangulationData& tds = triangulation.tds();
  const Vertex infinite = triangulation.infinite_vertex();
  tds.delete_face(infinite->face());  // the face of dimension −1 that held it
  const Vertex va = tds.create_vertex(), vb = tds.create_vertex(), vc = tds.create_vertex();
  va->set_point(a);
  vb->set_point(b);
  vc->set_point(c);
  tds.set_dimension(2);
  const Face f = tds.create_face(va, vb, vc);
  // Beyond each edge of f, the infinite face with that edge the other way round.
  const Face beyond_a = tds.create_face(vc, vb, infinite), beyond_b = tds.create_face(va, vc, infinite),
             beyond_c = tds.create_face(vb, va, infinite);
  tds.set_adjacency(f, 0, beyond_a, 2);
  tds.set_adjacency(f, 1, beyond_b, 2);
  tds.set_adjacency(f, 2, beyond_c, 2);
  tds.set_adjacency(beyond_a, 0, beyond_c, 1);  // across (b, ∞)
  tds.set_adjacency(beyond_a, 1, beyond_b, 0);  // across (∞, c)
  tds.set_adjacency(beyond_b, 1, beyond_c, 0);  // across (∞, a)
  va->set_face(f);
  vb->set_face(f);
  vc->set_face(f);
  infinite->set_face(beyond_a);
  return {va, vb, vc};
}

// Is corner k of the simple polygon `polygon` an ear: strictly convex, and its triangle with the
// corners beside it holds no other corner, inside or on its border (then the segment between
// those two is a diagonal inside the polygon)?
bool is_ear(const SeamTriangulation& triangulation, const std::vector<Vertex>& polygon, size_t k) {
  const size_t n = polygon.size(), before = (k + n - 1) % n, after = (k + 1) % n;
  const Point &a = polygon[before]->point(), &b = polygon[k]->point(), &c = polygon[after]->point();
  if (triangulation.orientation(a, b, c) != CGAL::LEFT_TURN) return false;
  for (size_t m = 0; m < n; ++m) {
    if (m == before || m == k || m == after) continue;
    const Point& p = polygon[m]->point();
    if (triangulation.orientation(a, b, p) != CGAL::RIGHT_TURN && triangulation.orientation(b, c, p) != CGAL::RIGHT_TURN &&
        triangulation.orientation(c, a, p) != CGAL::RIGHT_TURN) {
      return false;
    }
  }
  return true;
}

// The ears to cut off the hole of v, in turn, each as its tip and the corners beside it then,
// into s.ears. The polygon starts as v's neighbours (s.link). Inside the hull it is cut
// down to a triangle. On the hull it is the chain of v's finite neighbours, w1 … wk counter-
// clockwise, w1 and wk on the hull: ears are cut off between them (never at w1 or wk) until none
// is left, and the chain must then turn right or run straight at every corner: it is the new
// hull. (v itself may lie on an ear's new side, where the hull ran straight through it; it
// cannot lie inside an ear, its finite faces spanning at most a straight angle.) False, with
// nothing changed, where that fails (inside the hull a simple polygon always has an ear; this
// only guards), or where no finite face would be left.
bool find_ears(const SeamTriangulation& triangulation, bool on_hull, RemovalScratch& s) {
  s.polygon = s.link;
  s.ears.clear();
  const size_t ends = on_hull ? 1 : 0;  // corners at each end that are never ears
  while (s.polygon.size() >= (on_hull ? 3u : 4u)) {
    size_t k = ends;
    while (k + ends < s.polygon.size() && !is_ear(triangulation, s.polygon, k)) ++k;
    if (k + ends == s.polygon.size()) break;
    const size_t n = s.polygon.size();
    s.ears.push_back({s.polygon[(k + n - 1) % n], s.polygon[k], s.polygon[(k + 1) % n]});
    s.polygon.erase(s.polygon.begin() + static_cast<std::ptrdiff_t>(k));
  }
  if (!on_hull) return s.polygon.size() == 3;
  for (size_t k = 1; k + 1 < s.polygon.size(); ++k) {
    if (triangulation.orientation(s.polygon[k - 1]->point(), s.polygon[k]->point(), s.polygon[k + 1]->point()) == CGAL::LEFT_TURN) {
      return false;
    }
  }
  // v's finite faces (k − 1) go, the ears come.
  return triangulation.number_of_faces() + s.ears.size() > s.link.size() - 1;
}

// v is on the hull and its finite neighbours (what find_ears left of s.polygon) turn right or run straight at
// every corner: they become the hull. Each finite face of v becomes an infinite face (v is
// replaced by the infinite vertex, its neighbours stay), and v's two infinite faces go, their
// neighbours beyond joined to the faces that took their place.
void merge_into_infinite_vertex(SeamTriangulation& triangulation, Vertex v, std::vector<Face>& faces) {
  SeamTriangulationData& tds = triangulation.tds();
  const Vertex infinite = triangulation.infinite_vertex();
  faces.clear();
  SeamTriangulation::Face_circulator f = triangulation.incident_faces(v), first = f;
  do {
    faces.push_back(f);
  } while (++f != first);
  // Each infinite face of v: its neighbour beyond (across ∞ and its finite corner) and the finite
  // face of v beside it (across v and that corner), with their indices of the edge to be joined.
  struct End {
    Face gone, beyond, inner;
    int beyond_edge, inner_edge;
    Vertex corner;
  };
  std::array<End, 2> ends;
  int found = 0;
  for (const Face face : faces) {
    if (!triangulation.is_infinite(face)) continue;
    assert(found < 2);
    End& end = ends[found++];
    const int at_v = face->index(v), at_infinite = face->index(infinite);
    end = {face, face->neighbor(at_v), face->neighbor(at_infinite), triangulation.mirror_index(face, at_v),
           triangulation.mirror_index(face, at_infinite), face->vertex(3 - at_v - at_infinite)};
  }
  assert(found == 2);
  // The faces that become infinite take a new face's info, as those CGAL's removal makes: the
  // seam reads an infinite face's as never output (clipping.cc).
  for (const Face face : faces) {
    if (triangulation.is_infinite(face)) continue;
    face->set_vertex(face->index(v), infinite);
    face->info() = SeamFaceInfo{};
  }
  for (const End& end : ends) {
    tds.set_adjacency(end.inner, end.inner_edge, end.beyond, end.beyond_edge);
    end.inner->set_constraint(end.inner_edge, false);
    if (end.corner->face() == end.gone) end.corner->set_face(end.inner);
  }
  infinite->set_face(ends[0].inner);
  tds.delete_face(ends[0].gone);
  tds.delete_face(ends[1].gone);
  tds.delete_vertex(v);
}

}  // namespace

void remove_point(SeamTriangulation& triangulation, Vertex v, RemovalScratch& s) {
  constexpr size_t kMostNeighbours = 64;  // the ears' search takes the square of the neighbours each
  s.link.clear();
  bool to_cgal = triangulation.dimension() != 2, on_hull = false;
  if (!to_cgal) {
    // The neighbours counter-clockwise; on the hull, from the one after the infinite vertex.
    SeamTriangulation::Vertex_circulator w = triangulation.incident_vertices(v), first = w;
    do {
      on_hull = on_hull || triangulation.is_infinite(w);
    } while (!on_hull && ++w != first);
    if (on_hull) first = ++w;
    do {
      if (!triangulation.is_infinite(w)) s.link.push_back(w);
    } while (++w != first && s.link.size() <= kMostNeighbours);
    to_cgal = s.link.size() > kMostNeighbours || !find_ears(triangulation, on_hull, s);
  }
  if (to_cgal) {
    ++s.left_to_cgal;
    triangulation.remove(v);
    return;
  }
  // The hole's edges: the link's sides and the ears' diagonals, to be tested once v is gone.
  // Each ear is cut off by flipping v's edge to its tip: the ear becomes a face, and the face left
  // to v spans the tip's two neighbours (for a while it may lie the wrong way round: nothing reads
  // its geometry before v goes).
  s.created.clear();
  const size_t sides = on_hull ? s.link.size() - 1 : s.link.size();
  for (size_t k = 0; k < sides; ++k) s.created.emplace_back(s.link[k], s.link[(k + 1) % s.link.size()]);
  for (const RemovalScratch::Ear& ear : s.ears) {
    Face f;
    int i = 0;
    [[maybe_unused]] const bool is_edge = triangulation.is_edge(v, ear.tip, f, i);
    assert(is_edge);
    triangulation.flip(f, i);
    s.created.emplace_back(ear.before, ear.after);
  }
  if (on_hull) {
    merge_into_infinite_vertex(triangulation, v, s.faces);
  } else {
    // v has three neighbours: one of its faces becomes their triangle, the other two go.
    const Face kept = v->face();
    triangulation.tds().remove_degree_3(v, kept);
    for (int k = 0; k < 3; ++k) kept->set_constraint(k, kept->neighbor(k)->is_constrained(triangulation.mirror_index(kept, k)));
  }
  restore_delaunay(triangulation, s.created);
}

void clear_keeping_memory(SeamTriangulationBase& triangulation) {
  free_in_block_order(triangulation.tds().faces());
  free_in_block_order(triangulation.tds().vertices());
  triangulation.tds().set_dimension(-2);
  triangulation.set_infinite_vertex(triangulation.tds().insert_first());
}

void insert_points(SeamPointTriangulation& triangulation, const std::vector<SeamPoint>& points, std::vector<Vertex>& handle,
                   InsertionScratch& scratch) {
  assert(triangulation.number_of_vertices() == 0);
  handle.assign(points.size(), Vertex());
  Face hint;
  auto place = [&](size_t k, Vertex v) {
    if (v->info().index < 0 || points[k].second.index < v->info().index) v->info() = points[k].second;
    handle[k] = v;
    hint = v->face();
  };
  auto insert = [&](size_t k) {
    if (handle[k] == Vertex()) place(k, triangulation.insert(points[k].first, hint));
  };
  find_hull(points, scratch);
  const std::vector<int>& hull = scratch.hull;
  if (!hull.empty()) {
    const std::array<Vertex, 3> corners =
        start_with_triangle(triangulation, points[hull[0]].first, points[hull[1]].first, points[hull[2]].first);
    for (int k = 0; k < 3; ++k) place(static_cast<size_t>(hull[k]), corners[k]);
    for (size_t k = 3; k < hull.size(); ++k) insert(static_cast<size_t>(hull[k]));
  }
  // A skeleton of the whole seam, then the rest: the same triangulation in any order, but this
  // one sets the faces' order in memory, which fairing's float sums follow (clipping.cc).
  constexpr size_t kSkeletonStrides[] = {16, 4};
  for (const size_t stride : kSkeletonStrides) {
    for (size_t k = 0; k < points.size(); k += stride) insert(k);
  }
  for (size_t k = 0; k < points.size(); ++k) insert(k);
}

void constrain(SeamTriangulation& triangulation, Vertex from, Vertex to, ConstraintScratch& scratch) {
  // Empty as every call leaves them, unless one was cut short by an exception: their handles
  // would then be another triangulation's.
  scratch.crossing.clear();
  scratch.created.clear();
  constrain_at_depth(triangulation, from, to, scratch, 0);
}

}  // namespace zipfusion
