// zipfusion reconstruct: one mesh per frame of a capture, with per-stage timings in stats.json.

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <type_traits>

#include "cli/commands.h"
#include "cli/frame_range.h"
#include "cli/live_devices.h"
#include "cli/rig_poses.h"
#include "zipfusion/core/error.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/mesh_io.h"
#include "zipfusion/live/live_rig.h"
#include "zipfusion/pipeline/background_registration.h"
#include "zipfusion/pipeline/pipeline.h"

namespace zipfusion::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct ReconstructArgs {
  std::string capture;
  std::string out;
  std::string frames;
  std::string mode = "zipper";
  std::string filter = "bilateral";
  std::string format = "ply";
  std::string rig;
  std::string register_mode = "auto";
  bool no_volume_crop = false;
  ReconstructOptions options;
  BackgroundRegistrationOptions background;
  int once_frames = 8;
  bool live = false;
  LiveDeviceArgs devices;
  double seconds = 0;
};

static_assert(std::is_same_v<FrameSource, LiveFrameSource>, "live_frame_source feeds run_pipeline as it is");

// Where the frame sets come from: a capture on disk, or live cameras (--live).
struct Input {
  std::optional<Capture> capture;
  std::unique_ptr<LiveRig> live;
  Rig rig;
  FrameRange range;        // capture: the frames; live: [0, --frames) or [0, 0) without a limit
  FrameSource source;
  std::mutex skew_mutex;   // live: per frame set skew, written by the source thread
  std::vector<double> skew_ms;
};

void open_input(ReconstructArgs& args, Input& in) {
  if (!args.live) {
    if (args.capture.empty()) throw InvalidInput("capture: required (or --live)");
    if (!args.devices.devices.empty() || !args.devices.replay.empty() || args.seconds > 0) {
      throw InvalidInput("--devices, --replay, --seconds: only with --live");
    }
    in.capture.emplace(Capture::open(args.capture));
    in.rig = args.rig.empty() ? in.capture->rig() : rig_with_poses_from(in.capture->rig(), args.rig);
    in.range = parse_frame_range(args.frames, in.capture->frame_count());
    in.source = capture_source(*in.capture, in.range.begin, in.range.end);
    return;
  }
  if (!args.capture.empty()) throw InvalidInput("--live: takes no CAPTURE (frames come from --devices or --replay)");
  if (args.register_mode == "once") throw InvalidInput("--register once: needs a capture; with --live use auto, background or off");
  if (!(args.seconds >= 0)) throw InvalidInput("--seconds: must be >= 0 (0 = until Ctrl-C or the streams end)");
  int max_frames = 0;
  if (!args.frames.empty()) {
    size_t used = 0;
    try {
      max_frames = std::stoi(args.frames, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != args.frames.size() || max_frames < 1) {
      throw InvalidInput("--frames: with --live, the number of frame sets to reconstruct (a whole number >= 1), got \"" + args.frames + "\"");
    }
  }
  install_stop_on_signal();
  in.live = std::make_unique<LiveRig>(open_live_cameras(args.devices), LiveRigOptions{.cancel = &stop_requested()});
  if (args.rig.empty()) {
    in.rig = make_live_rig(*in.live);
    std::cout << "reconstruct: no --rig: world poses are identity; calibrate the rig (README.md) and pass --rig\n" << std::flush;
  } else {
    const Rig calibration = read_rig(args.rig);
    in.rig = make_live_rig(*in.live, &calibration, args.rig);
  }
  in.range = {0, max_frames};
  in.source = live_frame_source(*in.live, {.max_frames = max_frames, .max_seconds = args.seconds, .observe = [&in](const LiveFrameSet& set) {
    std::lock_guard lock(in.skew_mutex);
    in.skew_ms.resize(set.index + 1, 0);
    in.skew_ms[set.index] = set.skew_s * 1000;
  }});
}

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

double median_of(std::vector<double> values) {
  if (values.empty()) return 0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

void run_reconstruct(ReconstructArgs& args) {
  ReconstructOptions& options = args.options;
  options.bilateral = args.filter != "none";
  options.filter.separable = args.filter == "bilateral-separable";
  options.mode = args.mode == "zipper" ? ReconstructMode::kZipper : ReconstructMode::kSeparate;
  options.foreground.crop_to_volume = !args.no_volume_crop;
  options.validate();
  args.background.validate();
  Input in;
  open_input(args, in);
  const Rig& rig = in.rig;
  const FrameRange& range = in.range;
  // auto: refine in the background unless the rig's poses are marked as trusted.
  if (args.register_mode == "auto") args.register_mode = rig.poses_trusted ? "off" : "background";

  const fs::path out_dir = args.out;
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (!fs::is_directory(out_dir, ec)) throw IoError(out_dir.string() + ": cannot create output folder");

  // --register once: refine on frames spread over the range, then keep those poses.
  Rig start_rig = rig;
  nlohmann::ordered_json pose_updates = nlohmann::json::array();
  if (args.register_mode == "once") {
    args.background.registration.validate();
    std::vector<std::vector<Image<float>>> depth;
    const int count = std::min(args.once_frames, range.end - range.begin);
    for (int i = 0; i < count; ++i) {
      depth.push_back(registration_depth(rig, in.capture->load_frame(range.begin + i * (range.end - range.begin) / count), args.background.registration));
    }
    const RegistrationResult refined = register_rig(rig, depth, args.background.registration);
    for (size_t c = 0; c < start_rig.cameras.size(); ++c) start_rig.cameras[c].world_from_depth = refined.world_from_depth[c];
    pose_updates.push_back({{"frame", range.begin}, {"version", 1}});
  }
  std::unique_ptr<BackgroundRegistration> background;
  if (args.register_mode == "background") background = std::make_unique<BackgroundRegistration>(rig, args.background);
  int pose_version = 0;

  FrameReconstructor reconstructor(start_rig, options);
  nlohmann::ordered_json frames = nlohmann::json::array();
  std::vector<double> totals;
  const std::string extension = "." + args.format;
  // --register background: refined poses are swapped in between frames on the reconstruction
  // thread, and frame sets are offered to the worker there; neither waits for a refinement.
  PipelineOptions pipeline_options;
  if (in.live) pipeline_options.source_policy = QueuePolicy::kDropOldest;  // the cameras do not wait
  if (background) {
    pipeline_options.before_reconstruct = [&](const FrameSet& set, FrameReconstructor& target) {
      const auto poses = background->latest_poses();
      if (poses->version != pose_version) {
        target.set_poses(poses->world_from_depth);
        pose_version = poses->version;
        pose_updates.push_back({{"frame", set.index}, {"version", pose_version}, {"refined_on_frame", poses->frame}});
      }
      background->offer(set);
    };
  }
  // Decoding, reconstruction and writing overlap: each runs on its own thread.
  const PipelineStats pipeline = run_pipeline(in.source, reconstructor, [&](PipelineFrame& frame) {
    const FrameResult& result = frame.result;
    const Clock::time_point write_start = Clock::now();
    write_mesh(out_dir / frame_file_name(frame.index, extension), result.mesh);
    const double write_ms = ms_since(write_start);
    const StageTimes& t = result.times;
    totals.push_back(t.total_ms);
    frames.push_back({{"frame", frame.index},
                      {"cameras_used", result.cameras_used},
                      {"triangles", result.mesh.triangle_count()},
                      {"vertices", result.mesh.vertex_count()},
                      {"ms", {{"decode", frame.decode_ms}, {"foreground", t.foreground_ms}, {"filter", t.filter_ms}, {"triangulate", t.triangulate_ms},
                              {"color", t.color_ms}, {"overlap", t.overlap_ms}, {"redundancy", t.redundancy_ms}, {"clipping", t.clipping_ms},
                              {"assemble", t.assemble_ms}, {"total", t.total_ms}, {"write", write_ms}}},
                      {"zipper", {{"pairs", result.zipper.pairs}, {"redundant_removed", result.zipper.redundant_removed},
                                  {"seam_taken", result.zipper.seam_taken}, {"seam_added", result.zipper.seam_added}}}});
    if (in.live) {
      std::lock_guard lock(in.skew_mutex);
      if (frame.index < static_cast<int>(in.skew_ms.size())) frames.back()["skew_ms"] = in.skew_ms[frame.index];
    }
    if (range.end > range.begin) show_progress("reconstruct", frame.index - range.begin + 1, range.end - range.begin);
  }, pipeline_options);

  nlohmann::ordered_json stats;
  stats["capture"] = in.live ? "live" : args.capture;
  if (in.live) {
    nlohmann::ordered_json devices = nlohmann::json::array();
    const std::vector<LiveCameraStats> live_stats = in.live->stats();
    for (int c = 0; c < in.live->camera_count(); ++c) {
      devices.push_back({{"name", rig.cameras[c].name}, {"device", in.live->camera(c).description()}, {"frames", live_stats[c].frames},
                         {"dropped_by_camera", live_stats[c].dropped}, {"late", live_stats[c].discarded_late},
                         {"end_reason", live_stats[c].end_reason}});
    }
    stats["devices"] = devices;
    stats["dropped_frame_sets"] = pipeline.dropped;
  }
  stats["mode"] = args.mode;
  stats["filter"] = args.filter;
  stats["rig"] = args.rig.empty() ? (in.live ? std::string("identity poses") : (fs::path(args.capture) / "rig.json").string()) : args.rig;
  stats["options"] = {{"min_depth_m", options.foreground.min_depth_m},
                      {"max_depth_m", options.foreground.max_depth_m},
                      {"crop_to_volume", options.foreground.crop_to_volume},
                      {"max_depth_jump_m", options.sdc.max_depth_jump_m},
                      {"bilateral_sigma_px", options.filter.spatial_sigma_px},
                      {"bilateral_radius_px", options.filter.radius_px},
                      {"bilateral_range_sigma_m", options.filter.range_sigma_m},
                      {"redundancy_distance_m", options.zipper.redundancy_distance_m},
                      {"coarse_levels", options.zipper.coarse_levels},
                      {"coarse_shrink", options.zipper.coarse_shrink},
                      {"clipping_distance_m", options.zipper.clipping_distance_m},
                      {"max_seam_edge_m", options.zipper.max_seam_edge_m},
                      {"min_overlap_share", options.zipper.min_overlap_share},
                      {"hole_closing_px", options.zipper.hole_closing_px},
                      {"threads", options.num_threads}};
  stats["register"] = args.register_mode;
  stats["pose_updates"] = pose_updates;
  stats["frames"] = frames;
  stats["median_total_ms"] = median_of(totals);
  stats["wall_ms"] = pipeline.wall_ms;
  write_file_atomic(out_dir / "stats.json", stats.dump(2) + "\n");
  std::cout << "wrote " << frames.size() << " meshes (" << args.mode << ") to " << out_dir.string() << ", median reconstruction "
            << median_of(totals) << " ms per frame set; timings in " << (out_dir / "stats.json").string() << "\n";
  if (in.live && pipeline.dropped > 0) {
    std::cout << "reconstruct: " << pipeline.dropped << " live frame sets were dropped because reconstruction fell behind the cameras\n";
  }
}

}  // namespace

void add_reconstruct_command(CLI::App& app) {
  auto args = std::make_shared<ReconstructArgs>();
  ReconstructOptions& o = args->options;
  CLI::App* cmd = app.add_subcommand("reconstruct", "Reconstruct one mesh per frame of a capture");
  cmd->add_option("capture", args->capture, "Capture folder (with rig.json); not with --live");
  cmd->add_flag("--live", args->live, "Reconstruct live cameras (--devices or --replay) instead of a capture; Ctrl-C stops");
  add_live_device_options(cmd, args->devices);
  cmd->add_option("--seconds", args->seconds, "--live: seconds to run (0 = until Ctrl-C or the streams end)")->capture_default_str();
  cmd->add_option("--out", args->out, "Output folder: NNNNNN.ply per frame and stats.json")->required();
  cmd->add_option("--frames", args->frames, "Frames A:B (A included, B excluded; default all); with --live, the number of frame sets");
  cmd->add_option("--mode", args->mode, "zipper: one connected mesh; separate: one SDC mesh per camera, concatenated")
      ->check(CLI::IsMember({"zipper", "separate"}))
      ->capture_default_str();
  cmd->add_option("--filter", args->filter,
                  "Depth filter before triangulation: bilateral (the paper's square window), bilateral-separable (a row then a "
                  "column pass, 4.5x faster) or none")
      ->check(CLI::IsMember({"bilateral", "bilateral-separable", "none"}))
      ->capture_default_str();
  cmd->add_option("--format", args->format, "Mesh file format")->check(CLI::IsMember({"ply", "obj"}))->capture_default_str();
  cmd->add_option("--rig", args->rig,
                  "Take camera poses from this rig.json instead (e.g. CAPTURE/ground_truth/rig.json); with --live, the calibration "
                  "(camera i's name and pose)");
  cmd->add_option("--register", args->register_mode,
                  "Pose refinement by GPA-ICP: background (a worker thread, poses swapped in as they come), once (on the first frames), off, "
                  "or auto: background unless rig.json marks its poses as trusted (\"poses_trusted\": true, written by synth, calibrate and "
                  "register)")
      ->check(CLI::IsMember({"auto", "background", "once", "off"}))
      ->capture_default_str();
  cmd->add_option("--register-every", args->background.every_frames, "background: frames between two refinements")->capture_default_str();
  cmd->add_option("--register-window", args->background.window_frames, "background: newest offered frame sets refined together")
      ->capture_default_str();
  cmd->add_option("--min-depth", o.foreground.min_depth_m, "Nearest depth kept, metres")->capture_default_str();
  cmd->add_option("--max-depth", o.foreground.max_depth_m, "Farthest depth kept, metres")->capture_default_str();
  cmd->add_flag("--no-volume-crop", args->no_volume_crop, "Keep depth outside the rig's capture volume");
  cmd->add_option("--max-depth-jump", o.sdc.max_depth_jump_m, "SDC threshold: largest depth difference inside a triangle, metres")
      ->capture_default_str();
  cmd->add_option("--bilateral-sigma-px", o.filter.spatial_sigma_px, "Bilateral spatial sigma, pixels")->capture_default_str();
  cmd->add_option("--bilateral-radius", o.filter.radius_px, "Bilateral radius, pixels")->capture_default_str();
  cmd->add_option("--bilateral-range-sigma", o.filter.range_sigma_m, "Bilateral range sigma, metres")->capture_default_str();
  cmd->add_option("--redundancy-distance", o.zipper.redundancy_distance_m, "d_r: overlap closer than this is redundant, metres")
      ->capture_default_str();
  cmd->add_option("--coarse-levels", o.zipper.coarse_levels, "L: redundancy removal starts on depth downsampled by 2^L")->capture_default_str();
  cmd->add_option("--coarse-shrink", o.zipper.coarse_shrink, "beta: d_r at level l is beta^l d_r")->capture_default_str();
  cmd->add_option("--clipping-distance", o.zipper.clipping_distance_m, "d_c: triangles this close to another mesh are re-triangulated, metres")
      ->capture_default_str();
  cmd->add_option("--max-seam-edge", o.zipper.max_seam_edge_m, "Longest edge of a seam triangle, metres")->capture_default_str();
  cmd->add_option("--hole-closing", o.zipper.hole_closing_px, "Holes up to 2*this+1 pixels wide are not borders when judging which camera sees better")
      ->capture_default_str();
  cmd->add_option("--min-overlap", o.zipper.min_overlap_share, "Share of a mesh within d_r of another for the pair to be zippered")
      ->capture_default_str();
  cmd->add_option("--threads", o.num_threads, "Worker threads (0 = all cores)")->capture_default_str();
  cmd->callback([args] { run_reconstruct(*args); });
}

}  // namespace zipfusion::cli
