#include "zipfusion/depth/color_lookup.h"

namespace zipfusion {

void lookup_colors(const DepthMesh& mesh, const CameraModel& camera, const ColorImage* color, std::vector<Rgb8>& out) {
  const int count = mesh.width * mesh.height;
  out.assign(count, kNoColor);
  if (color == nullptr || color->empty() || !camera.has_color()) return;
  const Intrinsics& depth_k = camera.depth_intrinsics;
  const Intrinsics& color_k = *camera.color_intrinsics;
  const Rigid3f color_from_depth = camera.color_from_depth.cast<float>();
  for (int i = 0; i < count; ++i) {
    const float z = mesh.depth[i];
    if (z <= 0) continue;
    const Eigen::Vector3f p_color = color_from_depth * unproject(depth_k, static_cast<float>(i % mesh.width), static_cast<float>(i / mesh.width), z);
    if (p_color.z() <= 0) continue;
    Eigen::Vector2f pixel;
    if (color_k.has_distortion) {
      pixel = project(color_k, p_color.cast<double>()).cast<float>();
    } else {
      pixel = project_pinhole(color_k, p_color);
    }
    out[i] = sample_bilinear(*color, pixel.x(), pixel.y());
  }
}

}  // namespace zipfusion
