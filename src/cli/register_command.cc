// zipfusion register: refine a capture's camera poses by GPA-ICP and write the refined rig.json.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "cli/commands.h"
#include "cli/frame_input.h"
#include "cli/frame_range.h"
#include "cli/rig_poses.h"
#include "zipfusion/core/error.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/registration/gpa_icp.h"

namespace zipfusion::cli {
namespace {

namespace fs = std::filesystem;

struct RegisterArgs {
  std::string capture;
  std::string out;
  std::string frames;
  std::string rig;
  int max_frames = 16;
  // A camera whose final correspondences fix its pose only to more than this (the formal σ along
  // its least fixed direction, RegistrationResult::least_fixed_m) leaves the rig untrusted. The
  // formal σ is smaller than the error, 1.1-5 times in these runs (16 frames unless said):
  // samba-4cam 0.3-0.5 mm (0.5-1.1 mm off the truth); synth 4 cameras 640x480, 8 frames,
  // 0.7-1.0 mm (1.1-1.4 mm off); 3 cameras 320x240 2.8-4.5 mm (8.5-10.2 mm off), on 3 frames
  // 6.2-8.8 mm (32-39 mm off).
  double trust_within_m = 0.002;
  RegistrationOptions options;
};

// Up to `count` frames spread evenly over [begin, end): the subject moves between them, so each adds
// constraints that the others lack.
std::vector<int> spread_frames(const FrameRange& range, int count) {
  const int available = range.end - range.begin;
  const int used = std::min(count, available);
  std::vector<int> frames;
  for (int i = 0; i < used; ++i) frames.push_back(range.begin + static_cast<int>(static_cast<long long>(i) * available / used));
  return frames;
}

void run_register(RegisterArgs& args) {
  if (args.max_frames < 1) throw InvalidInput("--max-frames: must be at least 1, got " + std::to_string(args.max_frames));
  args.options.validate();
  check_output_file(args.out);
  Capture capture = open_capture(args.capture, "register");
  capture.check_output_outside(args.out, "--out");
  check_replaces_only_format(args.out, kRigFormat, "--out");
  // GPA-ICP refines poses near the truth; from one shared pose it has no start (calibrated_rig).
  const Rig start = calibrated_rig(capture, args.rig);
  if (start.cameras.size() < 2) throw InvalidInput(args.capture + ": nothing to register: the rig has one camera");
  const FrameRange range = parse_frame_range(args.frames, capture.frame_count());
  const std::vector<int> frames = spread_frames(range, args.max_frames);

  std::vector<std::vector<Image<float>>> depth;
  UnreadableFrames unreadable("register");
  for (size_t i = 0; i < frames.size(); ++i) {
    const FrameSet set = capture.load_frame(frames[i]);
    unreadable.report(capture.rig(), set);
    depth.push_back(registration_depth(start, set, args.options));
    show_progress("register: loading", static_cast<int>(i) + 1, static_cast<int>(frames.size()));
  }
  const auto t0 = std::chrono::steady_clock::now();
  const RegistrationResult result = register_rig(start, depth, args.options);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  // A camera not joined to the gauge (the first with depth) keeps its starting pose. When that is
  // every other camera nothing was registered (poses too far off for the depth to meet, or no
  // depth): an error, not a rig that says its poses are trusted. When it is some, the rig is
  // written but not marked trusted, so that reconstruct's --register auto refines it again.
  const std::string& gauge = start.cameras[result.gauge].name;
  std::string without_depth;
  for (size_t c = 0; c < start.cameras.size(); ++c) {
    if (!result.has_depth[c]) without_depth += (without_depth.empty() ? "" : ", ") + start.cameras[c].name;
  }
  if (std::count(result.has_depth.begin(), result.has_depth.end(), 1) < 2) {
    throw InvalidInput(args.capture + ": fewer than two cameras have depth in the frames used" +
                       (without_depth.empty() ? std::string() : " (none: " + without_depth + ")") + "; nothing to register, nothing written");
  }
  int unmatched = 0;
  for (size_t c = 0; c < start.cameras.size(); ++c) unmatched += !result.joined_to_gauge[c];
  if (unmatched == static_cast<int>(start.cameras.size()) - 1) {
    char reach[64];
    std::snprintf(reach, sizeof reach, "%.0f mm at the finest level, %d correspondences a pair", args.options.end_distance_m * 1000,
                  args.options.min_correspondences);
    throw InvalidInput(args.capture + ": no camera's depth joins " + gauge + "'s within the registration's reach (" + reach +
                       "): the starting poses are too far off, the depth too small for --coarsest-level " + std::to_string(args.options.coarsest_level) +
                       ", or the frames have no overlapping depth; nothing written");
  }
  // Joined is not yet placed: correspondences that leave a direction free (only the floor: the
  // slide along it; a few frames at a coarse resolution) leave the pose wherever the steps
  // stopped. Such a rig is written untrusted too.
  std::string loosely_fixed;
  for (size_t c = 0; c < start.cameras.size(); ++c) {
    if (result.joined_to_gauge[c] && static_cast<int>(c) != result.gauge && !(result.least_fixed_m[c] <= args.trust_within_m)) {
      loosely_fixed += (loosely_fixed.empty() ? "" : ", ") + start.cameras[c].name;
    }
  }
  Rig refined = start;
  for (size_t c = 0; c < refined.cameras.size(); ++c) refined.cameras[c].world_from_depth = result.world_from_depth[c];
  refined.poses_trusted = unmatched == 0 && loosely_fixed.empty();
  write_rig(args.out, refined);

  std::printf("registered %zu cameras on %zu frames (%d..%d) in %.0f ms, %d iterations%s\n", start.cameras.size(), frames.size(), frames.front(),
              frames.back(), ms, result.iterations, result.converged ? ", converged" : "");
  std::printf("%-10s %12s %12s %14s %14s %10s %10s\n", "camera", "change deg", "change mm", "rms before mm", "rms after mm", "matches", "fixed mm");
  // "-": no correspondences to measure at those poses.
  const auto rms_mm = [](double rms_m, int count) {
    char text[32];
    std::snprintf(text, sizeof text, count > 0 ? "%.2f" : "-", rms_m * 1000);
    return std::string(text);
  };
  for (size_t c = 0; c < start.cameras.size(); ++c) {
    const Rigid3d change = start.cameras[c].world_from_depth.inverse() * result.world_from_depth[c];
    const double moved_mm = (result.world_from_depth[c].translation() - start.cameras[c].world_from_depth.translation()).norm() * 1000;
    const char* note = static_cast<int>(c) == result.gauge ? "  (held: the others are registered to it)"
                       : !result.has_depth[c]              ? "  (no depth in these frames, or none in the volume: keeps its pose)"
                       : !result.joined_to_gauge[c]        ? "  (not joined to the held camera through any overlap: keeps its pose)"
                                                           : "";
    // "-": the gauge, or a camera not registered (it keeps its pose).
    char fixed[32] = "-";
    if (static_cast<int>(c) != result.gauge && result.joined_to_gauge[c]) std::snprintf(fixed, sizeof fixed, "%.1f", result.least_fixed_m[c] * 1000);
    std::printf("%-10s %12.3f %12.1f %14s %14s %10d %10s%s\n", start.cameras[c].name.c_str(), rotation_angle_deg(change), moved_mm,
                rms_mm(result.rmse_before_m[c], result.correspondences_before[c]).c_str(),
                rms_mm(result.rmse_after_m[c], result.correspondences_after[c]).c_str(), result.correspondences_after[c], fixed, note);
  }
  if (unmatched > 0) {
    std::printf("%d camera(s) not joined to %s: %s is written without \"poses_trusted\", so reconstruct refines it again\n", unmatched, gauge.c_str(),
                args.out.c_str());
  }
  if (!loosely_fixed.empty()) {
    std::printf("%s fixed to more than %.3g mm (--trust-within): the correspondences leave a direction of the pose loose (only the "
                "floor, too few frames (--max-frames), coarse depth); %s is written without \"poses_trusted\", so reconstruct refines it again\n",
                loosely_fixed.c_str(), args.trust_within_m * 1000, args.out.c_str());
  }
  if (const auto& truth = capture.ground_truth_rig()) {
    const std::vector<Rigid3d> true_poses = world_from_depth_poses(*truth);
    const auto before = relative_pose_errors(world_from_depth_poses(start), true_poses, result.gauge);
    const auto after = relative_pose_errors(result.world_from_depth, true_poses, result.gauge);
    std::printf("against ground_truth/rig.json (pose relative to %s):\n", gauge.c_str());
    for (size_t c = 0; c < before.size(); ++c) {
      if (static_cast<int>(c) == result.gauge) continue;
      std::printf("%-10s before %6.1f mm %6.3f deg   after %6.1f mm %6.3f deg\n", start.cameras[c].name.c_str(), before[c].translation_m * 1000,
                  before[c].rotation_deg, after[c].translation_m * 1000, after[c].rotation_deg);
    }
  }
  std::printf("wrote %s\n", args.out.c_str());
}

}  // namespace

void add_register_command(CLI::App& app) {
  auto args = std::make_shared<RegisterArgs>();
  RegistrationOptions& o = args->options;
  CLI::App* cmd = app.add_subcommand("register", "Refine all camera poses at once (GPA-ICP) and write the refined rig.json");
  cmd->add_option("capture", args->capture, "Capture folder (with rig.json)")->required();
  cmd->add_option("--out", args->out, "Refined rig.json to write")->required();
  cmd->add_option("--frames", args->frames, "Frames A:B to draw from (A included, B excluded; default all)");
  cmd->add_option("--max-frames", args->max_frames, "Frames used, spread evenly over --frames")->capture_default_str();
  cmd->add_option("--trust-within", args->trust_within_m,
                  "The rig is written as trusted only if every camera's correspondences fix its pose to this, metres (the formal "
                  "standard deviation along its least fixed direction; a rotation counts at a 2 m lever arm)")
      ->check(kFiniteNumber & CLI::Range(1e-6, 1.0))
      ->capture_default_str();
  cmd->add_option("--rig", args->rig, "Start from the calibration (poses, intrinsics, volume) of this rig.json instead of the capture's");
  cmd->add_option("--coarsest-level", o.coarsest_level, "First level: depth sampled every 2^L pixels of a 640x480 Kinect (every 2^L*f/580 of a camera of focal length f), L in [0, 5]")->capture_default_str();
  cmd->add_option("--finest-level", o.finest_level, "Last level, in [0, --coarsest-level] (0 = full resolution; so is 1 for 320x240)")->capture_default_str();
  cmd->add_option("--iterations", o.iterations_per_level, "Iterations per level, in [1, 100]")->capture_default_str();
  cmd->add_option("--start-distance", o.start_distance_m, "Correspondence distance at the first iteration, metres")->capture_default_str();
  cmd->add_option("--end-distance", o.end_distance_m, "Correspondence distance at the last iteration, metres")->capture_default_str();
  cmd->add_option("--trim", o.trim_fraction, "Share of each pair's worst correspondences dropped, in [0, 1)")->capture_default_str();
  cmd->add_option("--below-volume", o.below_volume_m, "Depth this far below the capture volume (the floor) is used too, metres")
      ->capture_default_str();
  cmd->add_option("--max-pair-view-angle", o.max_pair_view_angle_deg,
                  "Correspondences whose mean normal either camera sees more obliquely are dropped, degrees")
      ->capture_default_str();
  cmd->add_option("--fit-radius", o.fit_radius_px,
                  "Half-width of the window each point and normal are fitted over at the finest level, pixels: wider averages more noise, narrower "
                  "bends curved surfaces less (1 for low-noise depth at 320x240); in [1, 16]")
      ->capture_default_str();
  cmd->add_option("--min-noise-cos", o.min_noise_cos, "The noise along a pair's normal is taken as seen at a cosine of at least this")
      ->capture_default_str();
  cmd->add_flag("!--floor-every-frame", o.floor_counts_once,
                "Weigh the floor's correspondences in full in every frame (default: 1/F over F frames, as it does not move)");
  add_threads_option(cmd, o.num_threads);
  cmd->callback([args] { run_register(*args); });
}

}  // namespace zipfusion::cli
