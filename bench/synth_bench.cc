// Micro-benchmarks of the capture I/O and synthesis kernels (Google Benchmark).

#include <benchmark/benchmark.h>

#include "zipfusion/io/image_io.h"
#include "zipfusion/core/rasterizer.h"
#include "zipfusion/synth/synth.h"

namespace zipfusion {
namespace {

struct Scene {
  SynthOptions options;
  Rig rig = make_ring_rig(options);
  TriangleMesh subject = subject_mesh(options, 0);
  SyntheticView view = render_view(subject, rig, 0, 0, options);
};

const Scene& scene() {
  static const Scene s;
  return s;
}

void BM_MakeHuman(benchmark::State& state) {
  double t = 0;
  for (auto _ : state) benchmark::DoNotOptimize(make_human(t += 0.033));
}
BENCHMARK(BM_MakeHuman)->Unit(benchmark::kMillisecond);

void BM_RasterizeSubject(benchmark::State& state) {
  const Scene& s = scene();
  const CameraModel& cam = s.rig.cameras[0];
  RenderBuffers buffers;
  for (auto _ : state) {
    buffers.reset(cam.depth_intrinsics, false);
    rasterize_mesh(s.subject, cam.depth_intrinsics, cam.world_from_depth.inverse(), buffers);
    benchmark::DoNotOptimize(buffers.depth.data.data());
  }
}
BENCHMARK(BM_RasterizeSubject)->Unit(benchmark::kMillisecond);

void BM_RenderKinectView(benchmark::State& state) {
  const Scene& s = scene();
  for (auto _ : state) benchmark::DoNotOptimize(render_view(s.subject, s.rig, 0, 0, s.options));
}
BENCHMARK(BM_RenderKinectView)->Unit(benchmark::kMillisecond);

void BM_DecodeDepthPng(benchmark::State& state) {
  const std::vector<std::uint8_t> png = encode_depth_png(scene().view.depth);
  for (auto _ : state) benchmark::DoNotOptimize(decode_depth_png(png, "bench"));
}
BENCHMARK(BM_DecodeDepthPng)->Unit(benchmark::kMillisecond);

void BM_DecodeColorJpeg(benchmark::State& state) {
  const std::vector<std::uint8_t> jpg = encode_color_image(scene().view.color, ".jpg", 90);
  for (auto _ : state) benchmark::DoNotOptimize(decode_color_image(jpg, "bench"));
}
BENCHMARK(BM_DecodeColorJpeg)->Unit(benchmark::kMillisecond);

// The same two decodes as the pipeline makes them: one ImageDecoder, into the same image each
// time (its buffers, and libpng's memory, kept).
template <typename ImageT>
void decode_reused(benchmark::State& state, const std::vector<std::uint8_t>& bytes,
                   void (ImageDecoder::*decode)(std::span<const std::uint8_t>, const std::string&, ImageT&)) {
  ImageDecoder decoder;
  ImageT image;
  for (auto _ : state) {
    (decoder.*decode)(bytes, "bench", image);
    benchmark::DoNotOptimize(image.data.data());
  }
}

void BM_DecodeDepthPngReused(benchmark::State& state) {
  decode_reused(state, encode_depth_png(scene().view.depth), &ImageDecoder::decode_depth_png);
}
BENCHMARK(BM_DecodeDepthPngReused)->Unit(benchmark::kMillisecond);

void BM_DecodeColorJpegReused(benchmark::State& state) {
  decode_reused(state, encode_color_image(scene().view.color, ".jpg", 90), &ImageDecoder::decode_color_image);
}
BENCHMARK(BM_DecodeColorJpegReused)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace zipfusion

BENCHMARK_MAIN();
