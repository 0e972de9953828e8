#include "zipfusion/depth/foreground.h"

#include "zipfusion/core/error.h"

namespace zipfusion {

void ForegroundOptions::validate() const {
  if (!(min_depth_m >= 0)) throw InvalidInput("min-depth: must be >= 0 metres");
  if (!(max_depth_m > min_depth_m)) throw InvalidInput("max-depth: must exceed min-depth");
}

void extract_foreground(const DepthImage& raw, double depth_unit_m, const CameraModel& camera, const std::optional<Box3d>& volume,
                        const ForegroundOptions& options, Image<float>& depth_m) {
  depth_m.resize(raw.width, raw.height);
  const Rigid3f world_from_depth = camera.world_from_depth.cast<float>();
  const Box3d* box = options.crop_to_volume && volume ? &*volume : nullptr;
  const int count = static_cast<int>(raw.size());
  for (int i = 0; i < count; ++i) {
    depth_m.data[i] = foreground_depth(i, raw.data.data(), raw.width, static_cast<float>(depth_unit_m), static_cast<float>(options.min_depth_m),
                                       static_cast<float>(options.max_depth_m), camera.depth_intrinsics, world_from_depth, box);
  }
}

}  // namespace zipfusion
