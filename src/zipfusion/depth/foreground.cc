#include "zipfusion/depth/foreground.h"

#include "zipfusion/core/error.h"

namespace zipfusion {

void ForegroundOptions::validate() const {
  if (!(min_depth_m >= 0)) throw InvalidInput("min-depth: must be >= 0 metres");
  if (!(max_depth_m > min_depth_m)) throw InvalidInput("max-depth: must exceed min-depth");
}

ForegroundParams::ForegroundParams(double depth_unit, const CameraModel& camera, const std::optional<Box3d>& volume,
                                   const ForegroundOptions& options)
    : depth_unit_m(static_cast<float>(depth_unit)),
      min_depth_m(static_cast<float>(options.min_depth_m)),
      max_depth_m(static_cast<float>(options.max_depth_m)),
      crop(options.crop_to_volume && volume.has_value()),
      world_rays(camera.depth_intrinsics, camera.world_from_depth.cast<float>()) {
  if (crop) {
    box_min = volume->min.cast<float>();
    box_max = volume->max.cast<float>();
  }
}

void extract_foreground(const DepthImage& raw, double depth_unit_m, const CameraModel& camera, const std::optional<Box3d>& volume,
                        const ForegroundOptions& options, Image<float>& depth_m) {
  depth_m.width = raw.width;
  depth_m.height = raw.height;
  depth_m.data.resize(raw.size());
  const ForegroundParams params(depth_unit_m, camera, volume, options);
  for (int v = 0; v < raw.height; ++v) {
    const unsigned short* in = raw.data.data() + static_cast<size_t>(v) * raw.width;
    float* out = depth_m.data.data() + static_cast<size_t>(v) * raw.width;
    for (int u = 0; u < raw.width; ++u) out[u] = in[u] == 0 ? 0.0f : foreground_depth(u, v, in[u], params);
  }
}

}  // namespace zipfusion
