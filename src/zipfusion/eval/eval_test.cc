#include "zipfusion/eval/eval.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <numbers>

#include "zipfusion/core/error.h"
#include "zipfusion/core/error_test_util.h"
#include "zipfusion/io/mesh_io.h"
#include "zipfusion/io/rig.h"
#include "zipfusion/synth/synth.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

const fs::path kSamba = fs::path(ZF_SOURCE_DIR) / ".." / "shared" / "data" / "samba-4cam";

// A square in the plane y = offset (normal −y, facing a camera on −y), x in [x0, x1], z in
// [z0, z1], as a grid of cells × cells quads. Colours (when asked) a linear function of x and z.
TriangleMesh grid_square(double x0, double x1, double z0, double z1, double offset, int cells, bool colored = false,
                         int color_shift = 0) {
  TriangleMesh mesh;
  for (int j = 0; j <= cells; ++j) {
    for (int i = 0; i <= cells; ++i) {
      const double x = x0 + (x1 - x0) * i / cells, z = z0 + (z1 - z0) * j / cells;
      mesh.positions.emplace_back(static_cast<float>(x), static_cast<float>(offset), static_cast<float>(z));
      if (colored) {
        auto channel = [&](double value) { return static_cast<unsigned char>(std::lround(value) + color_shift); };
        mesh.colors.push_back({channel(40 + 300 * (x + 0.25)), channel(60 + 200 * (z - 0.75)), channel(120 + 100 * (x + 0.25) - 50 * (z - 0.75))});
      }
    }
  }
  for (int j = 0; j < cells; ++j) {
    for (int i = 0; i < cells; ++i) {
      const int a = j * (cells + 1) + i, b = a + 1, c = a + cells + 1, d = c + 1;
      // Counter-clockwise seen from −y: x right, z up.
      mesh.triangles.emplace_back(a, b, d);
      mesh.triangles.emplace_back(a, d, c);
    }
  }
  return mesh;
}

// The 0.5 m square x in ±0.25, z in [0.75, 1.25] on the plane y = offset.
TriangleMesh square(double offset, int cells = 100) { return grid_square(-0.25, 0.25, 0.75, 1.25, offset, cells); }

// One Kinect-like depth camera at (0, −2, 1) looking along +y at the square.
Rig one_camera_rig(const Eigen::Vector3d& eye = {0, -2, 1}) {
  Rig rig;
  rig.frame_count = 1;
  CameraModel cam;
  cam.name = "cam0";
  cam.depth_intrinsics = {.width = 640, .height = 480, .fx = 580, .fy = 580, .cx = 319.5, .cy = 239.5};
  cam.world_from_depth = look_at(eye, Eigen::Vector3d(0, 0, eye.z()));
  rig.cameras.push_back(cam);
  return rig;
}

// A closed axis-aligned box, outward counter-clockwise triangles.
TriangleMesh box(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) {
  TriangleMesh mesh;
  for (int k = 0; k < 8; ++k) mesh.positions.emplace_back(k & 1 ? hi.x() : lo.x(), k & 2 ? hi.y() : lo.y(), k & 4 ? hi.z() : lo.z());
  const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : faces) {
    mesh.triangles.emplace_back(f[0], f[1], f[2]);
    mesh.triangles.emplace_back(f[0], f[2], f[3]);
  }
  return mesh;
}

TEST(Eval, SquareShiftedAlongItsNormal) {
  const TriangleMesh truth = square(0, 1);  // two large triangles: subdivided for sampling
  const Rig rig = one_camera_rig();
  const FrameQuality q = evaluate_frame(square(-0.005), truth, rig, std::nullopt);
  EXPECT_NEAR(q.accuracy_mean_mm, 5.0, 0.05);
  EXPECT_NEAR(q.accuracy_p95_mm, 5.0, 0.05);
  EXPECT_DOUBLE_EQ(q.completeness, 1.0);
  EXPECT_NEAR(q.observed_true_area_m2, 0.25, 1e-4);
  EXPECT_NEAR(q.true_area_m2, 0.25, 1e-4);
  EXPECT_NEAR(q.reconstruction_area_m2, 0.25, 1e-4);
  EXPECT_NEAR(q.area_ratio, 1.0, 1e-3);
  EXPECT_EQ(q.triangles, 20000);
  EXPECT_EQ(q.vertices, 101 * 101);
  EXPECT_EQ(q.components, 1);
  EXPECT_EQ(q.large_components, 1);
  EXPECT_EQ(q.non_manifold_edges, 0);
  EXPECT_TRUE(std::isnan(q.color_error));  // no colours

  const FrameQuality far = evaluate_frame(square(-0.015), truth, rig, std::nullopt);
  EXPECT_NEAR(far.accuracy_mean_mm, 15.0, 0.05);
  EXPECT_DOUBLE_EQ(far.completeness, 0.0);
}

TEST(Eval, LargeReconstructionTrianglesAreSubdivided) {
  // The reconstruction is two triangles tilted about the x axis: one edge 2 mm from the truth,
  // the other 12 mm: distances spread evenly over [2, 12] mm, mean 7 mm, p95 11.5 mm. The two
  // centroids alone (5.3 and 8.7 mm) would give a p95 of 8.7 mm.
  TriangleMesh tilted = square(0, 1);
  for (Eigen::Vector3f& p : tilted.positions) p.y() = -0.002f - 0.010f * (p.z() - 0.75f) / 0.5f;
  const FrameQuality q = evaluate_frame(tilted, square(0), one_camera_rig(), std::nullopt);
  EXPECT_NEAR(q.accuracy_mean_mm, 7.0, 0.05);
  EXPECT_NEAR(q.accuracy_p95_mm, 11.5, 0.1);
}

TEST(Eval, HalfCoveredSquare) {
  // The reconstruction covers x < 0 of the truth, 5 mm in front. Samples of the truth up to
  // sqrt(10² − 5²) = 8.7 mm beyond its edge are covered too: 0.5 + 8.7 mm / 0.5 m.
  const TriangleMesh half = grid_square(-0.25, 0, 0.75, 1.25, -0.005, 50);
  const FrameQuality q = evaluate_frame(half, square(0), one_camera_rig(), std::nullopt);
  EXPECT_NEAR(q.completeness, 0.5 + 0.00866 / 0.5, 0.005);
  EXPECT_NEAR(q.area_ratio, 0.5, 1e-3);
  EXPECT_NEAR(q.accuracy_mean_mm, 5.0, 0.05);
}

TEST(Eval, TwoCopiesDoubleTheAreaInTwoComponents) {
  TriangleMesh twice = square(-0.005);
  twice.append(square(-0.005));
  const FrameQuality q = evaluate_frame(twice, square(0), one_camera_rig(), std::nullopt);
  EXPECT_NEAR(q.area_ratio, 2.0, 2e-3);
  EXPECT_EQ(q.components, 2);
  EXPECT_EQ(q.large_components, 2);
  EXPECT_EQ(q.non_manifold_edges, 0);  // the copies share no vertex index
  EXPECT_DOUBLE_EQ(q.completeness, 1.0);
  EXPECT_NEAR(q.accuracy_mean_mm, 5.0, 0.05);
}

TEST(Eval, SmallComponentsAreCountedButNotLarge) {
  TriangleMesh recon = square(-0.005);
  for (int k = 0; k < 3; ++k) recon.append(grid_square(-0.2 + 0.1 * k, -0.15 + 0.1 * k, 0.8, 0.85, -0.003, 3));  // 18 triangles each
  const FrameQuality q = evaluate_frame(recon, square(0), one_camera_rig(), std::nullopt, {.min_component_triangles = 50});
  EXPECT_EQ(q.components, 4);
  EXPECT_EQ(q.large_components, 1);
  const FrameQuality all_large = evaluate_frame(recon, square(0), one_camera_rig(), std::nullopt, {.min_component_triangles = 18});
  EXPECT_EQ(all_large.large_components, 4);
}

TEST(Eval, SurfaceHiddenFromEveryCameraIsNotObserved) {
  // A 0.4 m box seen from the front by one camera: only its front face (0.16 of 0.96 m²) is
  // observed, plus the strips of the side faces within the 1 cm tolerance behind the front edge
  // (4 × 0.4 m × 1 cm, and up to one more row of the 5.6 mm sample grid).
  const TriangleMesh truth = box({-0.2f, -0.2f, 0.8f}, {0.2f, 0.2f, 1.2f});
  const Rig rig = one_camera_rig({0, -2.5, 1});
  const TriangleMesh front = grid_square(-0.2, 0.2, 0.8, 1.2, -0.2, 80);
  const FrameQuality q = evaluate_frame(front, truth, rig, std::nullopt);
  EXPECT_NEAR(q.true_area_m2, 0.96, 1e-3);
  EXPECT_GT(q.observed_true_area_m2, 0.159);
  EXPECT_LT(q.observed_true_area_m2, 0.16 + 4 * 0.4 * 0.0125);
  EXPECT_GT(q.completeness, 0.99);
  EXPECT_NEAR(q.accuracy_mean_mm, 0.0, 0.01);

  // Seen from behind instead, the same reconstruction covers nothing observed.
  const FrameQuality behind = evaluate_frame(front, truth, one_camera_rig({0, 2.5, 1}), std::nullopt);
  EXPECT_DOUBLE_EQ(behind.completeness, 0.0);
  // Out of the working range, nothing is observed.
  const FrameQuality near = evaluate_frame(front, truth, rig, std::nullopt, {.min_range_m = 3.0, .max_range_m = 4.5});
  EXPECT_EQ(near.observed_true_area_m2, 0.0);
  EXPECT_TRUE(std::isnan(near.completeness));
  EXPECT_TRUE(std::isnan(near.area_ratio));
}

TEST(Eval, GrazingSurfacesAreObserved) {
  // The square turned to 85° from the line of sight: its depth changes by about 4 cm per pixel, far
  // more than the tolerance, yet the camera sees it. (Only a sliver beyond the last pixel
  // column at either end of its 13-pixel-wide image is not observed; the nearest-pixel test
  // alone would keep about half.)
  TriangleMesh truth = square(0);
  const double angle = 85 * M_PI / 180;
  for (Eigen::Vector3f& p : truth.positions) {
    const double x = p.x();
    p.x() = static_cast<float>(x * std::cos(angle));
    p.y() = static_cast<float>(x * std::sin(angle));
  }
  const FrameQuality q = evaluate_frame(truth, truth, one_camera_rig(), std::nullopt);
  EXPECT_GT(q.observed_true_area_m2, 0.95 * 0.25);
  EXPECT_LT(q.observed_true_area_m2, 0.25 + 1e-4);
  EXPECT_DOUBLE_EQ(q.completeness, 1.0);
}

TEST(Eval, NonManifoldEdges) {
  // Three triangles around the edge 0-1, plus one ordinary neighbour.
  TriangleMesh mesh;
  mesh.positions = {{0, 0, 1}, {0.1f, 0, 1}, {0.05f, 0, 1.1f}, {0.05f, 0, 0.9f}, {0.05f, 0.1f, 1}, {0.15f, 0, 1.1f}};
  mesh.triangles = {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}, {1, 5, 2}};
  EXPECT_EQ(count_non_manifold_edges(mesh), 1);
  EXPECT_EQ(connected_components(mesh).count(), 1);
  EXPECT_NEAR(surface_area(mesh), 4 * 0.5 * 0.1 * 0.1, 1e-7);
  const FrameQuality q = evaluate_frame(mesh, square(0), one_camera_rig(), std::nullopt);
  EXPECT_EQ(q.non_manifold_edges, 1);
  EXPECT_EQ(q.components, 1);
  EXPECT_EQ(q.large_components, 0);
  EXPECT_EQ(q.triangles, 4);
  EXPECT_EQ(q.vertices, 6);
  // The square itself is a manifold with boundary.
  EXPECT_EQ(count_non_manifold_edges(square(0)), 0);
}

// Two triangles on the edge (0,0,0)–(1,0,0): the first in the plane z = 0, the second's far corner
// at `angle_deg` from the first's (0: the flat continuation across the edge, 180: folded back
// onto the first).
TriangleMesh hinge(double angle_deg, bool consistent = true) {
  const double a = angle_deg * std::numbers::pi / 180;
  TriangleMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0.5f, 1, 0}, {0.5f, static_cast<float>(-std::cos(a)), static_cast<float>(std::sin(a))}};
  mesh.triangles = {{0, 1, 2}, consistent ? Eigen::Vector3i(1, 0, 3) : Eigen::Vector3i(0, 1, 3)};
  return mesh;
}

TEST(Eval, FoldedEdges) {
  // The normals are `angle` apart: folded beyond 120°.
  for (const double angle : {0.0, 45.0, 90.0, 119.0}) {
    EXPECT_EQ(count_folded_edges(hinge(angle)), 0) << angle;
    EXPECT_EQ(count_folded_edges(hinge(angle, false)), 0) << angle << ", the second turned over";
  }
  for (const double angle : {121.0, 150.0, 179.0}) {
    EXPECT_EQ(count_folded_edges(hinge(angle)), 1) << angle;
    EXPECT_EQ(count_folded_edges(hinge(angle, false)), 1) << angle << ", the second turned over";
  }
  // A third triangle on the edge makes it non-manifold, not folded; a triangle without area
  // folds nothing.
  TriangleMesh three = hinge(150);
  three.positions.emplace_back(0.5f, 0, -1);
  three.triangles.emplace_back(0, 1, 4);
  EXPECT_EQ(count_folded_edges(three), 0);
  TriangleMesh flat = hinge(150);
  flat.positions[3] = {0.5f, 0, 0};
  EXPECT_EQ(count_folded_edges(flat), 0);
  // The grid of a square, and evaluate_frame reports the count.
  EXPECT_EQ(count_folded_edges(grid_square(0, 0.1, 0, 0.1, 0, 4)), 0);
  TriangleMesh folded = hinge(160);
  for (Eigen::Vector3f& p : folded.positions) p = 0.1f * p + Eigen::Vector3f(0, 0, 1);
  EXPECT_EQ(evaluate_frame(folded, square(0), one_camera_rig(), std::nullopt).folded_edges, 1);
}

TEST(Eval, DoubledTriangles) {
  TriangleMesh mesh = grid_square(0, 0.1, 0, 0.1, 0, 4);  // 32 triangles, none doubled
  EXPECT_EQ(count_doubled_triangles(mesh), 0);
  const Eigen::Vector3i first = mesh.triangles[0], fifth = mesh.triangles[4];
  mesh.triangles.emplace_back(first[0], first[2], first[1]);  // turned over
  EXPECT_EQ(count_doubled_triangles(mesh), 1);
  mesh.triangles.emplace_back(fifth[1], fifth[2], fifth[0]);  // the same way round, rotated
  mesh.triangles.emplace_back(first[2], first[1], first[0]);  // a third on the first's corners
  EXPECT_EQ(count_doubled_triangles(mesh), 3);
  mesh.triangles.emplace_back(first[0], first[0], first[1]);  // repeats a vertex: skipped, twice over
  mesh.triangles.emplace_back(first[0], first[0], first[1]);
  EXPECT_EQ(count_doubled_triangles(mesh), 3);
  // Two triangles on the same positions but their own vertices are not doubled by index.
  const TriangleMesh twins = [] {
    TriangleMesh m = grid_square(0, 0.1, 0, 0.1, 0, 1);
    m.append(grid_square(0, 0.1, 0, 0.1, 0, 1));
    return m;
  }();
  EXPECT_EQ(count_doubled_triangles(twins), 0);
  // evaluate_frame reports the count.
  TriangleMesh doubled = square(0);
  doubled.triangles.emplace_back(doubled.triangles[1][0], doubled.triangles[1][2], doubled.triangles[1][1]);
  EXPECT_EQ(evaluate_frame(doubled, square(0), one_camera_rig(), std::nullopt).doubled_triangles, 1);
}

TEST(Eval, ColourErrorOfShiftedColours) {
  // Truth: a coarse grid with colours linear in x and z (rounded at the vertices); the
  // reconstruction: a finer grid 2 mm in front with the same function + 10 levels. Interpolating
  // the rounded true colours differs from the function by at most 0.5 levels.
  const TriangleMesh truth = grid_square(-0.25, 0.25, 0.75, 1.25, 0, 10, true);
  const TriangleMesh recon = grid_square(-0.25, 0.25, 0.75, 1.25, -0.002, 37, true, 10);
  const FrameQuality q = evaluate_frame(recon, truth, one_camera_rig(), std::nullopt);
  EXPECT_NEAR(q.color_error, 10.0, 0.5);
  EXPECT_EQ(q.color_vertices, 38 * 38);
  const FrameQuality same = evaluate_frame(grid_square(-0.25, 0.25, 0.75, 1.25, -0.002, 10, true), truth, one_camera_rig(), std::nullopt);
  EXPECT_NEAR(same.color_error, 0.0, 1e-3);
  // Vertices farther than color_max_distance_m are not compared.
  const FrameQuality far = evaluate_frame(recon, truth, one_camera_rig(), std::nullopt, {.color_max_distance_m = 0.001});
  EXPECT_EQ(far.color_vertices, 0);
  EXPECT_TRUE(std::isnan(far.color_error));
}

TEST(Eval, GeometryOutsideTheVolumeIsIgnored) {
  // Truth: the square plus a second one at x = 0.6 m; reconstruction: the first square plus a
  // stray square at x = −0.6 m. The volume holds only the first.
  TriangleMesh truth = square(0);
  truth.append(grid_square(0.5, 0.7, 0.9, 1.1, 0, 10));
  TriangleMesh recon = square(-0.005);
  recon.append(grid_square(-0.7, -0.5, 0.9, 1.1, -0.1, 10));
  const Box3d volume{{-0.4, -0.5, 0.5}, {0.4, 0.5, 1.5}};
  const FrameQuality q = evaluate_frame(recon, truth, one_camera_rig(), volume);
  EXPECT_EQ(q.triangles, 20000);
  EXPECT_EQ(q.vertices, 101 * 101);
  EXPECT_EQ(q.components, 1);
  EXPECT_NEAR(q.true_area_m2, 0.25, 1e-4);
  EXPECT_NEAR(q.observed_true_area_m2, 0.25, 1e-4);
  EXPECT_NEAR(q.reconstruction_area_m2, 0.25, 1e-4);
  EXPECT_NEAR(q.accuracy_mean_mm, 5.0, 0.05);
  EXPECT_DOUBLE_EQ(q.completeness, 1.0);
  // Without the volume, both extra squares count.
  const FrameQuality all = evaluate_frame(recon, truth, one_camera_rig(), std::nullopt);
  EXPECT_EQ(all.components, 2);
  EXPECT_NEAR(all.observed_true_area_m2, 0.29, 1e-3);
  EXPECT_GT(all.accuracy_p95_mm, 50);
  EXPECT_LT(all.completeness, 0.9);
}

TEST(Eval, EmptyReconstruction) {
  const FrameQuality q = evaluate_frame(TriangleMesh{}, square(0), one_camera_rig(), std::nullopt);
  EXPECT_EQ(q.triangles, 0);
  EXPECT_EQ(q.components, 0);
  EXPECT_TRUE(std::isnan(q.accuracy_mean_mm));
  EXPECT_DOUBLE_EQ(q.completeness, 0.0);
  EXPECT_DOUBLE_EQ(q.area_ratio, 0.0);
}

TEST(Eval, ResultsDoNotDependOnThreads) {
  TriangleMesh recon = grid_square(-0.25, 0.1, 0.75, 1.25, -0.004, 70, true, 5);
  for (size_t i = 0; i < recon.positions.size(); ++i) recon.positions[i].y() += 0.003f * std::sin(0.37f * static_cast<float>(i));
  const TriangleMesh truth = grid_square(-0.25, 0.25, 0.75, 1.25, 0, 30, true);
  const FrameQuality one = evaluate_frame(recon, truth, one_camera_rig(), std::nullopt, {.num_threads = 1});
  const FrameQuality many = evaluate_frame(recon, truth, one_camera_rig(), std::nullopt, {.num_threads = 7});
  EXPECT_EQ(one.accuracy_mean_mm, many.accuracy_mean_mm);
  EXPECT_EQ(one.accuracy_p95_mm, many.accuracy_p95_mm);
  EXPECT_EQ(one.completeness, many.completeness);
  EXPECT_EQ(one.observed_true_area_m2, many.observed_true_area_m2);
  EXPECT_EQ(one.color_error, many.color_error);
  EXPECT_GT(one.accuracy_mean_mm, 2.0);
  EXPECT_LT(one.completeness, 0.75);
  EXPECT_GT(one.completeness, 0.65);
}

TEST(Eval, OptionsAreValidated) {
  const TriangleMesh s = square(0, 1);
  const std::string message = invalid_input_message([&] { evaluate_frame(s, s, one_camera_rig(), std::nullopt, {.sample_spacing_m = 0}); });
  EXPECT_NE(message.find("sample_spacing_m"), std::string::npos) << message;
  EXPECT_THROW(EvalOptions({.completeness_threshold_m = -1}).validate(), InvalidInput);
  EXPECT_THROW(EvalOptions({.min_range_m = 2, .max_range_m = 1}).validate(), InvalidInput);
  EXPECT_THROW(EvalOptions({.min_component_triangles = 0}).validate(), InvalidInput);
  EXPECT_THROW(EvalOptions({.num_threads = -1}).validate(), InvalidInput);
  EXPECT_NO_THROW(EvalOptions{}.validate());
}

TEST(Eval, BuiltInHumanAgainstItself) {
  SynthOptions options;
  const TriangleMesh human = subject_mesh(options, 0);
  const Rig rig = make_ring_rig(options);
  const FrameQuality q = evaluate_frame(human, human, rig, std::nullopt);
  EXPECT_LT(q.accuracy_mean_mm, 0.01);
  EXPECT_LT(q.accuracy_p95_mm, 0.01);
  EXPECT_DOUBLE_EQ(q.completeness, 1.0);
  EXPECT_NEAR(q.color_error, 0.0, 0.01);
  EXPECT_EQ(q.non_manifold_edges, 0);
  EXPECT_EQ(q.components, 18);  // one closed part each
  EXPECT_EQ(q.large_components, 18);
  EXPECT_NEAR(q.reconstruction_area_m2, surface_area(human), 1e-6 * surface_area(human));
  EXPECT_NEAR(q.true_area_m2, q.reconstruction_area_m2, 1e-4 * q.reconstruction_area_m2);
  // Four cameras around the subject see most of it, but not the overlaps at the joints, the
  // soles or the inner sides of the limbs.
  const double observed = q.observed_true_area_m2 / q.true_area_m2;
  EXPECT_GT(observed, 0.65);  // 0.735 when written
  EXPECT_LT(observed, 0.85);
  EXPECT_NEAR(q.area_ratio, 1 / observed, 1e-9);
}

// A reconstruction-sized frame of real data: samba-4cam frame 0's true surface (≈ 20k
// triangles), split 16-fold, against the original, with the 4 true cameras. Unoptimised builds
// (asserts on, e.g. the ASan build, about 200× slower) split it 4-fold only.
#ifdef NDEBUG
constexpr int kSubdivisionRounds = 2;
#else
constexpr int kSubdivisionRounds = 1;
#endif

TEST(Eval, SambaFrameAgainstItsSubdivision) {
  if (!fs::exists(kSamba / "ground_truth" / "mesh" / "000000.ply")) GTEST_SKIP() << "no " << kSamba;
  const TriangleMesh truth = read_mesh(kSamba / "ground_truth" / "mesh" / "000000.ply");
  const Rig rig = read_rig(kSamba / "ground_truth" / "rig.json");
  TriangleMesh fine = truth;
  for (int round = 0; round < kSubdivisionRounds; ++round) {  // midpoint subdivision, 1 → 4 triangles, no shared midpoints
    TriangleMesh next;
    next.positions = fine.positions;
    next.colors = fine.colors;
    for (const Eigen::Vector3i& t : fine.triangles) {
      const int m = static_cast<int>(next.positions.size());
      for (int k = 0; k < 3; ++k) {
        next.positions.push_back(0.5f * (fine.positions[t[k]] + fine.positions[t[(k + 1) % 3]]));
        if (fine.has_colors()) next.colors.push_back(fine.colors[t[k]]);
      }
      next.triangles.emplace_back(t[0], m, m + 2);
      next.triangles.emplace_back(m, t[1], m + 1);
      next.triangles.emplace_back(m + 2, m + 1, t[2]);
      next.triangles.emplace_back(m, m + 1, m + 2);
    }
    fine = std::move(next);
  }
  ASSERT_EQ(fine.triangle_count(), (kSubdivisionRounds == 2 ? 16 : 4) * truth.triangle_count());
  const auto start = std::chrono::steady_clock::now();
  const std::optional<Box3d> volume = read_rig(kSamba / "rig.json").volume;
  const FrameQuality q = evaluate_frame(fine, truth, rig, volume, {.num_threads = 2});
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cout << "samba frame 0: " << fine.triangle_count() << " reconstruction triangles, " << truth.triangle_count()
            << " true, evaluated in " << seconds << " s on 2 threads; observed " << q.observed_true_area_m2 << " of "
            << q.true_area_m2 << " m2\n";
  RecordProperty("seconds", std::to_string(seconds));
  EXPECT_LT(q.accuracy_mean_mm, 0.01);
  EXPECT_DOUBLE_EQ(q.completeness, 1.0);
  EXPECT_GT(q.observed_true_area_m2, 0.6 * q.true_area_m2);
  EXPECT_NEAR(q.reconstruction_area_m2, q.true_area_m2, 1e-3 * q.true_area_m2);
}

}  // namespace
}  // namespace zipfusion
