#include "zipfusion/depth/color_lookup.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

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

// The row kernel behind sample_row gives sample_bilinear's colours bit for bit: on noise (every
// weight shows), at the image's edges and corners (the last pixels' reads are moved back from the
// end), outside it, at NaN and infinity, and on images too small for its eight-byte reads.
TEST(ColorLookup, SampleRowGivesTheElementFunctionsColours) {
  CameraModel camera;
  camera.depth_intrinsics = {.width = 4, .height = 4, .fx = 4, .fy = 4, .cx = 2, .cy = 2};
  camera.color_intrinsics = Intrinsics{.width = 4, .height = 4, .fx = 4, .fy = 4, .cx = 2, .cy = 2};
  std::uint32_t state = 12345;
  auto next = [&] { return state = state * 1664525u + 1013904223u; };
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  for (const auto& [width, height] : {std::pair{1, 1}, {2, 1}, {1, 3}, {3, 1}, {2, 2}, {37, 5}, {640, 480}}) {
    ColorImage image(width, height);
    for (Rgb8& c : image.data) c = {static_cast<unsigned char>(next() >> 24), static_cast<unsigned char>(next() >> 24), static_cast<unsigned char>(next() >> 24)};
    const ColorLookup lookup(camera, &image);
    std::vector<float> x, y;
    const float w = static_cast<float>(width - 1), h = static_cast<float>(height - 1);
    for (const float ex : {0.0f, w, std::nextafter(w, 0.0f), std::nextafter(w, 1e9f), -0.0f, -1e-7f}) {
      for (const float ey : {0.0f, h, std::nextafter(h, 0.0f), std::nextafter(h, 1e9f)}) {
        x.push_back(ex);
        y.push_back(ey);
      }
    }
    for (const float bad : {nan, inf, -inf, -1.0f}) {
      x.insert(x.end(), {bad, 0.5f * w, bad});
      y.insert(y.end(), {0.5f * h, bad, bad});
    }
    // Alternately inside the image and anywhere up to a pixel around it.
    while (x.size() < 3 * ColorLookup::kRowChunk) {
      const float margin = x.size() % 2 == 0 ? 0.0f : 1.0f;
      x.push_back(static_cast<float>(next() % 100000) * (w + 2 * margin) / 100000.0f - margin);
      y.push_back(static_cast<float>(next() % 100000) * (h + 2 * margin) / 100000.0f - margin);
    }
    int inside = 0;
    for (size_t first = 0; first < x.size(); first += ColorLookup::kRowChunk) {
      const int count = static_cast<int>(std::min<size_t>(ColorLookup::kRowChunk, x.size() - first));
      std::uint32_t packed[ColorLookup::kRowChunk];
      lookup.sample_row(x.data() + first, y.data() + first, count, packed);
      for (int i = 0; i < count; ++i) {
        const Rgb8 expected = sample_bilinear(image, x[first + i], y[first + i]);
        EXPECT_EQ(ColorLookup::unpack_rgb(packed[i]), expected) << width << "×" << height << " at " << x[first + i] << ", " << y[first + i];
        inside += !(expected == kNoColor);
      }
    }
    EXPECT_GT(inside, ColorLookup::kRowChunk) << width << "×" << height;
  }
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

// The row form (project_row, then sample) and lookup_colors, which uses it, must give exactly
// the colours at() gives, pixel by pixel: over rows longer than one chunk, for a rotated colour
// camera with and without distortion, at depths where points fall outside the colour image and
// behind the colour camera.
TEST(ColorLookup, RowFormGivesTheColoursOfThePixelForm) {
  for (const bool distorted : {false, true}) {
    CameraModel camera;
    const int width = ColorLookup::kRowChunk + 45, height = 7;
    camera.depth_intrinsics = {.width = width, .height = height, .fx = 140, .fy = 150, .cx = 150.3, .cy = 3.2};
    Intrinsics color_k{.width = 320, .height = 90, .fx = 160, .fy = 155, .cx = 160.7, .cy = 44.1};
    if (distorted) {
      color_k.distortion = {0.08, -0.11, 0.002, -0.001, 0.02};
      color_k.has_distortion = true;
    }
    camera.color_intrinsics = color_k;
    // Rotated 10° about y and placed 1.1 m in front of the depth camera: depths up to 1.1 m
    // (plus the rotation's share) lie behind it.
    camera.color_from_depth.linear() = Eigen::AngleAxisd(0.17, Eigen::Vector3d::UnitY()).toRotationMatrix();
    camera.color_from_depth.translation() = Eigen::Vector3d(0.03, -0.01, -1.1);
    DepthMesh mesh;
    mesh.width = width;
    mesh.height = height;
    mesh.depth.resize(static_cast<size_t>(width) * height);
    for (int i = 0; i < width * height; ++i) mesh.depth[i] = i % 11 == 0 ? 0.0f : 0.6f + 0.004f * static_cast<float>((i * 37) % 500);
    ColorImage image(320, 90);
    for (int y = 0; y < 90; ++y) {
      for (int x = 0; x < 320; ++x) image(x, y) = {static_cast<unsigned char>((x * 7 + y) % 256), static_cast<unsigned char>((y * 13) % 256), 5};
    }
    const ColorLookup lookup(camera, &image);
    std::vector<Rgb8> colors;
    lookup_colors(mesh, camera, &image, colors);
    int behind = 0, inside = 0;
    float x[ColorLookup::kRowChunk], y[ColorLookup::kRowChunk];
    for (int v = 0; v < height; ++v) {
      for (int u0 = 0; u0 < width; u0 += ColorLookup::kRowChunk) {
        const int count = std::min(ColorLookup::kRowChunk, width - u0);
        lookup.project_row(v, u0, count, mesh.depth.data() + v * width + u0, x, y);
        for (int i = 0; i < count; ++i) {
          const int u = u0 + i;
          const float z = mesh.depth[v * width + u];
          if (z <= 0) {
            EXPECT_EQ(colors[v * width + u], kNoColor);
            continue;
          }
          const Rgb8 expected = lookup.at(u, v, z);
          EXPECT_EQ(lookup.sample(x[i], y[i]), expected) << u << "," << v << (distorted ? " distorted" : "");
          EXPECT_EQ(colors[v * width + u], expected) << u << "," << v << (distorted ? " distorted" : "");
          behind += x[i] == -1.0f;
          inside += !(expected == kNoColor);
        }
      }
    }
    EXPECT_GT(behind, 100);  // the case behind the colour camera is exercised
    EXPECT_GT(inside, 500);  // and so is the sampling
  }
}

}  // namespace
}  // namespace zipfusion
