#include "zipfusion/io/draco_codec.h"

#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <set>

#include "zipfusion/core/error.h"
#include "zipfusion/core/error_test_util.h"
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
  const std::string message = invalid_input_message([&] { decode_draco(truncated, "frame 8"); });
  EXPECT_NE(message.find("frame 8"), std::string::npos) << message;
  EXPECT_THROW(encode_draco(empty, {}, {.position_bits = 0}), InvalidInput);
}

// Draco allocates what a header claims: 103 bytes claiming 175 million faces took 15 s and
// gigabytes (fuzzing found it). The counts are bounded before Draco reads the stream.
TEST(Draco, HugeCountsInTheHeaderAreRefusedBeforeDecoding) {
  // Bitstream 2.2, a mesh by Edgebreaker, no flags; traversal 0, 3 vertices, then 2^24 faces.
  const std::string faces("DRACO\x02\x02\x01\x01\x00\x00\x00\x03\x80\x80\x80\x08\x00\x01\x00", 20);
  // The same with 1 face, 1 symbol and 2^23 split symbols, which Draco adds to the vertices.
  const std::string splits("DRACO\x02\x02\x01\x01\x00\x00\x00\x03\x01\x00\x01\x80\x80\x80\x04", 20);
  for (const auto& [bytes, message] : {std::pair{faces, "frame 9: Draco face count 16777216 is more than 8388608"},
                                       std::pair{splits, "frame 9: Draco vertex and split symbol counts 3 + 8388608 are more than 8388608"}}) {
    const std::string error = invalid_input_message([&] { decode_draco(bytes, "frame 9"); });
    EXPECT_NE(error.find(message), std::string::npos) << "expected: " << message << "\n  actual: " << error;
  }
  // The counts our own encoder writes, both methods, pass.
  const TriangleMesh sheet = wavy_sheet(20, 20);
  for (const int level : {0, 10}) {
    EXPECT_EQ(decode_draco(encode_draco(sheet, quantization_box(sheet, std::nullopt), {.compression_level = level})).triangles.size(), sheet.triangles.size());
  }
}

// Draco's Edgebreaker refused a mesh of only triangles with a repeated corner (fuzzing found it):
// they are left out at every level. A triangle of three corners at one position is kept.
TEST(Draco, TrianglesWithARepeatedCornerAreLeftOut) {
  TriangleMesh mesh = wavy_sheet(4, 4);
  mesh.positions.push_back(mesh.positions[0]);
  mesh.positions.push_back(mesh.positions[0]);
  const int n = static_cast<int>(mesh.positions.size());
  mesh.triangles.push_back({0, n - 2, n - 1});  // one position, three corners: kept
  const size_t good = mesh.triangles.size();
  mesh.triangles.push_back({0, 0, 1});
  mesh.triangles.push_back({2, 3, 2});
  const QuantizationBox box = quantization_box(mesh, std::nullopt);
  for (const int level : {0, 4, 10}) {  // sequential, and Edgebreaker at two speeds
    EXPECT_EQ(decode_draco(encode_draco(mesh, box, {.compression_level = level})).triangles.size(), good) << level;
  }
  mesh.triangles.erase(mesh.triangles.begin(), mesh.triangles.begin() + static_cast<std::ptrdiff_t>(good));
  EXPECT_TRUE(encode_draco(mesh, box).empty());
}

// Draco's own conversions read an attribute's `normalized` byte as a bool whatever the stream held
// (undefined behaviour, found by fuzzing under UBSan): values are read as stored instead, and a
// mesh whose positions are not 32-bit floats (here 16-bit integers, normalised) is refused.
TEST(Draco, PositionsThatAreNotFloatsAreRefused) {
  draco::Mesh mesh;
  mesh.set_num_points(3);
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_INT16, true, sizeof(std::int16_t) * 3, 0);
  draco::PointAttribute* positions = mesh.attribute(mesh.AddAttribute(position, true, 3));
  const std::int16_t corners[3][3] = {{0, 0, 0}, {1000, 0, 0}, {0, 1000, 0}};
  for (int i = 0; i < 3; ++i) positions->SetAttributeValue(draco::AttributeValueIndex(i), corners[i]);
  mesh.SetNumFaces(1);
  mesh.SetFace(draco::FaceIndex(0), {draco::PointIndex(0), draco::PointIndex(1), draco::PointIndex(2)});
  draco::Encoder encoder;
  draco::EncoderBuffer buffer;
  ASSERT_TRUE(encoder.EncodeMeshToBuffer(mesh, &buffer).ok());
  const std::string message = invalid_input_message([&] { decode_draco(std::string(buffer.data(), buffer.size()), "frame 10"); });
  EXPECT_NE(message.find("frame 10: POSITION: missing or not three 32-bit floats"), std::string::npos) << message;
}

// Draco's sequential decoder (compression level 0) refused what its encoder wrote for a mesh with
// a vertex no triangle uses (fuzzing found it): such vertices are not encoded, at every level.
TEST(Draco, VerticesNoTriangleUsesAreNotEncoded) {
  TriangleMesh mesh = wavy_sheet(4, 4);
  mesh.positions.push_back({0.5f, 0.5f, 0.5f});
  mesh.colors.push_back({1, 2, 3});
  for (int level = 0; level <= 10; ++level) {
    const TriangleMesh back = decode_draco(encode_draco(mesh, quantization_box(mesh, std::nullopt), {.compression_level = level}));
    EXPECT_EQ(back.triangles.size(), mesh.triangles.size()) << level;
    EXPECT_EQ(back.positions.size(), mesh.positions.size() - 1) << level;
    EXPECT_EQ(back.colors.size(), back.positions.size()) << level;
  }
}

// Positions farther apart than a float holds make the quantisation range infinite, which crashed
// Draco's encoder (fuzzing found it): refused, one line, nothing encoded.
TEST(Draco, RangesPastWhatDracosFloatsHoldAreRefused) {
  TriangleMesh mesh = wavy_sheet(4, 4);
  mesh.positions[0].z() = 3e38f;
  mesh.positions[1].z() = -3e38f;
  const QuantizationBox box = quantization_box(mesh, std::nullopt);
  EXPECT_FALSE(std::isfinite(box.range));
  const std::string message = invalid_input_message([&] { encode_draco(mesh, box); });
  EXPECT_NE(message.find("is not within a quarter of a float's range"), std::string::npos) << message;
  // A range near the largest float decoded to infinities (Draco's q · range / (2^bits − 1) rounds
  // past it): refused too.
  mesh.positions[1].z() = 0;
  EXPECT_FALSE(draco_can_quantise(quantization_box(mesh, std::nullopt)));
  EXPECT_THROW(encode_draco(mesh, quantization_box(mesh, std::nullopt)), InvalidInput);
  // Within it, the far positions come back finite.
  mesh.positions[0].z() = 8e37f;
  ASSERT_TRUE(draco_can_quantise(quantization_box(mesh, std::nullopt)));
  const TriangleMesh back = decode_draco(encode_draco(mesh, quantization_box(mesh, std::nullopt)));
  ASSERT_EQ(back.triangles.size(), mesh.triangles.size());
  for (const Eigen::Vector3f& p : back.positions) EXPECT_TRUE(p.allFinite()) << p.transpose();
}

}  // namespace
}  // namespace zipfusion
