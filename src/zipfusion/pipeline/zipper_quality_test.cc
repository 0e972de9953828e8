// End-to-end quality of the zipper mode against ground truth on synthetic rings of cameras: the
// project's targets (one connected, manifold mesh without the doubled overlaps of the separate
// meshes, as complete and as accurate as they are), measured with evaluate_frame.
//
// Each case renders two frames of the built-in subject in memory, reconstructs them in both
// modes and averages the quality over the frames (counts: the worse frame). The measured numbers
// are printed so the test log keeps them.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "zipfusion/core/mesh_distance.h"
#include "zipfusion/eval/eval.h"
#include "zipfusion/pipeline/reconstruct.h"
#include "zipfusion/synth/synth.h"

namespace zipfusion {
namespace {

constexpr int kFrames[] = {0, 15};

// Quality of one mode, averaged over the frames; counts are the worst frame's.
struct ModeQuality {
  double area_ratio = 0;
  double completeness = 0;
  double accuracy_mean_mm = 0;
  double accuracy_p95_mm = 0;
  int large_components = 0;
  int components = 0;
  int non_manifold_edges = 0;
  int folded_edges = 0;
  int doubled_triangles = 0;
  int min_cameras_used = 1 << 30;
  int max_cameras_used = 0;
  double triangles = 0;
};

struct CaseQuality {
  ModeQuality zipper;
  ModeQuality separate;
  double separate_area_m2 = 0;   // mean over frames, inside the volume
  double zipper_area_m2 = 0;
  double redundant_area_m2 = 0;  // half the area of the separate meshes that another camera's mesh doubles (within 1 cm)
};

// Area of the triangles of each camera's own mesh that lie within 1 cm of another camera's mesh,
// halved: what removing every doubled layer takes away.
double redundant_area(const Rig& rig, const FrameSet& frames, bool bilateral) {
  std::vector<TriangleMesh> meshes;
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    FrameSet single = frames;
    for (size_t k = 0; k < single.cameras.size(); ++k) single.cameras[k].has_depth = single.cameras[k].has_depth && k == c;
    FrameReconstructor reconstructor(rig, {.mode = ReconstructMode::kSeparate, .bilateral = bilateral});
    meshes.push_back(reconstructor.reconstruct(single).mesh);
  }
  double doubled = 0;
  for (size_t c = 0; c < meshes.size(); ++c) {
    TriangleMesh others;
    for (size_t k = 0; k < meshes.size(); ++k) {
      if (k != c) others.append(meshes[k]);
    }
    if (others.triangles.empty()) continue;
    const MeshDistance distance(others);
    for (const Eigen::Vector3i& t : meshes[c].triangles) {
      const Eigen::Vector3f& a = meshes[c].positions[t[0]];
      const Eigen::Vector3f& b = meshes[c].positions[t[1]];
      const Eigen::Vector3f& d = meshes[c].positions[t[2]];
      if (distance.closest((a + b + d) / 3.0f, 0.01f).triangle >= 0) doubled += 0.5 * (b - a).cross(d - a).norm();
    }
  }
  return doubled / 2;
}

struct CaseSpec {
  std::string name;
  SynthOptions synth;
  bool bilateral = true;
  int dead_camera = -1;  // this camera has no depth in any frame set
  Ownership ownership = Ownership::kAuto;
  double sdc_growth_depth_m = SdcOptions{}.growth_depth_m;
  double floor_noise_sigmas = ForegroundOptions{}.floor_noise_sigmas;
};

CaseQuality measure(const CaseSpec& spec) {
  Rig rig = make_ring_rig(spec.synth);
  rig.volume = synthetic_capture_volume(subject_mesh(spec.synth, 0));
  rig.frame_count = spec.synth.frames;

  // The observed truth is what the working cameras can see: a dead camera's view is no gap.
  Rig eval_rig = rig;
  if (spec.dead_camera >= 0) eval_rig.cameras.erase(eval_rig.cameras.begin() + spec.dead_camera);

  CaseQuality result;
  const auto modes = {ReconstructMode::kSeparate, ReconstructMode::kZipper};
  for (const int frame : kFrames) {
    const TriangleMesh truth = subject_mesh(spec.synth, frame);
    FrameSet frames{.index = frame, .cameras = {}};
    for (int c = 0; c < static_cast<int>(rig.cameras.size()); ++c) {
      SyntheticView view = render_view(truth, rig, c, frame, spec.synth);
      frames.cameras.push_back({.has_depth = c != spec.dead_camera, .depth = std::move(view.depth), .has_color = true,
                                .color = std::move(view.color)});
    }
    result.redundant_area_m2 += redundant_area(rig, frames, spec.bilateral) / std::size(kFrames);
    for (const ReconstructMode mode : modes) {
      ReconstructOptions options{.mode = mode, .bilateral = spec.bilateral};
      options.zipper.ownership = spec.ownership;
      options.sdc.growth_depth_m = spec.sdc_growth_depth_m;
      options.foreground.floor_noise_sigmas = spec.floor_noise_sigmas;
      FrameReconstructor reconstructor(rig, options);
      const FrameResult frame_result = reconstructor.reconstruct(frames);
      const FrameQuality q = evaluate_frame(frame_result.mesh, truth, eval_rig, rig.volume);
      const bool zipper = mode == ReconstructMode::kZipper;
      ModeQuality& m = zipper ? result.zipper : result.separate;
      const double n = std::size(kFrames);
      m.area_ratio += q.area_ratio / n;
      (zipper ? result.zipper_area_m2 : result.separate_area_m2) += q.reconstruction_area_m2 / n;
      m.completeness += q.completeness / n;
      m.accuracy_mean_mm += q.accuracy_mean_mm / n;
      m.accuracy_p95_mm += q.accuracy_p95_mm / n;
      m.triangles += q.triangles / n;
      m.large_components = std::max(m.large_components, q.large_components);
      m.components = std::max(m.components, q.components);
      m.non_manifold_edges = std::max(m.non_manifold_edges, q.non_manifold_edges);
      m.folded_edges = std::max(m.folded_edges, q.folded_edges);
      m.doubled_triangles = std::max(m.doubled_triangles, q.doubled_triangles);
      m.min_cameras_used = std::min(m.min_cameras_used, frame_result.cameras_used);
      m.max_cameras_used = std::max(m.max_cameras_used, frame_result.cameras_used);

      char line[320];
      std::snprintf(line, sizeof line,
                    "[%s] frame %2d %-8s area_ratio %.3f completeness %.4f accuracy %.2f mm (p95 %.2f) "
                    "large_components %d (all %d) non_manifold %d folded %d triangles %d cameras_used %d",
                    spec.name.c_str(), frame, zipper ? "zipper" : "separate", q.area_ratio, q.completeness,
                    q.accuracy_mean_mm, q.accuracy_p95_mm, q.large_components, q.components, q.non_manifold_edges,
                    q.folded_edges, q.triangles, frame_result.cameras_used);
      std::cout << line;
      if (zipper) {
        std::cout << " pairs " << frame_result.zipper.pairs << " redundant_removed " << frame_result.zipper.redundant_removed
                  << " seam_added " << frame_result.zipper.seam_added;
      }
      std::cout << '\n';
    }
  }
  for (const bool zipper : {false, true}) {
    const ModeQuality& m = zipper ? result.zipper : result.separate;
    char line[320];
    std::snprintf(line, sizeof line,
                  "[%s] mean     %-8s area_ratio %.3f completeness %.4f accuracy %.2f mm (p95 %.2f) "
                  "large_components(max) %d non_manifold(max) %d folded(max) %d triangles %.0f\n",
                  spec.name.c_str(), zipper ? "zipper" : "separate", m.area_ratio, m.completeness, m.accuracy_mean_mm,
                  m.accuracy_p95_mm, m.large_components, m.non_manifold_edges, m.folded_edges, m.triangles);
    std::cout << line << std::flush;
  }
  return result;
}

SynthOptions ring(int cameras) {
  SynthOptions options;
  options.frames = 30;  // the subject's clock only: frames are rendered in memory
  options.cameras = cameras;
  return options;
}

// Noise-free depth: the zipper removes the doubled overlaps (the separate meshes cover the
// overlaps twice) and still covers what the cameras see, as one manifold mesh.
TEST(ZipperQuality, NoiseFreeFourCameras) {
  SynthOptions synth = ring(4);
  synth.noise = KinectNoiseOptions::none();
  synth.color_noise_sigma = 0;
  const CaseQuality q = measure({.name = "4cam noise-free", .synth = synth, .bilateral = false});
  EXPECT_LE(q.zipper.area_ratio, 1.10);
  EXPECT_GE(q.separate.area_ratio, 1.25);
  EXPECT_GE(q.zipper.completeness, 0.95);
  EXPECT_LE(q.zipper.large_components, 3);
  EXPECT_EQ(q.zipper.non_manifold_edges, 0);
  EXPECT_EQ(q.zipper.doubled_triangles, 0);
  // The seams add hardly a fold to those of the cameras' own meshes (15 at silhouettes): 11 with
  // the seam's points moved halfway between the layers, faired and the creases left relaxed (12
  // with every relaxed point held within 0.35 pixel of its pixel, 13 before the relaxation, 18
  // before the fairing, 19 before the consensus and the crease flips); 363 when output at their
  // measured depth.
  EXPECT_LE(q.zipper.folded_edges, q.separate.folded_edges + 5);
  EXPECT_LE(q.zipper.accuracy_mean_mm, q.separate.accuracy_mean_mm + 0.2);
  EXPECT_EQ(q.zipper.min_cameras_used, 4);
}

// Cameras 0.9 m from the person: pixels 1–1.5 mm wide on the body, so the thresholds in metres
// span many pixels. Moving a seam point halfway to the other camera's layer by more than its
// pixel's width, next to kept neighbours that stay, folded the grid: 21 and 39 folded edges on
// frame 0 of such rings (with and without noise), where the separate meshes had none; the
// consensus step is now bounded by the pixel's width (consensus_move). Here, noise-free with the
// filter (reconstruct's default): 39 and 36 folded edges before, 1 and 0 now, the separate
// meshes 0. (Without the filter this ring's frame 0 has 5 large components: not yet a target.)
TEST(ZipperQuality, NoiseFreeCloseRingSeamsDoNotFold) {
  SynthOptions synth = ring(4);
  synth.radius_m = 0.9;
  synth.floor = false;
  synth.noise = KinectNoiseOptions::none();
  synth.color_noise_sigma = 0;
  const CaseQuality q = measure({.name = "4cam close noise-free", .synth = synth, .bilateral = true});
  EXPECT_LE(q.zipper.folded_edges, q.separate.folded_edges + 2);
  EXPECT_EQ(q.zipper.non_manifold_edges, 0);
  EXPECT_EQ(q.zipper.doubled_triangles, 0);
  EXPECT_LE(q.zipper.large_components, 3);
  EXPECT_LE(q.zipper.accuracy_mean_mm, q.separate.accuracy_mean_mm + 0.2);
}

// Kinect v1 noise with the bilateral filter on, for a sparse and a dense ring.
void expect_noisy_ring_targets(int cameras) {
  const CaseQuality q = measure({.name = std::to_string(cameras) + "cam kinect", .synth = ring(cameras), .bilateral = true});
  // The doubled layers go: the zipper's area is at most the separate meshes' less 65 % of their
  // redundant area (measured: 6 cameras remove all of it, 3 cameras 68 %: their overlaps are
  // seen at grazing angles from both sides, where the two noisy layers are often more than d_r
  // apart). A fixed share of the separate area, as the samba-4cam target is stated, does not fit
  // every rig: three cameras 120° apart overlap little, so removing every doubled layer takes away
  // only 8 % of the area.
  std::cout << "[" << cameras << "cam kinect] area m2: separate " << q.separate_area_m2 << " zipper " << q.zipper_area_m2
            << " redundant in separate " << q.redundant_area_m2 << "\n";
  EXPECT_LE(q.zipper_area_m2, q.separate_area_m2 - 0.65 * q.redundant_area_m2);
  EXPECT_LE(q.zipper.large_components, 3);
  EXPECT_EQ(q.zipper.non_manifold_edges, 0);
  EXPECT_EQ(q.zipper.doubled_triangles, 0);
  // Folds: the zipper has fewer than the separate meshes (6 cameras: 24 against 72, 26 before the
  // seams weighed creases against the kept triangles and dropped the points at those left, 28 with
  // the filtered seams' points as measured (--seam-smoothing 0), 34 before the creases left were
  // relaxed, 50 before the seam's points were moved halfway between the layers and faired, 104
  // before the consensus and the crease flips, 172 when they were output at their measured depth;
  // 3 cameras: 18 against 37, 28 and 31 before, 18 too with the seams' 3×3 mean).
  EXPECT_LE(q.zipper.folded_edges, q.separate.folded_edges);
  if (cameras >= 4) {
    EXPECT_GE(q.zipper.completeness, 0.95);
  } else {
    // Three cameras 120° apart see the body's sides at grazing angles, where edge dropout,
    // projector shadows and the SDC depth-jump test leave no depth: even the separate meshes,
    // which keep all the data, cover only about 93 % of the observed truth. The zipper must not
    // lose coverage beyond that.
    EXPECT_GE(q.zipper.completeness, q.separate.completeness - 0.01);
  }
  EXPECT_LE(q.zipper.accuracy_mean_mm, q.separate.accuracy_mean_mm + 0.2);
  EXPECT_EQ(q.zipper.min_cameras_used, cameras);
}

TEST(ZipperQuality, KinectNoiseThreeCameras) { expect_noisy_ring_targets(3); }

TEST(ZipperQuality, KinectNoiseSixCameras) { expect_noisy_ring_targets(6); }

// Without the filter, noise along each camera's rays roughens its sheet most where it sees the
// surface frontally. Keeping the smoother of two layers (the default without the filter) leaves
// less of that roughness than keeping the more frontal one: less area, no less accurate, still one
// connected mesh that covers what the cameras see.
TEST(ZipperQuality, UnfilteredSmoothnessOwnershipKeepsTheSmootherLayer) {
  const CaseQuality border = measure({.name = "4cam unfiltered border", .synth = ring(4), .bilateral = false, .ownership = Ownership::kBorder});
  const CaseQuality smooth =
      measure({.name = "4cam unfiltered smoothness", .synth = ring(4), .bilateral = false, .ownership = Ownership::kSmoothness});
  EXPECT_LE(smooth.zipper_area_m2, 0.95 * border.zipper_area_m2);
  EXPECT_LE(smooth.zipper.accuracy_mean_mm, border.zipper.accuracy_mean_mm + 0.05);
  EXPECT_LE(smooth.zipper.accuracy_mean_mm, smooth.separate.accuracy_mean_mm + 0.2);
  EXPECT_GE(smooth.zipper.completeness, 0.95);
  EXPECT_LE(smooth.zipper.large_components, 3);
  EXPECT_EQ(smooth.zipper.non_manifold_edges, 0);
  EXPECT_EQ(smooth.zipper.doubled_triangles, 0);
}

// A ring of 3.4 m radius without the filter: the far side of the body lies 3.4–3.7 m from a
// camera, where a Kinect's depth step (3.3–3.9 cm) exceeds the 3 cm SDC threshold, so with a
// constant threshold a sloped surface loses its triangles (the meshes cover about half of what the
// cameras see). Grown with depth² beyond 2.5 m (5.5–6.6 cm there) the threshold keeps them.
TEST(ZipperQuality, FarRingKeepsItsFarSurfacesWithTheGrowingThreshold) {
  SynthOptions far = ring(4);
  far.radius_m = 3.4;
  const CaseQuality grown = measure({.name = "4cam 3.4 m unfiltered", .synth = far, .bilateral = false});
  const CaseQuality constant = measure({.name = "4cam 3.4 m unfiltered constant", .synth = far, .bilateral = false, .sdc_growth_depth_m = 0});
  EXPECT_GE(grown.separate.completeness, 0.97);
  EXPECT_GE(grown.zipper.completeness, 0.95);
  EXPECT_LE(constant.zipper.completeness, grown.zipper.completeness - 0.1);
  EXPECT_LT(grown.zipper.large_components, constant.zipper.large_components);
  // The far surfaces kept are as noisy as the sensor makes them (7.9 against 6.9 mm for the
  // separate meshes); the zipper adds to that no more than it does with the constant threshold.
  // (Measured: 8.55 against 7.90 mm, and 7.54 against 6.86. Unfiltered at this range the zipper
  // still leaves up to 14 large components a frame set, against 24: docs/design.md, "SDC triangulation".)
  EXPECT_LE(grown.zipper.accuracy_mean_mm - grown.separate.accuracy_mean_mm,
            constant.zipper.accuracy_mean_mm - constant.separate.accuracy_mean_mm + 0.1);
  EXPECT_EQ(grown.zipper.non_manifold_edges, 0);
  EXPECT_EQ(grown.zipper.doubled_triangles, 0);
}

// Cameras 2.6 m up see the floor around the subject 3–4 m away, where the Kinect's depth noise
// moves a floor point's height by about 14 mm: the volume's fixed 2 cm above the floor let its
// noise in as hundreds of specks (measured: 700–1 000 pieces, mean accuracy 15 mm). The bottom
// raised to 3σ of each pixel's height noise keeps them out, and costs little of the feet.
TEST(ZipperQuality, HighRingKeepsTheFloorsNoiseOut) {
  SynthOptions high = ring(4);
  high.camera_height_m = 2.6;
  const CaseQuality fixed = measure({.name = "4cam 2.6 m up, fixed bottom", .synth = high, .floor_noise_sigmas = 0});
  const CaseQuality lifted = measure({.name = "4cam 2.6 m up", .synth = high});
  EXPECT_GT(fixed.zipper.components, 200);
  EXPECT_LE(lifted.zipper.components, 40);
  EXPECT_GT(fixed.zipper.accuracy_mean_mm, 6.0);
  EXPECT_LE(lifted.zipper.accuracy_mean_mm, 3.0);
  EXPECT_LE(lifted.zipper.large_components, 3);
  EXPECT_GE(lifted.zipper.completeness, fixed.zipper.completeness - 0.01);
}

// A dead camera leaves a gap in the coverage, not in the connectivity: the three cameras that
// remain still give one large manifold mesh covering what they see (completeness here is of the
// truth the working cameras observe).
TEST(ZipperQuality, DeadCameraIsLeftOut) {
  const CaseQuality q = measure({.name = "4cam cam2 dead", .synth = ring(4), .bilateral = true, .dead_camera = 2});
  EXPECT_LE(q.zipper.large_components, 3);
  EXPECT_EQ(q.zipper.non_manifold_edges, 0);
  EXPECT_EQ(q.zipper.doubled_triangles, 0);
  EXPECT_EQ(q.zipper.min_cameras_used, 3);
  EXPECT_EQ(q.zipper.max_cameras_used, 3);
  EXPECT_LE(q.zipper.folded_edges, q.separate.folded_edges);  // 14 against 30 (17 before the creases were relaxed, 27 before the seam was faired)
  // Covering the rest: as much of the observed truth as the separate meshes of the three cameras.
  EXPECT_GE(q.zipper.completeness, q.separate.completeness - 0.01);
}

}  // namespace
}  // namespace zipfusion
