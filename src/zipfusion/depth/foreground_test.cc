#include "zipfusion/depth/foreground.h"

#include <gtest/gtest.h>

#include <random>

namespace zipfusion {
namespace {

// A camera 2 m from the origin looking at it; raw depth in millimetres.
CameraModel test_camera() {
  CameraModel camera;
  camera.depth_intrinsics = {.width = 64, .height = 48, .fx = 60, .fy = 60, .cx = 31.5, .cy = 23.5};
  camera.world_from_depth = look_at({2.0, 0.3, 1.2}, {0, 0, 1.0});
  return camera;
}

TEST(Foreground, KeepsTheWorkingRangeInsideTheVolume) {
  const CameraModel camera = test_camera();
  const Box3d volume{{-0.4, -0.4, 0.5}, {0.4, 0.4, 1.5}};
  DepthImage raw(64, 48);
  std::mt19937 rng(4);
  std::uniform_int_distribution<int> depth_mm(0, 5000);
  for (auto& d : raw.data) d = static_cast<unsigned short>(depth_mm(rng));
  raw(0, 0) = 0;
  raw(1, 0) = 399;   // nearer than 0.4 m
  raw(2, 0) = 4501;  // beyond 4.5 m
  Image<float> out;
  extract_foreground(raw, 0.001, camera, volume, {}, out);
  ASSERT_EQ(out.width, 64);
  ASSERT_EQ(out.height, 48);
  EXPECT_EQ(out(0, 0), 0.0f);
  EXPECT_EQ(out(1, 0), 0.0f);
  EXPECT_EQ(out(2, 0), 0.0f);
  int kept = 0;
  for (int v = 0; v < 48; ++v) {
    for (int u = 0; u < 64; ++u) {
      const float z = raw(u, v) * 0.001f;
      const Eigen::Vector3d p = camera.world_from_depth * unproject(camera.depth_intrinsics, u, v, z).cast<double>();
      const bool expected = raw(u, v) != 0 && z >= 0.4f && z <= 4.5f && volume.contains(p);
      // Points within float rounding of the volume's faces may go either way.
      const bool on_face = ((p - volume.min).array().abs() < 1e-5).any() || ((p - volume.max).array().abs() < 1e-5).any();
      if (on_face) continue;
      EXPECT_EQ(out(u, v), expected ? z : 0.0f) << u << "," << v;
      // The row kernel agrees with the element function.
      EXPECT_EQ(out(u, v), foreground_depth(u, v, raw(u, v), ForegroundParams(0.001, camera, volume, {}))) << u << "," << v;
      kept += expected;
    }
  }
  EXPECT_GT(kept, 20);  // the volume is in view: some pixels are kept
}

TEST(Foreground, WithoutCropOnlyTheRangeCounts) {
  const CameraModel camera = test_camera();
  DepthImage raw(64, 48, 3000);
  raw(5, 5) = 100;
  Image<float> out;
  extract_foreground(raw, 0.001, camera, Box3d{{0, 0, 0}, {0.1, 0.1, 0.1}}, {.crop_to_volume = false}, out);
  for (int v = 0; v < 48; ++v) {
    for (int u = 0; u < 64; ++u) EXPECT_EQ(out(u, v), u == 5 && v == 5 ? 0.0f : 3000 * 0.001f);
  }
}

}  // namespace
}  // namespace zipfusion
