#include "zipfusion/io/draco_codec.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <set>

#include "zipfusion/core/error.h"
#include "zipfusion/core/mesh_test_util.h"

namespace zipfusion {
namespace {

// A wavy coloured sheet, 1 m × 1.5 m, vertices 5 mm apart (farther than the quantisation error,
// so each decoded vertex maps back to one original).
TriangleMesh wavy_sheet(int nu, int nv) {
  TriangleMesh mesh = grid_mesh(nu, nv, [&](float s, float t) {
    const float x = 0.005f * nu * s, z = 0.3f + 0.005f * nv * t;
    return Eigen::Vector3f(x - 0.4f, 0.05f * std::sin(10.0f * x) + 0.02f * std::cos(7.0f * z), z);
  });
  for (int j = 0; j <= nv; ++j) {
    for (int i = 0; i <= nu; ++i) mesh.colors.push_back({static_cast<unsigned char>(i % 256), static_cast<unsigned char>(j % 256), 77});
  }
  return mesh;
}

TEST(Draco, RoundTripWithinTheQuantisationStep) {
  const TriangleMesh mesh = wavy_sheet(200, 300);
  const Box3d volume{{-1, -1, 0.02}, {1, 1, 2.2}};
  const QuantizationBox box = quantization_box(mesh, volume);
  EXPECT_FLOAT_EQ(box.range, 2.18f);  // the volume's longest side
  for (const int bits : {11, 14}) {
    const std::string bytes = encode_draco(mesh, box, {.position_bits = bits});
    const TriangleMesh back = decode_draco(bytes);
    const float bound = box.max_error(bits);
    ASSERT_EQ(back.triangles.size(), mesh.triangles.size());
    ASSERT_EQ(back.positions.size(), mesh.positions.size());
    ASSERT_EQ(back.colors.size(), back.positions.size());
    // Every decoded vertex lies within the bound of exactly one original vertex (the grid is 5 mm;
    // the bound is 0.9 mm at 11 bits), with its colour unchanged.
    std::vector<int> original(back.positions.size(), -1);
    float worst = 0;
    for (size_t k = 0; k < back.positions.size(); ++k) {
      const Eigen::Vector3f& p = back.positions[k];
      const int i = static_cast<int>(std::lround((p.x() + 0.4f) / 0.005f)), j = static_cast<int>(std::lround((p.z() - 0.3f) / 0.005f));
      ASSERT_TRUE(i >= 0 && i <= 200 && j >= 0 && j <= 300) << k;
      original[k] = j * 201 + i;
      worst = std::max(worst, (p - mesh.positions[original[k]]).norm());
      EXPECT_EQ(back.colors[k], mesh.colors[original[k]]);
    }
    EXPECT_LE(worst, bound) << bits << " bits";
    EXPECT_GT(worst, bound / 20) << "positions are quantised, not copied";
    // The same triangles, each with its orientation (as a cyclic order of original vertices).
    auto canonical = [](int a, int b, int c) {
      const int m = std::min({a, b, c});
      return m == a ? std::tuple(a, b, c) : m == b ? std::tuple(b, c, a) : std::tuple(c, a, b);
    };
    std::set<std::tuple<int, int, int>> expected, got;
    for (const Eigen::Vector3i& t : mesh.triangles) expected.insert(canonical(t[0], t[1], t[2]));
    for (const Eigen::Vector3i& t : back.triangles) got.insert(canonical(original[t[0]], original[t[1]], original[t[2]]));
    EXPECT_EQ(got, expected);
  }
}

TEST(Draco, CompressesWellBelowThePlainMesh) {
  const TriangleMesh mesh = wavy_sheet(200, 300);
  const std::string bytes = encode_draco(mesh, quantization_box(mesh, std::nullopt));
  const size_t plain = mesh.positions.size() * (12 + 3) + mesh.triangles.size() * 12;
  EXPECT_LT(bytes.size() * 10, plain) << bytes.size() << " of " << plain;
}

TEST(Draco, EmptyMeshesAndGarbageAreHandled) {
  const TriangleMesh empty;
  const TriangleMesh back = decode_draco(encode_draco(empty, quantization_box(empty, std::nullopt)));
  EXPECT_TRUE(back.triangles.empty());
  EXPECT_THROW(decode_draco("not a mesh at all", "frame 7"), InvalidInput);
  std::string truncated = encode_draco(wavy_sheet(20, 20), quantization_box(wavy_sheet(20, 20), std::nullopt));
  truncated.resize(truncated.size() / 2);
  try {
    decode_draco(truncated, "frame 8");
    FAIL() << "a truncated buffer decoded";
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("frame 8"), std::string::npos);
  }
  EXPECT_THROW(encode_draco(empty, {}, {.position_bits = 0}), InvalidInput);
}

}  // namespace
}  // namespace zipfusion
