// Micro-benchmarks of the per-frame kernels on one real frame set (samba-4cam frame 0, true
// poses), one camera for the per-camera kernels: Google Benchmark, single thread unless named.
// Run from anywhere: the capture is found through ZF_SOURCE_DIR.

#include <benchmark/benchmark.h>

#include <chrono>

#include "samba_frame.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/depth/bilateral.h"
#include "zipfusion/depth/color_lookup.h"
#include "zipfusion/depth/foreground.h"
#include "zipfusion/depth/sdc_mesh.h"
#include "zipfusion/fusion/zipper.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/pipeline/reconstruct.h"

namespace zipfusion {
namespace {

const SambaFrame& frame() {
  static const SambaFrame f = load_samba_frame(0);
  return f;
}

void BM_Foreground(benchmark::State& state) {
  const SambaFrame& f = frame();
  Image<float> out;
  for (auto _ : state) extract_foreground(f.frames.cameras[0].depth, f.rig.depth_unit_m, f.rig.cameras[0], f.rig.volume, {}, out);
}
BENCHMARK(BM_Foreground)->Unit(benchmark::kMillisecond);

// Level of detail 1: the full-resolution foreground to every second pixel, each the mean of its surface.
void BM_SubsampleDepth(benchmark::State& state) {
  const SambaFrame& f = frame();
  Image<float> out;
  // Same surface: the camera's full-resolution SDC threshold, as FrameReconstructor gives it.
  const float same_surface = static_cast<float>(f.sdc[0].max_depth_jump_m);
  for (auto _ : state) subsample_depth(f.foreground[0], 1, same_surface, out);
}
BENCHMARK(BM_SubsampleDepth)->Unit(benchmark::kMillisecond);

void BM_BilateralFilter(benchmark::State& state) {
  const SambaFrame& f = frame();
  const BilateralKernel kernel(BilateralOptions{});
  Image<float> out;
  for (auto _ : state) bilateral_filter(f.foreground[0], kernel, out);
}
BENCHMARK(BM_BilateralFilter)->Unit(benchmark::kMillisecond);

// The 5×5 window `zipfusion bench` also runs (σ 2 px, each pixel's 25 taps gathered).
void BM_BilateralFilter5x5(benchmark::State& state) {
  const SambaFrame& f = frame();
  const BilateralKernel kernel(BilateralOptions{.spatial_sigma_px = 2, .radius_px = 2});
  Image<float> out;
  for (auto _ : state) bilateral_filter(f.foreground[0], kernel, out);
}
BENCHMARK(BM_BilateralFilter5x5)->Unit(benchmark::kMillisecond);

void BM_TriangulateSdc(benchmark::State& state) {
  const SambaFrame& f = frame();
  DepthMesh mesh;
  for (auto _ : state) {
    triangulate_sdc(f.foreground[0], f.rig.cameras[0].depth_intrinsics, f.rig.cameras[0].world_from_depth.cast<float>(), f.sdc[0], mesh);
  }
}
BENCHMARK(BM_TriangulateSdc)->Unit(benchmark::kMillisecond);

void BM_LookupColors(benchmark::State& state) {
  const SambaFrame& f = frame();
  std::vector<Rgb8> colors;
  for (auto _ : state) lookup_colors(f.meshes[0], f.rig.cameras[0], &f.frames.cameras[0].color, colors);
}
BENCHMARK(BM_LookupColors)->Unit(benchmark::kMillisecond);

// The ownership scores on pyramid level 1, as the zipper computes them.
void BM_BorderDistance(benchmark::State& state) {
  const SambaFrame& f = frame();
  DepthMesh coarse;
  downsample_mesh(f.meshes[0], 1, depth_jump(SdcOptions{}), coarse);
  OwnershipScore border;
  for (auto _ : state) compute_border_distance(coarse, 1, 1, border);
}
BENCHMARK(BM_BorderDistance)->Unit(benchmark::kMillisecond);

void BM_Smoothness(benchmark::State& state) {
  const SambaFrame& f = frame();
  DepthMesh coarse;
  const ZipperOptions options;
  downsample_mesh(f.meshes[0], 1, depth_jump(options.sdc_max_depth_jump_m, options.sdc_growth_depth_m), coarse);
  // As zippering computes it, on level 1.
  const SmoothnessOptions smoothness_options{.window_cells = (options.smoothness_window_px >> 1) | 1,
                                             .exponent = static_cast<float>(options.smoothness_exponent),
                                             .same_surface_m = 2 * static_cast<float>(options.sdc_max_depth_jump_m)};
  OwnershipScore smoothness;
  for (auto _ : state) compute_smoothness(coarse, subsampled_intrinsics(f.rig.cameras[0].depth_intrinsics, 1), 1, smoothness_options, smoothness);
}
BENCHMARK(BM_Smoothness)->Unit(benchmark::kMillisecond);

void BM_DownsampleMesh(benchmark::State& state) {
  const SambaFrame& f = frame();
  DepthMesh coarse;
  for (auto _ : state) downsample_mesh(f.meshes[0], 2, depth_jump(SdcOptions{}), coarse);
}
BENCHMARK(BM_DownsampleMesh)->Unit(benchmark::kMillisecond);

// All of zippering (pyramid, pairs, FRBR, clipping, assembly) for the four cameras; Args =
// threads, ownership (0 border, 1 smoothness), depth (0 unfiltered, 1 bilateral-filtered). The
// reconstruction's defaults are smoothness for unfiltered and border for filtered depth; the seam
// smoothing is the reconstruction's default for the depth.
void BM_ZipperFourCameras(benchmark::State& state) {
  const SambaFrame& f = frame();
  ZipperScratch scratch;
  std::vector<DepthMesh> meshes;
  const ZipperOptions options{.ownership = state.range(1) ? Ownership::kSmoothness : Ownership::kBorder,
                              .seam_smoothing_px = ReconstructOptions{.bilateral = state.range(2) != 0}.seam_smoothing_px(),
                              .num_threads = static_cast<int>(state.range(0))};
  const std::vector<DepthMesh>& input = state.range(2) ? f.filtered_meshes : f.meshes;
  TriangleMesh reused;  // the output mesh's buffers, reused as the pipeline does
  for (auto _ : state) {
    state.PauseTiming();
    meshes = input;  // zippering clears bits: start each iteration from the same meshes
    std::vector<ZipperCamera> cameras;
    for (size_t c = 0; c < meshes.size(); ++c) cameras.push_back({&meshes[c], &f.frames.cameras[c].color, &f.rig.cameras[c], f.sdc[c].max_depth_jump_m});
    state.ResumeTiming();
    ZipperResult result = zipper_meshes(cameras, options, scratch, std::move(reused));
    benchmark::DoNotOptimize(result.mesh.triangles.data());
    reused = std::move(result.mesh);
  }
}
BENCHMARK(BM_ZipperFourCameras)
    ->Args({1, 0, 0})
    ->Args({2, 0, 0})
    ->Args({1, 1, 0})
    ->Args({2, 1, 0})
    ->Args({1, 0, 1})
    ->Args({2, 0, 1})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

// The cost of one parallel_for call as zippering makes them: two blocks of 50 µs each on two
// threads, then 100 µs of the caller's own sequential work before the next call. Without any
// overhead an iteration takes 150 µs; a worker that sleeps between calls and must be woken adds
// its wake-up time (docs/profile.md).
void busy_wait(std::chrono::microseconds duration) {
  const auto end = std::chrono::steady_clock::now() + duration;
  while (std::chrono::steady_clock::now() < end) {
  }
}

void BM_ParallelForTwoBlocks(benchmark::State& state) {
  for (auto _ : state) {
    parallel_for(0, 2, [](int) { busy_wait(std::chrono::microseconds(50)); }, 2);
    busy_wait(std::chrono::microseconds(100));
  }
}
BENCHMARK(BM_ParallelForTwoBlocks)->UseRealTime()->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace zipfusion

BENCHMARK_MAIN();
