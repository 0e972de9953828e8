// zipfusion bench: per-stage timings of the reconstruction on a capture, in the style of the
// paper's Tables III–V, with the configurations side by side, frame rate and memory.

#include <sys/resource.h>
#include <sys/utsname.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <map>

#include "cli/commands.h"
#include "cli/frame_input.h"
#include "cli/rig_poses.h"
#include "zipfusion/core/error.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/pipeline/pipeline.h"

namespace zipfusion::cli {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct BenchArgs {
  std::string capture;
  std::string rig;
  int frames = 30;
  bool frames_given = false;  // --frames on the command line: more than the capture has is an error
  int repeat = 3;
  int soak = 0;
  int threads = 0;
  bool json = false;
};

struct Percentiles {
  double median = 0;
  double p95 = 0;
};

Percentiles percentiles(std::vector<double> values) {
  if (values.empty()) return {};
  std::sort(values.begin(), values.end());
  // Nearest rank: the smallest value with at least a share q of the values at or below it.
  auto at = [&](double q) {
    const size_t rank = static_cast<size_t>(std::ceil(q * static_cast<double>(values.size())));
    return values[std::clamp<size_t>(rank, 1, values.size()) - 1];
  };
  return {at(0.5), at(0.95)};
}

// The stages of StageTimes, in pipeline order, with the paper's names.
const std::vector<std::pair<std::string, double StageTimes::*>> kStages = {
    {"foreground", &StageTimes::foreground_ms}, {"filter", &StageTimes::filter_ms},         {"triangulate", &StageTimes::triangulate_ms},
    {"color", &StageTimes::color_ms},           {"overlap", &StageTimes::overlap_ms},       {"redundancy", &StageTimes::redundancy_ms},
    {"clipping", &StageTimes::clipping_ms},     {"assemble", &StageTimes::assemble_ms},     {"total", &StageTimes::total_ms}};

// Issue 4's figure: the two zippering stages added up per frame set, then their median. The sum of
// the two stages' medians is not it, since a frame set slow in one need not be slow in the other.
constexpr const char* kRedundancyPlusClipping = "redundancy+clipping";

// What the report gives for each configuration, in its order: the stages, then issue 4's figure.
std::vector<std::string> reported_rows() {
  std::vector<std::string> rows;
  for (const auto& [name, field] : kStages) rows.push_back(name);
  rows.push_back(kRedundancyPlusClipping);
  return rows;
}

struct BenchConfig {
  std::string name;
  ReconstructOptions options;
};

struct ConfigResult {
  std::string name;
  std::map<std::string, Percentiles> stages;
  double triangles = 0;
  double pairs = 0;  // overlapping camera pairs the zipper found (0 for separate meshes)
  double fps = 0;
  double stolen_share = 0;  // of all CPU time while this configuration ran (cpu_times)
};

// The machine's CPU time so far, in clock ticks: all of it, and the part "stolen", that a virtual
// machine's CPUs wanted but the hypervisor gave to others (/proc/stat). On a shared host that
// part inflates wall-clock times, so timings are comparable only where it is small. Zero where
// /proc/stat cannot be read.
struct CpuTimes {
  long long total = 0;
  long long steal = 0;
};

CpuTimes cpu_times() {
  std::ifstream stat("/proc/stat");
  std::string label;
  CpuTimes times;
  if (!(stat >> label) || label != "cpu") return times;
  // user nice system idle iowait irq softirq steal (guest time is counted in user already)
  for (int field = 0; field < 8; ++field) {
    long long ticks = 0;
    if (!(stat >> ticks)) return {};
    times.total += ticks;
    if (field == 7) times.steal = ticks;
  }
  return times;
}

double resident_mb() {
  std::ifstream statm("/proc/self/statm");
  long pages = 0, resident = 0;
  statm >> pages >> resident;
  return static_cast<double>(resident) * static_cast<double>(::sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

double peak_resident_mb() {
  rusage usage{};
  ::getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // kilobytes on Linux
}

std::string cpu_model() {
  std::ifstream cpuinfo("/proc/cpuinfo");
  std::string line;
  while (std::getline(cpuinfo, line)) {
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  }
  return "unknown CPU";
}

ConfigResult run_config(const BenchConfig& config, const Rig& rig, const std::vector<FrameSet>& frames, int repeat) {
  const CpuTimes before = cpu_times();
  FrameReconstructor reconstructor(rig, config.options);
  reconstructor.recycle(reconstructor.reconstruct(frames.front()).mesh);  // buffers sized: steady state
  std::map<std::string, std::vector<double>> samples;
  std::vector<double> triangles, pairs;
  for (int pass = 0; pass < repeat; ++pass) {
    for (const FrameSet& set : frames) {
      FrameResult result = reconstructor.reconstruct(set);
      for (const auto& [name, field] : kStages) samples[name].push_back(result.times.*field);
      samples[kRedundancyPlusClipping].push_back(result.times.redundancy_ms + result.times.clipping_ms);
      triangles.push_back(static_cast<double>(result.mesh.triangle_count()));
      pairs.push_back(result.zipper.pairs);
      reconstructor.recycle(std::move(result.mesh));  // as the pipeline does after its sink
    }
  }
  ConfigResult out{.name = config.name};
  for (const auto& [name, values] : samples) out.stages[name] = percentiles(values);
  out.triangles = percentiles(triangles).median;
  out.pairs = percentiles(pairs).median;
  out.fps = out.stages["total"].median > 0 ? 1000.0 / out.stages["total"].median : 0;
  const CpuTimes after = cpu_times();
  // Clamped: some kernels' steal counter has been seen to step back.
  if (after.total > before.total) {
    out.stolen_share = std::clamp(static_cast<double>(after.steal - before.steal) / static_cast<double>(after.total - before.total), 0.0, 1.0);
  }
  return out;
}

// The kernel, as `uname -sr` prints it: timings move with it.
std::string operating_system() {
  utsname name{};
  if (uname(&name) != 0) return "unknown";
  return std::string(name.sysname) + " " + name.release;
}

// Today's date in UTC, YYYY-MM-DD: when the timings were taken (a report may be written later).
std::string utc_date() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[16];
  std::strftime(text, sizeof text, "%Y-%m-%d", &utc);
  return text;
}

void run_bench(const BenchArgs& args) {
  if (args.frames < 1) throw InvalidInput("--frames: must be at least 1");
  if (args.repeat < 1) throw InvalidInput("--repeat: must be at least 1");
  if (args.soak < 0) throw InvalidInput("--soak: must be 0 or more");
  if (args.threads < 0) throw InvalidInput("--threads: must be 0 (all cores) or more");
  Capture capture = open_capture(args.capture, "bench");
  const Rig rig = calibrated_rig(capture, args.rig);
  if (args.frames_given && args.frames > capture.frame_count()) {
    throw InvalidInput("--frames: " + std::to_string(args.frames) + " reaches past the last frame of a capture with " +
                       std::to_string(capture.frame_count()) + " frames (" + (capture.dir() / "rig.json").string() + ")");
  }
  const int count = std::min(args.frames, capture.frame_count());
  if (count == 0) throw InvalidInput((capture.dir() / "rig.json").string() + ": frame_count: is 0, nothing to time");

  // Decoding, separately from reconstruction: each frame set's cameras in parallel.
  std::vector<FrameSet> frames;
  std::vector<double> decode_ms;
  const FrameSource source = capture_source(capture, 0, count);
  double ms = 0;
  UnreadableFrames unreadable("bench");
  // Decoded into the same frame set each time, as the pipeline's recycled sets are (its buffers
  // already there); a copy kept for every configuration, outside the time.
  for (FrameSet set; source(set, ms);) {
    unreadable.report(capture.rig(), set);
    frames.push_back(set);
    decode_ms.push_back(ms);
    show_progress("decode", static_cast<int>(frames.size()), count);
  }

  auto options = [&](ReconstructMode mode, bool bilateral) {
    ReconstructOptions o;
    o.mode = mode;
    o.bilateral = bilateral;
    o.num_threads = args.threads;
    return o;
  };
  std::vector<BenchConfig> configs = {
      {"zipper+filter", options(ReconstructMode::kZipper, true)},
      {"zipper", options(ReconstructMode::kZipper, false)},
      {"separate+filter", options(ReconstructMode::kSeparate, true)},
      {"separate", options(ReconstructMode::kSeparate, false)},
  };
  // Unfiltered, ownership by smoothness (the default) against by border distance (the default
  // with the filter): quality for time.
  configs.push_back({"zipper border ownership", options(ReconstructMode::kZipper, false)});
  configs.back().options.zipper.ownership = Ownership::kBorder;
  configs.push_back({"zipper+separable filter", options(ReconstructMode::kZipper, true)});
  configs.back().options.filter.separable = true;
  // The filter over 5×5 pixels (σ 2 px) instead of the paper's 13×13 (σ 4 px): on samba-4cam more
  // accurate and more complete, at a quarter of the filter's time (docs/design.md).
  for (const auto& [name, mode] : {std::pair{"zipper+5x5 filter", ReconstructMode::kZipper}, std::pair{"separate+5x5 filter", ReconstructMode::kSeparate}}) {
    configs.push_back({name, options(mode, true)});
    configs.back().options.filter.radius_px = 2;
    configs.back().options.filter.spatial_sigma_px = 2;
  }
  configs.push_back({"zipper 1 thread", options(ReconstructMode::kZipper, false)});
  configs.back().options.num_threads = 1;
  configs.push_back({"zipper no coarse-to-fine", options(ReconstructMode::kZipper, false)});
  configs.back().options.zipper.coarse_levels = 0;
  // Level of detail 1 (`--lod 1`): every second depth pixel, each the mean of its surface around
  // it; a quarter of the triangles, about as many as Open3D's TSDF at 10 mm.
  configs.push_back({"zipper lod 1", options(ReconstructMode::kZipper, false)});
  configs.back().options.depth_level = 1;
  configs.push_back({"zipper+filter lod 1", options(ReconstructMode::kZipper, true)});
  configs.back().options.depth_level = 1;
  // `--min-component 50`: pieces of fewer than 50 triangles dropped after assembly (specks of
  // noise); its cost is in the assembly stage.
  configs.push_back({"zipper min component 50", options(ReconstructMode::kZipper, false)});
  configs.back().options.min_component_triangles = 50;

  std::vector<ConfigResult> results;
  for (size_t i = 0; i < configs.size(); ++i) {
    results.push_back(run_config(configs[i], rig, frames, args.repeat));
    show_progress("bench", static_cast<int>(i + 1), static_cast<int>(configs.size()));
  }

  // Memory over a long run: the resident size must not grow once buffers are sized.
  nlohmann::ordered_json soak = nullptr;
  if (args.soak > 0) {
    FrameReconstructor reconstructor(rig, configs[0].options);
    const int early = std::min(100, args.soak);
    double at_early = 0;
    for (int i = 0; i < args.soak; ++i) {
      FrameResult result = reconstructor.reconstruct(frames[i % frames.size()]);
      reconstructor.recycle(std::move(result.mesh));
      if (i + 1 == early) at_early = resident_mb();
      if ((i + 1) % 50 == 0) show_progress("soak", i + 1, args.soak);
    }
    soak = {{"frames", args.soak}, {"early_frames", early}, {"rss_mb_early", at_early}, {"rss_mb_at_end", resident_mb()}};
  }

  const Percentiles decode = percentiles(decode_ms);
  nlohmann::ordered_json report;
  report["date"] = utc_date();
  report["machine"] = {{"cpu", cpu_model()}, {"hardware_threads", hardware_threads()}, {"os", operating_system()}};
  report["capture"] = args.capture;
  report["cameras"] = capture.camera_count();
  report["depth_size"] = std::to_string(rig.cameras[0].depth_intrinsics.width) + "x" + std::to_string(rig.cameras[0].depth_intrinsics.height);
  report["frames"] = count;
  report["repeat"] = args.repeat;
  report["decode_ms"] = {{"median", decode.median}, {"p95", decode.p95}};
  for (const ConfigResult& r : results) {
    nlohmann::ordered_json stages;
    for (const std::string& name : reported_rows()) stages[name] = {{"median", r.stages.at(name).median}, {"p95", r.stages.at(name).p95}};
    report["configs"].push_back({{"name", r.name}, {"ms", stages}, {"fps", r.fps}, {"triangles", r.triangles}, {"pairs", r.pairs},
                                 {"cpu_stolen_share", r.stolen_share}});
  }
  report["peak_rss_mb"] = peak_resident_mb();
  report["soak"] = soak;

  if (args.json) {
    std::cout << json_text(report, 2) << "\n";
    return;
  }
  std::printf("%s, %d hardware threads\n%s: %d cameras, depth %s, %d frame sets x %d passes; decode %.1f ms median (%.1f p95) per frame set\n\n",
              cpu_model().c_str(), hardware_threads(), args.capture.c_str(), capture.camera_count(), report["depth_size"].get<std::string>().c_str(),
              count, args.repeat, decode.median, decode.p95);
  // Five configurations a block, so that the table fits a terminal.
  constexpr size_t kBlock = 5;
  for (size_t first = 0; first < results.size(); first += kBlock) {
    const size_t last = std::min(results.size(), first + kBlock);
    std::printf("%s%-13s", first == 0 ? "" : "\n\n", "ms median/p95");
    for (size_t i = first; i < last; ++i) std::printf(" %24s", results[i].name.c_str());
    std::printf("\n");
    for (const std::string& name : reported_rows()) {
      std::printf("%-13s", name == kRedundancyPlusClipping ? "redund+clip" : name.c_str());
      for (size_t i = first; i < last; ++i) std::printf("              %5.1f/%5.1f", results[i].stages.at(name).median, results[i].stages.at(name).p95);
      std::printf("\n");
    }
    std::printf("%-13s", "fps");
    for (size_t i = first; i < last; ++i) std::printf(" %24.1f", results[i].fps);
    std::printf("\n%-13s", "triangles");
    for (size_t i = first; i < last; ++i) std::printf(" %24.0f", results[i].triangles);
    std::printf("\n%-13s", "CPU stolen %");
    for (size_t i = first; i < last; ++i) std::printf(" %24.1f", 100.0 * results[i].stolen_share);
  }
  std::printf("\n\npeak resident memory %.0f MB", peak_resident_mb());
  if (args.soak > 0) {
    std::printf("; resident after %d frame sets %.0f MB, after %d %.0f MB", soak["early_frames"].get<int>(), soak["rss_mb_early"].get<double>(),
                args.soak, soak["rss_mb_at_end"].get<double>());
  }
  std::printf("\n");
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto args = std::make_shared<BenchArgs>();
  CLI::App* cmd = app.add_subcommand("bench", "Time every stage of the reconstruction on a capture (median and 95th percentile)");
  cmd->add_option("capture", args->capture, "Capture folder (with rig.json)")->required();
  const CLI::Option* frames = cmd->add_option("--frames", args->frames, "Frame sets to load (the first N; by default as many of 30 as the capture has), decoded once")
                                  ->capture_default_str();
  cmd->add_option("--repeat", args->repeat, "Passes over the frame sets per configuration")->capture_default_str();
  cmd->add_option("--rig", args->rig, "Take the calibration (poses, intrinsics, volume) from this rig.json (e.g. CAPTURE/ground_truth/rig.json)");
  cmd->add_option("--soak", args->soak, "Also reconstruct this many frame sets in a row and report resident memory at 100 and at the end")
      ->capture_default_str();
  add_threads_option(cmd, args->threads);
  cmd->add_flag("--json", args->json, "Print JSON instead of a table");
  cmd->callback([args, frames] {
    args->frames_given = frames->count() > 0;
    run_bench(*args);
  });
}

}  // namespace zipfusion::cli
