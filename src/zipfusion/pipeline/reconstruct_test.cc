#include "zipfusion/pipeline/reconstruct.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <utility>

#include "zipfusion/core/error.h"
#include "zipfusion/core/error_test_util.h"
#include "zipfusion/core/mesh_distance.h"
#include "zipfusion/eval/eval.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/synth/synth.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

const fs::path kSharedData = fs::path(ZF_SOURCE_DIR) / ".." / "shared" / "data";

// Largest depth difference (along the camera that made it) between two vertices of a triangle,
// less the SDC threshold `jump` allows between them; and the largest difference itself.
std::pair<double, double> largest_depth_jump(const TriangleMesh& mesh, const CameraModel& camera, DepthJump jump) {
  const Rigid3d depth_from_world = camera.world_from_depth.inverse();
  double excess = -1, largest = 0;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    double z[3];
    for (int k = 0; k < 3; ++k) z[k] = (depth_from_world * mesh.positions[t[k]].cast<double>()).z();
    for (int k = 0; k < 3; ++k) {
      const double a = z[k], b = z[(k + 1) % 3];
      excess = std::max(excess, std::abs(a - b) - jump.between(static_cast<float>(a), static_cast<float>(b)));
      largest = std::max(largest, std::abs(a - b));
    }
  }
  return {excess, largest};
}

// Real single-camera captures give sensible meshes: many triangles, none across a depth jump
// larger than the SDC threshold for their focal length (3 cm at 580 px, the Kinect's: 3.3 cm for
// the PCL Kinect capture's 525 px, 3.6 cm for the RealSense's 482 px), grown with depth² beyond
// 3 m.
TEST(Reconstruct, RealCapturesGiveMeshesWithoutJumps) {
  for (const auto& [name, focal] : {std::pair{"pcl-desk", 525.0}, std::pair{"realsense-person", 481.94}}) {
    const Capture capture = Capture::open(kSharedData / name);
    const double threshold = sdc_depth_jump(0.03, capture.rig().cameras[0].depth_intrinsics);
    EXPECT_NEAR(threshold, 0.03 * 580.0 / focal, 1e-12) << name;
    for (bool bilateral : {false, true}) {
      FrameReconstructor reconstructor(capture.rig(), {.mode = ReconstructMode::kSeparate, .bilateral = bilateral});
      const FrameSet frames = capture.load_frame(0);
      const FrameResult result = reconstructor.reconstruct(frames);
      size_t valid = 0;
      for (unsigned short d : frames.cameras[0].depth.data) valid += d != 0;
      // Nearly two triangles per valid pixel: only edges and depth steps lose some.
      EXPECT_GT(result.mesh.triangle_count(), valid) << name;
      EXPECT_LT(result.mesh.triangle_count(), 2 * valid) << name;
      EXPECT_LE(result.mesh.vertex_count(), valid) << name;
      const auto [excess, largest] = largest_depth_jump(result.mesh, capture.rig().cameras[0], depth_jump(threshold, SdcOptions{}.growth_depth_m));
      EXPECT_LT(excess, 1e-4) << name;
      EXPECT_GT(largest, 0.5 * threshold) << name;
      // With a constant threshold no triangle spans more than it.
      FrameReconstructor constant(capture.rig(), {.mode = ReconstructMode::kSeparate, .bilateral = bilateral, .sdc = {.growth_depth_m = 0}});
      EXPECT_LT(largest_depth_jump(constant.reconstruct(frames).mesh, capture.rig().cameras[0], DepthJump{static_cast<float>(threshold)}).second,
                threshold + 1e-4)
          << name;
      EXPECT_EQ(result.mesh.colors.size(), result.mesh.vertex_count());
      EXPECT_EQ(result.cameras_used, 1);
    }
  }
}

// The SDC threshold follows each camera's focal length (sdc_depth_jump, pinned in sdc_mesh_test):
// 3 cm at 580 px, scaled up by 580/f for a shorter one, kept for a longer one, and at a level of
// detail taken from the subsampled focal length. Meshes of a depth ramp, `step_m` deeper per column
// from 1 m, seen by cameras of the given focal lengths, all at the same pose.
FrameResult ramp_meshes(const std::vector<double>& focal_lengths, double step_m, int depth_level, ReconstructMode mode) {
  Rig rig;
  FrameSet frames;
  for (size_t c = 0; c < focal_lengths.size(); ++c) {
    CameraModel camera;
    camera.name = "cam" + std::to_string(c);
    camera.depth_intrinsics = {.width = 48, .height = 36, .fx = focal_lengths[c], .fy = focal_lengths[c], .cx = 23.5, .cy = 17.5};
    rig.cameras.push_back(camera);
    DepthImage depth(48, 36);
    for (int v = 0; v < 36; ++v) {
      for (int u = 0; u < 48; ++u) depth(u, v) = static_cast<unsigned short>(std::lround(1000.0 * (1.0 + step_m * u)));
    }
    frames.cameras.push_back({.has_depth = true, .depth = std::move(depth)});
  }
  FrameReconstructor reconstructor(rig, {.mode = mode, .bilateral = false, .depth_level = depth_level});
  for (int c = 0; c < static_cast<int>(focal_lengths.size()); ++c) {
    const double f = focal_lengths[c] / (1 << depth_level);
    EXPECT_DOUBLE_EQ(reconstructor.max_depth_jump_m(c), 0.03 * std::max(1.0, 580.0 / f)) << "camera " << c;
  }
  return reconstructor.reconstruct(frames);
}

TEST(Reconstruct, SdcThresholdFollowsTheFocalLength) {
  auto triangles = [](const std::vector<double>& focal_lengths, double step_m, int depth_level) {
    return ramp_meshes(focal_lengths, step_m, depth_level, ReconstructMode::kSeparate).mesh.triangle_count();
  };
  const size_t every = 2 * 47 * 35;
  EXPECT_EQ(triangles({290}, 0.04, 0), every);  // 4 cm steps against 6 cm
  EXPECT_EQ(triangles({580}, 0.04, 0), 0u);     // against 3 cm
  EXPECT_EQ(triangles({1160}, 0.04, 0), 0u);
  EXPECT_EQ(triangles({1160}, 0.02, 0), every);  // a longer focal length keeps 3 cm: not tightened
  EXPECT_EQ(triangles({290, 580}, 0.04, 0), every);  // each camera its own threshold
  // Every second pixel of a 580 px camera is a 290 px one: 5 cm steps against 6 cm; every fourth a
  // 145 px one: 10 cm against 12 cm. A 1160 px camera's second pixel is a 580 px one: 5 cm against 3.
  EXPECT_EQ(triangles({580}, 0.025, 1), static_cast<size_t>(2 * 23 * 17));
  EXPECT_EQ(triangles({580}, 0.025, 2), static_cast<size_t>(2 * 11 * 8));
  EXPECT_EQ(triangles({1160}, 0.025, 1), 0u);
}

// The zipper takes each camera's threshold too: two 290 px cameras at one pose see the 4 cm ramp
// as one surface, overlap, and come out as one sheet; a 580 px camera beside them sees no surface.
// (The zipper's coarse levels need the 290 px threshold: with camera 0's, the smallest or the
// 3 cm fallback for all, they hold no triangles and no pair is found.)
TEST(Reconstruct, ZipperUsesEachCamerasSdcThreshold) {
  const FrameResult result = ramp_meshes({580, 290, 290}, 0.04, 0, ReconstructMode::kZipper);
  EXPECT_EQ(result.zipper.pairs, 1);
  EXPECT_GT(result.zipper.redundant_removed, 0);
  const size_t every = 2 * 47 * 35;
  EXPECT_GT(result.mesh.triangle_count(), every * 9 / 10);
  EXPECT_LT(result.mesh.triangle_count(), every * 11 / 10);
}

// A capture's rig with its ground-truth poses (and the capture's volume).
Rig rig_with_true_poses(const Capture& capture) {
  Rig rig = *capture.ground_truth_rig();
  rig.volume = capture.rig().volume;
  return rig;
}

// A samba-4cam frame set and the rig with its ground-truth poses.
std::pair<Rig, FrameSet> samba_frame_with_true_poses(int frame) {
  const Capture capture = Capture::open(kSharedData / "samba-4cam");
  return {rig_with_true_poses(capture), capture.load_frame(frame)};
}

// --min-component drops the pieces under its size and nothing else: on samba-4cam frame 0
// unfiltered, the specks of noise at silhouettes (over a hundred pieces) go and every piece left
// has at least 50 triangles, and the triangles left are those of the large pieces.
TEST(Reconstruct, SmallPiecesAreDroppedWhenAsked) {
  const auto [rig, frames] = samba_frame_with_true_poses(0);
  FrameReconstructor all_pieces(rig, {.mode = ReconstructMode::kZipper, .bilateral = false});
  FrameReconstructor large_pieces(rig, {.mode = ReconstructMode::kZipper, .bilateral = false, .min_component_triangles = 50});
  const FrameResult all = all_pieces.reconstruct(frames);
  const FrameResult large = large_pieces.reconstruct(frames);
  const MeshComponents before = connected_components(all.mesh), after = connected_components(large.mesh);
  int small_pieces = 0, small_triangles = 0;
  for (const int n : before.triangle_counts) {
    if (n < 50) ++small_pieces, small_triangles += n;
  }
  EXPECT_GT(small_pieces, 20);
  EXPECT_EQ(all.small_component_triangles, 0);
  EXPECT_EQ(large.small_component_triangles, small_triangles);
  EXPECT_EQ(large.mesh.triangle_count() + small_triangles, all.mesh.triangle_count());
  EXPECT_EQ(after.count(), before.count() - small_pieces);
  for (const int n : after.triangle_counts) EXPECT_GE(n, 50);
  std::vector<Eigen::Vector3i> large_triangles;
  for (size_t i = 0; i < all.mesh.triangles.size(); ++i) {
    if (before.triangle_counts[before.triangle_component[i]] >= 50) large_triangles.push_back(all.mesh.triangles[i]);
  }
  EXPECT_EQ(large.mesh.triangles, large_triangles);
}

// The seams fold none of their triangles over their neighbours (count_folded_edges:
// the folds of the zippered mesh less those of its kept triangles alone, whose vertices the seams
// may have moved along their rays, and by at most 1.5 pixels off them (relax_creases): folds among
// kept triangles are bounded against the separate meshes by zipper_quality_test), on samba-4cam
// frame 0 with the true poses, and every seam
// triangle faces a camera (each faces its seam's virtual camera, halfway between its two). When
// the seam points were laid out at their surface's mean depth but output at their measured depth,
// the unfiltered seam folded at 1 681 edges (57 after, for 7 231 seam triangles) and 25 of its
// triangles faced away from every camera; filtered, at 54 edges (26 after, for 8 825). Moving the
// points towards the other camera's layer and flipping creases out left 53 and 16; moving them to
// halfway between the layers along the surface normal and fairing the seam, 29 and 3; relaxing
// the creases left along the layout's line of sight (clipping.cc, relax_creases), 26 and 0;
// testing the pixel grid around each moved point exactly where no other seam's point is a corner
// of it (keeps_pixel_grid_unfolded), with three rounds, 27 and 0; and so with the filtered
// seams' 3×3 mean (ReconstructOptions::seam_smoothing_px 1); weighing the creases against the kept
// triangles beyond the kept edges too and dropping the points at the creases left
// (drop_crease_points), 12 and 0; refusing faces on a kept triangle's side of a kept edge (which
// assembly had dropped: 484 unfiltered, now 1), 10 and 0; leaving out the faces at the creases
// still left (drop_creased_faces), 0 and 0, for 10 and 0 one-triangle gaps.
TEST(Reconstruct, ZipperSeamsDoNotFold) {
  const auto [rig, frames] = samba_frame_with_true_poses(0);
  for (const bool bilateral : {false, true}) {
    FrameReconstructor reconstructor(rig, {.mode = ReconstructMode::kZipper, .bilateral = bilateral});
    const FrameResult result = reconstructor.reconstruct(frames);
    // The seam triangles come last.
    const int seam_triangles = result.zipper.seam_added;
    ASSERT_GT(seam_triangles, 5000) << "bilateral " << bilateral;
    EXPECT_EQ(result.zipper.seam_pca, 0) << "bilateral " << bilateral << ": a seam on its PCA plane faces along the plane's normal only";
    TriangleMesh kept = result.mesh;
    kept.triangles.resize(kept.triangles.size() - seam_triangles);
    const int seam_folds = count_folded_edges(result.mesh) - count_folded_edges(kept);
    EXPECT_EQ(seam_folds, 0) << "bilateral " << bilateral;
    // The few faces still at a crease after everything else are left out: one-triangle gaps.
    EXPECT_LT(result.zipper.seam_crease_gaps, (bilateral ? 0.0005 : 0.003) * seam_triangles) << "bilateral " << bilateral;
    // The seams lay no face on a kept triangle's side of a kept edge, which assembly would drop.
    EXPECT_LT(result.zipper.seam_rejected, 0.0005 * seam_triangles) << "bilateral " << bilateral;
    int facing_no_camera = 0;
    for (size_t i = kept.triangles.size(); i < result.mesh.triangles.size(); ++i) {
      const Eigen::Vector3i& t = result.mesh.triangles[i];
      const Eigen::Vector3f& a = result.mesh.positions[t[0]];
      const Eigen::Vector3f normal = (result.mesh.positions[t[1]] - a).cross(result.mesh.positions[t[2]] - a);
      bool faces = false;
      for (const CameraModel& camera : rig.cameras) faces = faces || normal.dot(camera.world_from_depth.translation().cast<float>() - a) > 0;
      facing_no_camera += !faces;
    }
    EXPECT_EQ(facing_no_camera, 0) << "bilateral " << bilateral;
    std::cout << (bilateral ? "filtered" : "unfiltered") << ": " << seam_triangles << " seam triangles, " << seam_folds << " folded edges, "
              << facing_no_camera << " facing no camera, " << result.zipper.seam_crease_gaps << " left out at creases, "
              << result.zipper.seam_rejected << " dropped by assembly\n";
  }
}

// With the filter the zippered meshes fold less than the separate meshes, whose folds they keep
// where they keep the triangles (count_folded_edges over the whole mesh, samba-4cam frames 0–39
// with the true poses): 27 folded edges against 58. The seams' default smoothing (points at the
// mean depth of their surface over 3×3 pixels, normals from a plane over the 5×5) folds no more
// than points laid out where they were measured: 27 folds and 4 seam faces left out at creases
// each. It saved folds (36 and 2 against 38 and 4) until the consensus step was bounded by a
// pixel's width (consensus_move), which took both to 27 (drop_creased_faces: before it, 41
// folds and 46). Before the
// seams weighed their creases against the kept triangles and dropped the points at the creases
// left (clipping.cc, drop_crease_points), the zippered meshes had 89 and 118 (docs/design.md). No
// triangle is doubled: before the seams checked for faces on a kept triangle's corners, frame 31
// had one (and 3 of the 44 folds).
TEST(Reconstruct, FilteredZipperFoldsLessThanTheSeparateMeshes) {
  const Capture capture = Capture::open(kSharedData / "samba-4cam");
  const Rig rig = rig_with_true_poses(capture);
  const ReconstructOptions smoothed{.mode = ReconstructMode::kZipper, .bilateral = true};
  ASSERT_EQ(smoothed.seam_smoothing_px(), 1);
  ReconstructOptions as_measured = smoothed;
  as_measured.zipper.seam_smoothing_px = 0;
  ReconstructOptions separate = smoothed;
  separate.mode = ReconstructMode::kSeparate;
  FrameReconstructor with_smoothing(rig, smoothed), without_smoothing(rig, as_measured), separate_meshes(rig, separate);
  int folds_smoothed = 0, folds_as_measured = 0, folds_separate = 0, doubled = 0, gaps_smoothed = 0, gaps_as_measured = 0;
  for (int frame = 0; frame < std::min(40, capture.frame_count()); ++frame) {
    const FrameSet frames = capture.load_frame(frame);
    const FrameResult zippered = with_smoothing.reconstruct(frames);
    folds_smoothed += count_folded_edges(zippered.mesh);
    gaps_smoothed += zippered.zipper.seam_crease_gaps;
    // A seam face on the three corners of a kept triangle (frame 31 had one, turned over).
    doubled += count_doubled_triangles(zippered.mesh);
    const FrameResult as_measured_result = without_smoothing.reconstruct(frames);
    folds_as_measured += count_folded_edges(as_measured_result.mesh);
    gaps_as_measured += as_measured_result.zipper.seam_crease_gaps;
    folds_separate += count_folded_edges(separate_meshes.reconstruct(frames).mesh);
  }
  std::cout << "folded edges, frames 0-39 filtered: " << folds_smoothed << " zippered (" << gaps_smoothed << " seam faces left out at creases), "
            << folds_as_measured << " with the seam points as measured (" << gaps_as_measured << "), " << folds_separate << " separate meshes\n";
  EXPECT_LT(folds_smoothed, 0.85 * folds_separate);
  EXPECT_LE(folds_smoothed + gaps_smoothed, folds_as_measured + gaps_as_measured);
  EXPECT_EQ(doubled, 0);
}

// The zippered mesh is the same however many threads make it and wherever its buffers land. The
// seams' crease relaxation moves points one after another, so their order matters: taken in the
// order of their CGAL handles' addresses, which differ between runs, 21–29 of frame 30's
// positions differed here.
TEST(Reconstruct, ZipperMeshIsTheSameOnAnyNumberOfThreads) {
  const auto [rig, frames] = samba_frame_with_true_poses(30);
  for (const bool bilateral : {false, true}) {
    std::vector<TriangleMesh> meshes;
    for (const int threads : {1, 2, 3}) {
      FrameReconstructor reconstructor(rig, {.mode = ReconstructMode::kZipper, .bilateral = bilateral, .num_threads = threads});
      meshes.push_back(reconstructor.reconstruct(frames).mesh);
    }
    for (size_t k = 1; k < meshes.size(); ++k) {
      const TriangleMesh &mesh = meshes[k], &first = meshes[0];
      if (mesh.triangles.size() != first.triangles.size() || mesh.positions.size() != first.positions.size()) {
        ADD_FAILURE() << "bilateral " << bilateral << ", " << k + 1 << " threads: " << mesh.triangles.size() << " triangles, "
                      << mesh.positions.size() << " vertices against " << first.triangles.size() << ", " << first.positions.size();
        continue;
      }
      int triangles_differ = 0, positions_differ = 0;
      for (size_t i = 0; i < first.triangles.size(); ++i) triangles_differ += mesh.triangles[i] != first.triangles[i];
      for (size_t i = 0; i < first.positions.size(); ++i) positions_differ += mesh.positions[i] != first.positions[i];
      EXPECT_EQ(triangles_differ, 0) << "bilateral " << bilateral << ", " << k + 1 << " threads";
      EXPECT_EQ(positions_differ, 0) << "bilateral " << bilateral << ", " << k + 1 << " threads";
    }
  }
}

// Each step after the first of a seam's crease mending (flips, relaxing, dropping points, then
// faces: clipping.cc) looks for creases only where the steps before can have made or left one
// (CreaseWatch). It must find every one a look at every edge finds: the same meshes, bit for bit,
// on frames with creases to mend; some are left as gaps, so the last step, which only looks, has
// some to find. Without the faces around a dropped point, frame 35 unfiltered differs; without
// those of a flip, frame 21 filtered and frame 35; without those of a moved point, frame 21
// unfiltered. (No frame of samba-4cam needs the kept triangles of a moved third corner.)
TEST(Reconstruct, SeamsLookForCreasesWhereTheyCanBe) {
  int gaps = 0;
  for (const int frame : {0, 21, 30, 35}) {
    const auto [rig, frames] = samba_frame_with_true_poses(frame);
    for (const bool bilateral : {false, true}) {
      ReconstructOptions options{.mode = ReconstructMode::kZipper, .bilateral = bilateral};
      FrameReconstructor watched(rig, options);
      options.zipper.seam_crease_watch = false;
      FrameReconstructor everywhere(rig, options);
      const FrameResult result = watched.reconstruct(frames), reference = everywhere.reconstruct(frames);
      const std::string where = "frame " + std::to_string(frame) + (bilateral ? ", filtered" : ", unfiltered");
      EXPECT_EQ(result.zipper.seam_crease_gaps, reference.zipper.seam_crease_gaps) << where;
      gaps += reference.zipper.seam_crease_gaps;
      ASSERT_EQ(result.mesh.triangles.size(), reference.mesh.triangles.size()) << where;
      ASSERT_EQ(result.mesh.positions.size(), reference.mesh.positions.size()) << where;
      EXPECT_TRUE(result.mesh.triangles == reference.mesh.triangles) << where;
      EXPECT_TRUE(result.mesh.positions == reference.mesh.positions) << where;
    }
  }
  EXPECT_GT(gaps, 0);
}

struct SyntheticFrame {
  Rig rig;
  TriangleMesh truth;
  FrameSet frames;
};

// `frame` of the built-in subject seen by a ring of `cameras` with the Kinect model at `width` ×
// `height` (`synth --cameras C --resolution WxH`'s frame), true poses.
SyntheticFrame synthetic_frame(int cameras, int frame = 0, int width = 640, int height = 480) {
  SynthOptions options;
  options.frames = frame + 1;
  options.cameras = cameras;
  options.depth_width = width;
  options.depth_height = height;
  SyntheticFrame out{make_ring_rig(options), subject_mesh(options, frame), {}};
  out.rig.volume = Box3d{{-1, -1, 0.02}, {1, 1, 2.2}};
  for (int c = 0; c < cameras; ++c) {
    SyntheticView view = render_view(out.truth, out.rig, c, frame, options);
    out.frames.cameras.push_back({.has_depth = true, .depth = std::move(view.depth), .has_color = true, .color = std::move(view.color)});
  }
  return out;
}

// Flipping a seam's creases once checked convexity only where fairing had moved the points, not
// where CGAL has them: the flips could leave CGAL an invalid triangulation, and removing a point
// from it (drop_crease_points) crashed without the filter and never ended with it on frame 8 of
// a 4-camera 1280×960 ring (`make bench`'s scaling capture). Both now give one sound mesh.
// Unfiltered with the SDC threshold grown from 2.5 m, two seams that share three vertices each
// laid a triangle on them, turned over against each other (a doubled triangle whose edges each
// had a face on either side, so the directed-edge test let it through).
TEST(Reconstruct, FineRingZippersIntoASoundMesh) {
  const SyntheticFrame scene = synthetic_frame(4, 8, 1280, 960);
  for (const auto& [bilateral, growth] : {std::pair{false, SdcOptions{}.growth_depth_m}, std::pair{true, SdcOptions{}.growth_depth_m}, std::pair{false, 2.5}}) {
    FrameReconstructor reconstructor(scene.rig, {.mode = ReconstructMode::kZipper, .bilateral = bilateral, .sdc = {.growth_depth_m = growth}});
    const FrameResult result = reconstructor.reconstruct(scene.frames);
    EXPECT_GT(result.zipper.seam_added, 10000) << "bilateral " << bilateral;
    EXPECT_EQ(count_non_manifold_edges(result.mesh), 0) << "bilateral " << bilateral;
    EXPECT_EQ(count_doubled_triangles(result.mesh), 0) << "bilateral " << bilateral;
    const FrameQuality q = evaluate_frame(result.mesh, scene.truth, scene.rig, scene.rig.volume);
    std::cout << "1280x960 ring, frame 8, bilateral " << bilateral << ", SDC growth from " << growth << " m: " << result.mesh.triangles.size() << " triangles, " << result.zipper.seam_added
              << " in seams, completeness " << q.completeness << ", large components " << q.large_components << "\n";
    EXPECT_GT(q.completeness, 0.95) << "bilateral " << bilateral;
  }
}

// On a synthetic capture with true poses, the separate meshes lie on the true surface.
TEST(Reconstruct, SeparateMeshesLieOnTheTrueSurface) {
  const SyntheticFrame scene = synthetic_frame(3);
  const Rig& rig = scene.rig;
  const FrameSet& frames = scene.frames;
  const MeshDistance distance(scene.truth);
  for (bool bilateral : {false, true}) {
    FrameReconstructor reconstructor(rig, {.mode = ReconstructMode::kSeparate, .bilateral = bilateral});
    const FrameResult result = reconstructor.reconstruct(frames);
    EXPECT_EQ(result.cameras_used, 3);
    ASSERT_GT(result.mesh.triangle_count(), 30000u);
    std::vector<float> d;
    for (const Eigen::Vector3f& p : result.mesh.positions) d.push_back(distance.closest(p, 1.0f).distance);
    std::sort(d.begin(), d.end());
    // Kinect noise at 2–3 m is σ ≈ 5–9 mm with 1 cm steps; filtering must reduce the error.
    const float median = d[d.size() / 2];
    EXPECT_LT(median, bilateral ? 0.004f : 0.007f) << "bilateral " << bilateral;
    EXPECT_LT(d[d.size() * 95 / 100], bilateral ? 0.015f : 0.02f) << "bilateral " << bilateral;
    // The floor is cropped away by the volume: nothing below 2 cm.
    for (const Eigen::Vector3f& p : result.mesh.positions) ASSERT_GE(p.z(), 0.02f);
  }
}

// A level of detail: every second depth pixel gives a quarter of the triangles on the same surface,
// zippered into one mesh.
TEST(Reconstruct, CoarserLevelOfDetailKeepsTheSurface) {
  const SyntheticFrame scene = synthetic_frame(4);
  const Rig& rig = scene.rig;
  const FrameSet& frames = scene.frames;
  const MeshDistance distance(scene.truth);
  auto median_error = [&](const TriangleMesh& mesh) {
    std::vector<float> d;
    for (const Eigen::Vector3f& p : mesh.positions) d.push_back(distance.closest(p, 1.0f).distance);
    std::sort(d.begin(), d.end());
    return d[d.size() / 2];
  };
  FrameReconstructor full(rig, {});
  FrameReconstructor half(rig, {.depth_level = 1});
  const FrameResult a = full.reconstruct(frames), b = half.reconstruct(frames);
  const double share = static_cast<double>(b.mesh.triangle_count()) / static_cast<double>(a.mesh.triangle_count());
  EXPECT_GT(share, 0.2);
  EXPECT_LT(share, 0.3);
  EXPECT_LT(median_error(b.mesh), 0.005f);
  EXPECT_LT(median_error(b.mesh), median_error(a.mesh) + 0.0015f);
  EXPECT_GE(b.zipper.pairs, 4);
  EXPECT_THROW(FrameReconstructor(rig, {.depth_level = 4}), InvalidInput);
}

// New poses reach every part of a reconstructor at a level of detail, the full-resolution
// foreground's crop to the volume included: one built with poses half a metre off and then given
// the true ones makes exactly the mesh of one built with the true ones. A depth image of another
// size than the rig's is refused, naming the camera.
TEST(Reconstruct, NewPosesReachTheLevelOfDetailsForeground) {
  const SyntheticFrame scene = synthetic_frame(4);
  Rig moved = scene.rig;
  std::vector<Rigid3d> true_poses;
  for (CameraModel& camera : moved.cameras) {
    true_poses.push_back(camera.world_from_depth);
    camera.world_from_depth.translation() += Eigen::Vector3d(0.5, 0.0, 0.3);
  }
  for (const ReconstructMode mode : {ReconstructMode::kZipper, ReconstructMode::kSeparate}) {
    FrameReconstructor truth(scene.rig, {.mode = mode, .depth_level = 1});
    FrameReconstructor corrected(moved, {.mode = mode, .depth_level = 1});
    const size_t moved_triangles = corrected.reconstruct(scene.frames).mesh.triangle_count();
    corrected.set_poses(true_poses);
    const FrameResult a = truth.reconstruct(scene.frames), b = corrected.reconstruct(scene.frames);
    EXPECT_NE(moved_triangles, a.mesh.triangle_count());  // the wrong poses crop other pixels
    EXPECT_EQ(a.mesh.positions, b.mesh.positions);
    EXPECT_EQ(a.mesh.triangles, b.mesh.triangles);
  }
  FrameSet cropped = scene.frames;
  DepthImage& depth = cropped.cameras[2].depth;
  depth.resize(depth.width - 1, depth.height);
  FrameReconstructor half(scene.rig, {.depth_level = 1});
  const std::string message = invalid_input_message([&] { half.reconstruct(cropped); });
  EXPECT_NE(message.find(scene.rig.cameras[2].name + ": depth image 639x480"), std::string::npos) << message;
}

// A recycled mesh's buffers hold the next frame set's mesh, and that mesh is exactly the one a
// fresh reconstructor makes (nothing of the recycled one is left in it), in both modes.
TEST(Reconstruct, RecycledMeshHoldsTheNextMeshExactly) {
  const SyntheticFrame scene = synthetic_frame(4);
  FrameSet three_cameras = scene.frames;
  three_cameras.cameras[1].has_depth = false;  // a smaller mesh than the recycled one
  for (const ReconstructMode mode : {ReconstructMode::kZipper, ReconstructMode::kSeparate}) {
    FrameReconstructor reused(scene.rig, {.mode = mode}), fresh(scene.rig, {.mode = mode});
    FrameResult first = reused.reconstruct(scene.frames);
    const Eigen::Vector3i* buffer = first.mesh.triangles.data();
    reused.recycle(std::move(first.mesh));
    const FrameResult second = reused.reconstruct(three_cameras), expected = fresh.reconstruct(three_cameras);
    EXPECT_EQ(second.mesh.triangles.data(), buffer) << "mode " << static_cast<int>(mode);
    ASSERT_GT(expected.mesh.triangle_count(), 10000u);
    EXPECT_EQ(second.mesh.triangles, expected.mesh.triangles) << "mode " << static_cast<int>(mode);
    EXPECT_EQ(second.mesh.positions, expected.mesh.positions) << "mode " << static_cast<int>(mode);
    EXPECT_EQ(second.mesh.colors, expected.mesh.colors) << "mode " << static_cast<int>(mode);
  }
}

TEST(Reconstruct, MissingCameraIsLeftOut) {
  const Capture capture = Capture::open(kSharedData / "samba-4cam");
  FrameSet frames = capture.load_frame(0);
  FrameReconstructor reconstructor(capture.rig(), {.mode = ReconstructMode::kSeparate, .bilateral = false});
  const size_t all = reconstructor.reconstruct(frames).mesh.triangle_count();
  frames.cameras[2].has_depth = false;
  const FrameResult without = reconstructor.reconstruct(frames);
  EXPECT_EQ(without.cameras_used, 3);
  EXPECT_LT(without.mesh.triangle_count(), all * 0.85);
  EXPECT_GT(without.mesh.triangle_count(), all * 0.6);
}

}  // namespace
}  // namespace zipfusion
