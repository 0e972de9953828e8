// zipfusion reconstruct: one mesh per frame of a capture, with per-stage timings in stats.json.

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/frame_range.h"
#include "cli/reconstruction_setup.h"
#include "zipfusion/core/error.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/mesh_io.h"
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
  std::string format = "ply";
  ReconstructionArgs reconstruction;
};

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

double median_of(std::vector<double> values) {
  if (values.empty()) return 0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

void run_reconstruct(ReconstructArgs& args) {
  const Capture capture = Capture::open(args.capture);
  const FrameRange range = parse_frame_range(args.frames, capture.frame_count());
  Reconstruction reconstruction(capture, args.reconstruction, range);
  FrameReconstructor& reconstructor = reconstruction.reconstructor();

  const fs::path out_dir = args.out;
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (!fs::is_directory(out_dir, ec)) throw IoError(out_dir.string() + ": cannot create output folder");

  nlohmann::ordered_json frames = nlohmann::json::array();
  std::vector<double> totals;
  const std::string extension = "." + args.format;
  // Decoding, reconstruction and writing overlap: each runs on its own thread.
  const PipelineStats pipeline = run_pipeline(capture_source(capture, range.begin, range.end), reconstructor, [&](PipelineFrame& frame) {
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
    show_progress("reconstruct", frame.index - range.begin + 1, range.end - range.begin);
  }, reconstruction.pipeline_options());

  const ReconstructionArgs& r = args.reconstruction;
  nlohmann::ordered_json stats;
  stats["capture"] = args.capture;
  stats["mode"] = r.mode;
  stats["filter"] = r.filter;
  stats["rig"] = r.rig.empty() ? (fs::path(args.capture) / "rig.json").string() : r.rig;
  stats["options"] = options_json(r.options);
  stats["register"] = reconstruction.register_mode();
  stats["pose_updates"] = reconstruction.pose_updates();
  stats["frames"] = frames;
  stats["median_total_ms"] = median_of(totals);
  stats["wall_ms"] = pipeline.wall_ms;
  write_file_atomic(out_dir / "stats.json", stats.dump(2) + "\n");
  std::cout << "wrote " << frames.size() << " meshes (" << r.mode << ") to " << out_dir.string() << ", median reconstruction "
            << median_of(totals) << " ms per frame set; timings in " << (out_dir / "stats.json").string() << "\n";
}

}  // namespace

void add_reconstruct_command(CLI::App& app) {
  auto args = std::make_shared<ReconstructArgs>();
  CLI::App* cmd = app.add_subcommand("reconstruct", "Reconstruct one mesh per frame of a capture");
  cmd->add_option("capture", args->capture, "Capture folder (with rig.json)")->required();
  cmd->add_option("--out", args->out, "Output folder: NNNNNN.ply per frame and stats.json")->required();
  cmd->add_option("--frames", args->frames, "Frames A:B (A included, B excluded; default all)");
  cmd->add_option("--format", args->format, "Mesh file format")->check(CLI::IsMember({"ply", "obj"}))->capture_default_str();
  add_reconstruction_options(cmd, args->reconstruction);
  cmd->callback([args] { run_reconstruct(*args); });
}

}  // namespace zipfusion::cli
