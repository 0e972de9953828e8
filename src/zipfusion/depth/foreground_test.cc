#include "zipfusion/depth/foreground.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <iostream>
#include <random>
#include <vector>

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
  const ForegroundOptions options{.floor_noise_sigmas = 0};  // the box as given (the lift: below)
  extract_foreground(raw, 0.001, camera, volume, options, out);
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
      EXPECT_EQ(out(u, v), foreground_depth(u, v, raw(u, v), ForegroundParams(0.001, camera, volume, options))) << u << "," << v;
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

// A camera 2.6 m up, 3 m from the volume's axis, looking down at (0, 0, 0.9) over a floor at z = 0
// (depth with the Kinect's axial noise) or over a noise-free platform `platform_m` high.
struct HighCameraView {
  CameraModel camera;
  DepthImage raw;
  std::vector<bool> inside;  // the pixel's true point lies within the volume's x and y
};
HighCameraView high_camera_view(const Box3d& volume, double platform_m) {
  HighCameraView view;
  view.camera.depth_intrinsics = {.width = 160, .height = 120, .fx = 145, .fy = 145, .cx = 79.5, .cy = 59.5};
  view.camera.world_from_depth = look_at({3.0, 0.0, 2.6}, {0, 0, 0.9});
  view.raw = DepthImage(160, 120, 0);
  view.inside.assign(view.raw.size(), false);
  std::mt19937 rng(11);
  std::normal_distribution<double> standard_normal;
  const Eigen::Vector3d origin = view.camera.world_from_depth.translation();
  for (int v = 0; v < 120; ++v) {
    for (int u = 0; u < 160; ++u) {
      // The world point at camera depth 1 on this pixel's ray: depth z reaches origin + z·ray.
      const Eigen::Vector3d ray = view.camera.world_from_depth * unproject(view.camera.depth_intrinsics, u, v, 1.0f).cast<double>() - origin;
      if (ray.z() >= 0) continue;
      const double z = (platform_m - origin.z()) / ray.z();
      const Eigen::Vector3d p = origin + z * ray;
      view.inside[v * 160 + u] = p.x() > volume.min.x() && p.x() < volume.max.x() && p.y() > volume.min.y() && p.y() < volume.max.y();
      const double noisy = platform_m > 0 ? z : z + kinect_axial_sigma_m(z) * standard_normal(rng);
      if (noisy > 0.4 && noisy < 4.5) view.raw(u, v) = static_cast<unsigned short>(std::lround(noisy * 1000));
    }
  }
  return view;
}

// The floor's noise, seen from high up, lifts a share of it above the volume's fixed 2 cm
// clearance; the bottom raised to 3σ of each pixel's height noise keeps it out, while a surface
// 6 cm up (a shoe's top) stays in, and the row kernel agrees with the element function.
TEST(Foreground, AHighCamerasFloorNoiseStaysBelowTheVolume) {
  const Box3d volume{{-1, -1, kVolumeFloorClearanceM}, {1, 1, 2.2}};
  const HighCameraView floor = high_camera_view(volume, 0.0);
  const HighCameraView platform = high_camera_view(volume, 0.06);
  auto kept_share = [&](const HighCameraView& view, double sigmas) {
    const ForegroundOptions options{.floor_noise_sigmas = sigmas};
    Image<float> out;
    extract_foreground(view.raw, 0.001, view.camera, volume, options, out);
    const ForegroundParams params(0.001, view.camera, volume, options);
    int inside = 0, kept = 0;
    for (int v = 0; v < 120; ++v) {
      for (int u = 0; u < 160; ++u) {
        EXPECT_EQ(out(u, v), foreground_depth(u, v, view.raw(u, v), params)) << u << "," << v;
        if (!view.inside[v * 160 + u] || view.raw(u, v) == 0) continue;
        ++inside;
        kept += out(u, v) > 0;
      }
    }
    EXPECT_GT(inside, 3000);  // the volume's floor fills a good part of the view
    std::cout << "sigmas " << sigmas << ": " << kept << " of " << inside << " kept\n";
    return static_cast<double>(kept) / inside;
  };
  EXPECT_GT(kept_share(floor, 0), 0.03);  // measured: 348 of 3 649
  EXPECT_LT(kept_share(floor, 3), 0.005);  // 8 (a one-sided 3σ tail is 0.0013, with the millimetre steps more)
  EXPECT_EQ(kept_share(platform, 3), 1.0);
  // The lift is what 3σ exceeds the clearance by: none for a ring at Kinect height looking level
  // at 2.8 m (σ 12 mm, half of it in height), and none asked for.
  EXPECT_EQ(floor_lift_m(2.8f, -0.5f, 3.0f), 0.0f);
  EXPECT_GT(floor_lift_m(3.6f, -0.75f, 3.0f), 0.02f);
  EXPECT_EQ(floor_lift_m(4.5f, -1.0f, 0.0f), 0.0f);
}

// The row kernel gives the element function's depth with the floor's lift on every kind of ray:
// looking down, up, level (a row whose rays climb less than 1e-6 m a metre) and straight down.
TEST(Foreground, RowKernelAgreesOnEveryRayWithTheFloorsLift) {
  const Box3d volume{{-1, -1, kVolumeFloorClearanceM}, {1, 1, 2.2}};
  struct Pose {
    Eigen::Vector3d eye, target;
  };
  const Pose poses[] = {{{3.0, 0.0, 2.6}, {0, 0, 0.9}},      // down
                        {{2.0, 0.0, 0.3}, {0, 0, 1.8}},      // up
                        {{2.0, 0.0, 1.0}, {0, 0, 1.0}},      // level
                        {{0.0, 0.0, 3.5}, {0.001, 0, 0}}};  // straight down
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> depth_mm(0, 5000);
  for (const Pose& pose : poses) {
    CameraModel camera;
    camera.depth_intrinsics = {.width = 64, .height = 48, .fx = 60, .fy = 60, .cx = 31.5, .cy = 24};  // row 24 is level when the axis is
    camera.world_from_depth = look_at(pose.eye, pose.target);
    DepthImage raw(64, 48);
    for (auto& d : raw.data) d = static_cast<unsigned short>(depth_mm(rng));
    for (const double sigmas : {0.0, 3.0, 10.0}) {
      const ForegroundOptions options{.floor_noise_sigmas = sigmas};
      Image<float> out;
      extract_foreground(raw, 0.001, camera, volume, options, out);
      const ForegroundParams params(0.001, camera, volume, options);
      int kept = 0;
      for (int v = 0; v < 48; ++v) {
        for (int u = 0; u < 64; ++u) {
          ASSERT_EQ(out(u, v), foreground_depth(u, v, raw(u, v), params)) << pose.eye.transpose() << " sigmas " << sigmas << " at " << u << "," << v;
          kept += out(u, v) > 0;
        }
      }
      EXPECT_GT(kept, 50) << pose.eye.transpose();  // the volume is in view
    }
  }
  EXPECT_NEAR(PixelRays(Intrinsics{.width = 64, .height = 48, .fx = 60, .fy = 60, .cx = 31.5, .cy = 24},
                        look_at({2.0, 0.0, 1.0}, {0, 0, 1.0}).cast<float>())
                  .row_ray(24)
                  .z(),
              0.0f, 1e-6f);
}

// The true surface of noisy_surface: without `step` a plane facing the camera (a tap that strays
// past a row's end into the next row lies on the same surface, and would be counted); with it, a
// slanted plane and a band of it 0.4 m or more farther away inside the image.
bool in_far_band(int width, int height, int u, int v, bool step) {
  return step && u > width / 4 && u < width / 2 + v / 4 && v > 2 && v < height - 3;
}
float true_surface(int width, int height, int u, int v, bool step) {
  const bool far = in_far_band(width, height, u, v, step);
  const float slope = step ? 0.002f : 0.0f;
  return 2.0f + slope * static_cast<float>(u) + (far ? 0.4f + 0.001f * static_cast<float>(v) : 0.0f);
}

// true_surface with noise (σ 8 mm) and holes (10 %).
Image<float> noisy_surface(int width, int height, bool step, std::uint32_t seed) {
  Image<float> depth(width, height);
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, 0.008f);
  std::uniform_real_distribution<float> hole(0.0f, 1.0f);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) depth(u, v) = hole(rng) < 0.1f ? 0.0f : true_surface(width, height, u, v, step) + noise(rng);
  }
  return depth;
}

// The row kernel gives the element function's float at every pixel, at every level, with and
// without a step, and the subsampled size is the one subsampled_intrinsics gives. The image's size
// makes the last column and row come from the border path at every level.
TEST(SubsampleDepth, RowKernelGivesTheElementFunctionsDepth) {
  for (const bool step : {false, true}) {
    for (const int level : {1, 2, 3}) {
      const Image<float> depth = noisy_surface(301, 77, step, 9 + level);
      Image<float> out;
      subsample_depth(depth, level, 0.03f, out);
      const Intrinsics sub = subsampled_intrinsics({.width = 301, .height = 77, .fx = 1, .fy = 1}, level);
      ASSERT_EQ(out.width, sub.width);
      ASSERT_EQ(out.height, sub.height);
      for (int v = 0; v < out.height; ++v) {
        for (int u = 0; u < out.width; ++u) {
          ASSERT_EQ(out(u, v), subsampled_depth(u, v, depth.data.data(), depth.width, depth.height, level, 0.03f))
              << "step " << step << ", level " << level << ": " << u << "," << v;
        }
      }
    }
  }
}

// The weights by hand: pixel (1, 1) at level 1 is the tent mean of the 3×3 pixels around (2, 2),
// weights 4 at the centre, 2 beside it, 1 at the corners, without the hole and the two pixels off
// its surface (3.1 cm and 5 cm from the centre's 2 m; the threshold is 3 cm).
TEST(SubsampleDepth, TentWeightsOverTheSameSurface) {
  Image<float> depth(5, 5, 9.0f);  // pixels outside the 3×3 window: far from anything
  const float window[3][3] = {{2.01f, 0.0f, 2.031f}, {1.99f, 2.0f, 2.02f}, {2.05f, 2.005f, 1.98f}};
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 3; ++x) depth(1 + x, 1 + y) = window[y][x];
  }
  Image<float> out;
  subsample_depth(depth, 1, 0.03f, out);
  ASSERT_EQ(out.width, 3);
  const double expected = (1 * 2.01 + 2 * 1.99 + 4 * 2.0 + 2 * 2.02 + 2 * 2.005 + 1 * 1.98) / (1 + 2 + 4 + 2 + 2 + 1);
  EXPECT_NEAR(out(1, 1), expected, 1e-6);
  EXPECT_EQ(out(0, 0), 9.0f);  // the far pixels around it alone
}

// The mean keeps the averaging of the pixels it drops (noise σ 8 mm: taking every second pixel
// leaves σ), does not mix the surface with the one across the step (every
// subsampled pixel stays within 4 σ of its own surface), and leaves holes as holes.
TEST(SubsampleDepth, AveragesTheSurfaceWithoutMixingSurfaces) {
  constexpr int kWidth = 640, kHeight = 480;
  const Image<float> depth = noisy_surface(kWidth, kHeight, true, 3);
  Image<float> out;
  subsample_depth(depth, 1, 0.03f, out);
  double squared_error = 0, squared_error_picked = 0;
  int count = 0;
  for (int v = 0; v < out.height; ++v) {
    for (int u = 0; u < out.width; ++u) {
      const int x = 2 * u, y = 2 * v;
      const float picked = depth(x, y);
      if (picked == 0.0f) {
        ASSERT_EQ(out(u, v), 0.0f);
        continue;
      }
      const float surface = true_surface(kWidth, kHeight, x, y, true);
      ASSERT_LT(std::abs(out(u, v) - surface), 0.032f) << u << "," << v;
      // Away from the step, the error against the true surface.
      bool near_step = false;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          if (depth.contains(x + dx, y + dy)) near_step |= in_far_band(kWidth, kHeight, x + dx, y + dy, true) != in_far_band(kWidth, kHeight, x, y, true);
        }
      }
      if (!near_step) {
        squared_error += (out(u, v) - surface) * (out(u, v) - surface);
        squared_error_picked += (picked - surface) * (picked - surface);
        ++count;
      }
    }
  }
  const double sigma = std::sqrt(squared_error / count), sigma_picked = std::sqrt(squared_error_picked / count);
  EXPECT_NEAR(sigma_picked, 0.008, 0.0005);
  // 0.375 σ with all nine pixels, 0.397 σ with 10 % holes, and a little more where a neighbour's
  // noise puts it off the centre's surface (measured: 0.424); a box of 3×3 leaves 1/3 σ (0.35 with
  // the holes). The exact weights are TentWeightsOverTheSameSurface's. Below the full tent's
  // 0.375 σ it would average more than its 3×3 pixels (a wider window blurs a limb's curve).
  EXPECT_GT(sigma, 0.375 * sigma_picked);
  EXPECT_LT(sigma, 0.45 * sigma_picked);
}

}  // namespace
}  // namespace zipfusion
