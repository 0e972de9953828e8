// The stream's compression on a real capture: each frame set reconstructed at level of detail 0
// and 1 (default options, true poses), compressed with Draco as `zipfusion serve` does (11-bit
// positions over the capture volume, compression level 4): size, encoding time, and the largest
// distance of a decoded vertex from the reconstructed surface against the quantisation bound.
// Usage: zf_draco_bench CAPTURE [--frames N] [--compression-level L] [--json]

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "zipfusion/core/mesh_distance.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/draco_codec.h"
#include "zipfusion/pipeline/reconstruct.h"

int main(int argc, char** argv) {
  using namespace zipfusion;
  if (argc < 2) {
    std::fprintf(stderr, "usage: zf_draco_bench CAPTURE [--frames N] [--compression-level L] [--json]\n");
    return 2;
  }
  int frames = 40;
  bool json = false;
  DracoOptions draco;
  for (int i = 2; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--frames") && i + 1 < argc) frames = std::atoi(argv[++i]);
    if (!std::strcmp(argv[i], "--compression-level") && i + 1 < argc) {
      char* end = nullptr;
      const char* value = argv[++i];
      draco.compression_level = static_cast<int>(std::strtol(value, &end, 10));
      if (end == value || *end != '\0') draco.compression_level = -1;  // not a number: validate() names the option
    }
    if (!std::strcmp(argv[i], "--json")) json = true;
  }
  std::optional<Capture> opened;
  try {
    draco.validate();
    opened.emplace(Capture::open(argv[1]));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "zf_draco_bench: %s\n", e.what());
    return 2;
  }
  const Capture& capture = *opened;
  Rig rig = capture.ground_truth_rig().value_or(capture.rig());
  rig.volume = capture.rig().volume;
  frames = std::min(frames, capture.frame_count());
  nlohmann::ordered_json result;
  float bound = 0;
  for (const int lod : {0, 1}) {
    FrameReconstructor reconstructor(rig, {.depth_level = lod});
    double triangles = 0, bytes = 0, worst = 0;
    std::vector<double> encode_ms;
    for (int f = 0; f < frames; ++f) {
      const TriangleMesh mesh = reconstructor.reconstruct(capture.load_frame(f)).mesh;
      const QuantizationBox box = quantization_box(mesh, rig.volume);
      bound = box.max_error(draco.position_bits);
      const auto t0 = std::chrono::steady_clock::now();
      const std::string encoded = encode_draco(mesh, box, draco);
      encode_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      const TriangleMesh back = decode_draco(encoded);
      const MeshDistance surface(mesh);
      for (const Eigen::Vector3f& p : back.positions) worst = std::max<double>(worst, surface.closest(p, 0.01f).distance);
      triangles += static_cast<double>(mesh.triangle_count()) / frames;
      bytes += static_cast<double>(encoded.size()) / frames;
    }
    std::sort(encode_ms.begin(), encode_ms.end());
    result["lod" + std::to_string(lod)] = {{"triangles", triangles}, {"kb", bytes / 1024}, {"encode_ms", encode_ms[encode_ms.size() / 2]},
                                           {"max_error_mm", worst * 1000}};
  }
  result["bound_mm"] = bound * 1000;
  result["compression_level"] = draco.compression_level;
  result["frames"] = frames;
  if (json) {
    std::printf("%s\n", result.dump().c_str());
  } else {
    for (const int lod : {0, 1}) {
      const auto& r = result["lod" + std::to_string(lod)];
      std::printf("lod %d: %.0f triangles, %.1f kB, encode %.1f ms (median), largest decoded error %.2f mm (bound %.2f mm)\n", lod,
                  r["triangles"].get<double>(), r["kb"].get<double>(), r["encode_ms"].get<double>(), r["max_error_mm"].get<double>(), bound * 1000);
    }
  }
  return 0;
}
