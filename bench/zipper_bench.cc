// Whole-frame pipeline benchmark on samba-4cam (Google Benchmark): one frame set of four cameras
// in, one mesh out, in the separate and the zipper mode, with the bilateral filter off (Arg 0) and
// on (Arg 1). Per-stage times are reported as counters, like the paper's Table IV: each is the
// mean over the iterations of a run; with --benchmark_repetitions the aggregates give their
// median over runs.
//
// Frames are decoded once, outside the timed loop; the iterations rotate over kFrameCount of them.
// Poses are the capture's ground truth (ground_truth/rig.json) with the main rig's volume.
// Run from anywhere: the capture is found through ZF_SOURCE_DIR.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <filesystem>
#include <vector>

#include "zipfusion/io/capture.h"
#include "zipfusion/pipeline/reconstruct.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

constexpr int kFrameCount = 8;

struct Data {
  Rig rig;
  std::vector<FrameSet> frames;
};

const Data& data() {
  static const Data d = [] {
    const Capture capture = Capture::open(fs::path(ZF_SOURCE_DIR) / ".." / "shared" / "data" / "samba-4cam");
    Data result;
    result.rig = capture.ground_truth_rig().value_or(capture.rig());
    result.rig.volume = capture.rig().volume;
    // Spread over the sequence so the subject's poses differ.
    const int step = std::max(1, capture.frame_count() / kFrameCount);
    for (int k = 0; k < kFrameCount; ++k) result.frames.push_back(capture.load_frame((k * step) % capture.frame_count()));
    return result;
  }();
  return d;
}

void run_frames(benchmark::State& state, ReconstructMode mode) {
  const Data& d = data();
  FrameReconstructor reconstructor(d.rig, {.mode = mode, .bilateral = state.range(0) != 0});
  benchmark::DoNotOptimize(reconstructor.reconstruct(d.frames[0]));  // buffers sized: steady state

  StageTimes sum;
  double triangles = 0;
  size_t next = 0;
  for (auto _ : state) {
    const FrameResult result = reconstructor.reconstruct(d.frames[next]);
    next = (next + 1) % d.frames.size();
    const StageTimes& t = result.times;
    sum.foreground_ms += t.foreground_ms;
    sum.filter_ms += t.filter_ms;
    sum.triangulate_ms += t.triangulate_ms;
    sum.color_ms += t.color_ms;
    sum.overlap_ms += t.overlap_ms;
    sum.redundancy_ms += t.redundancy_ms;
    sum.clipping_ms += t.clipping_ms;
    sum.assemble_ms += t.assemble_ms;
    sum.total_ms += t.total_ms;
    triangles += static_cast<double>(result.mesh.triangle_count());
    benchmark::DoNotOptimize(result.mesh.positions.data());
  }

  auto avg = [](double value) { return benchmark::Counter(value, benchmark::Counter::kAvgIterations); };
  state.counters["foreground_ms"] = avg(sum.foreground_ms);
  state.counters["filter_ms"] = avg(sum.filter_ms);
  state.counters["triangulate_ms"] = avg(sum.triangulate_ms);
  state.counters["color_ms"] = avg(sum.color_ms);
  state.counters["overlap_ms"] = avg(sum.overlap_ms);
  state.counters["redundancy_ms"] = avg(sum.redundancy_ms);
  state.counters["clipping_ms"] = avg(sum.clipping_ms);
  state.counters["assemble_ms"] = avg(sum.assemble_ms);
  state.counters["total_ms"] = avg(sum.total_ms);
  state.counters["triangles"] = avg(triangles);
}

void BM_FrameSeparate(benchmark::State& state) { run_frames(state, ReconstructMode::kSeparate); }
BENCHMARK(BM_FrameSeparate)->ArgName("bilateral")->Arg(0)->Arg(1)->UseRealTime()->Unit(benchmark::kMillisecond);

void BM_FrameZipper(benchmark::State& state) { run_frames(state, ReconstructMode::kZipper); }
BENCHMARK(BM_FrameZipper)->ArgName("bilateral")->Arg(0)->Arg(1)->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace zipfusion

BENCHMARK_MAIN();
