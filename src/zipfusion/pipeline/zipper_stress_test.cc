// The zipper on inputs no capture of a person gives: random rigs of 2–10 cameras near and far,
// depth corrupted by salt-and-pepper values, walls of one depth, stripes, extremes, and random
// options. Whatever comes in, the output must be a well-formed mesh: every index in range, no
// triangle with a repeated corner, every position finite and inside the cameras' range, and no
// edge shared by more than two triangles (the seams create no non-manifold edge).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "zipfusion/eval/eval.h"
#include "zipfusion/pipeline/reconstruct.h"
#include "zipfusion/synth/synth.h"

namespace zipfusion {
namespace {

// One way of damaging a depth image, chosen per camera.
enum class Damage { kNone, kSaltAndPepper, kWall, kStripes, kExtremes, kCoarse, kHalfGone, kCount };

void damage_depth(DepthImage& depth, Damage damage, std::mt19937& random) {
  std::uniform_int_distribution<int> any_u(0, depth.width - 1), any_v(0, depth.height - 1);
  std::uniform_int_distribution<int> any_depth(1, 65535), body_depth(400, 4500);
  switch (damage) {
    case Damage::kNone:
      break;
    case Damage::kSaltAndPepper: {  // a tenth of the pixels anywhere in the sensor's range
      const int count = static_cast<int>(depth.size() / 10);
      for (int k = 0; k < count; ++k) depth(any_u(random), any_v(random)) = static_cast<unsigned short>(body_depth(random));
      break;
    }
    case Damage::kWall: {  // a rectangle at one depth in front of or behind the subject
      const int u0 = any_u(random), v0 = any_v(random);
      const int u1 = std::min(depth.width, u0 + depth.width / 2), v1 = std::min(depth.height, v0 + depth.height / 2);
      const auto wall = static_cast<unsigned short>(body_depth(random));
      for (int v = v0; v < v1; ++v) {
        for (int u = u0; u < u1; ++u) depth(u, v) = wall;
      }
      break;
    }
    case Damage::kStripes: {  // every other row shifted by 5 cm: SDC edges everywhere
      for (int v = 0; v < depth.height; v += 2) {
        for (int u = 0; u < depth.width; ++u) {
          if (depth(u, v) != 0) depth(u, v) = static_cast<unsigned short>(std::min(65535, depth(u, v) + 50));
        }
      }
      break;
    }
    case Damage::kExtremes: {  // the smallest and largest values the format holds
      for (int k = 0; k < static_cast<int>(depth.size() / 20); ++k) depth(any_u(random), any_v(random)) = (k % 2) ? 1 : 65535;
      break;
    }
    case Damage::kCoarse: {  // depth in steps of 10 cm: terraces
      for (unsigned short& z : depth.data) z = static_cast<unsigned short>(z / 100 * 100);
      break;
    }
    case Damage::kHalfGone: {  // the right half of the sensor dark
      for (int v = 0; v < depth.height; ++v) {
        for (int u = depth.width / 2; u < depth.width; ++u) depth(u, v) = 0;
      }
      break;
    }
    case Damage::kCount:
      break;
  }
  (void)any_depth;
}

struct MeshCheck {
  int bad_indices = 0;
  int repeated_corners = 0;
  int non_finite = 0;
  int non_manifold_edges = 0;
};

MeshCheck check_mesh(const TriangleMesh& mesh) {
  MeshCheck check;
  const int n = static_cast<int>(mesh.positions.size());
  for (const Eigen::Vector3i& t : mesh.triangles) {
    if (t.minCoeff() < 0 || t.maxCoeff() >= n) {
      ++check.bad_indices;
      continue;
    }
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) ++check.repeated_corners;
  }
  for (const Eigen::Vector3f& p : mesh.positions) {
    if (!p.allFinite() || p.norm() > 100) ++check.non_finite;
  }
  if (check.bad_indices == 0) check.non_manifold_edges = count_non_manifold_edges(mesh);
  return check;
}

TEST(ZipperStress, RandomRigsAndDamagedDepthGiveWellFormedMeshes) {
  // ZF_STRESS_CASES and ZF_STRESS_SEED run more, or other, cases by hand.
  const char* cases_text = std::getenv("ZF_STRESS_CASES");
  const char* seed_text = std::getenv("ZF_STRESS_SEED");
  const int cases = cases_text ? std::atoi(cases_text) : 60;
  std::mt19937 random(seed_text ? static_cast<unsigned>(std::atol(seed_text)) : 20261207u);
  for (int c = 0; c < cases; ++c) {
    SynthOptions synth;
    synth.frames = 1;
    synth.cameras = std::uniform_int_distribution<int>(2, 10)(random);
    synth.radius_m = std::uniform_real_distribution<double>(0.7, 4.0)(random);
    synth.camera_height_m = std::uniform_real_distribution<double>(0.3, 2.8)(random);
    const int size = std::uniform_int_distribution<int>(0, 2)(random);
    synth.depth_width = size == 0 ? 160 : size == 1 ? 320 : 640;
    synth.depth_height = synth.depth_width * 3 / 4;
    if (random() % 3 == 0) synth.noise = KinectNoiseOptions::none();
    synth.seed = c + 1;
    // A quarter of the rigs are no ring: each camera but the first turned by up to 60° and moved by
    // up to a metre (looking past the subject, tilted, upside down nearly).
    const bool scattered = random() % 4 == 0;
    const double scatter_deg = std::uniform_real_distribution<double>(0, 60)(random);
    const double scatter_m = std::uniform_real_distribution<double>(0, 1.0)(random);
    const Rig rig = [&] {
      Rig made = make_ring_rig(synth);
      if (scattered) {
        SynthOptions scatter = synth;
        scatter.miscalibrate_deg = scatter_deg;
        scatter.miscalibrate_m = scatter_m;
        scatter.seed = synth.seed + 1000;
        made = miscalibrate(made, scatter);
      }
      made.volume = synthetic_capture_volume(subject_mesh(synth, 0));
      made.frame_count = 1;
      return made;
    }();
    const TriangleMesh truth = subject_mesh(synth, 0);

    FrameSet frames{.index = 0, .cameras = {}};
    std::string damages;
    for (int k = 0; k < synth.cameras; ++k) {
      SyntheticView view = render_view(truth, rig, k, 0, synth);
      const auto damage = static_cast<Damage>(random() % static_cast<unsigned>(Damage::kCount));
      damage_depth(view.depth, damage, random);
      damages += std::to_string(static_cast<int>(damage));
      const bool dead = random() % 8 == 0;
      frames.cameras.push_back({.has_depth = !dead, .depth = std::move(view.depth), .has_color = random() % 5 != 0,
                                .color = std::move(view.color)});
    }

    ReconstructOptions options;
    options.bilateral = random() % 2 == 0;
    options.zipper.ownership = static_cast<Ownership>(random() % 3);
    options.zipper.redundancy_distance_m = std::uniform_real_distribution<double>(0.005, 0.1)(random);
    options.zipper.clipping_distance_m = std::uniform_real_distribution<double>(0.001, 0.05)(random);
    options.zipper.coarse_levels = std::uniform_int_distribution<int>(0, 4)(random);
    options.zipper.max_seam_edge_m = std::uniform_real_distribution<double>(0.005, 0.1)(random);
    options.zipper.seam_smoothing_px = std::uniform_int_distribution<int>(-1, 4)(random);
    options.zipper.seam_fairing_iterations = std::uniform_int_distribution<int>(0, 8)(random);
    options.zipper.min_overlap_share = random() % 2 ? 0.0 : 0.01;
    options.depth_level = random() % 4 == 0 ? 1 : 0;

    // A third of the cases reconstruct with poses off by up to 10° and 20 cm: layers that cross.
    Rig reconstruction_rig = rig;
    double off_deg = 0, off_m = 0;
    if (random() % 3 == 0) {
      SynthOptions off = synth;
      off.miscalibrate_deg = off_deg = std::uniform_real_distribution<double>(0, 10)(random);
      off.miscalibrate_m = off_m = std::uniform_real_distribution<double>(0, 0.2)(random);
      reconstruction_rig = miscalibrate(rig, off);
    }
    options.min_component_triangles = random() % 4 == 0 ? 50 : 0;

    char name[512];
    std::snprintf(name, sizeof name,
                  "case %d: %d cameras, radius %.2f m, height %.2f m, scattered %.0f deg %.2f m, %d px, damages %s, poses off %.1f deg %.3f m, bilateral %d, "
                  "ownership %d, d_r %.4f, d_c %.4f, L %d, max edge %.4f, smoothing %d, fairing %d, lod %d, min component %d",
                  c, synth.cameras, synth.radius_m, synth.camera_height_m, scattered ? scatter_deg : 0.0,
                  scattered ? scatter_m : 0.0, synth.depth_width, damages.c_str(), off_deg, off_m,
                  options.bilateral, static_cast<int>(options.zipper.ownership), options.zipper.redundancy_distance_m,
                  options.zipper.clipping_distance_m, options.zipper.coarse_levels, options.zipper.max_seam_edge_m,
                  options.zipper.seam_smoothing_px, options.zipper.seam_fairing_iterations, options.depth_level,
                  options.min_component_triangles);
    SCOPED_TRACE(name);
    std::printf("%s\n", name);
    std::fflush(stdout);
    FrameReconstructor reconstructor(reconstruction_rig, options);
    const FrameResult result = reconstructor.reconstruct(frames);
    const MeshCheck check = check_mesh(result.mesh);
    EXPECT_EQ(check.bad_indices, 0);
    EXPECT_EQ(check.repeated_corners, 0);
    EXPECT_EQ(check.non_finite, 0);
    EXPECT_EQ(check.non_manifold_edges, 0);
    if (result.mesh.has_colors()) {
      EXPECT_EQ(result.mesh.colors.size(), result.mesh.positions.size());
    }
    std::printf("  %zu triangles, %d pairs, non-manifold %d, doubled %d\n", result.mesh.triangle_count(), result.zipper.pairs,
                check.non_manifold_edges, check.bad_indices == 0 ? count_doubled_triangles(result.mesh) : -1);
  }
}

}  // namespace
}  // namespace zipfusion
