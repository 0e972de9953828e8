// zipfusion eval: quality of reconstructed meshes against a synthetic capture's ground truth.

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <set>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "cli/frame_range.h"
#include "zipfusion/core/error.h"
#include "zipfusion/eval/eval.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/mesh_io.h"

namespace zipfusion::cli {
namespace {

namespace fs = std::filesystem;

struct EvalArgs {
  std::string capture;
  std::string recon_dir;
  std::string frames;
  bool json = false;
  double completeness_mm = 10;
  double visibility_mm = 10;
  double spacing_mm = 4;
  double color_distance_mm = 10;
  EvalOptions options;
};

// A warning line where the reconstruction's stats.json names another capture folder that exists:
// meshes of one capture scored against another's truth gave 147 mm without a word (a review).
// Nothing is said where it cannot be told (no stats.json, live input, a folder no longer there).
void warn_if_made_of_another_capture(const fs::path& recon_dir, const fs::path& capture) {
  std::error_code ec;
  const fs::path stats_path = recon_dir / "stats.json";
  if (!fs::is_regular_file(stats_path, ec)) return;
  std::string made_of;
  try {
    const nlohmann::json stats = nlohmann::json::parse(read_file_bytes(stats_path));
    if (!stats.is_object() || !stats.contains("capture_folder") || !stats["capture_folder"].is_string()) return;
    made_of = stats["capture_folder"].get<std::string>();  // absolute
  } catch (const std::exception&) {
    return;  // not one of ours: eval does not need it
  }
  if (!fs::is_directory(made_of, ec)) return;
  const bool same = fs::equivalent(made_of, capture, ec);
  if (ec || same) return;
  print_diagnostic("eval: warning: " + stats_path.string() + " says these meshes were made of " + made_of + ", not " + capture.string());
}

// A warning line where the folder holds meshes numbered past the capture's last frame: they
// cannot be scored, and were left out without a word (a review: 10 meshes, 6 frames, "6 of 6").
void warn_of_meshes_beyond_capture(const fs::path& recon_dir, int frame_count) {
  std::set<int> beyond;  // frame numbers (a frame's .ply and .obj are one)
  std::error_code ec;
  for (const fs::directory_entry& entry : fs::directory_iterator(recon_dir, ec)) {
    if (const int frame = frame_index_of(entry.path(), {".ply", ".obj"}); frame >= frame_count) beyond.insert(frame);
  }
  if (beyond.empty()) return;
  const int count = static_cast<int>(beyond.size());
  print_diagnostic(format("eval: warning: %s: %d mesh%s numbered past the capture's last frame (%s), from %s on; not scored", recon_dir.c_str(),
                          count, count == 1 ? "" : "es", frame_file_name(frame_count - 1, "").c_str(), frame_file_name(*beyond.begin(), "").c_str()));
}

// A number for the table, or "-" when undefined.
std::string cell(const char* fmt, double value) { return std::isfinite(value) ? format(fmt, value) : "-"; }

// NaN and infinities as JSON null.
nlohmann::ordered_json number(double value) { return std::isfinite(value) ? nlohmann::ordered_json(value) : nlohmann::ordered_json(); }

// The reconstruction of a frame: RECON_DIR/NNNNNN.ply, else .obj; empty when neither exists.
fs::path reconstruction_path(const fs::path& dir, int frame) {
  fs::path found;
  for (const char* extension : {".ply", ".obj"}) {
    const fs::path path = dir / frame_file_name(frame, extension);
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) continue;
    // Two runs' meshes of one frame (reconstruct refuses to write the second into the first's folder).
    if (!found.empty()) throw InvalidInput(found.string() + ", " + path.filename().string() + ": two reconstructions of one frame; keep one");
    found = path;
  }
  return found;
}

// The per-frame values averaged over the frames with a reconstruction, each over those where it
// is defined; completeness over every frame (a missing one is 0), so that leaving a frame out
// cannot raise it, nor lower a count of defects.
struct MeanQuality {
  double triangles = 0, accuracy_mean_mm = 0, accuracy_p95_mm = 0, completeness = 0, area_ratio = 0;
  double reconstruction_area_m2 = 0, observed_true_area_m2 = 0, components = 0, large_components = 0;
  double non_manifold_edges = 0, folded_edges = 0, doubled_triangles = 0, color_error = 0;
};

MeanQuality mean_quality(const std::vector<FrameQuality>& frames, const std::vector<char>& present) {
  auto mean = [&](auto field, bool missing_counts = false) {
    double sum = 0;
    int count = 0;
    for (size_t i = 0; i < frames.size(); ++i) {
      if (!present[i] && !missing_counts) continue;
      const double value = static_cast<double>(frames[i].*field);
      if (!std::isfinite(value)) continue;
      sum += value;
      ++count;
    }
    return count ? sum / count : std::numeric_limits<double>::quiet_NaN();
  };
  return {.triangles = mean(&FrameQuality::triangles),
          .accuracy_mean_mm = mean(&FrameQuality::accuracy_mean_mm),
          .accuracy_p95_mm = mean(&FrameQuality::accuracy_p95_mm),
          .completeness = mean(&FrameQuality::completeness, true),
          .area_ratio = mean(&FrameQuality::area_ratio),
          .reconstruction_area_m2 = mean(&FrameQuality::reconstruction_area_m2),
          .observed_true_area_m2 = mean(&FrameQuality::observed_true_area_m2),
          .components = mean(&FrameQuality::components),
          .large_components = mean(&FrameQuality::large_components),
          .non_manifold_edges = mean(&FrameQuality::non_manifold_edges),
          .folded_edges = mean(&FrameQuality::folded_edges),
          .doubled_triangles = mean(&FrameQuality::doubled_triangles),
          .color_error = mean(&FrameQuality::color_error)};
}

void run_eval(EvalArgs& args) {
  EvalOptions& options = args.options;
  options.completeness_threshold_m = args.completeness_mm / 1000;
  options.visibility_tolerance_m = args.visibility_mm / 1000;
  options.sample_spacing_m = args.spacing_mm / 1000;
  options.color_max_distance_m = args.color_distance_mm / 1000;
  // The one check across two options; validate() would name EvalOptions' fields, not the flags.
  if (!(options.max_range_m > options.min_range_m)) throw InvalidInput("--max-range: must be above --min-range");
  options.validate();

  const Capture capture = Capture::open(args.capture);
  const fs::path truth_dir = fs::path(args.capture) / "ground_truth";
  if (!capture.ground_truth_rig_problem().empty()) throw InvalidInput(capture.ground_truth_rig_problem());
  if (!capture.ground_truth_rig()) {
    throw InvalidInput((truth_dir / "rig.json").string() + ": missing: eval needs a capture with ground truth (synth writes one)");
  }
  if (!capture.has_ground_truth_meshes()) {
    throw InvalidInput((truth_dir / "mesh").string() + ": missing: eval needs the true meshes (synth writes them)");
  }
  const Rig& true_rig = *capture.ground_truth_rig();
  const std::optional<Box3d>& volume = capture.rig().volume;
  check_input_folder(args.recon_dir, "a folder of reconstructions");
  warn_if_made_of_another_capture(args.recon_dir, args.capture);
  warn_of_meshes_beyond_capture(args.recon_dir, capture.frame_count());
  const FrameRange range = parse_frame_range(args.frames, capture.frame_count());

  // A frame without a reconstruction is scored as an empty mesh (nothing complete, no accuracy).
  std::vector<int> frames, missing;
  std::vector<fs::path> paths;  // per frame; empty where missing
  for (int frame = range.begin; frame < range.end; ++frame) {
    const fs::path path = reconstruction_path(args.recon_dir, frame);
    if (path.empty()) missing.push_back(frame);
    frames.push_back(frame);
    paths.push_back(path);
  }
  if (missing.size() == frames.size()) {
    throw InvalidInput(args.recon_dir + ": no reconstruction: expected " + frame_file_name(range.begin, ".ply") + " (or .obj) to " +
                       frame_file_name(range.end - 1, ".ply"));
  }

  std::vector<FrameQuality> results;
  for (size_t i = 0; i < frames.size(); ++i) {
    const TriangleMesh reconstruction = paths[i].empty() ? TriangleMesh{} : read_mesh(paths[i]);
    const TriangleMesh truth = read_mesh(capture.ground_truth_mesh_path(frames[i]));
    results.push_back(evaluate_frame(reconstruction, truth, true_rig, volume, options));
    show_progress("eval", static_cast<int>(i + 1), static_cast<int>(frames.size()));
  }
  std::vector<char> present;
  for (const fs::path& path : paths) present.push_back(!path.empty());
  const MeanQuality mean = mean_quality(results, present);

  if (args.json) {
    nlohmann::ordered_json out;
    out["capture"] = args.capture;
    out["reconstructions"] = args.recon_dir;
    out["options"] = {{"completeness_threshold_m", options.completeness_threshold_m},
                      {"visibility_tolerance_m", options.visibility_tolerance_m},
                      {"sample_spacing_m", options.sample_spacing_m},
                      {"color_max_distance_m", options.color_max_distance_m},
                      {"min_component_triangles", options.min_component_triangles},
                      {"min_range_m", options.min_range_m},
                      {"max_range_m", options.max_range_m}};
    out["frames"] = nlohmann::ordered_json::array();
    for (size_t i = 0; i < frames.size(); ++i) {
      const FrameQuality& q = results[i];
      out["frames"].push_back({{"frame", frames[i]},
                               {"file", paths[i].empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(paths[i].filename().string())},
                               {"triangles", q.triangles},
                               {"vertices", q.vertices},
                               {"accuracy_mean_mm", number(q.accuracy_mean_mm)},
                               {"accuracy_p95_mm", number(q.accuracy_p95_mm)},
                               {"completeness", number(q.completeness)},
                               {"area_ratio", number(q.area_ratio)},
                               {"reconstruction_area_m2", q.reconstruction_area_m2},
                               {"observed_true_area_m2", q.observed_true_area_m2},
                               {"true_area_m2", q.true_area_m2},
                               {"components", q.components},
                               {"large_components", q.large_components},
                               {"non_manifold_edges", q.non_manifold_edges},
                               {"folded_edges", q.folded_edges},
                               {"doubled_triangles", q.doubled_triangles},
                               {"color_error", number(q.color_error)},
                               {"color_vertices", q.color_vertices}});
    }
    out["mean"] = {{"frames", frames.size()},
                   {"triangles", number(mean.triangles)},
                   {"accuracy_mean_mm", number(mean.accuracy_mean_mm)},
                   {"accuracy_p95_mm", number(mean.accuracy_p95_mm)},
                   {"completeness", number(mean.completeness)},
                   {"area_ratio", number(mean.area_ratio)},
                   {"reconstruction_area_m2", number(mean.reconstruction_area_m2)},
                   {"observed_true_area_m2", number(mean.observed_true_area_m2)},
                   {"components", number(mean.components)},
                   {"large_components", number(mean.large_components)},
                   {"non_manifold_edges", number(mean.non_manifold_edges)},
                   {"folded_edges", number(mean.folded_edges)},
                   {"doubled_triangles", number(mean.doubled_triangles)},
                   {"color_error", number(mean.color_error)}};
    out["missing_frames"] = missing;
    std::cout << json_text(out, 2) << "\n";
    return;
  }

  std::cout << "capture          " << args.capture << " (" << true_rig.cameras.size() << " true cameras"
            << (volume ? ", inside the capture volume" : "") << ")\n";
  std::cout << "reconstructions  " << args.recon_dir << ": " << frames.size() - missing.size() << " of " << frames.size() << " frames"
            << (missing.empty() ? "" : " (a missing one is scored as an empty mesh)") << "\n";
  std::cout << format("observed         true surface seen by a camera within %.2f-%.2f m (depth tolerance %g mm); covered within %g mm\n",
                      options.min_range_m, options.max_range_m, args.visibility_mm, args.completeness_mm);
  std::cout << format("\n%6s %9s %9s %9s %9s %6s %12s %9s %7s %9s %7s\n", "", "in volume", "accuracy", "(mm)", "complete", "area", "components", "non-man.",
                      "folded", "doubled", "colour");
  std::cout << format("%6s %9s %9s %9s %9s %6s %12s %9s %7s %9s %7s\n", "frame", "triangles", "mean", "p95", "%", "ratio", "(large)", "edges", "edges",
                      "triangles", "error");
  for (size_t i = 0; i < frames.size(); ++i) {
    const FrameQuality& q = results[i];
    std::cout << format("%6d %9s %9s %9s %9s %6s %12s %9d %7d %9d %7s\n", frames[i], paths[i].empty() ? "missing" : std::to_string(q.triangles).c_str(), cell("%.2f", q.accuracy_mean_mm).c_str(),
                        cell("%.2f", q.accuracy_p95_mm).c_str(), cell("%.1f", 100 * q.completeness).c_str(), cell("%.2f", q.area_ratio).c_str(),
                        format("%d (%d)", q.components, q.large_components).c_str(), q.non_manifold_edges, q.folded_edges,
                        q.doubled_triangles, cell("%.1f", q.color_error).c_str());
  }
  std::cout << format("%6s %9s %9s %9s %9s %6s %12s %9s %7s %9s %7s\n", "mean", cell("%.0f", mean.triangles).c_str(),
                      cell("%.2f", mean.accuracy_mean_mm).c_str(), cell("%.2f", mean.accuracy_p95_mm).c_str(),
                      cell("%.1f", 100 * mean.completeness).c_str(), cell("%.2f", mean.area_ratio).c_str(),
                      format("%.1f (%.1f)", mean.components, mean.large_components).c_str(), cell("%.1f", mean.non_manifold_edges).c_str(),
                      cell("%.1f", mean.folded_edges).c_str(), cell("%.1f", mean.doubled_triangles).c_str(), cell("%.1f", mean.color_error).c_str());
  if (!missing.empty()) {
    std::string list;
    for (size_t i = 0; i < missing.size() && i < 20; ++i) list += (i ? ", " : "") + std::to_string(missing[i]);
    if (missing.size() > 20) list += ", ...";
    std::cout << "\nmissing reconstructions: " << missing.size() << (missing.size() == 1 ? " frame (" : " frames (") << list << ")\n";
  }
}

}  // namespace

void add_eval_command(CLI::App& app) {
  auto args = std::make_shared<EvalArgs>();
  EvalOptions& o = args->options;
  CLI::App* cmd = app.add_subcommand("eval", "Measure reconstructed meshes against a synthetic capture's ground truth");
  cmd->add_option("capture", args->capture, "Capture folder with ground_truth/ (as synth writes it)")->required();
  cmd->add_option("recon_dir", args->recon_dir, "Folder of reconstructions, one NNNNNN.ply or .obj per frame")->required();
  cmd->add_option("--frames", args->frames, "Frames A:B (B exclusive; 'A:', ':B' or 'N'); default all");
  cmd->add_flag("--json", args->json, "Print JSON instead of a table (completeness as a fraction, 0 to 1; other units in the keys)");
  add_threads_option(cmd, o.num_threads);
  cmd->add_option("--completeness-mm", args->completeness_mm, "A true point is covered when the reconstruction is this close, mm")
      ->check(kFiniteNumber & CLI::Range(0.01, 1000.0))
      ->capture_default_str();
  cmd->add_option("--visibility-mm", args->visibility_mm, "Depth tolerance of the test whether a camera sees a true point, mm")
      ->check(kFiniteNumber & CLI::Range(0.0, 1000.0))
      ->capture_default_str();
  cmd->add_option("--spacing-mm", args->spacing_mm, "Surfaces are sampled at about this spacing, mm")
      ->check(kFiniteNumber & CLI::Range(0.1, 1000.0))
      ->capture_default_str();
  cmd->add_option("--color-distance-mm", args->color_distance_mm, "Compare colours only of vertices this close to the truth, mm")
      ->check(kFiniteNumber & CLI::Range(0.0, 1000.0))
      ->capture_default_str();
  cmd->add_option("--min-component-triangles", o.min_component_triangles, "Components with at least this many triangles count as large")
      ->check(kWholeNumber)->check(CLI::Range(1, 1 << 30))
      ->capture_default_str();
  cmd->add_option("--min-range", o.min_range_m, "Cameras observe from this depth, metres")->check(kFiniteNumber & CLI::Range(0.0, 100.0))->capture_default_str();
  cmd->add_option("--max-range", o.max_range_m, "... to this depth, metres")->check(kFiniteNumber & CLI::Range(0.0, 100.0))->capture_default_str();
  cmd->callback([args] { run_eval(*args); });
}

}  // namespace zipfusion::cli
