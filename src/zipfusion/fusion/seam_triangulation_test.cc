#include "zipfusion/fusion/seam_triangulation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

#include "zipfusion/core/allocation_count_test_util.h"

namespace zipfusion {
namespace {

using Point = SeamKernel::Point_2;
using Vertex = SeamTriangulation::Vertex_handle;

// A 20 × 20 grid of points 1 apart, each moved by up to 0.4 in x and y: in general position (no
// four points on a circle, no three on a line), so the constrained Delaunay triangulation of any
// constraints is unique.
std::vector<Point> jittered_grid(std::mt19937& random) {
  std::uniform_real_distribution<double> jitter(-0.4, 0.4);
  std::vector<Point> points;
  for (int y = 0; y < 20; ++y) {
    for (int x = 0; x < 20; ++x) points.emplace_back(x + jitter(random), y + jitter(random));
  }
  return points;
}

// The points triangulated as the seam is: a plain Delaunay triangulation swapped into the
// constrained one. handle[i]: point i's vertex.
void triangulate(const std::vector<Point>& points, SeamTriangulation& triangulation, std::vector<Vertex>& handle) {
  SeamPointTriangulation points_only;
  handle.clear();
  for (size_t i = 0; i < points.size(); ++i) {
    const Vertex v = points_only.insert(points[i]);
    v->info().index = static_cast<int>(i);
    handle.push_back(v);
  }
  triangulation.swap(points_only);
}

// Segments between points 1.5 to 6 apart, which cross several edges of the triangulation each.
// With `crossing`, any; without, none crosses or touches another but at a shared end.
std::vector<std::pair<int, int>> random_segments(const std::vector<Point>& points, int count, bool crossing, std::mt19937& random) {
  std::uniform_int_distribution<int> pick(0, static_cast<int>(points.size()) - 1);
  std::vector<std::pair<int, int>> segments;
  for (int tries = 0; static_cast<int>(segments.size()) < count && tries < 100000; ++tries) {
    const int i = pick(random), j = pick(random);
    const double length = std::sqrt(CGAL::squared_distance(points[i], points[j]));
    if (i == j || length < 1.5 || length > 6) continue;
    const SeamKernel::Segment_2 candidate(points[i], points[j]);
    const bool clear = crossing || std::none_of(segments.begin(), segments.end(), [&](const std::pair<int, int>& s) {
                         const bool shares_end = s.first == i || s.first == j || s.second == i || s.second == j;
                         return !shares_end && CGAL::do_intersect(candidate, SeamKernel::Segment_2(points[s.first], points[s.second]));
                       });
    if (clear) segments.emplace_back(i, j);
  }
  return segments;
}

// Every edge of the triangulation as its two corners' places (a vertex made at a crossing has
// no index), sorted, and whether it is constrained.
using PlacedEdge = std::pair<std::pair<Point, Point>, bool>;
std::vector<PlacedEdge> placed_edges(const SeamTriangulation& triangulation) {
  std::vector<PlacedEdge> edges;
  for (auto e = triangulation.finite_edges_begin(); e != triangulation.finite_edges_end(); ++e) {
    Point p = e->first->vertex(SeamTriangulation::cw(e->second))->point();
    Point q = e->first->vertex(SeamTriangulation::ccw(e->second))->point();
    if (q < p) std::swap(p, q);
    edges.push_back({{p, q}, e->first->is_constrained(e->second)});
  }
  std::sort(edges.begin(), edges.end());
  return edges;
}

// How many of the segments are not edges of the triangulation: those that `constrain` must flip
// (or split) into place rather than mark.
int segments_not_edges(const SeamTriangulation& triangulation, const std::vector<Vertex>& handle,
                       const std::vector<std::pair<int, int>>& segments) {
  int count = 0;
  for (const auto& [i, j] : segments) count += !triangulation.is_edge(handle[i], handle[j]);
  return count;
}

// The same points triangulated twice, the same segments then constrained in each: by CGAL's
// insert_constraint and by `constrain`.
struct BothWays {
  explicit BothWays(const std::vector<Point>& points) {
    triangulate(points, by_cgal, cgal_handle);
    triangulate(points, by_flips, flips_handle);
  }
  void constrain_each(const std::vector<std::pair<int, int>>& segments) {
    for (const auto& [i, j] : segments) {
      by_cgal.insert_constraint(cgal_handle[i], cgal_handle[j]);
      constrain(by_flips, flips_handle[i], flips_handle[j], scratch);
    }
  }
  SeamTriangulation by_cgal, by_flips;
  std::vector<Vertex> cgal_handle, flips_handle;
  ConstraintScratch scratch;
};

TEST(Constrain, GivesCgalsConstrainedDelaunayTriangulation) {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    std::mt19937 random(seed);
    const std::vector<Point> points = jittered_grid(random);
    const std::vector<std::pair<int, int>> segments = random_segments(points, 40, false, random);
    BothWays both(points);
    auto& [by_cgal, by_flips, cgal_handle, flips_handle, scratch] = both;
    ASSERT_GE(segments_not_edges(by_flips, flips_handle, segments), 30) << "seed " << seed;
    both.constrain_each(segments);
    EXPECT_EQ(scratch.left_to_cgal, 0) << "seed " << seed;
    EXPECT_TRUE(by_flips.is_valid()) << "seed " << seed;
    EXPECT_EQ(by_flips.number_of_vertices(), points.size()) << "seed " << seed;
    EXPECT_EQ(placed_edges(by_flips), placed_edges(by_cgal)) << "seed " << seed;
    for (const auto& [i, j] : segments) EXPECT_TRUE(by_flips.is_edge(flips_handle[i], flips_handle[j])) << "seed " << seed;
  }
}

// Crossing constraints are split at a vertex made where they cross, constructed and snapped as
// CGAL constructs and snaps it: the same triangulation to the bit, none of it left to CGAL.
TEST(Constrain, SplitsCrossingConstraintsAsCgalDoes) {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    std::mt19937 random(seed);
    const std::vector<Point> points = jittered_grid(random);
    const std::vector<std::pair<int, int>> segments = random_segments(points, 30, true, random);
    BothWays both(points);
    auto& [by_cgal, by_flips, cgal_handle, flips_handle, scratch] = both;
    both.constrain_each(segments);
    ASSERT_GE(by_cgal.number_of_vertices(), points.size() + 10) << "seed " << seed << ": too few crossings to test";
    EXPECT_EQ(scratch.left_to_cgal, 0) << "seed " << seed;
    EXPECT_TRUE(by_flips.is_valid()) << "seed " << seed;
    EXPECT_EQ(by_flips.number_of_vertices(), by_cgal.number_of_vertices()) << "seed " << seed;
    EXPECT_EQ(placed_edges(by_flips), placed_edges(by_cgal)) << "seed " << seed;
  }
}

// A crossing two units in the last place from an end of the crossed edge snaps to that end, as
// in CGAL: no vertex is made a hair's breadth from another, and the crossing segment bends
// through the end.
TEST(Constrain, SnapsACrossingBesideAnEndAsCgalDoes) {
  const double just_above_1 = std::nextafter(std::nextafter(1.0, 2.0), 2.0);
  const std::vector<Point> points = {{-1, -1}, {3, -1}, {3, 4}, {-1, 4}, {1, 1}, {1, 3}, {0, just_above_1}, {2, just_above_1}};
  BothWays both(points);
  auto& [by_cgal, by_flips, cgal_handle, flips_handle, scratch] = both;
  both.constrain_each({{4, 5}, {6, 7}});  // the vertical edge first, then the segment across it
  EXPECT_EQ(by_cgal.number_of_vertices(), points.size());
  EXPECT_EQ(by_flips.number_of_vertices(), points.size());
  EXPECT_EQ(scratch.left_to_cgal, 0);
  EXPECT_EQ(placed_edges(by_flips), placed_edges(by_cgal));
  EXPECT_TRUE(by_flips.is_edge(flips_handle[6], flips_handle[4]) && by_flips.is_edge(flips_handle[4], flips_handle[7]));
}

// Degenerate crossings: several constraints through one point that is no vertex, and pairs of
// constraints crossing at angles of 1e-2 to 1e-14 radians. The result is still CGAL's to the bit,
// the vertices made at the crossings included.
TEST(Constrain, MatchesCgalWhereManyCrossAtOnePointOrNearlyParallel) {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    std::mt19937 random(seed);
    std::vector<Point> points = jittered_grid(random);
    std::uniform_real_distribution<double> unit(0, 1);
    std::vector<std::pair<int, int>> segments;
    auto add_segment = [&](double x0, double y0, double x1, double y1) {
      points.emplace_back(x0, y0);
      points.emplace_back(x1, y1);
      segments.emplace_back(static_cast<int>(points.size()) - 2, static_cast<int>(points.size()) - 1);
    };
    const double centre_x = 9.5 + 0.1 * unit(random), centre_y = 9.5 + 0.1 * unit(random);
    for (unsigned k = 0; k < 3 + seed; ++k) {
      const double angle = std::numbers::pi * unit(random), out = 3 + 5 * unit(random), back = 3 + 5 * unit(random);
      add_segment(centre_x + out * std::cos(angle), centre_y + out * std::sin(angle), centre_x - back * std::cos(angle),
                  centre_y - back * std::sin(angle));
    }
    for (int k = 0; k < 4; ++k) {
      const double angle = std::numbers::pi * unit(random), apart = std::pow(10.0, -2 - 12 * unit(random));
      const double x = 4 + 11 * unit(random), y = 4 + 11 * unit(random);
      for (const double a : {angle, angle + apart}) add_segment(x - 2 * std::cos(a), y - 2 * std::sin(a), x + 2 * std::cos(a), y + 2 * std::sin(a));
    }
    BothWays both(points);
    auto& [by_cgal, by_flips, cgal_handle, flips_handle, scratch] = both;
    both.constrain_each(segments);
    ASSERT_GE(by_cgal.number_of_vertices(), points.size() + 5) << "seed " << seed << ": too few crossings to test";
    EXPECT_TRUE(by_flips.is_valid()) << "seed " << seed;
    EXPECT_EQ(by_flips.number_of_vertices(), by_cgal.number_of_vertices()) << "seed " << seed;
    EXPECT_EQ(placed_edges(by_flips), placed_edges(by_cgal)) << "seed " << seed;
  }
}

// Points on an integer grid: four on a circle in every square, three on a line along every row,
// column and diagonal, and segments that run through grid points (left to CGAL's insertion from
// there on). The result is still CGAL's (both break ties among co-circular points the same way),
// and every segment is covered by constrained edges through the grid points on it.
TEST(Constrain, MatchesCgalOnAnIntegerGrid) {
  std::vector<Point> points;
  for (int y = 0; y < 12; ++y) {
    for (int x = 0; x < 12; ++x) points.emplace_back(x, y);
  }
  for (unsigned seed = 1; seed <= 5; ++seed) {
    std::mt19937 random(seed);
    const std::vector<std::pair<int, int>> segments = random_segments(points, 25, false, random);
    BothWays both(points);
    auto& [by_cgal, by_flips, cgal_handle, flips_handle, scratch] = both;
    both.constrain_each(segments);
    EXPECT_GT(scratch.left_to_cgal, 0) << "seed " << seed << ": no segment through a grid point";
    EXPECT_TRUE(by_flips.is_valid()) << "seed " << seed;
    EXPECT_EQ(placed_edges(by_flips), placed_edges(by_cgal)) << "seed " << seed;
    for (const auto& [i, j] : segments) {
      // The grid points on the segment, in order from i: each next to the one before by a constrained edge.
      std::vector<Vertex> on_segment;
      for (const Vertex v : flips_handle) {
        if (CGAL::collinear(points[i], points[j], v->point()) && CGAL::collinear_are_ordered_along_line(points[i], v->point(), points[j])) {
          on_segment.push_back(v);
        }
      }
      std::sort(on_segment.begin(), on_segment.end(), [&](Vertex u, Vertex v) {
        return CGAL::squared_distance(points[i], u->point()) < CGAL::squared_distance(points[i], v->point());
      });
      for (size_t k = 0; k + 1 < on_segment.size(); ++k) {
        SeamTriangulation::Face_handle f;
        int e = 0;
        ASSERT_TRUE(by_flips.is_edge(on_segment[k], on_segment[k + 1], f, e)) << "seed " << seed;
        EXPECT_TRUE(f->is_constrained(e)) << "seed " << seed;
      }
    }
  }
}

// What `change(triangulation, handle)` allocates, on a triangulation of `points` made first.
template <typename Change>
long long allocations_changing(const std::vector<Point>& points, Change&& change) {
  SeamTriangulation triangulation;
  std::vector<Vertex> handle;
  triangulate(points, triangulation, handle);
  const long long before = g_allocations.load();
  change(triangulation, handle);
  return g_allocations.load() - before;
}

TEST(Constrain, AllocatesNothingOnceItsScratchHasGrown) {
  std::mt19937 random(7);
  const std::vector<Point> points = jittered_grid(random);
  const std::vector<std::pair<int, int>> segments = random_segments(points, 40, false, random);
  ConstraintScratch scratch;
  auto allocations = [&](bool by_cgal) {
    return allocations_changing(points, [&](SeamTriangulation& triangulation, const std::vector<Vertex>& handle) {
      for (const auto& [i, j] : segments) {
        if (by_cgal) {
          triangulation.insert_constraint(handle[i], handle[j]);
        } else {
          constrain(triangulation, handle[i], handle[j], scratch);
        }
      }
    });
  };
  allocations(false);  // grows the scratch
  EXPECT_EQ(allocations(false), 0);
  EXPECT_GT(allocations(true), 40);  // CGAL's insertion, for comparison: at least its work stack each
}

// The points as insert_points takes them: info index k at place k.
std::vector<SeamPoint> numbered(const std::vector<Point>& points) {
  std::vector<SeamPoint> numbered;
  for (size_t k = 0; k < points.size(); ++k) numbered.emplace_back(points[k], SeamVertexInfo{static_cast<int>(k)});
  return numbered;
}

// Every finite edge of a triangulation as its corners' places, sorted.
std::vector<std::pair<Point, Point>> edges_of(const SeamTriangulationBase& triangulation) {
  std::vector<std::pair<Point, Point>> edges;
  for (auto e = triangulation.finite_edges_begin(); e != triangulation.finite_edges_end(); ++e) {
    Point p = e->first->vertex(SeamTriangulation::cw(e->second))->point();
    Point q = e->first->vertex(SeamTriangulation::ccw(e->second))->point();
    if (q < p) std::swap(p, q);
    edges.emplace_back(p, q);
  }
  std::sort(edges.begin(), edges.end());
  return edges;
}

// The faces in the order the triangulation's container holds them, each as its corners' indices
// (−2 for the infinite vertex): equal for two triangulations whose faces lie in the same order.
std::vector<std::array<int, 3>> faces_in_memory_order(const SeamTriangulationBase& triangulation) {
  std::vector<std::array<int, 3>> faces;
  for (auto f = triangulation.all_faces_begin(); f != triangulation.all_faces_end(); ++f) {
    std::array<int, 3> corners;
    for (int k = 0; k < 3; ++k) corners[k] = triangulation.is_infinite(f->vertex(k)) ? -2 : f->vertex(k)->info().index;
    faces.push_back(corners);
  }
  return faces;
}

// Point sets a seam can have: a jittered grid in row order (as seam points come, each next to
// the one before) and shuffled; an integer grid, whose points are co-circular by fours and
// collinear along the hull; and a jittered grid with every fifth point repeated further on.
std::vector<std::vector<Point>> seam_like_point_sets(std::mt19937& random) {
  std::vector<std::vector<Point>> sets;
  sets.push_back(jittered_grid(random));
  std::vector<Point> shuffled = jittered_grid(random);
  std::shuffle(shuffled.begin(), shuffled.end(), random);
  sets.push_back(shuffled);
  std::vector<Point> integer;
  for (int y = 0; y < 12; ++y) {
    for (int x = 0; x < 15; ++x) integer.emplace_back(x, y);
  }
  sets.push_back(integer);
  std::vector<Point> repeated = jittered_grid(random);
  for (size_t k = 0; k < 400; k += 5) repeated.push_back(repeated[k]);
  std::shuffle(repeated.begin() + 300, repeated.end(), random);
  sets.push_back(repeated);
  return sets;
}

TEST(InsertPoints, GivesCgalsDelaunayTriangulationWithTheLowestIndexAtEachPlace) {
  std::mt19937 random(11);
  InsertionScratch scratch;
  for (const std::vector<Point>& points : seam_like_point_sets(random)) {
    SeamPointTriangulation by_cgal;
    by_cgal.insert(points.begin(), points.end());
    SeamPointTriangulation triangulation;
    std::vector<SeamPointTriangulation::Vertex_handle> handle;
    insert_points(triangulation, numbered(points), handle, scratch);
    ASSERT_TRUE(triangulation.is_valid());
    EXPECT_EQ(triangulation.number_of_vertices(), by_cgal.number_of_vertices());
    EXPECT_EQ(edges_of(triangulation), edges_of(by_cgal));
    for (size_t k = 0; k < points.size(); ++k) {
      ASSERT_EQ(handle[k]->point(), points[k]);
      const int lowest = static_cast<int>(std::find(points.begin(), points.end(), points[k]) - points.begin());
      EXPECT_EQ(handle[k]->info().index, lowest) << "point " << k;
    }
    EXPECT_GE(scratch.hull.size(), 4u);  // the triangle built directly, then insertions on the hull
  }
}

TEST(InsertPoints, TakesFewerThanThreePoints) {
  const std::vector<Point> points{{0.5, 0.25}, {0.5, 0.25}, {2, 1}};
  for (size_t n = 0; n <= 3; ++n) {
    SeamPointTriangulation triangulation;
    std::vector<SeamPointTriangulation::Vertex_handle> handle;
    InsertionScratch scratch;
    insert_points(triangulation, numbered({points.begin(), points.begin() + static_cast<std::ptrdiff_t>(n)}), handle, scratch);
    EXPECT_TRUE(triangulation.is_valid());
    EXPECT_EQ(triangulation.number_of_vertices(), n < 2 ? n : n - 1) << n << " points";
    EXPECT_EQ(triangulation.dimension(), n == 0 ? -1 : n < 3 ? 0 : 1) << n << " points";
  }
}

TEST(InsertPoints, PointsOnOneLineAreInsertedByCgal) {
  std::vector<Point> points;
  for (int k = 0; k < 10; ++k) points.emplace_back(0.5 * k, 0.25 * k);
  points.push_back(points[3]);
  SeamPointTriangulation triangulation;
  std::vector<SeamPointTriangulation::Vertex_handle> handle;
  InsertionScratch scratch;
  insert_points(triangulation, numbered(points), handle, scratch);
  EXPECT_TRUE(triangulation.is_valid());
  EXPECT_EQ(triangulation.dimension(), 1);
  EXPECT_EQ(triangulation.number_of_vertices(), 10u);
  EXPECT_EQ(handle[10], handle[3]);
  EXPECT_EQ(handle[10]->info().index, 3);
}

// A triangulation cleared by clear_keeping_memory after seams of other sizes, some of its
// vertices removed (which leaves its containers' free slots out of order), lays out the next
// seam's faces in memory exactly as a new triangulation does: fairing's sums follow that order.
TEST(ClearKeepingMemory, ReusedTriangulationLaysOutFacesAsANewOne) {
  std::mt19937 random(5);
  std::vector<Point> small = jittered_grid(random), large = jittered_grid(random);
  small.resize(150);
  for (const Point& p : jittered_grid(random)) large.emplace_back(p.x() + 20, p.y());
  InsertionScratch scratch;
  std::vector<SeamPointTriangulation::Vertex_handle> handle;
  SeamPointTriangulation reused;
  for (const std::vector<Point>* earlier : {&large, &small}) {
    clear_keeping_memory(reused);
    insert_points(reused, numbered(*earlier), handle, scratch);
    for (size_t k = 7; k < earlier->size(); k += 13) {
      if (handle[k]->info().index == static_cast<int>(k)) reused.remove(handle[k]);
    }
  }
  for (const std::vector<Point>* points : {&small, &large, &small}) {
    SeamPointTriangulation fresh;
    insert_points(fresh, numbered(*points), handle, scratch);
    clear_keeping_memory(reused);
    insert_points(reused, numbered(*points), handle, scratch);
    ASSERT_TRUE(reused.is_valid());
    EXPECT_EQ(faces_in_memory_order(reused), faces_in_memory_order(fresh)) << points->size() << " points";
  }
}

// The cycle each seam goes through in clipping.cc: points into the kept plain triangulation,
// swapped into the constrained one, kept edges constrained, points removed, swapped back. A
// triangulation reused through it gives the faces in the order a new one gives.
TEST(ClearKeepingMemory, ReusedThroughTheSeamsCycleAsANewOne) {
  std::mt19937 random(8);
  std::vector<std::vector<Point>> seams;
  for (int k = 0; k < 4; ++k) {
    seams.push_back(jittered_grid(random));
    seams.back().resize(400 - 90 * (k % 2));  // a smaller seam, then a larger one again
  }
  auto seam_cycle = [&](SeamPointTriangulation& points_only, const std::vector<Point>& points, std::mt19937& segments_random) {
    std::vector<SeamPointTriangulation::Vertex_handle> handle;
    InsertionScratch insertion;
    ConstraintScratch constraints;
    RemovalScratch removal;
    clear_keeping_memory(points_only);
    insert_points(points_only, numbered(points), handle, insertion);
    SeamTriangulation triangulation;
    triangulation.swap(points_only);
    for (const auto& [i, j] : random_segments(points, 25, true, segments_random)) constrain(triangulation, handle[i], handle[j], constraints);
    for (size_t k = 5; k < points.size(); k += 11) {
      if (!triangulation.are_there_incident_constraints(handle[k])) remove_point(triangulation, handle[k], removal);
    }
    std::vector<std::array<int, 3>> faces = faces_in_memory_order(triangulation);
    triangulation.swap(points_only);
    return faces;
  };
  SeamPointTriangulation reused;
  for (const std::vector<Point>& points : seams) {
    std::mt19937 same_segments(1), again(1);
    SeamPointTriangulation fresh;
    EXPECT_EQ(seam_cycle(reused, points, same_segments), seam_cycle(fresh, points, again)) << points.size() << " points";
  }
}

TEST(InsertPoints, AllocatesNothingIntoAReusedTriangulation) {
  std::mt19937 random(3);
  const std::vector<SeamPoint> points = numbered(jittered_grid(random));
  InsertionScratch scratch;
  std::vector<SeamPointTriangulation::Vertex_handle> handle;
  SeamPointTriangulation triangulation;
  insert_points(triangulation, points, handle, scratch);  // grows the scratch and the containers
  const long long before = g_allocations.load();
  for (int k = 0; k < 3; ++k) {
    clear_keeping_memory(triangulation);
    insert_points(triangulation, points, handle, scratch);
  }
  EXPECT_EQ(g_allocations.load() - before, 0);
  // CGAL's insertion into a new triangulation, for comparison: its blocks, and lists wherever a
  // point extends the hull over several edges or raises the dimension.
  const long long before_cgal = g_allocations.load();
  {
    SeamPointTriangulation by_cgal;
    for (const SeamPoint& p : points) by_cgal.insert(p.first);
  }
  EXPECT_GT(g_allocations.load() - before_cgal, 20);
}

// Points removed from two copies of a constrained triangulation, by CGAL's `remove` and by
// remove_point: the same triangulation, constraint flags included. The points: every third of
// those no constraint touches, and every one on the hull (removing them brings others to it), none
// left to CGAL.
void expect_removal_as_cgals(const std::vector<Point>& points, const std::vector<std::pair<int, int>>& segments,
                             RemovalScratch& scratch) {
  BothWays both(points);
  both.constrain_each(segments);
  ASSERT_EQ(placed_edges(both.by_flips), placed_edges(both.by_cgal));
  const long left_before = scratch.left_to_cgal;
  int removed = 0, on_hull = 0;
  // Every finite face output, as the seam marks faces: an infinite face must never read so (the
  // faces remove_point turns infinite on the hull were finite ones).
  for (auto f = both.by_flips.finite_faces_begin(); f != both.by_flips.finite_faces_end(); ++f) f->info().output = true;
  auto infinite_faces_output = [&] {
    int count = 0;
    SeamTriangulation::Face_circulator f = both.by_flips.incident_faces(both.by_flips.infinite_vertex()), first = f;
    do {
      count += f->info().output;
    } while (++f != first);
    return count;
  };
  // Every third point, and every point on the hull as the triangulation starts.
  std::vector<bool> chosen(points.size());
  for (size_t k = 0; k < points.size(); k += 3) chosen[k] = true;
  for (auto w = both.by_cgal.incident_vertices(both.by_cgal.infinite_vertex()), first = w;;) {
    for (size_t k = 0; k < points.size(); ++k) chosen[k] = chosen[k] || both.cgal_handle[k] == w;
    if (++w == first) break;
  }
  for (size_t k = 0; k < points.size(); ++k) {
    if (!chosen[k] || both.by_cgal.are_there_incident_constraints(both.cgal_handle[k])) continue;
    bool hull = false;
    SeamTriangulation::Vertex_circulator w = both.by_cgal.incident_vertices(both.cgal_handle[k]), first = w;
    do {
      hull = hull || both.by_cgal.is_infinite(w);
    } while (++w != first);
    on_hull += hull;
    ++removed;
    both.by_cgal.remove(both.cgal_handle[k]);
    remove_point(both.by_flips, both.flips_handle[k], scratch);
    ASSERT_TRUE(both.by_flips.is_valid()) << "after point " << k;
    ASSERT_EQ(placed_edges(both.by_flips), placed_edges(both.by_cgal)) << "after point " << k;
    ASSERT_EQ(infinite_faces_output(), 0) << "after point " << k;
  }
  EXPECT_GT(removed - on_hull, 20);
  EXPECT_GT(on_hull, 15);
  EXPECT_EQ(scratch.left_to_cgal - left_before, 0);
}

TEST(RemovePoint, GivesCgalsTriangulation) {
  RemovalScratch scratch;
  for (unsigned seed = 1; seed <= 5; ++seed) {
    std::mt19937 random(seed);
    const std::vector<Point> points = jittered_grid(random);
    expect_removal_as_cgals(points, random_segments(points, 30, true, random), scratch);
  }
}

// On an integer grid four neighbours of a point lie on a circle, and many points on a line: the
// hole's triangulation there comes from CGAL's perturbation of co-circular points, in both.
TEST(RemovePoint, GivesCgalsTriangulationOnAnIntegerGrid) {
  std::vector<Point> points;
  for (int y = 0; y < 15; ++y) {
    for (int x = 0; x < 15; ++x) points.emplace_back(x, y);
  }
  std::mt19937 random(2);
  RemovalScratch scratch;
  expect_removal_as_cgals(points, {}, scratch);
  expect_removal_as_cgals(points, random_segments(points, 20, false, random), scratch);
}

TEST(RemovePoint, AllocatesNothingOnceItsScratchHasGrown) {
  std::mt19937 random(9);
  const std::vector<Point> points = jittered_grid(random);
  // Points inside, every third of every third row, then on the hull, of the left column.
  std::vector<int> removed;
  for (int y = 2; y < 18; y += 3) {
    for (int x = 2; x < 18; x += 3) removed.push_back(y * 20 + x);
  }
  for (int y = 2; y < 18; y += 4) removed.push_back(y * 20);
  RemovalScratch scratch;
  auto allocations = [&](bool by_cgal) {
    return allocations_changing(points, [&](SeamTriangulation& triangulation, const std::vector<Vertex>& handle) {
      for (const int k : removed) {
        if (by_cgal) {
          triangulation.remove(handle[k]);
        } else {
          remove_point(triangulation, handle[k], scratch);
        }
      }
    });
  };
  allocations(false);  // grows the scratch
  EXPECT_EQ(allocations(false), 0);
  EXPECT_EQ(scratch.left_to_cgal, 0);
  EXPECT_GT(allocations(true), static_cast<long long>(removed.size()));  // CGAL's removal: at least the hole's list each
}

}  // namespace
}  // namespace zipfusion
