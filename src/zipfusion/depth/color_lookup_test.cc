#include "zipfusion/depth/color_lookup.h"

#include <gtest/gtest.h>

namespace zipfusion {
namespace {

// A colour image whose red channel is 2·x and green 3·y: bilinear sampling is exact on it.
ColorImage gradient(int width, int height) {
  ColorImage image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) image(x, y) = {static_cast<unsigned char>(2 * x), static_cast<unsigned char>(3 * y), 77};
  }
  return image;
}

TEST(ColorLookup, BilinearSamplingIsExactOnAGradient) {
  const ColorImage image = gradient(100, 80);
  const Rgb8 c = sample_bilinear(image, 10.25f, 20.75f);
  EXPECT_EQ(c.r, 21);  // 2 × 10.25 = 20.5 → 21
  EXPECT_EQ(c.g, 62);  // 3 × 20.75 = 62.25 → 62
  EXPECT_EQ(c.b, 77);
  EXPECT_EQ(sample_bilinear(image, -0.5f, 3), kNoColor);
  EXPECT_EQ(sample_bilinear(image, 99.0f, 79.0f), (Rgb8{198, 237, 77}));
}

TEST(ColorLookup, ProjectsThroughColorFromDepth) {
  // A depth camera 2 m in front of a plane; the colour camera is 5 cm to its right (+x) with
  // other intrinsics. The colour at each pixel must be the gradient at the point's projection.
  CameraModel camera;
  camera.depth_intrinsics = {.width = 32, .height = 24, .fx = 30, .fy = 30, .cx = 15.5, .cy = 11.5};
  camera.color_intrinsics = Intrinsics{.width = 100, .height = 80, .fx = 90, .fy = 90, .cx = 49.5, .cy = 39.5};
  camera.color_from_depth.translation() = Eigen::Vector3f(-0.05f, 0, 0).cast<double>();
  DepthMesh mesh;
  mesh.width = 32;
  mesh.height = 24;
  mesh.depth.assign(32 * 24, 2.0f);
  mesh.depth[5] = 0;
  const ColorImage image = gradient(100, 80);
  std::vector<Rgb8> colors;
  lookup_colors(mesh, camera, &image, colors);
  ASSERT_EQ(colors.size(), 32u * 24u);
  EXPECT_EQ(colors[5], kNoColor);
  for (int v = 0; v < 24; v += 5) {
    for (int u = 0; u < 32; u += 3) {
      if (u == 5 && v == 0) continue;
      const float x = (u - 15.5f) * 2 / 30 - 0.05f, y = (v - 11.5f) * 2 / 30;
      const float cu = 90 * x / 2 + 49.5f, cv = 90 * y / 2 + 39.5f;
      const Rgb8 c = colors[v * 32 + u];
      EXPECT_NEAR(c.r, 2 * cu, 0.51) << u << "," << v;
      EXPECT_NEAR(c.g, 3 * cv, 0.51) << u << "," << v;
    }
  }
  // Without a colour image every vertex is grey.
  lookup_colors(mesh, camera, nullptr, colors);
  for (const Rgb8& c : colors) EXPECT_EQ(c, kNoColor);
}

}  // namespace
}  // namespace zipfusion
