#include "zipfusion/depth/foreground.h"

#include <gtest/gtest.h>

#include <cmath>
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


// A noisy surface with holes and a step to another 0.4–0.7 m nearer, sized so that at every level the last
// column and row come from the border path and others from the row kernel.
Image<float> noisy_surface_with_step(int width, int height, std::uint32_t seed) {
  Image<float> depth(width, height);
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, 0.008f);
  std::uniform_real_distribution<float> hole(0.0f, 1.0f);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const float surface = u < width / 2 + v / 4 ? 2.0f + 0.002f * static_cast<float>(u) : 2.2f;
      depth(u, v) = hole(rng) < 0.1f ? 0.0f : surface + noise(rng);
    }
  }
  return depth;
}

// The row kernel gives the element function's float at every pixel, at every level, and the
// subsampled size is the one subsampled_intrinsics gives.
TEST(SubsampleDepth, RowKernelGivesTheElementFunctionsDepth) {
  for (const int level : {1, 2, 3}) {
    const Image<float> depth = noisy_surface_with_step(301, 77, 9 + level);
    Image<float> out;
    subsample_depth(depth, level, 0.03f, out);
    const Intrinsics sub = subsampled_intrinsics({.width = 301, .height = 77, .fx = 1, .fy = 1}, level);
    ASSERT_EQ(out.width, sub.width);
    ASSERT_EQ(out.height, sub.height);
    for (int v = 0; v < out.height; ++v) {
      for (int u = 0; u < out.width; ++u) ASSERT_EQ(out(u, v), subsampled_depth(depth, u, v, level, 0.03f)) << level << ": " << u << "," << v;
    }
  }
}

// The mean keeps the averaging of the pixels it drops (noise σ 8 mm: a tent of 3×3 leaves 0.375 σ,
// taking every second pixel σ), does not mix the surface with the one across the step (every
// subsampled pixel stays within 4 σ of its own surface), and leaves holes as holes.
TEST(SubsampleDepth, AveragesTheSurfaceWithoutMixingSurfaces) {
  const Image<float> depth = noisy_surface_with_step(640, 480, 3);
  Image<float> out;
  subsample_depth(depth, 1, 0.03f, out);
  double squared_error = 0, squared_error_picked = 0;
  int count = 0;
  for (int v = 1; v < out.height - 1; ++v) {
    for (int u = 1; u < out.width - 1; ++u) {
      const int x = 2 * u, y = 2 * v;
      const float picked = depth(x, y);
      if (picked == 0.0f) {
        ASSERT_EQ(out(u, v), 0.0f);
        continue;
      }
      const float surface = x < 320 + y / 4 ? 2.0f + 0.002f * static_cast<float>(x) : 2.2f;
      ASSERT_LT(std::abs(out(u, v) - surface), 0.032f) << u << "," << v;
      // Away from the step, the error against the true surface.
      if (std::abs(x - (320 + y / 4)) > 2) {
        squared_error += (out(u, v) - surface) * (out(u, v) - surface);
        squared_error_picked += (picked - surface) * (picked - surface);
        ++count;
      }
    }
  }
  const double sigma = std::sqrt(squared_error / count), sigma_picked = std::sqrt(squared_error_picked / count);
  EXPECT_NEAR(sigma_picked, 0.008, 0.0005);
  EXPECT_LT(sigma, 0.45 * sigma_picked);  // 0.375 σ with all nine pixels; holes drop some
}

}  // namespace
}  // namespace zipfusion
