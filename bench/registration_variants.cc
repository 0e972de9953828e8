// Registration variants against ground truth: for each variant, GPA-ICP on samba-4cam (or the
// capture given as the first argument) started from the perturbed rig.json and from the true
// poses, and the worst camera's pose error relative to camera 0. The table in docs/design.md
// ("Registration") comes from this program: build/zf_registration_variants [CAPTURE].

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

#include "zipfusion/io/capture.h"
#include "zipfusion/registration/gpa_icp.h"

using namespace zipfusion;

namespace {

struct Variant {
  std::string name;
  std::function<void(RegistrationOptions&)> change;
  std::vector<int> frames;
};

struct Worst {
  double mm = 0, deg = 0;
};

Worst worst_error(const std::vector<Rigid3d>& poses, const Rig& truth) {
  const RelativePoseError worst = worst_relative_pose_error(poses, world_from_depth_poses(truth));
  return {worst.translation_m * 1000, worst.rotation_deg};
}

}  // namespace

int main(int argc, char** argv) {
  const std::string dir = argc > 1 && argv[1][0] != 0 ? argv[1] : std::string(ZF_SOURCE_DIR) + "/../shared/data/samba-4cam";
  const std::string only = argc > 2 ? argv[2] : "";
  const Capture capture = Capture::open(dir);
  const Rig& perturbed = capture.rig();
  const Rig& truth = *capture.ground_truth_rig();
  std::vector<int> eight, sixteen;
  for (int f = 0; f < 40 && f < capture.frame_count(); f += 5) eight.push_back(f);
  const int span = std::min(40, capture.frame_count());
  for (int k = 0; k < 16; ++k) sixteen.push_back(k * span / 16);  // 16 spread over the first 40 frames (all of samba-4cam)
  std::vector<int> all;
  for (int f = 0; f < capture.frame_count(); f += 2) all.push_back(f);

  std::vector<int> four;
  for (int f = 0; f < 40 && f < capture.frame_count(); f += 10) four.push_back(f);
  using O = RegistrationOptions&;
  const auto raw = RegistrationSurface::kRaw, bilateral = RegistrationSurface::kBilateral;
  // Each variant changes the final method (the defaults) in the way its name says.
  const std::vector<Variant> variants = {
      {"point-to-point (the paper's GPA), raw depth, no σ weights, no trim, 1 frame",
       [=](O o) { o.point_to_plane = false; o.surface = raw; o.noise_weights = false; o.trim_fraction = 0; }, {0}},
      {"point-to-plane, raw depth, no σ weights, no trim, 1 frame", [=](O o) { o.surface = raw; o.noise_weights = false; o.trim_fraction = 0; }, {0}},
      {"point-to-plane, bilateral, no σ weights, no trim, 1 frame", [=](O o) { o.surface = bilateral; o.noise_weights = false; o.trim_fraction = 0; }, {0}},
      {"point-to-plane, disparity fit, no σ weights, no trim, 1 frame", [=](O o) { o.noise_weights = false; o.trim_fraction = 0; }, {0}},
      {"point-to-plane, disparity fit, σ weights, no trim, 1 frame", [=](O o) { o.trim_fraction = 0; }, {0}},
      {"final (disparity fit, σ weights, trim 3 %), 1 frame", [](O) {}, {0}},
      {"final, 4 frames", [](O) {}, four},
      {"final, 8 frames", [](O) {}, eight},
      {"final, 16 frames (`zipfusion register` default)", [](O) {}, sixteen},
      {"final, 20 frames", [](O) {}, all},
      {"final, 16 frames, without the floor", [](O o) { o.below_volume_m = 0; }, sixteen},
      {"final, 16 frames, the floor weighed in full in every frame", [](O o) { o.floor_counts_once = false; }, sixteen},
      {"final, 16 frames, grazing pairs kept (no pair view angle limit, noise cosine not floored)", [](O o) { o.max_pair_view_angle_deg = 90; o.min_noise_cos = 0; }, sixteen},
      {"final, 16 frames, noise cosine not floored", [](O o) { o.min_noise_cos = 0; }, sixteen},
      {"final, 16 frames, none of the three (before 2026-12-02)", [](O o) { o.max_pair_view_angle_deg = 90; o.min_noise_cos = 0; o.floor_counts_once = false; }, sixteen},
      {"final, 8 frames, none of the three (before 2026-12-02)", [](O o) { o.max_pair_view_angle_deg = 90; o.min_noise_cos = 0; o.floor_counts_once = false; }, eight},
      {"final, 16 frames, bilateral instead of disparity fit", [=](O o) { o.surface = bilateral; }, sixteen},
      {"final, 16 frames, raw depth instead of disparity fit", [=](O o) { o.surface = raw; }, sixteen},
      {"final, 16 frames, point-to-point", [](O o) { o.point_to_plane = false; }, sixteen},
      {"final, 16 frames, no σ weights", [](O o) { o.noise_weights = false; }, sixteen},
      {"final, 16 frames, no trim", [](O o) { o.trim_fraction = 0; }, sixteen},
      {"final, 16 frames, down to full resolution (levels 3→0)", [](O o) { o.finest_level = 0; }, sixteen},
      {"final, 1 frame, levels 3→2", [](O o) { o.coarsest_level = 3; o.finest_level = 2; }, {0}},
      {"final, 4 frames, levels 3→2 (the background thread's window)", [](O o) { o.coarsest_level = 3; o.finest_level = 2; }, four},
      {"final, 16 frames, levels 3→2", [](O o) { o.coarsest_level = 3; o.finest_level = 2; }, sixteen},
  };


  std::printf("| variant | from perturbed: worst mm / deg | from truth: worst mm / deg | ms |\n| --- | --- | --- | --- |\n");
  for (size_t v = 0; v < variants.size(); ++v) {
    if (!only.empty() && std::to_string(v) != only) continue;
    const Variant& variant = variants[v];
    RegistrationOptions options;
    variant.change(options);
    // Quick experiments: ZF_SET="key=value,..." overrides a few options after the variant's.
    if (const char* set = std::getenv("ZF_SET")) {
      std::string text = set;
      for (size_t pos = 0; pos < text.size();) {
        size_t end = text.find(',', pos);
        if (end == std::string::npos) end = text.size();
        const std::string item = text.substr(pos, end - pos);
        const size_t eq = item.find('=');
        const std::string key = item.substr(0, eq);
        const double value = std::stod(item.substr(eq + 1));
        if (key == "fit_radius") options.fit_radius_px = static_cast<int>(value);
        if (key == "gate") options.fit_gate_m = value;
        if (key == "trim") options.trim_fraction = value;
        if (key == "coarsest") options.coarsest_level = static_cast<int>(value);
        if (key == "finest") options.finest_level = static_cast<int>(value);
        if (key == "iters") options.iterations_per_level = static_cast<int>(value);
        if (key == "end") options.end_distance_m = value;
        if (key == "start") options.start_distance_m = value;
        if (key == "view") options.max_view_angle_deg = value;
        if (key == "normal_angle") options.max_normal_angle_deg = value;

        if (key == "below") options.below_volume_m = value;
        if (key == "maxdepth") options.foreground.max_depth_m = value;
        pos = end + 1;
      }
    }
    options.validate();
    std::vector<std::vector<Image<float>>> depth;
    for (int f : variant.frames) depth.push_back(registration_depth(perturbed, capture.load_frame(f), options));
    const auto start = std::chrono::steady_clock::now();
    const RegistrationResult from_perturbed = register_rig(perturbed, depth, options);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    const RegistrationResult from_truth = register_rig(truth, depth, options);
    const Worst a = worst_error(from_perturbed.world_from_depth, truth), b = worst_error(from_truth.world_from_depth, truth);
    if (std::getenv("ZF_DETAIL")) {
      for (size_t c = 0; c < truth.cameras.size(); ++c) {
        const Rigid3d d = truth.cameras[c].world_from_depth.inverse() * from_truth.world_from_depth[c];
        const Eigen::AngleAxisd aa(Rigid3d(truth.cameras[0].world_from_depth.inverse() * from_truth.world_from_depth[0]).linear());
        const Eigen::AngleAxisd ac(d.linear());
        const Eigen::Vector3d shift = from_truth.world_from_depth[c].translation() - truth.cameras[c].world_from_depth.translation();
        std::printf("  cam%zu from truth: world shift mm %.1f %.1f %.1f, rot %.3f deg about world %.2f %.2f %.2f, rmse %.2f mm n %d\n", c, shift.x() * 1000,
                    shift.y() * 1000, shift.z() * 1000, ac.angle() * 180 / 3.14159265,
                    (truth.cameras[c].world_from_depth.linear() * ac.axis()).x(), (truth.cameras[c].world_from_depth.linear() * ac.axis()).y(),
                    (truth.cameras[c].world_from_depth.linear() * ac.axis()).z(), from_truth.rmse_after_m[c] * 1000, from_truth.correspondences_after[c]);
        (void)aa;
      }
    }
    std::printf("| %s | %.1f / %.3f | %.1f / %.3f | %.0f |\n", variant.name.c_str(), a.mm, a.deg, b.mm, b.deg, ms);
    std::fflush(stdout);
  }
  const Worst start = worst_error(world_from_depth_poses(perturbed), truth);
  std::printf("(rig.json itself: %.1f mm / %.3f deg)\n", start.mm, start.deg);
  return 0;
}
