#include "zipfusion/depth/sdc_mesh.h"

#include "zipfusion/core/error_test_util.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>
#include <string>
#include <tuple>
#include <utility>

namespace zipfusion {
namespace {

const Intrinsics kCamera{.width = 4, .height = 3, .fx = 100, .fy = 100, .cx = 1.5, .cy = 1.0};

Image<float> depth_from(std::initializer_list<std::initializer_list<float>> rows) {
  Image<float> depth(static_cast<int>(rows.begin()->size()), static_cast<int>(rows.size()));
  int v = 0;
  for (const auto& row : rows) {
    int u = 0;
    for (float z : row) depth(u++, v) = z;
    ++v;
  }
  return depth;
}

using TriangleSet = std::set<std::tuple<int, int, int>>;

// The triangles of a mesh as pixel-index triples.
TriangleSet triangles_of(const DepthMesh& mesh) {
  TriangleSet set;
  for (int i = 0; i < mesh.width * mesh.height; ++i) {
    for (TriangleBit bit : {kUpperTriangle, kLowerTriangle}) {
      if (!(mesh.triangles[i] & bit)) continue;
      int v[3];
      triangle_pixels(i, mesh.width, bit, v);
      set.insert({v[0], v[1], v[2]});
    }
  }
  return set;
}

DepthMesh triangulate(const Image<float>& depth, double max_jump = 0.03) {
  DepthMesh mesh;
  triangulate_sdc(depth, {.width = depth.width, .height = depth.height, .fx = 100, .fy = 100, .cx = 1.5, .cy = 1.0}, Rigid3f::Identity(),
                  {.max_depth_jump_m = max_jump}, mesh);
  return mesh;
}

// The vectorised row kernel gives, cell by cell, what the element function gives, with a
// constant threshold and with one that grows with depth.
TEST(Sdc, RowKernelMatchesTheElementFunction) {
  for (const float base_depth : {2.0f, 3.6f}) {
    Image<float> depth(37, 9);
    std::uint32_t state = 12345;
    for (float& z : depth.data) {
      state = state * 1664525u + 1013904223u;
      const int r = static_cast<int>(state >> 24);
      // Holes, and jumps around the 3 cm threshold (at 3.6 m, around its grown 6.2 cm).
      z = r < 40 ? 0.0f : base_depth + 0.0004f * (base_depth / 2) * static_cast<float>(r % 128);
    }
    for (const DepthJump jump : {DepthJump{0.03f}, depth_jump(0.03, 2.5)}) {
      int triangles = 0;
      for (int v = 0; v + 1 < depth.height; ++v) {
        std::vector<std::uint8_t> bits(depth.width - 1);
        sdc_row(depth.data.data() + v * depth.width, depth.width, depth.width - 1, jump, bits.data());
        for (int u = 0; u + 1 < depth.width; ++u) {
          EXPECT_EQ(bits[u], sdc_cell(u, v, depth.data.data(), depth.width, depth.height, jump)) << u << "," << v;
          triangles += std::popcount(bits[u]);
        }
      }
      EXPECT_GT(triangles, 20) << base_depth;  // some triangles kept and some cut: the comparisons matter
      EXPECT_LT(triangles, 2 * 36 * 8 - 20) << base_depth;
    }
  }
}

// Up to the growth depth the threshold is max_depth_jump_m; beyond, it grows with depth², judged
// at the nearer of two depths, so that a far surface's larger depth steps stay one surface while a
// step from a near surface to a far one is still cut.
TEST(Sdc, ThresholdGrowsWithTheSquareOfDepthBeyondTheGrowthDepth) {
  const DepthJump jump = depth_jump(0.03, 2.5);
  EXPECT_FLOAT_EQ(jump.between(1.0f, 1.02f), 0.03f);
  EXPECT_FLOAT_EQ(jump.between(2.5f, 2.6f), 0.03f);
  EXPECT_FLOAT_EQ(jump.between(4.0f, 4.1f), 0.03f * 4.0f * 4.0f / 6.25f);
  EXPECT_FLOAT_EQ(jump.between(4.1f, 4.0f), 0.03f * 4.0f * 4.0f / 6.25f);
  EXPECT_FLOAT_EQ(depth_jump(0.03, 0).between(4.0f, 4.1f), 0.03f);
  EXPECT_FLOAT_EQ(jump.scaled(4).between(4.0f, 4.1f), 4 * 0.03f * 4.0f * 4.0f / 6.25f);
  // A plane at 4 m sloping away 4 cm a pixel (a Kinect's depth step there is 4.6 cm): one surface
  // when the threshold grows (7.7 cm at 4 m), no triangle when it is constant; a 10 cm step on
  // it is cut either way, and at 2 m a 4 cm slope is cut too.
  auto sloped = [](float near_depth, float slope, int step_at) {
    Image<float> depth(6, 4);
    for (int v = 0; v < depth.height; ++v) {
      for (int u = 0; u < depth.width; ++u) depth(u, v) = near_depth + slope * static_cast<float>(u) + (u >= step_at ? 0.1f : 0.0f);
    }
    return depth;
  };
  auto triangles = [](const Image<float>& depth, double growth) {
    DepthMesh mesh;
    triangulate_sdc(depth, {.width = depth.width, .height = depth.height, .fx = 580, .fy = 580, .cx = 2.5, .cy = 1.5}, Rigid3f::Identity(),
                    {.max_depth_jump_m = 0.03, .growth_depth_m = growth}, mesh);
    return mesh.triangle_count();
  };
  EXPECT_EQ(triangles(sloped(4.0f, 0.04f, 99), 2.5), 2 * 5 * 3);
  EXPECT_EQ(triangles(sloped(4.0f, 0.04f, 99), 0), 0);
  EXPECT_EQ(triangles(sloped(4.0f, 0.04f, 3), 2.5), 2 * 4 * 3);  // the cells across the step go
  EXPECT_EQ(triangles(sloped(2.0f, 0.04f, 99), 2.5), 0);
  EXPECT_EQ(triangles(sloped(2.0f, 0.02f, 99), 2.5), 2 * 5 * 3);
}

TEST(Sdc, GrowthDepthIsValidated) {
  EXPECT_NO_THROW((SdcOptions{.growth_depth_m = 0}.validate()));
  EXPECT_NO_THROW((SdcOptions{.growth_depth_m = 3}.validate()));
  for (const double bad : {-1.0, 0.05, 25.0, std::nan("")}) {
    const std::string message = invalid_input_message([&] { SdcOptions{.growth_depth_m = bad}.validate(); });
    EXPECT_NE(message.find("max-depth-jump-growth"), std::string::npos) << bad << ": " << message;
  }
}

TEST(Sdc, NonzeroBytesAreVisitedOnceEachInOrder) {
  // Sparse, dense and empty words, and lengths that do not end on a word.
  std::mt19937 random(7);
  for (int count : {0, 1, 7, 8, 9, 64, 203}) {
    for (double density : {0.0, 0.05, 0.5, 1.0}) {
      std::vector<std::uint8_t> bytes(count);
      std::bernoulli_distribution set(density);
      for (auto& b : bytes) b = set(random) ? static_cast<std::uint8_t>(1 + random() % 255) : 0;
      std::vector<std::pair<int, int>> expected, visited;
      for (int i = 0; i < count; ++i) {
        if (bytes[i]) expected.emplace_back(i, bytes[i]);
      }
      for_each_nonzero_byte(bytes.data(), count, [&](int i, std::uint8_t b) { visited.emplace_back(i, b); });
      EXPECT_EQ(visited, expected) << count << " bytes, density " << density;
    }
  }
}

TEST(Sdc, GridTrianglesAtAPixelAreEveryTriangleWithThatCornerInCellOrder) {
  // Against every triangle of the grid, in cell order: each pixel of grids down to one cell and
  // one row or column of pixels (no cells), borders and corners included.
  for (const auto& [width, height] : {std::pair{1, 1}, {2, 1}, {1, 3}, {2, 2}, {3, 2}, {5, 4}}) {
    for (int pixel = 0; pixel < width * height; ++pixel) {
      std::vector<std::tuple<int, int, int, int, int, int>> expected, found;  // cell, bit, corners, k
      for (int cell_v = 0; cell_v + 1 < height; ++cell_v) {
        for (int cell_u = 0; cell_u + 1 < width; ++cell_u) {
          for (const TriangleBit bit : {kUpperTriangle, kLowerTriangle}) {
            int corners[3];
            triangle_pixels(cell_v * width + cell_u, width, bit, corners);
            for (int k = 0; k < 3; ++k) {
              if (corners[k] == pixel) expected.emplace_back(cell_v * width + cell_u, bit, corners[0], corners[1], corners[2], k);
            }
          }
        }
      }
      for_each_grid_triangle_at_pixel(pixel, width, height, [&](int cell, TriangleBit bit, const int* corners, int k) {
        found.emplace_back(cell, bit, corners[0], corners[1], corners[2], k);
      });
      EXPECT_EQ(found, expected) << width << "×" << height << ", pixel " << pixel;
    }
  }
}

TEST(Sdc, NonzeroSpanRunsFromTheFirstToPastTheLastNonzeroByte) {
  // Every placement of one or two nonzero bytes in rows that end on a word and do not, and rows
  // of zeros: the span against a byte-by-byte search.
  for (int count : {0, 1, 5, 8, 9, 16, 23, 40}) {
    EXPECT_EQ(nonzero_span(std::vector<std::uint8_t>(count, 0).data(), count), std::make_pair(0, 0)) << count;
    for (int i = 0; i < count; ++i) {
      for (int j = i; j < count; ++j) {
        std::vector<std::uint8_t> bytes(count, 0);
        bytes[i] = 3;
        bytes[j] = 200;
        EXPECT_EQ(nonzero_span(bytes.data(), count), std::make_pair(i, j + 1)) << count << " bytes, set at " << i << " and " << j;
      }
    }
  }
}

TEST(Sdc, FlatPatchIsFullyTriangulated) {
  const DepthMesh mesh = triangulate(depth_from({{2, 2, 2, 2}, {2, 2, 2, 2}, {2, 2, 2, 2}}));
  // Pixels are numbered row-major: 0 1 2 3 / 4 5 6 7 / 8 9 10 11.
  const TriangleSet expected = {{0, 4, 1}, {1, 4, 5}, {1, 5, 2}, {2, 5, 6}, {2, 6, 3}, {3, 6, 7},
                                {4, 8, 5}, {5, 8, 9}, {5, 9, 6}, {6, 9, 10}, {6, 10, 7}, {7, 10, 11}};
  EXPECT_EQ(triangles_of(mesh), expected);
  EXPECT_EQ(mesh.triangle_count(), 12);
}

// Taking the depth image's buffer gives the mesh the copy would give, frame after frame (the
// second frame reuses the buffers the first swapped), and hands back a buffer of the image's size.
TEST(Sdc, TakingTheDepthGivesTheSameMeshAsCopyingIt) {
  const Intrinsics k{.width = 4, .height = 3, .fx = 100, .fy = 100, .cx = 1.5, .cy = 1.0};
  DepthMesh taken;
  for (const Image<float>& frame : {depth_from({{2, 2, 2, 2.05f}, {2, 0, 2, 2}, {2, 2, 2.029f, 2}}),
                                    depth_from({{0, 0, 3, 3}, {3, 3, 3, 3}, {3, 3.1f, 3, 0}})}) {
    const DepthMesh copied = triangulate(frame);
    Image<float> depth = frame;
    triangulate_sdc_taking_depth(depth, k, Rigid3f::Identity(), {.max_depth_jump_m = 0.03}, taken);
    EXPECT_EQ(taken.depth, frame.data);
    EXPECT_EQ(triangles_of(taken), triangles_of(copied));
    EXPECT_EQ(taken.triangles, copied.triangles);
    EXPECT_EQ(taken.box().u0, copied.box().u0);
    EXPECT_EQ(taken.box().v1, copied.box().v1);
    EXPECT_EQ(depth.data.size(), frame.data.size());
    EXPECT_EQ(depth.width, frame.width);
  }
}

// Triangulation forms only the cells where a row's pixels with depth meet the next row's; every
// other cell must come out as the element function says (none), and the box must hold every
// pixel with depth. Blobs of depth with ragged rows, empty rows, rows that end at either edge
// and one pixel wide, with holes and steps; each frame reuses the mesh the one before left.
TEST(Sdc, TriangulationOverRowSpansMatchesTheElementFunctionEverywhere) {
  std::mt19937 random(11);
  DepthMesh mesh;
  for (int frame = 0; frame < 40; ++frame) {
    const int width = 5 + static_cast<int>(random() % 40), height = 3 + static_cast<int>(random() % 20);
    Image<float> depth(width, height);
    for (int v = 0; v < height; ++v) {
      if (random() % 5 == 0) continue;  // an empty row
      const int a = static_cast<int>(random() % width), b = static_cast<int>(random() % width);
      for (int u = std::min(a, b); u <= std::max(a, b); ++u) {
        if (random() % 9 == 0) continue;  // a hole
        depth(u, v) = 2.0f + 0.01f * static_cast<float>(random() % 6);  // steps up to 5 cm against 3 cm
      }
    }
    const Intrinsics k{.width = width, .height = height, .fx = 100, .fy = 100, .cx = width / 2.0, .cy = height / 2.0};
    triangulate_sdc(depth, k, Rigid3f::Identity(), {.max_depth_jump_m = 0.03}, mesh);
    const DepthJump jump = depth_jump(SdcOptions{.max_depth_jump_m = 0.03});
    const PixelBox box = mesh.box();
    for (int v = 0; v < height; ++v) {
      for (int u = 0; u < width; ++u) {
        ASSERT_EQ(mesh.triangles[v * width + u], sdc_cell(u, v, depth.data.data(), width, height, jump))
            << "frame " << frame << ", cell " << u << ", " << v;
        if (depth(u, v) > 0) {
          ASSERT_TRUE(u >= box.u0 && u < box.u1 && v >= box.v0 && v < box.v1) << "frame " << frame << ", pixel " << u << ", " << v;
        }
      }
    }
  }
}

TEST(Sdc, MissingDepthAndStepsRemoveExactlyTheirTriangles) {
  // Pixel 5 has no depth; pixel 3 stands 5 cm behind its neighbours (a step); pixel 10 is 2.9 cm
  // off, within the 3 cm threshold.
  const DepthMesh mesh = triangulate(depth_from({{2, 2, 2, 2.05f}, {2, 0, 2, 2}, {2, 2, 2.029f, 2}}));
  const TriangleSet expected = {{0, 4, 1}, {6, 9, 10}, {6, 10, 7}, {7, 10, 11}};
  EXPECT_EQ(triangles_of(mesh), expected);
}

TEST(Sdc, ThresholdIsStrict) {
  EXPECT_EQ(triangulate(depth_from({{2, 2}, {2, 2.0299f}})).triangle_count(), 2);
  EXPECT_EQ(triangulate(depth_from({{2, 2}, {2, 2.0301f}})).triangle_count(), 1);  // only the upper triangle
  EXPECT_EQ(triangulate(depth_from({{2, 2}, {2, 2.0301f}}), 0.05).triangle_count(), 2);
}

TEST(Sdc, TrianglesFaceTheCameraAndPointsUnproject) {
  const DepthMesh mesh = triangulate(depth_from({{2, 2}, {2, 2}}));
  const Eigen::Vector3f p0 = mesh.point(0);
  EXPECT_NEAR(p0.x(), (0 - 1.5f) * 2 / 100, 1e-6);
  EXPECT_NEAR(p0.y(), (0 - 1.0f) * 2 / 100, 1e-6);
  EXPECT_FLOAT_EQ(p0.z(), 2);
  for (TriangleBit bit : {kUpperTriangle, kLowerTriangle}) {
    int v[3];
    triangle_pixels(0, 2, bit, v);
    const Eigen::Vector3f normal = (mesh.point(v[1]) - mesh.point(v[0])).cross(mesh.point(v[2]) - mesh.point(v[0]));
    EXPECT_LT(normal.z(), 0) << "normal must point towards the camera (−z)";
  }
}

TEST(Sdc, BoundaryTrianglesAreThoseMissingANeighbour) {
  // A 5×5 valid patch: 4×4 cells, 32 triangles. Interior triangles have all three neighbours.
  Image<float> depth(5, 5, 2.0f);
  DepthMesh mesh = triangulate(depth);
  int boundary = 0;
  for (int i = 0; i < 25; ++i) {
    for (TriangleBit bit : {kUpperTriangle, kLowerTriangle}) boundary += is_boundary_triangle(mesh.triangles.data(), i, 5, bit);
  }
  // Around a 4×4 cell grid: upper triangles on the top row and left column, lower triangles on
  // the bottom row and right column: 4 + 4 − 1 (corner cell counted once) each.
  EXPECT_EQ(boundary, 14);
  // Removing the lower triangle of the centre cell (1,1) exposes its three neighbours.
  const int centre = 1 * 5 + 1;
  EXPECT_FALSE(is_boundary_triangle(mesh.triangles.data(), centre + 1, 5, kUpperTriangle));
  mesh.triangles[centre] &= ~kLowerTriangle;
  EXPECT_TRUE(is_boundary_triangle(mesh.triangles.data(), centre, 5, kUpperTriangle));
  EXPECT_TRUE(is_boundary_triangle(mesh.triangles.data(), centre + 1, 5, kUpperTriangle));
  EXPECT_TRUE(is_boundary_triangle(mesh.triangles.data(), centre + 5, 5, kUpperTriangle));
  EXPECT_FALSE(is_boundary_triangle(mesh.triangles.data(), centre, 5, kLowerTriangle));  // gone
}

TEST(Sdc, AppendCompactsVerticesAndSharesThem) {
  const DepthMesh mesh = triangulate(depth_from({{2, 2, 0}, {2, 2, 0}, {0, 0, 0}}));
  std::vector<Rgb8> colors(9, Rgb8{1, 2, 3});
  colors[4] = {9, 9, 9};
  TriangleMesh out;
  std::vector<int> scratch;
  append_depth_mesh(mesh, colors, out, scratch);
  ASSERT_EQ(out.triangle_count(), 2u);
  ASSERT_EQ(out.vertex_count(), 4u);  // pixels 0, 1, 3, 4 once each
  ASSERT_EQ(out.colors.size(), 4u);
  int nines = 0;
  for (const Rgb8& c : out.colors) nines += c == Rgb8{9, 9, 9};
  EXPECT_EQ(nines, 1);
  // Appending again offsets the indices.
  append_depth_mesh(mesh, colors, out, scratch);
  EXPECT_EQ(out.vertex_count(), 8u);
  EXPECT_EQ(out.triangles[2].minCoeff(), 4);
}

// The threshold is the reference at 580 px, scaled up by 580/f for a shorter focal length, kept for
// a longer one; f is the larger of fx and fy (the closer-spaced direction).
TEST(Sdc, DepthJumpFollowsTheFocalLength) {
  auto intrinsics = [](double fx, double fy) { return Intrinsics{.width = 48, .height = 36, .fx = fx, .fy = fy, .cx = 23.5, .cy = 17.5}; };
  EXPECT_EQ(sdc_depth_jump(0.03, intrinsics(580, 580)), 0.03);
  EXPECT_EQ(sdc_depth_jump(0.03, intrinsics(290, 290)), 0.06);
  EXPECT_DOUBLE_EQ(sdc_depth_jump(0.03, intrinsics(525, 525)), 0.03 * 580 / 525);
  EXPECT_EQ(sdc_depth_jump(0.03, intrinsics(1160, 1160)), 0.03);
  EXPECT_EQ(sdc_depth_jump(0.03, intrinsics(290, 580)), 0.03);
  EXPECT_EQ(sdc_depth_jump(0.03, intrinsics(580, 290)), 0.03);
}

TEST(Sdc, ProjectPinholeInvertsUnproject) {
  Rigid3f world_from_depth = Rigid3f::Identity();
  world_from_depth.linear() = Eigen::AngleAxisf(0.3f, Eigen::Vector3f::UnitY()).toRotationMatrix();
  world_from_depth.translation() = Eigen::Vector3f(0.5f, -1, 2);
  const Eigen::Vector3f p_world = world_from_depth * unproject(kCamera, 2.25f, 0.5f, 3.0f);
  const Eigen::Vector3f p = world_from_depth.inverse() * p_world;
  const Eigen::Vector2f pixel = project_pinhole(kCamera, p);
  EXPECT_NEAR(pixel.x(), 2.25f, 1e-4);
  EXPECT_NEAR(pixel.y(), 0.5f, 1e-4);
  EXPECT_NEAR(p.z(), 3.0f, 1e-5);
}

}  // namespace
}  // namespace zipfusion
