#include "zipfusion/depth/color_lookup.h"

#include <algorithm>
#include <cstring>

namespace zipfusion {

void lookup_colors(const DepthMesh& mesh, const CameraModel& camera, const ColorImage* color, std::vector<Rgb8>& out) {
  const int count = mesh.width * mesh.height;
  // kNoColor is grey 128 in every byte, so a memset fills it (a loop over 3-byte pixels was a
  // sixth of this function's time).
  static_assert(sizeof(Rgb8) == 3 && kNoColor.r == 128 && kNoColor.g == 128 && kNoColor.b == 128);
  out.resize(count);
  std::memset(static_cast<void*>(out.data()), 128, out.size() * sizeof(Rgb8));
  if (color == nullptr || color->empty() || !camera.has_color()) return;
  const Intrinsics& color_k = *camera.color_intrinsics;
  // Depth pixels straight into the colour camera's frame.
  const PixelRays rays(camera.depth_intrinsics, camera.color_from_depth.cast<float>());
  const PixelBox box = mesh.box();
  for (int v = box.v0; v < box.v1; ++v) {
    const float* depth = mesh.depth.data() + static_cast<size_t>(v) * mesh.width;
    Rgb8* colors = out.data() + static_cast<size_t>(v) * mesh.width;
    const Eigen::Vector3f row_ray = rays.row_ray(v);
    for (int u = box.u0; u < box.u1; ++u) {
      const float z = depth[u];
      if (!(z > 0)) continue;
      const Eigen::Vector3f p_color = rays.origin + z * (row_ray + static_cast<float>(u) * rays.ray_du);
      if (p_color.z() <= 0) continue;
      const Eigen::Vector2f pixel = color_k.has_distortion ? project(color_k, p_color.cast<double>()).cast<float>() : project_pinhole(color_k, p_color);
      colors[u] = sample_bilinear(*color, pixel.x(), pixel.y());
    }
  }
}

}  // namespace zipfusion
