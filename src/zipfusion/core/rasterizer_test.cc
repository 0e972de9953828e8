#include "zipfusion/core/rasterizer.h"

#include <gtest/gtest.h>

#include <cmath>

namespace zipfusion {
namespace {

const Intrinsics kCamera{.width = 160, .height = 120, .fx = 150, .fy = 150, .cx = 79.5, .cy = 59.5};

// A square of half-size `half` in the plane through `centre` spanned by unit vectors a and b.
TriangleMesh square(const Eigen::Vector3f& centre, const Eigen::Vector3f& a, const Eigen::Vector3f& b, float half, Rgb8 color) {
  TriangleMesh m;
  m.positions = {centre - half * a - half * b, centre + half * a - half * b, centre + half * a + half * b, centre - half * a + half * b};
  m.colors.assign(4, color);
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

TEST(Rasterizer, FrontoParallelPlaneHasExactDepth) {
  RenderBuffers buffers;
  buffers.reset(kCamera, true);
  rasterize_mesh(square({0, 0, 2}, {1, 0, 0}, {0, 1, 0}, 10, {10, 200, 30}), kCamera, Rigid3d::Identity(), buffers);
  for (float z : buffers.depth.data) EXPECT_NEAR(z, 2.0f, 1e-5f);
  for (const Rgb8& c : buffers.color.data) EXPECT_EQ(c, (Rgb8{10, 200, 30}));
}

TEST(Rasterizer, TiltedPlaneDepthIsPerspectiveCorrect) {
  // Plane n·p = d with n = (0, sin, cos): the depth at pixel (u, v) is d / (n·ray).
  const float tilt = 0.6f;
  const Eigen::Vector3f normal(0, std::sin(tilt), std::cos(tilt));
  const Eigen::Vector3f centre(0.1f, -0.05f, 2.5f);
  const float d = normal.dot(centre);
  RenderBuffers buffers;
  buffers.reset(kCamera, false);
  rasterize_mesh(square(centre, {1, 0, 0}, Eigen::Vector3f(0, std::cos(tilt), -std::sin(tilt)), 2, {}), kCamera, Rigid3d::Identity(), buffers);
  int covered = 0;
  for (int v = 0; v < kCamera.height; ++v) {
    for (int u = 0; u < kCamera.width; ++u) {
      const float z = buffers.depth(u, v);
      if (std::isinf(z)) continue;
      ++covered;
      const Eigen::Vector3f ray((u - kCamera.cx) / kCamera.fx, (v - kCamera.cy) / kCamera.fy, 1);
      EXPECT_NEAR(z, d / normal.dot(ray), 1e-4f * z) << u << "," << v;
    }
  }
  EXPECT_GT(covered, kCamera.width * kCamera.height / 2);
}

// A floor much larger than the rig reaches behind the camera: its two triangles have corners on
// both sides of the near plane. The part in front is drawn whole, with its colours, and nothing
// behind the camera or nearer than the near plane.
TEST(Rasterizer, TriangleReachingBehindTheCameraIsClippedNotDropped) {
  // Camera looking down its z axis, 1.2 m above a floor y = 1.2 (image y points down).
  TriangleMesh floor;
  floor.positions = {{-30, 1.2f, -30}, {30, 1.2f, -30}, {30, 1.2f, 30}, {-30, 1.2f, 30}};
  floor.colors = {{0, 0, 0}, {200, 0, 0}, {200, 200, 0}, {0, 200, 0}};
  floor.triangles = {{0, 1, 2}, {0, 2, 3}};
  RenderBuffers buffers;
  buffers.reset(kCamera, true);
  rasterize_mesh(floor, kCamera, Rigid3d::Identity(), buffers);
  int covered = 0;
  for (int v = 0; v < kCamera.height; ++v) {
    for (int u = 0; u < kCamera.width; ++u) {
      const float y_ray = (v - kCamera.cy) / kCamera.fy;  // the ray (·, y_ray, 1) meets y = 1.2 at z = 1.2 / y_ray
      const float z = buffers.depth(u, v);
      if (y_ray <= 1.2f / 30) {  // above the horizon, or beyond the floor's far edge
        EXPECT_TRUE(std::isinf(z)) << u << "," << v;
        continue;
      }
      ++covered;
      EXPECT_NEAR(z, 1.2f / y_ray, 1e-4f * z) << u << "," << v;
      // Colour is linear over the floor: red from x, green from z (x, z in [-30, 30]).
      const float x = (u - kCamera.cx) / kCamera.fx * z;
      const Rgb8 c = buffers.color(u, v);
      EXPECT_NEAR(c.r, 200 * (x + 30) / 60, 1.5) << u << "," << v;
      EXPECT_NEAR(c.g, 200 * (z + 30) / 60, 1.5) << u << "," << v;
    }
  }
  EXPECT_GT(covered, kCamera.width * kCamera.height / 3);
  // A triangle wholly nearer than the near plane, or behind the camera, draws nothing.
  RenderBuffers empty;
  empty.reset(kCamera, false);
  rasterize_mesh(square({0, 0, 0.02f}, {1, 0, 0}, {0, 1, 0}, 1, {}), kCamera, Rigid3d::Identity(), empty);
  rasterize_mesh(square({0, 0, -2}, {1, 0, 0}, {0, 1, 0}, 5, {}), kCamera, Rigid3d::Identity(), empty);
  for (float z : empty.depth.data) EXPECT_TRUE(std::isinf(z));
}

TEST(Rasterizer, NearerSurfaceWinsWhateverTheOrder) {
  const TriangleMesh far = square({0, 0, 3}, {1, 0, 0}, {0, 1, 0}, 10, {255, 0, 0});
  const TriangleMesh near = square({0, 0, 1.5f}, {1, 0, 0}, {0, 1, 0}, 0.2f, {0, 0, 255});
  for (bool near_first : {false, true}) {
    RenderBuffers buffers;
    buffers.reset(kCamera, true);
    rasterize_mesh(near_first ? near : far, kCamera, Rigid3d::Identity(), buffers);
    rasterize_mesh(near_first ? far : near, kCamera, Rigid3d::Identity(), buffers);
    EXPECT_NEAR(buffers.depth(80, 60), 1.5f, 1e-5f);
    EXPECT_EQ(buffers.color(80, 60), (Rgb8{0, 0, 255}));
    EXPECT_NEAR(buffers.depth(2, 2), 3.0f, 1e-5f);
    EXPECT_EQ(buffers.color(2, 2), (Rgb8{255, 0, 0}));
  }
}

TEST(Rasterizer, FloorDepthMatchesRayPlaneIntersection) {
  const Rigid3d world_from_cam = look_at({2, 0, 1.3}, {0, 0, 0.2});
  RenderBuffers buffers;
  buffers.reset(kCamera, true);
  rasterize_floor(kCamera, world_from_cam.inverse(), buffers);
  int covered = 0;
  for (int v = 0; v < kCamera.height; ++v) {
    for (int u = 0; u < kCamera.width; ++u) {
      const float z = buffers.depth(u, v);
      if (std::isinf(z)) continue;
      ++covered;
      const Eigen::Vector3d p_world = world_from_cam * unproject(kCamera, u, v, z).cast<double>();
      EXPECT_NEAR(p_world.z(), 0.0, 1e-5);
    }
  }
  EXPECT_GT(covered, kCamera.width * kCamera.height / 3);
  // The top rows look above the horizon-free floor square's far edge or at it, never below z = 0.
}

}  // namespace
}  // namespace zipfusion
