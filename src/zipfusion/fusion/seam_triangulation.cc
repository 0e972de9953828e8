#include "zipfusion/fusion/seam_triangulation.h"

#include <cstddef>

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
void restore_delaunay(SeamTriangulation& triangulation, ConstraintScratch& s) {
  while (!s.created.empty()) {
    const auto [u, w] = s.created.back();
    s.created.pop_back();
    Face f;
    int e;
    if (!triangulation.is_edge(u, w, f, e) || !triangulation.is_flipable(f, e)) continue;
    const Vertex p = f->vertex(e), q = f->neighbor(e)->vertex(triangulation.mirror_index(f, e));
    triangulation.flip(f, e);
    for (const Vertex corner : {u, w}) {
      s.created.emplace_back(p, corner);
      s.created.emplace_back(q, corner);
    }
  }
}

bool constrain_by_flips(SeamTriangulation& triangulation, Vertex from, Vertex to, ConstraintScratch& s, int depth);

// `constrain` inside `depth` crossings: by flips, else by CGAL's insertion.
void constrain_at_depth(SeamTriangulation& triangulation, Vertex from, Vertex to, ConstraintScratch& s, int depth) {
  if (constrain_by_flips(triangulation, from, to, s, depth)) return;
  triangulation.insert_constraint(from, to);
  restore_delaunay(triangulation, s);  // after flips that stopped short, if any
}

// Where the segment (from, to) crosses the constrained edge `crossed`, makes a vertex and
// constrains the four pieces, as CGAL's insertion does where two constraints cross (its vertex,
// like this one, has no seam index, and no output face touches it). The point is computed in
// floating point; where it falls outside the two triangles beside the crossed edge (the segments
// nearly parallel), or on one of their corners, nothing changes and false is returned.
bool split_at_crossing(SeamTriangulation& triangulation, Vertex from, Vertex to, Edge crossed, ConstraintScratch& s, int depth) {
  const auto [face, i] = crossed;
  const Vertex c = face->vertex(ccw(i)), d = face->vertex(cw(i));
  const Face beyond = face->neighbor(i);
  const Point &a = from->point(), &b = to->point(), &pc = c->point(), &pd = d->point();
  const double ux = b.x() - a.x(), uy = b.y() - a.y(), vx = pd.x() - pc.x(), vy = pd.y() - pc.y();
  const double denominator = ux * vy - uy * vx;
  if (denominator == 0) return false;
  const double t = ((pc.x() - a.x()) * vy - (pc.y() - a.y()) * vx) / denominator;
  const Point x(a.x() + t * ux, a.y() + t * uy);
  auto inside_or_on = [&](Face f) {
    for (int k = 0; k < 3; ++k) {
      if (triangulation.orientation(f->vertex(k)->point(), f->vertex(ccw(k))->point(), x) == CGAL::RIGHT_TURN) return false;
    }
    return true;
  };
  if (x == a || x == b || x == pc || x == pd || !(inside_or_on(face) || inside_or_on(beyond))) return false;
  face->set_constraint(i, false);
  beyond->set_constraint(triangulation.mirror_index(face, i), false);
  const size_t vertices = triangulation.number_of_vertices();
  const Vertex v = triangulation.insert(x, face);
  if (triangulation.number_of_vertices() != vertices + 1) {  // x was a vertex after all
    constrain_at_depth(triangulation, c, d, s, depth + 1);
    return false;
  }
  constrain_at_depth(triangulation, c, v, s, depth + 1);
  constrain_at_depth(triangulation, v, d, s, depth + 1);
  constrain_at_depth(triangulation, from, v, s, depth + 1);
  constrain_at_depth(triangulation, v, to, s, depth);  // the rest of the segment: one crossing fewer
  return true;
}

// Constrains (from, to) by flipping the edges it crosses (Sloan's insertion of a constraint,
// 1993): an edge whose two triangles form a convex quadrilateral is flipped, one that still
// crosses goes back into the queue, and one that does not waits for the Delaunay test
// (restore_delaunay). That gives the constrained Delaunay triangulation that CGAL's insertion
// gives (up to the choice among co-circular points). Where it crosses a constrained edge, the
// two are split where they cross (split_at_crossing). False, for CGAL to finish, where a vertex
// lies on the segment, where the crossing cannot be split, past a few nested crossings, or where
// the queue does not empty in a generous number of steps. Most kept edges cross nothing (they
// are marked in place) or one diagonal (one flip).
bool constrain_by_flips(SeamTriangulation& triangulation, Vertex from, Vertex to, ConstraintScratch& s, int depth) {
  if (from == to || mark_constrained(triangulation, from, to)) return true;
  if (triangulation.dimension() != 2 || depth > 8) return false;
  const Point &p_from = from->point(), &p_to = to->point();
  auto side_of = [&](Vertex v) { return triangulation.orientation(p_from, p_to, v->point()); };
  // The face around `from` that the segment leaves through: its corner after `from` (counter-
  // clockwise) on the segment's right, the next on its left.
  Face face;
  int i = -1;
  SeamTriangulation::Face_circulator around = triangulation.incident_faces(from), first = around;
  if (around == nullptr) return false;
  do {
    if (triangulation.is_infinite(around)) continue;
    const int k = around->index(from);
    if (side_of(around->vertex(ccw(k))) == CGAL::RIGHT_TURN && side_of(around->vertex(cw(k))) == CGAL::LEFT_TURN) {
      face = around;
      i = k;
      break;
    }
  } while (++around != first);
  if (i < 0) return false;  // a vertex next to `from` lies on the segment
  // Walk to `to`, listing the crossed edges as (right corner, left corner).
  s.crossing.clear();
  for (;;) {
    if (face->is_constrained(i)) return split_at_crossing(triangulation, from, to, {face, i}, s, depth);
    const Vertex right = face->vertex(ccw(i)), left = face->vertex(cw(i));
    s.crossing.emplace_back(right, left);
    const Face next = face->neighbor(i);
    if (triangulation.is_infinite(next)) return false;
    const int j = triangulation.mirror_index(face, i);
    const Vertex far = next->vertex(j);  // next's corners, counter-clockwise: far, left, right
    if (far == to) break;
    const CGAL::Orientation side = side_of(far);
    if (side == CGAL::COLLINEAR) return false;
    face = next;
    i = side == CGAL::LEFT_TURN ? ccw(j) : cw(j);  // the corner opposite the next crossed edge
  }
  // Flip. Each step either removes a crossing or moves a non-convex one to the back; the queue
  // always holds a convex one (Sloan), so the bound only guards against the unforeseen.
  s.created.clear();
  size_t head = 0, steps_left = 64 * s.crossing.size() + 64;
  while (head < s.crossing.size()) {
    if (steps_left-- == 0) return false;
    const auto [u, w] = s.crossing[head++];
    Face f;
    int e;
    if (!triangulation.is_edge(u, w, f, e)) return false;
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
  if (!mark_constrained(triangulation, from, to)) return false;
  restore_delaunay(triangulation, s);
  return true;
}

}  // namespace

void constrain(SeamTriangulation& triangulation, Vertex from, Vertex to, ConstraintScratch& scratch) {
  constrain_at_depth(triangulation, from, to, scratch, 0);
}

}  // namespace zipfusion
