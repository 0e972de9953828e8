#include "zipfusion/core/rasterizer.h"

#include <algorithm>
#include <cmath>

namespace zipfusion {
namespace {

// Twice the signed area of (a, b, p): positive when p is left of a→b in pixel coordinates.
inline float edge_function(const Eigen::Vector2f& a, const Eigen::Vector2f& b, float px, float py) {
  return (b.x() - a.x()) * (py - a.y()) - (b.y() - a.y()) * (px - a.x());
}

inline unsigned char clamp_channel(float c) { return static_cast<unsigned char>(std::clamp(c + 0.5f, 0.0f, 255.0f)); }

}  // namespace

void RenderBuffers::reset(const Intrinsics& k, bool with_color, Rgb8 background) {
  depth.resize(k.width, k.height, kNoDepth);
  if (with_color) {
    color.resize(k.width, k.height, background);
  } else {
    color = {};
  }
}

void rasterize_mesh(const TriangleMesh& mesh, const Intrinsics& k, const Rigid3d& cam_from_world, RenderBuffers& buffers,
                    float near_m) {
  const Rigid3f cam_from_world_f = cam_from_world.cast<float>();
  const bool want_color = !buffers.color.empty();
  const bool mesh_has_color = mesh.has_colors();
  const int width = k.width, height = k.height;

  std::vector<Eigen::Vector3f> in_cam(mesh.positions.size());
  std::vector<Eigen::Vector2f> pixel(mesh.positions.size());
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    in_cam[i] = cam_from_world_f * mesh.positions[i];
    if (in_cam[i].z() > near_m) pixel[i] = project_pinhole(k, in_cam[i]);
  }

  for (const Eigen::Vector3i& tri : mesh.triangles) {
    const Eigen::Vector3f& p0 = in_cam[tri[0]];
    const Eigen::Vector3f& p1 = in_cam[tri[1]];
    const Eigen::Vector3f& p2 = in_cam[tri[2]];
    if (p0.z() <= near_m || p1.z() <= near_m || p2.z() <= near_m) continue;
    const Eigen::Vector2f& a = pixel[tri[0]];
    const Eigen::Vector2f& b = pixel[tri[1]];
    const Eigen::Vector2f& c = pixel[tri[2]];
    const float area = edge_function(a, b, c.x(), c.y());
    if (std::abs(area) < 1e-12f) continue;
    const int u_min = std::max(0, static_cast<int>(std::ceil(std::min({a.x(), b.x(), c.x()}))));
    const int u_max = std::min(width - 1, static_cast<int>(std::floor(std::max({a.x(), b.x(), c.x()}))));
    const int v_min = std::max(0, static_cast<int>(std::ceil(std::min({a.y(), b.y(), c.y()}))));
    const int v_max = std::min(height - 1, static_cast<int>(std::floor(std::max({a.y(), b.y(), c.y()}))));
    if (u_min > u_max || v_min > v_max) continue;
    // Both orientations are drawn: the z-buffer, not back-face culling, decides visibility.
    const float inv_area = 1.0f / area;
    const float inv_z0 = 1.0f / p0.z(), inv_z1 = 1.0f / p1.z(), inv_z2 = 1.0f / p2.z();
    for (int v = v_min; v <= v_max; ++v) {
      for (int u = u_min; u <= u_max; ++u) {
        const float w0 = edge_function(b, c, u, v) * inv_area;
        const float w1 = edge_function(c, a, u, v) * inv_area;
        const float w2 = edge_function(a, b, u, v) * inv_area;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const float inv_z = w0 * inv_z0 + w1 * inv_z1 + w2 * inv_z2;
        const float z = 1.0f / inv_z;
        float& stored = buffers.depth(u, v);
        if (z >= stored) continue;
        stored = z;
        if (!want_color) continue;
        Rgb8& out = buffers.color(u, v);
        if (!mesh_has_color) {
          out = {160, 160, 160};
          continue;
        }
        // Perspective-correct barycentrics.
        const float b0 = w0 * inv_z0 * z, b1 = w1 * inv_z1 * z, b2 = w2 * inv_z2 * z;
        const Rgb8 c0 = mesh.colors[tri[0]], c1 = mesh.colors[tri[1]], c2 = mesh.colors[tri[2]];
        out = {clamp_channel(b0 * c0.r + b1 * c1.r + b2 * c2.r), clamp_channel(b0 * c0.g + b1 * c1.g + b2 * c2.g),
               clamp_channel(b0 * c0.b + b1 * c1.b + b2 * c2.b)};
      }
    }
  }
}

void rasterize_floor(const Intrinsics& k, const Rigid3d& cam_from_world, RenderBuffers& buffers, double half_extent_m,
                     double tile_m) {
  const Rigid3d world_from_cam = cam_from_world.inverse();
  const Eigen::Vector3d origin = world_from_cam.translation();
  const bool want_color = !buffers.color.empty();
  for (int v = 0; v < k.height; ++v) {
    for (int u = 0; u < k.width; ++u) {
      // Ray with unit z in the camera frame, so the ray parameter is the depth along the axis.
      const Eigen::Vector3d ray_in_cam((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
      const Eigen::Vector3d ray = world_from_cam.linear() * ray_in_cam;
      if (ray.z() >= -1e-9) continue;
      const double t = -origin.z() / ray.z();
      if (t <= 0) continue;
      const Eigen::Vector3d hit = origin + t * ray;
      if (std::abs(hit.x()) > half_extent_m || std::abs(hit.y()) > half_extent_m) continue;
      float& stored = buffers.depth(u, v);
      if (t >= stored) continue;
      stored = static_cast<float>(t);
      if (want_color) {
        const long tile = std::lround(std::floor(hit.x() / tile_m)) + std::lround(std::floor(hit.y() / tile_m));
        const unsigned char grey = (tile & 1) ? 110 : 150;
        buffers.color(u, v) = {grey, grey, static_cast<unsigned char>(grey + 10)};
      }
    }
  }
}

}  // namespace zipfusion
