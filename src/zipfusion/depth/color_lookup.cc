#include "zipfusion/depth/color_lookup.h"

#include <algorithm>
#include <cstring>

#include "zipfusion/core/row_kernel.h"

namespace zipfusion {
namespace {

// A pinhole colour camera's coordinates of the points z·(ray + u·ray_du) + origin, u = u0 + i:
// the operations of PixelRays::point and project_pinhole in their order, so the floats are
// at()'s; −1 (outside every image) where the point is not in front of the camera.
ZF_ROW_KERNEL void project_pinhole_row(const Eigen::Vector3f& row_ray, const Eigen::Vector3f& ray_du, const Eigen::Vector3f& origin, float fx,
                                       float fy, float cx, float cy, int u0, int n, const float* z, float* x, float* y) {
  // Scalars in locals: read through the references inside the loop, they might alias x or y, and
  // the loop would not vectorise.
  const float rx = row_ray.x(), ry = row_ray.y(), rz = row_ray.z(), dx = ray_du.x(), dy = ray_du.y(), dz = ray_du.z();
  const float ox = origin.x(), oy = origin.y(), oz = origin.z();
  for (int i = 0; i < n; ++i) {
    const float u = static_cast<float>(u0 + i);
    const float px = ox + z[i] * (rx + u * dx);
    const float py = oy + z[i] * (ry + u * dy);
    const float pz = oz + z[i] * (rz + u * dz);
    // Divided in every lane, then selected (select_if): GCC does not vectorise a division under
    // the condition.
    const float xi = fx * px / pz + cx, yi = fy * py / pz + cy;
    const unsigned behind = !(pz > 0.0f);
    x[i] = select_if(behind, -1.0f, xi);
    y[i] = select_if(behind, -1.0f, yi);
  }
}

}  // namespace

void ColorLookup::project_row(int v, int u0, int count, const float* z, float* x, float* y) const {
  if (color_k_->has_distortion) {
    for (int i = 0; i < count; ++i) {
      const Eigen::Vector3f p_color = rays_.point(u0 + i, v, z[i]);
      const Eigen::Vector2f pixel = p_color.z() > 0 ? project(*color_k_, p_color.cast<double>()).cast<float>() : Eigen::Vector2f(-1, -1);
      x[i] = pixel.x();
      y[i] = pixel.y();
    }
    return;
  }
  project_pinhole_row(rays_.row_ray(v), rays_.ray_du, rays_.origin, static_cast<float>(color_k_->fx), static_cast<float>(color_k_->fy),
                      static_cast<float>(color_k_->cx), static_cast<float>(color_k_->cy), u0, count, z, x, y);
}

void lookup_colors(const DepthMesh& mesh, const CameraModel& camera, const ColorImage* color, std::vector<Rgb8>& out) {
  const int count = mesh.width * mesh.height;
  // kNoColor is grey 128 in every byte, so a memset fills it (a loop over 3-byte pixels was a
  // sixth of this function's time).
  static_assert(sizeof(Rgb8) == 3 && kNoColor.r == 128 && kNoColor.g == 128 && kNoColor.b == 128);
  out.resize(count);
  std::memset(static_cast<void*>(out.data()), 128, out.size() * sizeof(Rgb8));
  const ColorLookup lookup(camera, color);
  if (!lookup.has_image()) return;
  const PixelBox box = mesh.box();
  for (int v = box.v0; v < box.v1; ++v) {
    const float* depth = mesh.depth.data() + static_cast<size_t>(v) * mesh.width;
    Rgb8* colors = out.data() + static_cast<size_t>(v) * mesh.width;
    lookup.for_each_color_in_row(v, box.u0, box.u1, depth, [&](int u) { return depth[u] > 0; }, [&](int u, Rgb8 c) { colors[u] = c; });
  }
}

}  // namespace zipfusion
