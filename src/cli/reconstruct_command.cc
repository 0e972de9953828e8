// zipfusion reconstruct: one mesh per frame of a capture (or of live cameras, --live), with
// per-stage timings in stats.json.

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/frame_input.h"
#include "cli/live_devices.h"
#include "cli/reconstruction_setup.h"
#include "zipfusion/core/error.h"
#include "zipfusion/core/stopwatch.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/mesh_io.h"
#include "zipfusion/pipeline/pipeline.h"
#include "zipfusion/registration/gpa_icp.h"

namespace zipfusion::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct ReconstructArgs {
  InputArgs input;
  std::string out;
  std::string format = "ply";
  ReconstructionArgs reconstruction;
};


double median_of(std::vector<double> values) {
  if (values.empty()) return 0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

void write_reconstruction(ReconstructArgs& args, Input& in, Reconstruction& reconstruction, StagedFolder& out);

// eval reads every NNNNNN.ply or .obj of a folder: a mesh of an earlier run that this one would
// not replace (another frame, or the other format) would be measured with this run's. `range`:
// the frames this run writes (empty for live input, whose frames are not known in advance). What
// stands where this run's files go must be a file it can replace, found now, not after the work.
void check_no_earlier_meshes(const fs::path& out_dir, const std::string& extension, const FrameRange& range) {
  std::error_code ec;
  for (const fs::directory_entry& entry : fs::directory_iterator(out_dir, ec)) {
    const int frame = frame_index_of(entry.path(), {".ply", ".obj"});
    const bool ours = entry.path().filename() == "stats.json" || (frame >= 0 && entry.path().extension() == extension);
    if (ours && (entry.is_symlink(ec) || !entry.is_regular_file(ec))) {
      throw IoError(entry.path().string() + ": is not a file (a folder, link or device), so this run's file of that name would replace it, not write "
                    "into it; remove it or choose another --out");
    }
    if (frame < 0 || (entry.path().extension() == extension && frame >= range.begin && frame < range.end)) continue;
    throw InvalidInput(entry.path().string() + ": a mesh of an earlier run that this one would not replace (eval would measure both runs, or refuse a frame with both formats); "
                       "choose an empty --out or remove it");
  }
  if (ec) throw IoError(out_dir.string() + ": cannot list the output folder: " + ec.message());
}

void run_reconstruct(ReconstructArgs& args) {
  if (!args.input.live && args.input.seconds > 0) throw InvalidInput("--seconds: only with --live");
  ReconstructionArgs& r = args.reconstruction;
  Input in;
  // A signal stops the run at a frame boundary from here on (live input installs it as it opens).
  if (!args.input.live) install_stop_on_signal();
  open_input(args.input, r.rig, "reconstruct", in);
  warn_if_world_not_z_up(in.rig, r, "reconstruct");

  // The output folder is checked before the reconstruction is set up (--register once registers
  // the rig first, which takes seconds). The meshes and stats.json go into a staging folder and
  // appear together when the run ends: a run that fails part-way (a frame of the wrong size, a
  // full disk) leaves the folder as it was, and a second run into it is refused meanwhile.
  const fs::path out_dir = output_folder(args.out);  // "out/." could not be removed on failure; a link's folder is made where it points
  if (in.capture) in.capture->check_output_outside(out_dir, "--out");
  StagedFolder out(out_dir, "--out");
  for (const fs::path& killed : out.removed()) {
    print_diagnostic("reconstruct: warning: removed " + killed.string() + ", the unfinished meshes of a run that was killed");
  }
  // Errors name --out as given, not the hidden staging folder the files were written in.
  try {
    check_no_earlier_meshes(out_dir, "." + args.format, in.live ? FrameRange{} : in.range);
    Reconstruction reconstruction(in.rig, in.capture ? &*in.capture : nullptr, r, in.range, in.take_before_start);
    reconstruction.say_how_far_poses_moved("reconstruct");
    if (!in.live && stop_requested()) throw Interrupted("reconstruct: stopped by a signal before the first frame set; nothing written", stop_signal());
    write_reconstruction(args, in, reconstruction, out);
  } catch (const IoError& e) {
    throw IoError(out.in_user_terms(e.what()));
  } catch (const InvalidInput& e) {
    throw InvalidInput(out.in_user_terms(e.what()));
  }
}

// Reconstructs every frame set of `in` into `out` (NNNNNN.ply or .obj) and writes stats.json. A
// capture's meshes are staged and appear at the end; live meshes go straight into the folder, for
// a live session cannot be made again should the process be killed. A capture's run stopped by a
// signal keeps the frames it made, says so in stats.json and throws Interrupted.
void write_reconstruction(ReconstructArgs& args, Input& in, Reconstruction& reconstruction, StagedFolder& out) {
  ReconstructionArgs& r = args.reconstruction;
  const FrameRange& range = in.range;
  const fs::path& out_dir = out.dir();
  const fs::path& mesh_dir = in.live ? out_dir : out.staging();
  if (!in.live) {
    // Live input stops on the signal by itself (its sources watch the flag).
    in.source = [source = std::move(in.source)](FrameSet& set, double& decode_ms) {
      if (stop_requested()) return false;
      return source(set, decode_ms);
    };
  }

  nlohmann::ordered_json frames = nlohmann::json::array();
  std::vector<double> totals;
  const std::string extension = "." + args.format;
  PipelineOptions pipeline_options = reconstruction.pipeline_options();
  if (in.live) pipeline_options.source_policy = QueuePolicy::kDropOldest;  // the cameras do not wait
  // Decoding, reconstruction and writing overlap: each runs on its own thread.
  std::vector<int> remap;  // remove_unreferenced_vertices' scratch
  const PipelineStats pipeline = run_pipeline(in.source, reconstruction.reconstructor(), [&](PipelineFrame& frame) {
    const Clock::time_point write_start = Clock::now();
    remove_unreferenced_vertices(frame.result.mesh, remap);
    const FrameResult& result = frame.result;
    // Every frame's file has colours, an empty one (no camera in its frame set) too.
    write_mesh(mesh_dir / frame_file_name(frame.index, extension), result.mesh, {.colors_when_empty = true});
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
                                  {"seam_taken", result.zipper.seam_taken}, {"seam_added", result.zipper.seam_added},
                                  {"seam_pca", result.zipper.seam_pca}, {"seam_crease_gaps", result.zipper.seam_crease_gaps}}}});
    if (args.reconstruction.options.min_component_triangles > 1) frames.back()["small_component_triangles"] = result.small_component_triangles;
    if (in.live && in.skew_of(frame.index) >= 0) frames.back()["skew_ms"] = in.skew_of(frame.index);
    if (const std::vector<std::string> unreadable = in.unreadable_of(frame.index); !unreadable.empty()) frames.back()["unreadable_files"] = unreadable;
    if (range.end > range.begin) show_progress("reconstruct", frame.index - range.begin + 1, range.end - range.begin);
  }, pipeline_options);

  nlohmann::ordered_json stats;
  stats["capture"] = in.live ? "live" : args.input.capture;
  // eval tells meshes of another capture by it (the path as typed is relative to where this ran).
  if (!in.live) stats["capture_folder"] = fs::absolute(args.input.capture).lexically_normal().string();
  if (in.live) {
    nlohmann::ordered_json devices = nlohmann::json::array();
    const std::vector<LiveCameraStats> live_stats = in.live->stats();
    for (int c = 0; c < in.live->camera_count(); ++c) {
      devices.push_back({{"name", in.rig.cameras[c].name}, {"device", in.live->camera(c).description()}, {"frames", live_stats[c].frames},
                         {"dropped_by_camera", live_stats[c].dropped}, {"late", live_stats[c].discarded_late},
                         {"end_reason", live_stats[c].end_reason}});
    }
    stats["devices"] = devices;
    stats["dropped_frame_sets"] = pipeline.dropped;
  }
  stats["mode"] = r.mode;
  stats["filter"] = r.filter;
  stats["rig"] = r.rig.empty() ? (in.live ? std::string("identity poses") : (fs::path(args.input.capture) / "rig.json").string()) : r.rig;
  stats["options"] = options_json(r.options);  // as given
  // At a level of detail the lengths in pixels shrink: what ran is written beside what was asked.
  if (r.options.depth_level > 0) stats["options_applied"] = options_json(reconstruction.reconstructor().applied_options());
  // The SDC threshold each camera was triangulated with (from max_depth_jump_m and its focal length).
  nlohmann::ordered_json applied_jumps = nlohmann::ordered_json::array();
  for (int c = 0; c < static_cast<int>(in.rig.cameras.size()); ++c) applied_jumps.push_back(reconstruction.reconstructor().max_depth_jump_m(c));
  stats["max_depth_jump_m_per_camera"] = applied_jumps;
  stats["register"] = reconstruction.register_mode();
  stats["pose_updates"] = reconstruction.pose_updates();
  stats["refinement_before_first_frame_s"] = reconstruction.refinement_s();
  stats["register_every"] = r.background.every_frames;
  stats["register_window"] = r.background.window_frames;
  stats["register_min_improvement"] = r.background.min_improvement;
  stats["frames"] = frames;
  stats["median_total_ms"] = median_of(totals);
  stats["wall_ms"] = pipeline.wall_ms;
  if (!in.live) stats["unreadable_file_count"] = in.unreadable_count();
  const int wanted = range.end - range.begin;
  const bool interrupted = !in.live && static_cast<int>(frames.size()) < wanted && stop_requested();
  if (interrupted) stats["interrupted"] = true;
  write_file_atomic(out.staging() / "stats.json", json_text(stats, 2) + "\n");
  if (interrupted) {
    // Meshes of an earlier run for the frames this one did not reach (none staged) would stay
    // beside its own, and eval would measure both: they go, as the whole run would have replaced them.
    std::error_code ec;
    for (int f = range.begin; f < range.end; ++f) {
      const std::string name = frame_file_name(f, extension);
      if (!fs::exists(out.staging() / name, ec)) fs::remove(out_dir / name, ec);
    }
  }
  out.commit("stats.json");
  if (interrupted) {
    throw Interrupted("reconstruct: stopped by a signal after " + std::to_string(frames.size()) + " of " + std::to_string(wanted) +
                          " frame sets; wrote those to " + out_dir.string() + " with stats.json (\"interrupted\": true)",
                      stop_signal());
  }
  std::cout << "wrote " << frames.size() << (frames.size() == 1 ? " mesh (" : " meshes (") << r.mode << ") to " << out_dir.string()
            << format(", median reconstruction %.1f ms per frame set; timings in ", median_of(totals)) << (out_dir / "stats.json").string() << "\n";
  // --frames N is frame N alone, as in eval and register; a review expected the first N frames.
  const std::string& frames_given = args.input.frames;
  if (!in.live && !frames_given.empty() && frames_given.find(':') == std::string::npos && range.begin > 0) {
    std::cout << format("reconstruct: --frames %s is frame %d alone; --frames 0:%d gives the first %d\n", frames_given.c_str(), range.begin, range.begin, range.begin);
  }
  // (Not where --min-component dropped pieces: then that is why.)
  if (!frames.empty() && std::all_of(frames.begin(), frames.end(), [](const auto& f) {
        return f["triangles"] == 0 && f.value("small_component_triangles", 0) == 0;
      })) {
    // Depth in tenths of a millimetre read as millimetres, or a volume beside the subject, made
    // nothing but empty meshes without a word.
    const ForegroundOptions& depth = r.options.foreground;
    std::string where = format("between --min-depth %g and --max-depth %g m", depth.min_depth_m, depth.max_depth_m);
    if (depth.crop_to_volume && in.rig.volume) where += " inside the capture volume";
    if (!in.live) where += format(" (rig.json's depth_unit_m: %g m; `zipfusion info` shows where the depth lies)", in.rig.depth_unit_m);
    print_diagnostic("reconstruct: warning: every mesh is empty; is there depth " + where + "?");
  }
  if (const int unreadable = in.unreadable_count(); unreadable > 0) {
    const char* listed = unreadable > UnreadableFrames::kListed ? "the first listed above, all" : "listed above and";
    std::cout << "reconstruct: " << unreadable << " frame files could not be decoded (" << listed
              << " in stats.json); those frame sets were made without them\n";
  }
  if (in.live && pipeline.dropped > 0) {
    std::cout << "reconstruct: " << pipeline.dropped << " live frame sets were dropped because reconstruction fell behind the cameras\n";
  }
}

}  // namespace

void add_reconstruct_command(CLI::App& app) {
  auto args = std::make_shared<ReconstructArgs>();
  CLI::App* cmd = app.add_subcommand("reconstruct", "Reconstruct one mesh per frame of a capture (or of live cameras)");
  add_input_options(cmd, args->input);
  cmd->add_option("--out", args->out, "Output folder: NNNNNN.ply per frame and stats.json")->required();
  cmd->add_option("--format", args->format, "Mesh file format")->check(CLI::IsMember({"ply", "obj"}))->capture_default_str();
  add_reconstruction_options(cmd, args->reconstruction);
  cmd->callback([args] { run_reconstruct(*args); });
}

}  // namespace zipfusion::cli
