#include "zipfusion/core/mesh_distance.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <random>

#include "zipfusion/core/parallel.h"

namespace zipfusion {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

struct BruteForce {
  float distance = kInf;
  int triangle = -1;
};

BruteForce brute_force(const TriangleMesh& mesh, const Eigen::Vector3f& p) {
  BruteForce best;
  for (int i = 0; i < static_cast<int>(mesh.triangles.size()); ++i) {
    const Eigen::Vector3i& t = mesh.triangles[i];
    const Eigen::Vector3f q =
        closest_point_on_triangle(p, mesh.positions[t[0]], mesh.positions[t[1]], mesh.positions[t[2]]);
    const float d = (q - p).norm();
    if (d < best.distance) best = {d, i};
  }
  return best;
}

TriangleMesh sphere(float radius, int stacks, int slices) {
  TriangleMesh mesh;
  for (int i = 0; i <= stacks; ++i) {
    const float theta = std::numbers::pi_v<float> * static_cast<float>(i) / static_cast<float>(stacks);
    for (int j = 0; j < slices; ++j) {
      const float phi = 2 * std::numbers::pi_v<float> * static_cast<float>(j) / static_cast<float>(slices);
      mesh.positions.emplace_back(radius * std::sin(theta) * std::cos(phi),
                                  radius * std::sin(theta) * std::sin(phi), radius * std::cos(theta));
    }
  }
  // The pole rows repeat one point: their triangles are degenerate on purpose.
  for (int i = 0; i < stacks; ++i) {
    for (int j = 0; j < slices; ++j) {
      const int a = i * slices + j, b = i * slices + (j + 1) % slices;
      const int c = a + slices, d = b + slices;
      mesh.triangles.emplace_back(a, c, b);
      mesh.triangles.emplace_back(b, c, d);
    }
  }
  return mesh;
}

TriangleMesh triangle_soup(int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> centre(-1.0f, 1.0f), offset(-0.1f, 0.1f);
  TriangleMesh mesh;
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3f c(centre(rng), centre(rng), centre(rng));
    for (int k = 0; k < 3; ++k)
      mesh.positions.push_back(c + Eigen::Vector3f(offset(rng), offset(rng), offset(rng)));
    mesh.triangles.emplace_back(3 * i, 3 * i + 1, 3 * i + 2);
  }
  return mesh;
}

std::vector<Eigen::Vector3f> random_points(int count, float extent, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-extent, extent);
  std::vector<Eigen::Vector3f> points;
  for (int i = 0; i < count; ++i) points.emplace_back(u(rng), u(rng), u(rng));
  return points;
}

void expect_matches_brute_force(const TriangleMesh& mesh, const std::vector<Eigen::Vector3f>& points) {
  const MeshDistance distance(mesh);
  for (const Eigen::Vector3f& p : points) {
    const BruteForce expected = brute_force(mesh, p);
    const MeshDistance::Hit hit = distance.closest(p);
    ASSERT_GE(hit.triangle, 0);
    EXPECT_NEAR(hit.distance, expected.distance, 1e-6f) << p.transpose();
    // The hit is consistent: its point lies on its triangle at its distance.
    const Eigen::Vector3i& t = mesh.triangles[hit.triangle];
    const Eigen::Vector3f q =
        closest_point_on_triangle(p, mesh.positions[t[0]], mesh.positions[t[1]], mesh.positions[t[2]]);
    EXPECT_EQ(hit.point, q);
    EXPECT_EQ(hit.distance, (q - p).norm());
  }
}

TEST(ClosestPointOnTriangle, Regions) {
  const Eigen::Vector3f a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  const std::pair<Eigen::Vector3f, Eigen::Vector3f> cases[] = {
      {{-1, -1, 0.5f}, a},                     // vertex a
      {{2, -0.5f, 0}, b},                      // vertex b
      {{-0.5f, 2, 1}, c},                      // vertex c
      {{0.5f, -1, 0.3f}, {0.5f, 0, 0}},        // edge ab
      {{-1, 0.5f, 3}, {0, 0.5f, 0}},           // edge ac
      {{1, 1, -2}, {0.5f, 0.5f, 0}},           // edge bc
      {{0.25f, 0.25f, 2}, {0.25f, 0.25f, 0}},  // face, above
      {{0.1f, 0.6f, -1}, {0.1f, 0.6f, 0}},     // face, below
      {{0.2f, 0.2f, 0}, {0.2f, 0.2f, 0}},      // on the face
  };
  for (const auto& [p, expected] : cases) {
    EXPECT_LT((closest_point_on_triangle(p, a, b, c) - expected).norm(), 1e-6f) << p.transpose();
    // Corner order does not matter.
    EXPECT_LT((closest_point_on_triangle(p, c, a, b) - expected).norm(), 1e-6f) << p.transpose();
    EXPECT_LT((closest_point_on_triangle(p, b, a, c) - expected).norm(), 1e-6f) << p.transpose();
  }
}

TEST(ClosestPointOnTriangle, NoSampledPointOfTheTriangleIsCloser) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-1, 1);
  const auto random_vector = [&] { return Eigen::Vector3f(u(rng), u(rng), u(rng)); };
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Vector3f a = random_vector(), b = random_vector(), c = random_vector(),
                          p = 2 * random_vector();
    const Eigen::Vector3f q = closest_point_on_triangle(p, a, b, c);
    // q lies in the triangle's plane, inside it (barycentric coordinates in [0, 1]).
    const Eigen::Vector3f n = (b - a).cross(c - a);
    const float area2 = n.squaredNorm();
    const float u_bary = (c - b).cross(q - b).dot(n) / area2;
    const float v_bary = (a - c).cross(q - c).dot(n) / area2;
    EXPECT_NEAR(n.normalized().dot(q - a), 0.0f, 1e-5f);
    EXPECT_GE(u_bary, -1e-4f);
    EXPECT_GE(v_bary, -1e-4f);
    EXPECT_LE(u_bary + v_bary, 1 + 1e-4f);
    const float d = (q - p).norm();
    for (int i = 0; i <= 40; ++i) {
      for (int j = 0; i + j <= 40; ++j) {
        const Eigen::Vector3f s = a + (i / 40.0f) * (b - a) + (j / 40.0f) * (c - a);
        ASSERT_GE((s - p).norm(), d - 1e-5f);
      }
    }
  }
}

TEST(ClosestPointOnTriangle, DegenerateTriangles) {
  const Eigen::Vector3f p(0.3f, 2, 1);
  // All corners equal.
  const Eigen::Vector3f x(1, 1, 1);
  EXPECT_EQ(closest_point_on_triangle(p, x, x, x), x);
  // Collinear corners, in every order: the closest point of the segment [0, 2] on the x axis.
  const Eigen::Vector3f a(0, 0, 0), b(1, 0, 0), c(2, 0, 0);
  for (const auto& [s, t, r] :
       {std::tuple{a, b, c}, std::tuple{b, c, a}, std::tuple{c, a, b}, std::tuple{a, c, b}}) {
    const Eigen::Vector3f q = closest_point_on_triangle(p, s, t, r);
    ASSERT_TRUE(q.allFinite());
    EXPECT_LT((q - Eigen::Vector3f(0.3f, 0, 0)).norm(), 1e-6f);
    const Eigen::Vector3f beyond = closest_point_on_triangle(Eigen::Vector3f(5, 1, 0), s, t, r);
    EXPECT_LT((beyond - c).norm(), 1e-6f);
  }
  // Two equal corners.
  const Eigen::Vector3f q = closest_point_on_triangle(p, a, a, c);
  EXPECT_LT((q - Eigen::Vector3f(0.3f, 0, 0)).norm(), 1e-6f);
}

TEST(MeshDistance, MatchesBruteForceOnRandomTriangles) {
  const TriangleMesh mesh = triangle_soup(1000, 3);
  expect_matches_brute_force(mesh, random_points(800, 1.5f, 4));
  expect_matches_brute_force(mesh, random_points(100, 50.0f, 5));  // far away
}

TEST(MeshDistance, MatchesBruteForceOnSphere) {
  const TriangleMesh mesh = sphere(0.8f, 30, 48);
  const MeshDistance distance(mesh);
  EXPECT_EQ(distance.triangle_count(), mesh.triangles.size());
  expect_matches_brute_force(mesh, random_points(800, 1.2f, 6));
  // Points near the surface: distance ~ |r - 0.8| up to the faceting (< 3 mm here).
  std::mt19937 rng(7);
  std::normal_distribution<float> g(0, 1);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3f dir = Eigen::Vector3f(g(rng), g(rng), g(rng)).normalized();
    const float r = 0.8f + 0.05f * g(rng);
    const MeshDistance::Hit hit = distance.closest(r * dir);
    EXPECT_NEAR(hit.distance, std::abs(r - 0.8f), 0.004f);  // faceting: chord sagitta
  }
  // The centre is ~0.8 from everything.
  EXPECT_NEAR(distance.closest(Eigen::Vector3f::Zero()).distance, 0.8f, 0.004f);
}

TEST(MeshDistance, MaxDistanceCutsOff) {
  const TriangleMesh mesh = sphere(1.0f, 20, 30);
  const MeshDistance distance(mesh);
  const Eigen::Vector3f p(0, 0, 1.5f);  // 0.5 above the pole
  const MeshDistance::Hit miss = distance.closest(p, 0.4f);
  EXPECT_EQ(miss.triangle, -1);
  EXPECT_EQ(miss.distance, kInf);
  const MeshDistance::Hit hit = distance.closest(p, 0.6f);
  ASSERT_GE(hit.triangle, 0);
  EXPECT_NEAR(hit.distance, 0.5f, 1e-6f);
  EXPECT_EQ(hit.distance, distance.closest(p).distance);
  EXPECT_EQ(distance.closest(p, 0.0f).triangle, -1);
  EXPECT_EQ(distance.closest(Eigen::Vector3f(0, 0, 1), 0.0f).triangle >= 0, true);  // on the surface

  // Random points and radii: a hit exactly when brute force is within the radius.
  const std::vector<Eigen::Vector3f> points = random_points(500, 2.0f, 8);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> radius(0, 1);
  for (const Eigen::Vector3f& q : points) {
    const float r = radius(rng);
    const BruteForce expected = brute_force(mesh, q);
    const MeshDistance::Hit h = distance.closest(q, r);
    if (expected.distance <= r) {
      ASSERT_GE(h.triangle, 0);
      EXPECT_NEAR(h.distance, expected.distance, 1e-6f);
    } else {
      EXPECT_EQ(h.triangle, -1);
      EXPECT_EQ(h.distance, kInf);
    }
  }
}

TEST(MeshDistance, DegenerateTrianglesAndEdgeCases) {
  TriangleMesh mesh = triangle_soup(300, 10);
  const int base = static_cast<int>(mesh.positions.size());
  mesh.positions.emplace_back(0.5f, 0.5f, 0.5f);
  mesh.positions.emplace_back(0.6f, 0.5f, 0.5f);
  mesh.positions.emplace_back(0.7f, 0.5f, 0.5f);
  mesh.triangles.emplace_back(base, base, base);          // a point
  mesh.triangles.emplace_back(base, base + 1, base + 2);  // collinear
  mesh.triangles.emplace_back(base, base + 2, base + 2);  // two equal corners
  for (int i = 0; i < 50; ++i) mesh.triangles.emplace_back(base + 1, base + 1, base + 1);  // many equal boxes
  expect_matches_brute_force(mesh, random_points(1000, 1.5f, 11));
  const MeshDistance distance(mesh);
  EXPECT_NEAR(distance.closest(Eigen::Vector3f(0.6f, 0.5f, 0.5f)).distance, 0.0f, 1e-6f);

  // No hit for non-finite queries, negative radii and an empty mesh.
  EXPECT_EQ(distance.closest(Eigen::Vector3f(kInf, 0, 0)).triangle, -1);
  EXPECT_EQ(distance.closest(Eigen::Vector3f(std::nanf(""), 0, 0)).triangle, -1);
  EXPECT_EQ(distance.closest(Eigen::Vector3f::Zero(), -1.0f).triangle, -1);
  const MeshDistance empty{TriangleMesh{}};
  EXPECT_EQ(empty.closest(Eigen::Vector3f::Zero()).triangle, -1);
  EXPECT_EQ(empty.triangle_count(), 0u);

  // A single triangle.
  TriangleMesh one;
  one.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  one.triangles = {{0, 1, 2}};
  const MeshDistance single(one);
  const MeshDistance::Hit hit = single.closest(Eigen::Vector3f(0.2f, 0.2f, 3));
  EXPECT_EQ(hit.triangle, 0);
  EXPECT_NEAR(hit.distance, 3.0f, 1e-6f);
}

TEST(MeshDistance, OwnsItsGeometryAndIsThreadSafe) {
  TriangleMesh mesh = sphere(0.5f, 30, 40);
  const MeshDistance distance(mesh);
  const TriangleMesh copy = mesh;
  mesh = TriangleMesh{};  // the index keeps its own copy
  const std::vector<Eigen::Vector3f> points = random_points(10000, 1.0f, 12);
  std::vector<float> serial(points.size()), parallel(points.size());
  for (size_t i = 0; i < points.size(); ++i) serial[i] = distance.closest(points[i]).distance;
  parallel_for(
      0, static_cast<int>(points.size()), [&](int i) { parallel[i] = distance.closest(points[i]).distance; },
      8);
  EXPECT_EQ(serial, parallel);
  for (size_t i = 0; i < 100; ++i) EXPECT_NEAR(serial[i], brute_force(copy, points[i]).distance, 1e-6f);
}

}  // namespace
}  // namespace zipfusion
