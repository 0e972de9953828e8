#include "zipfusion/fusion/surface_fit.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

namespace zipfusion {
namespace {

const Intrinsics kSmall{.width = 37, .height = 29, .fx = 33, .fy = 33, .cx = 18, .cy = 14};

DepthMesh depth_only(int width, int height) {
  DepthMesh mesh;
  reset_depth_mesh(mesh, width, height);
  return mesh;
}

MeshView view_of(DepthMesh& mesh, const Intrinsics& k) {
  MeshView view{&mesh, k, Rigid3f::Identity(), nullptr, 0, 0};
  view.same_surface = 0.03f;
  return view;
}

TEST(SurfaceFit, RecoversATiltedPlaneAndLeavesOtherSurfacesOut) {
  DepthMesh mesh = depth_only(kSmall.width, kSmall.height);
  const int u = 18, v = 14, pixel = v * kSmall.width + u;
  for (int y = 0; y < kSmall.height; ++y) {
    for (int x = 0; x < kSmall.width; ++x) mesh.depth[y * kSmall.width + x] = 2.0f + 0.004f * (x - u) - 0.002f * (y - v);
  }
  // A nearer surface over part of the window (a step of 0.3 m, ten times the threshold) and a hole.
  for (int y = v - 2; y <= v; ++y) {
    for (int x = u + 1; x <= u + 2; ++x) mesh.depth[y * kSmall.width + x] -= 0.3f;
  }
  mesh.depth[(v + 1) * kSmall.width + u - 1] = 0;
  const MeshView view = view_of(mesh, kSmall);
  for (const int spacing : {1, 2}) {
    const SurfaceFit fit = fit_surface(view, pixel, 2, spacing);
    ASSERT_TRUE(fit.sloped);
    EXPECT_NEAR(fit.du, 0.004f, 1e-5f) << "spacing " << spacing;
    EXPECT_NEAR(fit.dv, -0.002f, 1e-5f) << "spacing " << spacing;
    EXPECT_NEAR(fit.depth_at(0, 0), 2.0f, 1e-5f) << "spacing " << spacing;
  }
  // The 3 × 3 window's six pixels on the plane: x offsets −1, 0, −1, 0, 0, 1 and y offsets −1, −1, 0,
  // 0, 1, 1 from the centre.
  EXPECT_NEAR(smoothed_depth(view, pixel, 1), 2.0f + 0.004f * (-1.0f / 6), 1e-6f);

  // Only one row of the window on the surface: no slope.
  for (int y = 0; y < kSmall.height; ++y) {
    if (y != v) {
      for (int x = 0; x < kSmall.width; ++x) mesh.depth[y * kSmall.width + x] = 1.0f;
    }
  }
  EXPECT_FALSE(fit_surface(view, pixel, 2, 1).sloped);
}

// The same floats, bit for bit: the seams' points come out where the element functions put them.
bool same_bits(float a, float b) { return std::bit_cast<std::uint32_t>(a) == std::bit_cast<std::uint32_t>(b); }

TEST(SurfaceFit, ManyWindowsAtOnceGiveTheElementFunctionsFloats) {
  // Noisy depth in two layers with holes, and a few pixels whose depth is not a depth (infinite,
  // NaN, negative: they must add nothing, not poison a sum): every pixel with depth is a window's
  // centre, the image's edges and corners included, more windows than one chunk.
  DepthMesh mesh = depth_only(kSmall.width, kSmall.height);
  std::mt19937 random(11);
  std::uniform_real_distribution<float> noise(-0.012f, 0.012f), unit(0.0f, 1.0f);
  std::vector<int> pixels;
  for (int y = 0; y < kSmall.height; ++y) {
    for (int x = 0; x < kSmall.width; ++x) {
      const float layer = (x + 2 * y) % 11 < 4 ? 1.6f : 2.4f;
      const float odd = unit(random);
      const float not_depth = odd < 0.01f   ? std::numeric_limits<float>::infinity()
                              : odd < 0.02f ? std::numeric_limits<float>::quiet_NaN()
                                            : -1.0f;
      const float z = unit(random) < 0.15f ? 0.0f : odd < 0.03f ? not_depth : layer + 0.01f * x + noise(random);
      mesh.depth[y * kSmall.width + x] = z;
      if (z > 0 && std::isfinite(z)) pixels.push_back(y * kSmall.width + x);
    }
  }
  ASSERT_GT(pixels.size(), 600u);
  const MeshView view = view_of(mesh, kSmall);
  std::vector<SurfaceFit> fits(pixels.size());
  std::vector<float> depths(pixels.size());
  // Every window the seams use (normal planes: radius 1 spacing 2, radius 2 spacing 1 + r / 2 for
  // smoothing r = 1–4; planes and means over radius r), and one wider than the row kernels take.
  for (const auto& [radius, spacing] : {std::pair{1, 1}, {1, 2}, {2, 1}, {2, 2}, {2, 3}, {3, 1}}) {
    fit_surfaces(view, pixels, radius, spacing, fits.data());
    for (size_t k = 0; k < pixels.size(); ++k) {
      const SurfaceFit one = fit_surface(view, pixels[k], radius, spacing);
      const bool same = same_bits(fits[k].depth, one.depth) && same_bits(fits[k].du, one.du) && same_bits(fits[k].dv, one.dv) &&
                        same_bits(fits[k].cu, one.cu) && same_bits(fits[k].cv, one.cv) && fits[k].sloped == one.sloped;
      ASSERT_TRUE(same) << "radius " << radius << ", spacing " << spacing << ", pixel (" << pixels[k] % kSmall.width << ", "
                        << pixels[k] / kSmall.width << "): depth " << fits[k].depth << " against " << one.depth;
    }
  }
  for (const int radius : {1, 2, 3}) {
    smoothed_depths(view, pixels, radius, depths.data());
    for (size_t k = 0; k < pixels.size(); ++k) {
      ASSERT_TRUE(same_bits(depths[k], smoothed_depth(view, pixels[k], radius)))
          << "radius " << radius << ", pixel (" << pixels[k] % kSmall.width << ", " << pixels[k] / kSmall.width << ")";
    }
  }
}

}  // namespace
}  // namespace zipfusion
