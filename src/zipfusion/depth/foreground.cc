#include "zipfusion/depth/foreground.h"

#include "zipfusion/core/error.h"
#include "zipfusion/core/row_kernel.h"

namespace zipfusion {

void ForegroundOptions::validate() const {
  if (!(min_depth_m >= 0)) throw InvalidInput("min-depth: must be >= 0 metres");
  if (!(max_depth_m > min_depth_m)) throw InvalidInput("max-depth: must exceed min-depth");
}

namespace {

// foreground_depth over one row, as a branch-free loop that vectorises (a Kinect row is 640
// pixels and every one is tested).
ZF_ROW_KERNEL void foreground_row(const unsigned short* raw, int width, int v, const ForegroundParams& params, float* out) {
  const Eigen::Vector3f row_ray = params.world_rays.row_ray(v);
  const Eigen::Vector3f origin = params.world_rays.origin, du = params.world_rays.ray_du;
  const float lo_x = params.box_min.x(), lo_y = params.box_min.y(), lo_z = params.box_min.z();
  const float hi_x = params.box_max.x(), hi_y = params.box_max.y(), hi_z = params.box_max.z();
  const int crop = params.crop ? 1 : 0;
  for (int u = 0; u < width; ++u) {
    const float z = static_cast<float>(raw[u]) * params.depth_unit_m;
    const float uf = static_cast<float>(u);
    const float x = origin.x() + z * (row_ray.x() + uf * du.x());
    const float y = origin.y() + z * (row_ray.y() + uf * du.y());
    const float w = origin.z() + z * (row_ray.z() + uf * du.z());
    const int in_box = static_cast<int>(x >= lo_x) & static_cast<int>(x <= hi_x) & static_cast<int>(y >= lo_y) & static_cast<int>(y <= hi_y) &
                       static_cast<int>(w >= lo_z) & static_cast<int>(w <= hi_z);
    const int keep = static_cast<int>(raw[u] != 0) & static_cast<int>(z >= params.min_depth_m) & static_cast<int>(z <= params.max_depth_m) &
                     (in_box | (1 - crop));
    out[u] = static_cast<float>(keep) * z;
  }
}

}  // namespace

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
    foreground_row(raw.data.data() + static_cast<size_t>(v) * raw.width, raw.width, v, params, depth_m.data.data() + static_cast<size_t>(v) * raw.width);
  }
}

}  // namespace zipfusion
