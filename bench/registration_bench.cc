// One GPA-ICP refinement on samba-4cam (Google Benchmark): four 640×480 depth frames of one frame
// set in, four refined poses out, from the perturbed rig.json. Timed: foreground extraction and the
// whole coarse-to-fine refinement. Arg: the finest level (1 = the default, 2 = the background
// thread's). Counters: the worst camera's error against ground truth after the refinement.
// Run from anywhere: the capture is found through ZF_SOURCE_DIR.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <filesystem>

#include "zipfusion/io/capture.h"
#include "zipfusion/registration/gpa_icp.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

struct Data {
  Rig rig;
  Rig truth;
  FrameSet frames;
};

const Data& data() {
  static const Data d = [] {
    const Capture capture = Capture::open(fs::path(ZF_SOURCE_DIR) / ".." / "shared" / "data" / "samba-4cam");
    return Data{capture.rig(), capture.ground_truth_rig().value_or(capture.rig()), capture.load_frame(0)};
  }();
  return d;
}

void BM_RegisterOneFrameSet(benchmark::State& state) {
  const Data& d = data();
  RegistrationOptions options;
  options.finest_level = static_cast<int>(state.range(0));
  options.validate();
  RegistrationResult result;
  for (auto _ : state) {
    const std::vector<std::vector<Image<float>>> depth{registration_depth(d.rig, d.frames, options)};
    result = register_rig(d.rig, depth, options);
    benchmark::DoNotOptimize(result);
  }
  std::vector<Rigid3d> truth;
  for (const CameraModel& cam : d.truth.cameras) truth.push_back(cam.world_from_depth);
  double worst_mm = 0, worst_deg = 0;
  for (const RelativePoseError& e : relative_pose_errors(result.world_from_depth, truth)) {
    worst_mm = std::max(worst_mm, e.translation_m * 1000);
    worst_deg = std::max(worst_deg, e.rotation_deg);
  }
  state.counters["worst_mm"] = worst_mm;
  state.counters["worst_deg"] = worst_deg;
  state.counters["iterations"] = result.iterations;
}
BENCHMARK(BM_RegisterOneFrameSet)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace zipfusion

BENCHMARK_MAIN();
