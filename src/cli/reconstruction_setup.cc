#include "cli/reconstruction_setup.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "cli/commands.h"
#include "cli/live_devices.h"


namespace zipfusion::cli {

void add_reconstruction_options(CLI::App* cmd, ReconstructionArgs& args) {
  ReconstructOptions& o = args.options;
  cmd->add_option("--mode", args.mode, "zipper: one connected mesh; separate: one SDC mesh per camera, concatenated")
      ->check(CLI::IsMember({"zipper", "separate"}))
      ->capture_default_str();
  cmd->add_option("--filter", args.filter,
                  "Depth filter before triangulation: bilateral (the paper's square window), bilateral-separable (a row then a "
                  "column pass, 2-3x faster) or none")
      ->check(CLI::IsMember({"bilateral", "bilateral-separable", "none"}))
      ->capture_default_str();
  cmd->add_option("--rig", args.rig, "Take the calibration (poses, intrinsics with distortion, color_from_depth, volume) from this rig.json instead (e.g. "
                  "CAPTURE/ground_truth/rig.json, calibrate's output); with --live, the devices' camera i takes camera i's");
  cmd->add_option("--register", args.register_mode,
                  "Pose refinement by GPA-ICP: background (a worker thread, poses swapped in as they come), once (on up to 16 frames spread over the range, before the first), "
                  "once+background (once, then the worker from those poses), off, or auto: off for one camera or where rig.json marks its poses as trusted (\"poses_trusted\": true, "
                  "written by synth, calibrate and register), else once+background. With --live, once refines on the first 16 frame sets")
      ->check(CLI::IsMember({"auto", "background", "once", "once+background", "off"}))
      ->capture_default_str();
  cmd->add_option("--register-every", args.background.every_frames, "background: frames between two refinements, at least 1")->capture_default_str();
  cmd->add_option("--register-min-improvement", args.background.min_improvement,
                  "background: a window of fewer frame sets than the poses have been refined on (after once: every window) moves them only where "
                  "the residual falls by this share, in [0, 1)")
      ->capture_default_str();
  cmd->add_option("--register-window", args.background.window_frames, "background: newest frame sets handed over, refined together, in [1, 64]")
      ->capture_default_str();
  cmd->add_option("--lod", o.depth_level,
                  "Level of detail: reconstruct from every 2^LOD-th depth pixel, each the mean of its surface around it (1: a quarter of "
                  "the triangles), in [0, 3]")
      ->capture_default_str();
  cmd->add_option("--min-depth", o.foreground.min_depth_m, "Nearest depth kept, metres (>= 0)")->capture_default_str();
  cmd->add_option("--max-depth", o.foreground.max_depth_m, "Farthest depth kept, metres (finite, above --min-depth)")->capture_default_str();
  cmd->add_flag("--no-volume-crop", args.no_volume_crop, "Keep depth outside the rig's capture volume");
  cmd->add_option("--floor-noise", o.foreground.floor_noise_sigmas,
                  "Raise the volume's bottom, pixel by pixel, until it clears this many standard deviations of the pixel's height noise "
                  "(Kinect v1's depth noise along its ray; a z-up world, the floor taken 2 cm below the bottom): a high camera's floor noise "
                  "stays out; 0 = the bottom as rig.json puts it; in [0, 10]")
      ->capture_default_str();
  cmd->add_option("--max-depth-jump", o.sdc.max_depth_jump_m,
                  "SDC threshold: largest depth difference inside a triangle, metres in (0, 1), for a focal length of 580 px (a Kinect at "
                  "640x480); a camera with a shorter one f (at --lod, the subsampled one) takes it times 580/f")
      ->capture_default_str();
  cmd->add_option("--max-depth-jump-growth", o.sdc.growth_depth_m,
                  "SDC threshold: beyond this depth, metres, it grows with the square of depth, as a Kinect's depth step does "
                  "(0: constant; else in [0.1, 20])")
      ->capture_default_str();
  cmd->add_option("--bilateral-sigma-px", o.filter.spatial_sigma_px, "Bilateral spatial sigma, pixels (positive)")->capture_default_str();
  cmd->add_option("--bilateral-radius", o.filter.radius_px, "Bilateral radius, pixels, in [1, 32]")->capture_default_str();
  cmd->add_option("--bilateral-range-sigma", o.filter.range_sigma_m, "Bilateral range sigma, metres (positive)")->capture_default_str();
  cmd->add_option("--redundancy-distance", o.zipper.redundancy_distance_m, "d_r: overlap closer than this is redundant, metres in (0, 0.1]")
      ->capture_default_str();
  cmd->add_option("--coarse-levels", o.zipper.coarse_levels, "L: redundancy removal starts on depth downsampled by 2^L, L in [0, 4]")->capture_default_str();
  cmd->add_option("--coarse-shrink", o.zipper.coarse_shrink, "beta: d_r at level l is beta^l d_r, beta in (0, 1]")->capture_default_str();
  cmd->add_option("--clipping-distance", o.zipper.clipping_distance_m, "d_c: triangles this close to another mesh are re-triangulated, metres in (0, 0.05]")
      ->capture_default_str();
  cmd->add_option("--max-seam-edge", o.zipper.max_seam_edge_m, "Longest edge of a seam triangle, metres in (0, 0.1]")->capture_default_str();
  cmd->add_option("--seam-smoothing", o.zipper.seam_smoothing_px,
                  "Seam points lie at the mean depth of their surface over (2*this+1)^2 pixels, in [0, 4], halved at each --lod level (0: as "
                  "measured; -1: auto, 2 without the filter, 1 with it)")
      ->capture_default_str();
  cmd->add_option("--seam-fairing", o.zipper.seam_fairing_iterations,
                  "Rounds of smoothing the seams' points along their rays towards their neighbours, in [0, 8], then the corners of the creases "
                  "left (0: neither)")
      ->capture_default_str();
  cmd->add_option("--min-component", o.min_component_triangles,
                  "Drop connected pieces of fewer triangles than this (specks of noise, bits of floor), in [0, 1000000] (0: keep all)")
      ->check(kWholeNumber)
      ->capture_default_str();
  cmd->add_option("--ownership", args.ownership,
                  "Which camera keeps a surface two see: the smoother one (smoothness: less noise), the one seeing it farther from its "
                  "border (border: more frontally), or auto (smoothness without the filter, border with it)")
      ->check(CLI::IsMember({"auto", "border", "smoothness"}))
      ->capture_default_str();
  cmd->add_option("--hole-closing", o.zipper.hole_closing_px, "Border ownership: holes up to 2*this+1 pixels wide are not borders, this in [0, 32]")
      ->capture_default_str();
  cmd->add_option("--smoothness-window", o.zipper.smoothness_window_px, "Smoothness ownership: compared over windows this wide, pixels in [1, 256]")
      ->capture_default_str();
  cmd->add_option("--smoothness-exponent", o.zipper.smoothness_exponent,
                  "Smoothness ownership: exponent of the area ratio, how much a smoother surface outweighs a mesh's border, in (0, 128]")
      ->capture_default_str();
  cmd->add_option("--min-overlap", o.zipper.min_overlap_share, "Share of a mesh within d_r of another for the pair to be zippered, in [0, 1)")
      ->capture_default_str();
  add_threads_option(cmd, o.num_threads);
}

void warn_if_world_not_z_up(const Rig& rig, const ReconstructionArgs& args, const std::string& command) {
  args.options.foreground.validate();  // a bad --floor-noise is an error, not a warning first
  if (args.options.foreground.floor_noise_sigmas <= 0 || args.no_volume_crop || !rig.volume || world_looks_z_up(rig)) return;
  print_diagnostic(command + ": warning: the rig's world does not look z-up (most cameras neither stand upright nor look down along -z, "
                   "and they stand at no one height along z): --floor-noise raises the capture volume's lowest-z face as a floor's; pass "
                   "--floor-noise 0 if the floor is not below the volume along z");
}

nlohmann::ordered_json options_json(const ReconstructOptions& options) {
  return {{"min_depth_m", options.foreground.min_depth_m},
          {"max_depth_m", options.foreground.max_depth_m},
          {"crop_to_volume", options.foreground.crop_to_volume},
          {"floor_noise_sigmas", options.foreground.floor_noise_sigmas},
          {"lod", options.depth_level},
          {"max_depth_jump_m", options.sdc.max_depth_jump_m},  // for 580 px; each camera's is sdc_depth_jump of it
          {"max_depth_jump_growth_m", options.sdc.growth_depth_m},
          {"bilateral_sigma_px", options.filter.spatial_sigma_px},
          {"bilateral_radius_px", options.filter.radius_px},
          {"bilateral_range_sigma_m", options.filter.range_sigma_m},
          {"redundancy_distance_m", options.zipper.redundancy_distance_m},
          {"coarse_levels", options.zipper.coarse_levels},
          {"coarse_shrink", options.zipper.coarse_shrink},
          {"clipping_distance_m", options.zipper.clipping_distance_m},
          {"max_seam_edge_m", options.zipper.max_seam_edge_m},
          {"seam_smoothing_px", options.seam_smoothing_px()},  // auto resolved; full-resolution pixels (halved at each --lod level)
          {"seam_fairing_iterations", options.zipper.seam_fairing_iterations},
          {"min_overlap_share", options.zipper.min_overlap_share},
          {"min_component_triangles", options.min_component_triangles},
          {"ownership", options.ownership() == Ownership::kBorder ? "border" : "smoothness"},  // as used, auto resolved
          {"hole_closing_px", options.zipper.hole_closing_px},
          {"smoothness_window_px", options.zipper.smoothness_window_px},
          {"smoothness_exponent", options.zipper.smoothness_exponent},
          {"threads", options.num_threads}};
}

namespace {

using Clock = std::chrono::steady_clock;

// A pose update of stats.json's pose_updates: the poses swapped in at `frame`, per camera as
// rig.json writes them, so that the poses a mesh was made with can be read back.
nlohmann::ordered_json pose_update(int frame, int version, const std::vector<Rigid3d>& world_from_depth) {
  nlohmann::ordered_json poses = nlohmann::json::array();
  for (const Rigid3d& pose : world_from_depth) poses.push_back(matrix_json(pose));
  return {{"frame", frame}, {"version", version}, {"world_from_depth", std::move(poses)}};
}

}  // namespace

nlohmann::ordered_json matrix_json(const Rigid3d& pose) {
  const Eigen::Matrix4d m = pose.matrix();
  nlohmann::ordered_json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}

void apply_reconstruction_args(ReconstructionArgs& args) {
  ReconstructOptions& options = args.options;
  options.bilateral = args.filter != "none";
  options.filter.separable = args.filter == "bilateral-separable";
  options.mode = args.mode == "zipper" ? ReconstructMode::kZipper : ReconstructMode::kSeparate;
  options.zipper.ownership = args.ownership == "border" ? Ownership::kBorder
                             : args.ownership == "smoothness" ? Ownership::kSmoothness
                                                              : Ownership::kAuto;
  options.foreground.crop_to_volume = !args.no_volume_crop;
  options.validate();
  args.background.validate();
}

Reconstruction::Reconstruction(const Rig& rig, const Capture* capture, ReconstructionArgs& args, const FrameRange& range,
                               const std::function<bool(FrameSet&)>& take_live)
    : rig_(rig) {
  apply_reconstruction_args(args);
  ReconstructOptions& options = args.options;
  // auto refines untrusted poses before the first frame: the worker alone took its first
  // refinement from frame 0 and then one every 30 frames, and on a rig 2° / 5 cm off the first 34
  // meshes were 16.5–20.1 mm from the truth; refined first, 2.5–3.3 mm (docs/design.md).
  // One camera has no other to be registered to.
  register_mode_ = args.register_mode != "auto"                    ? args.register_mode
                   : rig_.poses_trusted || rig_.cameras.size() < 2 ? "off"
                                                                   : "once+background";
  // The mode's two parts (CLI11 checked the name against the list).
  const bool refine_first = register_mode_ == "once" || register_mode_ == "once+background";
  const bool in_background = register_mode_ == "background" || register_mode_ == "once+background";
  if (refine_first && capture == nullptr && !take_live) throw InvalidInput("--register " + register_mode_ + ": needs a capture or live input");

  // --register once: refine on frames spread over the range (a capture), or on the first live
  // frame sets, then keep those poses (or start the worker from them).
  start_rig_ = rig_;
  double refined_frame_sets = 0;  // what the starting poses were refined on, at the worker's level
  if (refine_first && rig_.cameras.size() >= 2) {
    const Clock::time_point start = Clock::now();
    RegistrationOptions registration = args.once_registration;
    registration.measure_fixed = false;  // the poses are used, not judged
    registration.num_threads = options.num_threads;
    registration.cancel = &stop_requested();  // Ctrl-C does not wait for seconds of refining
    registration.validate();
    std::vector<std::vector<Image<float>>> depth;
    if (capture != nullptr) {
      const int count = std::min(args.once_frames, range.end - range.begin);
      for (int i = 0; i < count; ++i) {
        depth.push_back(registration_depth(rig_, capture->load_frame(range.begin + i * (range.end - range.begin) / count), registration));
      }
    } else {
      // Taken as they come (about half a second of a 30 Hz rig), and not reconstructed: by the
      // time the poses are refined they are seconds old, and a live pipeline drops late sets.
      FrameSet set;
      for (int i = 0; i < args.once_frames && take_live(set); ++i) depth.push_back(registration_depth(rig_, set, registration));
    }
    if (stop_requested()) depth.clear();  // Ctrl-C while the frames were read: no seconds of refining first
    const RegistrationResult refined = depth.empty() ? RegistrationResult{} : register_rig(rig_, depth, registration);
    // Only cameras joined to the held one move; where none did (no depth in the volume, no
    // overlap, no live frame), the poses are as given and no update is recorded.
    int joined = 0;
    for (size_t c = 0; c < refined.joined_to_gauge.size(); ++c) joined += refined.joined_to_gauge[c] && static_cast<int>(c) != refined.gauge;
    if (joined > 0) {
      for (size_t c = 0; c < start_rig_.cameras.size(); ++c) start_rig_.cameras[c].world_from_depth = refined.world_from_depth[c];
      pose_updates_.push_back(pose_update(range.begin, 1, refined.world_from_depth));
      first_version_ = 1;
      // The worker (levels 3→2) then moves these poses only on clear evidence.
      refined_frame_sets = static_cast<double>(depth.size()) * std::pow(4.0, args.background.registration.finest_level - registration.finest_level);
    }
    refinement_s_ = std::chrono::duration<double>(Clock::now() - start).count();
  }
  if (in_background) {
    BackgroundRegistrationOptions background = args.background;
    background.start_frame_sets = refined_frame_sets;
    background_ = std::make_unique<BackgroundRegistration>(start_rig_, background);
  }
  reconstructor_ = std::make_unique<FrameReconstructor>(start_rig_, options);
}

void Reconstruction::say_how_far_poses_moved(const std::string& command) const {
  if (first_version_ == 0) return;
  // Refined before the first frame: how far the calibration was off is worth a line.
  const RelativePoseError moved = worst_relative_pose_error(world_from_depth_poses(start_rig_), world_from_depth_poses(rig_));
  std::cout << format("%s: poses refined before the first frame in %.1f s; cameras moved by up to %.1f mm and %.2f deg relative to %s\n",
                      command.c_str(), refinement_s_, moved.translation_m * 1000, moved.rotation_deg, rig_.cameras[0].name.c_str());
}

PipelineOptions Reconstruction::pipeline_options() {
  PipelineOptions options;
  // --register background: refined poses are swapped in between frames on the reconstruction
  // thread, and frame sets are offered to the worker there; neither waits for a refinement.
  if (background_) {
    options.before_reconstruct = [this](const FrameSet& set, FrameReconstructor& target) {
      const auto poses = background_->latest_poses();
      if (poses->version != pose_version_) {
        target.set_poses(poses->world_from_depth);
        pose_version_ = poses->version;
        nlohmann::ordered_json update = pose_update(set.index, first_version_ + pose_version_, poses->world_from_depth);
        update["refined_on_frame"] = poses->frame;
        pose_updates_.push_back(std::move(update));
      }
      background_->offer(set);
    };
  }
  return options;
}

}  // namespace zipfusion::cli
