// zipfusion info: describe a capture's rig and the statistics of its frames.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <numbers>

#include "cli/commands.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/io/capture.h"

namespace zipfusion::cli {
namespace {

struct InfoArgs {
  std::string capture;
  int sample = 0;
  bool json = false;
  bool strict = false;
};

struct CameraStats {
  int frames_with_depth = 0;
  int frames_with_color = 0;
  double valid_fraction_sum = 0;    // over frames with depth
  double in_volume_fraction_sum = 0;
  std::vector<float> depth_samples;  // metres, subsampled
  std::vector<std::string> unreadable;  // frame files examined that could not be decoded (CameraFrame::unreadable)
};

// Azimuth (degrees, from +x towards +y) and elevation of a camera's viewing direction.
std::pair<double, double> view_direction_deg(const Rigid3d& world_from_depth) {
  const Eigen::Vector3d z = world_from_depth.linear().col(2);
  const double to_deg = 180 / std::numbers::pi;
  return {std::atan2(z.y(), z.x()) * to_deg, std::asin(std::clamp(z.z(), -1.0, 1.0)) * to_deg};
}

void run_info(const InfoArgs& args) {
  const Capture capture = Capture::open(args.capture, {.strict = args.strict});
  const Rig& rig = capture.rig();
  const int cameras = capture.camera_count();

  std::vector<int> frames;
  const int count = capture.frame_count();
  const int wanted = args.sample > 0 ? std::min(args.sample, count) : count;
  for (int i = 0; i < wanted; ++i) frames.push_back(wanted == count ? i : static_cast<int>(static_cast<long long>(i) * count / wanted));

  std::vector<CameraStats> stats(cameras);
  std::mutex mutex;
  int done = 0;
  parallel_for(0, static_cast<int>(frames.size()), [&](int i) {
    const FrameSet set = capture.load_frame(frames[i]);
    std::vector<CameraStats> local(cameras);
    for (int c = 0; c < cameras; ++c) {
      const CameraFrame& f = set.cameras[c];
      const CameraModel& cam = rig.cameras[c];
      local[c].frames_with_color += f.has_color;
      local[c].unreadable = f.unreadable;
      if (!f.has_depth) continue;
      local[c].frames_with_depth++;
      size_t valid = 0, in_volume = 0;
      for (int v = 0; v < f.depth.height; ++v) {
        for (int u = 0; u < f.depth.width; ++u) {
          const unsigned short raw = f.depth(u, v);
          if (raw == 0) continue;
          ++valid;
          const float z = static_cast<float>(raw * rig.depth_unit_m);
          if (rig.volume) {
            const Eigen::Vector3d p = cam.world_from_depth * unproject(cam.depth_intrinsics, u, v, z).cast<double>();
            in_volume += rig.volume->contains(p);
          }
          if ((u % 8) == 0 && (v % 8) == 0) local[c].depth_samples.push_back(z);
        }
      }
      local[c].valid_fraction_sum += static_cast<double>(valid) / f.depth.size();
      local[c].in_volume_fraction_sum += valid ? static_cast<double>(in_volume) / valid : 0;
    }
    std::lock_guard lock(mutex);
    for (int c = 0; c < cameras; ++c) {
      stats[c].frames_with_depth += local[c].frames_with_depth;
      stats[c].frames_with_color += local[c].frames_with_color;
      stats[c].valid_fraction_sum += local[c].valid_fraction_sum;
      stats[c].in_volume_fraction_sum += local[c].in_volume_fraction_sum;
      stats[c].depth_samples.insert(stats[c].depth_samples.end(), local[c].depth_samples.begin(), local[c].depth_samples.end());
      stats[c].unreadable.insert(stats[c].unreadable.end(), local[c].unreadable.begin(), local[c].unreadable.end());
    }
    show_progress("info", ++done, static_cast<int>(frames.size()));
  });

  std::vector<int> missing_depth(cameras, 0), missing_color(cameras, 0);
  for (const MissingFrame& m : capture.missing_frames()) (m.color ? missing_color : missing_depth)[m.camera]++;

  nlohmann::ordered_json out;
  out["capture"] = args.capture;
  out["format"] = kRigFormat;
  out["fps"] = rig.fps;
  out["frame_count"] = rig.frame_count;
  out["depth_unit_m"] = rig.depth_unit_m;
  out["frames_examined"] = frames.size();
  if (rig.volume) out["volume"] = {{"min", {rig.volume->min.x(), rig.volume->min.y(), rig.volume->min.z()}},
                                   {"max", {rig.volume->max.x(), rig.volume->max.y(), rig.volume->max.z()}}};
  if (const auto& truth = capture.ground_truth_rig()) {
    double worst_deg = 0, worst_m = 0;
    for (int c = 0; c < cameras; ++c) {
      const Rigid3d error = truth->cameras[c].world_from_depth.inverse() * rig.cameras[c].world_from_depth;
      worst_deg = std::max(worst_deg, rotation_angle_deg(error));
      worst_m = std::max(worst_m, (truth->cameras[c].world_from_depth.translation() - rig.cameras[c].world_from_depth.translation()).norm());
    }
    out["ground_truth"] = {{"pose_error_max_deg", worst_deg}, {"pose_error_max_m", worst_m}, {"meshes", capture.has_ground_truth_meshes()}};
  }
  if (!capture.ground_truth_rig_problem().empty()) out["ground_truth_problem"] = capture.ground_truth_rig_problem();
  if (const std::string problem = shared_pose_problem(rig); !problem.empty()) out["poses_problem"] = problem;
  out["cameras"] = nlohmann::json::array();
  for (int c = 0; c < cameras; ++c) {
    const CameraModel& cam = rig.cameras[c];
    CameraStats& s = stats[c];
    std::sort(s.depth_samples.begin(), s.depth_samples.end());
    std::sort(s.unreadable.begin(), s.unreadable.end());  // gathered in the order the frames finished
    auto quantile = [&](double q) { return s.depth_samples.empty() ? 0.0 : s.depth_samples[static_cast<size_t>(q * (s.depth_samples.size() - 1))]; };
    const auto [azimuth, elevation] = view_direction_deg(cam.world_from_depth);
    const Eigen::Vector3d position = cam.world_from_depth.translation();
    nlohmann::ordered_json j = {
        {"name", cam.name},
        {"depth", {{"width", cam.depth_intrinsics.width}, {"height", cam.depth_intrinsics.height}, {"fx", cam.depth_intrinsics.fx}, {"fy", cam.depth_intrinsics.fy}}},
        {"position_m", {position.x(), position.y(), position.z()}},
        {"azimuth_deg", azimuth},
        {"elevation_deg", elevation},
        {"frames_with_depth", s.frames_with_depth},
        {"frames_with_color", s.frames_with_color},
        {"missing_depth_frames", missing_depth[c]},
        {"missing_color_frames", missing_color[c]},
        {"unreadable_frame_files", s.unreadable},
        {"valid_depth_fraction", s.frames_with_depth ? s.valid_fraction_sum / s.frames_with_depth : 0.0},
        // null where the frames examined hold no depth in range (not 0 m, a depth no camera measures)
        {"depth_m", s.depth_samples.empty() ? nlohmann::ordered_json(nullptr)
                                            : nlohmann::ordered_json{{"min", quantile(0)}, {"median", quantile(0.5)}, {"max", quantile(1)}}}};
    if (cam.color_intrinsics) j["color"] = {{"width", cam.color_intrinsics->width}, {"height", cam.color_intrinsics->height}, {"fx", cam.color_intrinsics->fx}};
    if (rig.volume) j["in_volume_fraction"] = s.frames_with_depth ? s.in_volume_fraction_sum / s.frames_with_depth : 0.0;
    out["cameras"].push_back(j);
  }

  if (args.json) {
    std::cout << json_text(out, 2) << "\n";
    return;
  }
  std::cout << "capture      " << args.capture << "\n";
  std::cout << format("format       %s, %d frames at %g fps (%.2f s), depth unit %g mm\n", kRigFormat, rig.frame_count, rig.fps,
                      rig.frame_count / rig.fps, rig.depth_unit_m * 1000);
  if (rig.volume) {
    std::cout << format("volume       [%.2f, %.2f, %.2f] .. [%.2f, %.2f, %.2f] m\n", rig.volume->min.x(), rig.volume->min.y(),
                        rig.volume->min.z(), rig.volume->max.x(), rig.volume->max.y(), rig.volume->max.z());
  }
  if (out.contains("ground_truth")) {
    std::cout << format("ground truth true poses differ from rig.json by up to %.3f deg / %.1f mm; meshes: %s\n",
                        out["ground_truth"]["pose_error_max_deg"].get<double>(), out["ground_truth"]["pose_error_max_m"].get<double>() * 1000,
                        capture.has_ground_truth_meshes() ? "yes" : "no");
  }
  if (out.contains("ground_truth_problem")) {
    std::cout << "ground truth not used: " << out["ground_truth_problem"].get<std::string>() << "\n";
  }
  if (out.contains("poses_problem")) std::cout << "poses        " << out["poses_problem"].get<std::string>() << "\n";
  std::cout << format("\n%-8s %-14s %-14s %-22s %-13s\n", "camera", "depth", "colour", "position (m)", "view az/el");
  for (int c = 0; c < cameras; ++c) {
    const auto& j = out["cameras"][c];
    const CameraModel& cam = rig.cameras[c];
    const std::string color = cam.color_intrinsics ? format("%dx%d f%.0f", cam.color_intrinsics->width, cam.color_intrinsics->height, cam.color_intrinsics->fx) : "none";
    std::cout << format("%-8s %-14s %-14s (%5.2f,%5.2f,%5.2f)   %6.1f/%5.1f\n", cam.name.c_str(),
                        format("%dx%d f%.0f", cam.depth_intrinsics.width, cam.depth_intrinsics.height, cam.depth_intrinsics.fx).c_str(),
                        color.c_str(), j["position_m"][0].get<double>(), j["position_m"][1].get<double>(), j["position_m"][2].get<double>(),
                        j["azimuth_deg"].get<double>(), j["elevation_deg"].get<double>());
  }
  std::cout << format("\nframes examined: %zu of %d\n", frames.size(), rig.frame_count);
  std::cout << format("%-8s %8s %8s %9s %10s %24s\n", "camera", "depth", "colour", "valid %", "in vol %", "depth min/med/max (m)");
  for (int c = 0; c < cameras; ++c) {
    const auto& j = out["cameras"][c];
    const std::string in_volume = j.contains("in_volume_fraction") ? format("%.1f", 100 * j["in_volume_fraction"].get<double>()) : "-";
    const std::string depth_range = j["depth_m"].is_null() ? "-" : format("%8.2f/%5.2f/%5.2f", j["depth_m"]["min"].get<double>(),
                                                                           j["depth_m"]["median"].get<double>(), j["depth_m"]["max"].get<double>());
    std::cout << format("%-8s %8s %8s %9.1f %10s %20s\n", rig.cameras[c].name.c_str(), format("%d", j["frames_with_depth"].get<int>()).c_str(),
                        format("%d", j["frames_with_color"].get<int>()).c_str(), 100 * j["valid_depth_fraction"].get<double>(),
                        in_volume.c_str(), depth_range.c_str());
  }
  // Cameras with depth of which none lies in the volume: reconstruct would make empty meshes of
  // them (depth in tenths of a millimetre read as millimetres lands about the cameras).
  std::string outside;
  for (int c = 0; c < cameras; ++c) {
    const auto& j = out["cameras"][c];
    if (j.contains("in_volume_fraction") && !j["depth_m"].is_null() && j["in_volume_fraction"].get<double>() == 0) {
      outside += (outside.empty() ? "" : ", ") + rig.cameras[c].name;
    }
  }
  if (!outside.empty()) {
    std::cout << "\nno depth in the volume: " << outside << "; reconstruct keeps only depth inside it (check rig.json's depth_unit_m, "
              << format("%g", rig.depth_unit_m) << " m, and volume, or reconstruct with --no-volume-crop)\n";
  }
  if (!capture.missing_frames().empty()) {
    std::cout << "\nmissing frame files: " << capture.missing_frames().size() << " (";
    for (int c = 0; c < cameras; ++c) {
      std::cout << (c ? ", " : "") << rig.cameras[c].name << " depth " << missing_depth[c] << " colour " << missing_color[c];
    }
    std::cout << "); reconstruct leaves a camera without its depth file out of that frame set, and gives one without its "
                 "colour file grey there\n";
  }
  std::vector<std::string> unreadable;
  for (const CameraStats& s : stats) unreadable.insert(unreadable.end(), s.unreadable.begin(), s.unreadable.end());
  if (!unreadable.empty()) {
    std::sort(unreadable.begin(), unreadable.end());
    std::cout << "\nunreadable frame files: " << unreadable.size() << " in the frames examined; reconstruct leaves a camera whose "
                 "depth file this is out of that frame set, and gives one whose colour file this is grey there\n";
    for (const std::string& file : unreadable) std::cout << "  " << file << "\n";
  }
}

}  // namespace

void add_info_command(CLI::App& app) {
  auto args = std::make_shared<InfoArgs>();
  CLI::App* cmd = app.add_subcommand("info", "Describe a capture: its rig and statistics of its frames");
  cmd->add_option("capture", args->capture, "Capture folder (with rig.json)")->required();
  cmd->add_option("--sample", args->sample, "Examine only this many evenly spaced frames (0 = all)")->check(kWholeNumber)->check(CLI::Range(0, 1 << 30))->capture_default_str();
  cmd->add_flag("--json", args->json, "Print JSON instead of tables");
  cmd->add_flag("--strict", args->strict, "Treat a missing or undecodable frame file as an error");
  cmd->callback([args] { run_info(*args); });
}

}  // namespace zipfusion::cli
