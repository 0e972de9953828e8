#include "zipfusion/core/rasterizer.h"

#include <algorithm>
#include <array>
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

namespace {

// A triangle's corner in the camera frame, with its colour as floats (interpolated where the
// near plane cuts an edge).
struct CameraCorner {
  Eigen::Vector3f point;
  Eigen::Vector3f color;
};

// Draws one triangle whose corners all lie beyond the near plane.
void rasterize_triangle(const CameraCorner& q0, const CameraCorner& q1, const CameraCorner& q2, const Intrinsics& k, bool want_color,
                        bool mesh_has_color, RenderBuffers& buffers) {
  const Eigen::Vector2f a = project_pinhole(k, q0.point), b = project_pinhole(k, q1.point), c = project_pinhole(k, q2.point);
  const float area = edge_function(a, b, c.x(), c.y());
  if (std::abs(area) < 1e-12f) return;
  const int u_min = std::max(0, static_cast<int>(std::ceil(std::min({a.x(), b.x(), c.x()}))));
  const int u_max = std::min(k.width - 1, static_cast<int>(std::floor(std::max({a.x(), b.x(), c.x()}))));
  const int v_min = std::max(0, static_cast<int>(std::ceil(std::min({a.y(), b.y(), c.y()}))));
  const int v_max = std::min(k.height - 1, static_cast<int>(std::floor(std::max({a.y(), b.y(), c.y()}))));
  if (u_min > u_max || v_min > v_max) return;
  // Both orientations are drawn: the z-buffer, not back-face culling, decides visibility.
  const float inv_area = 1.0f / area;
  const float inv_z0 = 1.0f / q0.point.z(), inv_z1 = 1.0f / q1.point.z(), inv_z2 = 1.0f / q2.point.z();
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
      const Eigen::Vector3f color = (w0 * inv_z0 * z) * q0.color + (w1 * inv_z1 * z) * q1.color + (w2 * inv_z2 * z) * q2.color;
      out = {clamp_channel(color.x()), clamp_channel(color.y()), clamp_channel(color.z())};
    }
  }
}

}  // namespace

void rasterize_mesh(const TriangleMesh& mesh, const Intrinsics& k, const Rigid3d& cam_from_world, RenderBuffers& buffers,
                    float near_m) {
  const Rigid3f cam_from_world_f = cam_from_world.cast<float>();
  const bool want_color = !buffers.color.empty();
  const bool mesh_has_color = mesh.has_colors();

  std::vector<Eigen::Vector3f> in_cam(mesh.positions.size());
  for (size_t i = 0; i < mesh.positions.size(); ++i) in_cam[i] = cam_from_world_f * mesh.positions[i];
  auto corner = [&](int vertex) {
    const Rgb8 c = mesh_has_color ? mesh.colors[vertex] : Rgb8{};
    return CameraCorner{in_cam[vertex], Eigen::Vector3f(c.r, c.g, c.b)};
  };

  for (const Eigen::Vector3i& tri : mesh.triangles) {
    const std::array<CameraCorner, 3> corners{corner(tri[0]), corner(tri[1]), corner(tri[2])};
    const int beyond = (corners[0].point.z() > near_m) + (corners[1].point.z() > near_m) + (corners[2].point.z() > near_m);
    if (beyond == 3) {
      rasterize_triangle(corners[0], corners[1], corners[2], k, want_color, mesh_has_color, buffers);
      continue;
    }
    if (beyond == 0) continue;
    // The near plane cuts the triangle (a floor or a wall larger than the rig reaches past the
    // cameras): the part beyond it, a triangle or a quadrilateral, is drawn (Sutherland-Hodgman
    // against one plane), so a large triangle is not lost for one corner behind a camera.
    std::array<CameraCorner, 4> clipped;
    int count = 0;
    for (int i = 0; i < 3; ++i) {
      const CameraCorner& from = corners[i];
      const CameraCorner& to = corners[(i + 1) % 3];
      const bool from_beyond = from.point.z() > near_m, to_beyond = to.point.z() > near_m;
      if (from_beyond) clipped[count++] = from;
      if (from_beyond != to_beyond) {
        const float t = (near_m - from.point.z()) / (to.point.z() - from.point.z());
        CameraCorner cut{from.point + t * (to.point - from.point), from.color + t * (to.color - from.color)};
        cut.point.z() = near_m;  // exactly on the plane, whatever the rounding
        clipped[count++] = cut;
      }
    }
    for (int i = 1; i + 1 < count; ++i) rasterize_triangle(clipped[0], clipped[i], clipped[i + 1], k, want_color, mesh_has_color, buffers);
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
