#include "zipfusion/io/mesh_io.h"

#include <gtest/gtest.h>

#include <bit>
#include <cstring>
#include <random>
#include <string>
#include <utility>

#include "zipfusion/core/error.h"
#include "zipfusion/core/error_test_util.h"
#include "zipfusion/io/file_util.h"

namespace zipfusion {
namespace {

const std::filesystem::path kGroundTruthMesh = "../shared/data/samba-4cam/ground_truth/mesh/000000.ply";

TriangleMesh random_mesh(int vertices, int triangles, bool colors, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> coordinate(-2.0f, 2.0f);
  std::uniform_int_distribution<int> channel(0, 255);
  std::uniform_int_distribution<int> index(0, vertices - 1);
  TriangleMesh mesh;
  for (int i = 0; i < vertices; ++i) {
    mesh.positions.emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
    if (colors) {
      mesh.colors.push_back(Rgb8{static_cast<unsigned char>(channel(rng)),
                                 static_cast<unsigned char>(channel(rng)),
                                 static_cast<unsigned char>(channel(rng))});
    }
  }
  // Values that are hard to round-trip through text.
  if (vertices >= 2) {
    mesh.positions[0] = Eigen::Vector3f(1e-30f, -0.0f, 3.4e38f);
    mesh.positions[1] = Eigen::Vector3f(0.1f, 1.0f / 3.0f, std::nextafter(1.0f, 2.0f));
  }
  for (int i = 0; i < triangles; ++i) mesh.triangles.emplace_back(index(rng), index(rng), index(rng));
  return mesh;
}

void expect_identical(const TriangleMesh& a, const TriangleMesh& b) {
  ASSERT_EQ(a.positions.size(), b.positions.size());
  for (size_t i = 0; i < a.positions.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(std::bit_cast<std::uint32_t>(a.positions[i][k]),
                std::bit_cast<std::uint32_t>(b.positions[i][k]))
          << "vertex " << i << " axis " << k;
    }
  }
  EXPECT_EQ(a.colors, b.colors);
  EXPECT_EQ(a.triangles, b.triangles);
}

std::vector<std::uint8_t> bytes_of(const std::string& text) { return {text.begin(), text.end()}; }

// Appends a big-endian value.
template <typename T>
void put_be(std::vector<std::uint8_t>& out, T value) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, &value, sizeof(T));
  if (std::endian::native == std::endian::little) std::reverse(b, b + sizeof(T));
  out.insert(out.end(), b, b + sizeof(T));
}

// Runs f, expecting InvalidInput whose message contains every one of `parts`.
template <typename F>
void expect_invalid(F&& f, std::initializer_list<std::string> parts) {
  const std::string message = invalid_input_message(std::forward<F>(f));
  EXPECT_NE(message, kNoInvalidInput);
  for (const std::string& part : parts) EXPECT_NE(message.find(part), std::string::npos) << message;
}

class MeshIoFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("zf_mesh_io_test_" + std::to_string(std::random_device{}()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

TEST(MeshIo, BinaryPlyRoundTripIsExact) {
  for (const bool colors : {true, false}) {
    const TriangleMesh mesh = random_mesh(500, 900, colors, 7);
    const TriangleMesh back = parse_ply(encode_ply(mesh), "mem.ply");
    expect_identical(mesh, back);
    EXPECT_EQ(back.has_colors(), colors);
  }
}

// Vertices no triangle uses go; the others keep their order, colours and triangles.
TEST(TriangleMesh, RemoveUnreferencedVertices) {
  TriangleMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {4, 0, 0}, {5, 0, 0}};
  mesh.colors = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}, {4, 4, 4}, {5, 5, 5}};
  mesh.triangles = {{1, 3, 4}, {4, 3, 5}};
  std::vector<int> remap;
  EXPECT_EQ(remove_unreferenced_vertices(mesh, remap), 2);
  EXPECT_EQ(mesh.positions, (std::vector<Eigen::Vector3f>{{1, 0, 0}, {3, 0, 0}, {4, 0, 0}, {5, 0, 0}}));
  EXPECT_EQ(mesh.colors, (std::vector<Rgb8>{{1, 1, 1}, {3, 3, 3}, {4, 4, 4}, {5, 5, 5}}));
  EXPECT_EQ(mesh.triangles, (std::vector<Eigen::Vector3i>{{0, 1, 2}, {2, 1, 3}}));
  const TriangleMesh compact = mesh;
  EXPECT_EQ(remove_unreferenced_vertices(mesh, remap), 0);
  EXPECT_EQ(mesh.positions, compact.positions);
  EXPECT_EQ(mesh.triangles, compact.triangles);
}

TEST(MeshIo, EncodePlyWritesTheGroundTruthHeader) {
  TriangleMesh mesh;
  mesh.positions = {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}};
  mesh.colors = {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}};
  mesh.triangles = {{0, 1, 2}};
  const std::vector<std::uint8_t> bytes = encode_ply(mesh);
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n";
  ASSERT_EQ(std::string(bytes.begin(), bytes.begin() + header.size()), header);
  EXPECT_EQ(bytes.size(), header.size() + 3 * 15 + 13);
  // First vertex x = 1.0f little-endian, first face "3 0 1 2".
  EXPECT_EQ((std::vector<std::uint8_t>(bytes.begin() + header.size(), bytes.begin() + header.size() + 4)),
            (std::vector<std::uint8_t>{0x00, 0x00, 0x80, 0x3f}));
  EXPECT_EQ((std::vector<std::uint8_t>(bytes.end() - 13, bytes.end())),
            (std::vector<std::uint8_t>{3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0}));

  mesh.colors.clear();
  const std::vector<std::uint8_t> plain = encode_ply(mesh);
  EXPECT_EQ(std::string(plain.begin(), plain.begin() + 100).find("red"), std::string::npos);
  // An empty mesh of a coloured sequence keeps the colour properties (and a plain mesh with
  // vertices is not coloured by the layout).
  EXPECT_EQ(encode_ply(mesh, {.colors_when_empty = true}), plain);
  const std::vector<std::uint8_t> empty = encode_ply(TriangleMesh{}, {.colors_when_empty = true});
  EXPECT_EQ(std::string(empty.begin(), empty.end()),
            "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
            "property uchar red\nproperty uchar green\nproperty uchar blue\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n");
}

TEST(MeshIo, GroundTruthMeshReadsAndReencodesByteForByte) {
  const TriangleMesh mesh = read_ply(kGroundTruthMesh);
  EXPECT_EQ(mesh.vertex_count(), 9971u);
  EXPECT_EQ(mesh.triangle_count(), 19938u);
  ASSERT_TRUE(mesh.has_colors());
  EXPECT_EQ(mesh.colors.size(), mesh.positions.size());
  for (const Eigen::Vector3i& t : mesh.triangles) {
    ASSERT_TRUE((t.array() >= 0).all() && (t.array() < 9971).all());
  }
  // Our writer produces the very same format.
  EXPECT_EQ(encode_ply(mesh), read_file_bytes(kGroundTruthMesh));
  // read_mesh dispatches on the extension.
  EXPECT_EQ(read_mesh(kGroundTruthMesh).triangles, mesh.triangles);
}

TEST_F(MeshIoFiles, WriteAndReadBothFormats) {
  const TriangleMesh mesh = random_mesh(200, 300, true, 11);
  for (const char* name : {"a.ply", "b.obj", "C.PLY", "D.Obj"}) {
    write_mesh(dir_ / name, mesh);
    expect_identical(mesh, read_mesh(dir_ / name));
  }
  expect_invalid([&] { write_mesh(dir_ / "x.stl", mesh); }, {"x.stl", ".stl"});
  expect_invalid([&] { read_mesh(dir_ / "x.off"); }, {"x.off"});
  EXPECT_THROW(read_mesh(dir_ / "missing.ply"), IoError);
}

TEST(MeshIo, ObjRoundTripIsExact) {
  for (const bool colors : {true, false}) {
    const TriangleMesh mesh = random_mesh(500, 900, colors, 3);
    const std::string text = encode_obj(mesh);
    expect_identical(mesh, parse_obj(text, "mem.obj"));
  }
}

TEST(MeshIo, ObjFaceForms) {
  const std::string text =
      "# comment\n"
      "mtllib x.mtl\n"
      "o thing\n"
      "v 0 0 0\nv 1 0 0\nv 1 1 0\r\nv 0 1 0 1.0\n"
      "vt 0 0\nvn 0 0 1\n"
      "g group\nusemtl m\ns off\n"
      "f 1/1 2/1/1 3//1\n"
      "f -4 -2 -1   # trailing comment\n"
      "f 1 2 3 4\n"
      "l 1 2\n";
  const TriangleMesh mesh = parse_obj(text, "forms.obj");
  EXPECT_EQ(mesh.vertex_count(), 4u);
  EXPECT_FALSE(mesh.has_colors());
  const std::vector<Eigen::Vector3i> expected = {{0, 1, 2}, {0, 2, 3}, {0, 1, 2}, {0, 2, 3}};
  EXPECT_EQ(mesh.triangles, expected);
  EXPECT_EQ(mesh.positions[2], Eigen::Vector3f(1, 1, 0));
}

TEST(MeshIo, ObjColorsScaleAndPartialColorsAreDropped) {
  const TriangleMesh colored =
      parse_obj("v 0 0 0 1 0.5 0\nv 1 0 0 0 0 1\nv 0 1 0 0.2 0.2 0.2\nf 1 2 3\n", "c.obj");
  ASSERT_TRUE(colored.has_colors());
  EXPECT_EQ(colored.colors[0], (Rgb8{255, 128, 0}));
  EXPECT_EQ(colored.colors[2], (Rgb8{51, 51, 51}));
  const TriangleMesh partial = parse_obj("v 0 0 0 1 0.5 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "p.obj");
  EXPECT_FALSE(partial.has_colors());
  EXPECT_EQ(partial.vertex_count(), 3u);
}

TEST(MeshIo, ObjErrorsNameFileAndLine) {
  expect_invalid([] { parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "bad.obj"); },
                 {"bad.obj", "line 4", "4"});
  expect_invalid([] { parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "bad.obj"); }, {"bad.obj", "line 4"});
  expect_invalid([] { parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", "bad.obj"); },
                 {"bad.obj", "line 4"});
  expect_invalid([] { parse_obj("v 0 0 0\nv 1 0 0\nf 1 2\n", "bad.obj"); }, {"bad.obj", "line 3"});
  expect_invalid([] { parse_obj("\n\nv 0 zero 0\n", "bad.obj"); }, {"bad.obj", "line 3", "zero"});
  expect_invalid([] { parse_obj("v 0 0\n", "bad.obj"); }, {"bad.obj", "line 1"});
  expect_invalid([] { parse_obj("v 0 0 nan\n", "bad.obj"); }, {"bad.obj", "line 1"});
  expect_invalid([] { parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x/3\n", "bad.obj"); },
                 {"bad.obj", "line 4"});
}

// Bytes that are not OBJ are an error, not an empty mesh (a PLY or binary data named .obj); an
// empty file is an empty mesh, as write_obj writes one.
TEST(MeshIo, ObjRefusesWhatIsNotObj) {
  expect_invalid([] { parse_obj("ply\nformat binary_little_endian 1.0\nelement vertex 3\n", "renamed.obj"); },
                 {"renamed.obj", "line 1", "not an OBJ statement", "ply"});
  expect_invalid([] { parse_obj(std::string_view("v 0 0 0\n\x7f\x01\x02garbage\n", 18), "binary.obj"); }, {"binary.obj", "line 2"});
  EXPECT_EQ(parse_obj("", "empty.obj").triangle_count(), 0u);
  // The specification's other statements, and a UTF-8 byte order mark, are OBJ.
  EXPECT_EQ(parse_obj("\xEF\xBB\xBF# exported\ncsh echo\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "bom.obj").triangle_count(), 1u);
  // An included file would be geometry silently missing.
  expect_invalid([] { parse_obj("call other.obj\n", "call.obj"); }, {"call.obj", "line 1", "includes another file"});
  EXPECT_EQ(parse_obj("# only a comment\n\n", "comment.obj").vertex_count(), 0u);
}

TEST(MeshIo, AsciiPlyWithQuadExtraElementsAndProperties) {
  const std::string text =
      "ply\r\n"
      "format ascii 1.0\n"
      "comment made by hand\n"
      "obj_info nothing\n"
      "element material 2\n"
      "property uchar ambient\n"
      "property list uchar float weights\n"
      "element vertex 5\n"
      "property double x\n"
      "property list ushort int neighbours\n"
      "property float y\n"
      "property float32 nx\n"
      "property float z\n"
      "property float r\n"
      "property float g\n"
      "property float b\n"
      "element face 2\n"
      "property uchar flags\n"
      "property list uint8 uint32 vertex_index\n"
      "property list uchar float texcoord\n"
      "element edge 1\n"
      "property int vertex1\n"
      "property int vertex2\n"
      "end_header\n"
      "1 3 0.5 0.25 0.125\n"
      "2 0\n"
      "0 0 0 9 0 1 0 0\n"
      "1 2 7 8 0 9 0 0 1 0\n"
      "1 0 1 9 0 0 0 1\n"
      "0 0 1 9 0 1 1 1\n"
      "0.5 1 3 0.5 9 2 0.5 0.5 0.5\n"
      "7 4 0 1 2 3 0\n"
      "0 3 2 3 4 6 0 0 1 0 1 1\n"
      "0 1\n";
  const TriangleMesh mesh = parse_ply(bytes_of(text), "hand.ply");
  ASSERT_EQ(mesh.vertex_count(), 5u);
  EXPECT_EQ(mesh.positions[1], Eigen::Vector3f(1, 0, 0));
  EXPECT_EQ(mesh.positions[4], Eigen::Vector3f(0.5f, 0.5f, 2.0f));
  ASSERT_TRUE(mesh.has_colors());
  EXPECT_EQ(mesh.colors[0], (Rgb8{255, 0, 0}));
  EXPECT_EQ(mesh.colors[3], (Rgb8{255, 255, 255}));
  EXPECT_EQ(mesh.colors[4], (Rgb8{128, 128, 128}));
  const std::vector<Eigen::Vector3i> expected = {{0, 1, 2}, {0, 2, 3}, {2, 3, 4}};
  EXPECT_EQ(mesh.triangles, expected);
}

TEST(MeshIo, BigEndianPlyWithMixedTypes) {
  const std::string header =
      "ply\nformat binary_big_endian 1.0\n"
      "element extra 2\nproperty list int short values\nproperty double weight\n"
      "element vertex 3\nproperty int16 x\nproperty double y\nproperty float z\nproperty ushort alpha\n"
      "property uchar diffuse_red\nproperty uchar diffuse_green\nproperty uchar diffuse_blue\n"
      "element face 1\nproperty list int uint vertex_indices\nproperty list short char extra\n"
      "end_header\n";
  std::vector<std::uint8_t> bytes = bytes_of(header);
  // extra: [2 values], [0 values]
  put_be<std::int32_t>(bytes, 2);
  put_be<std::int16_t>(bytes, 5);
  put_be<std::int16_t>(bytes, -5);
  put_be<double>(bytes, 1.5);
  put_be<std::int32_t>(bytes, 0);
  put_be<double>(bytes, 2.5);
  const float zs[3] = {0.25f, -1e-20f, 3e10f};
  for (int i = 0; i < 3; ++i) {
    put_be<std::int16_t>(bytes, static_cast<std::int16_t>(-i));
    put_be<double>(bytes, 0.1 * i);
    put_be<float>(bytes, zs[i]);
    put_be<std::uint16_t>(bytes, 65535);
    bytes.insert(bytes.end(), {static_cast<std::uint8_t>(10 * i), 20, 30});
  }
  put_be<std::int32_t>(bytes, 4);
  for (std::uint32_t k : {2u, 1u, 0u, 1u}) put_be<std::uint32_t>(bytes, k);
  put_be<std::int16_t>(bytes, 1);
  bytes.push_back(static_cast<std::uint8_t>(-1));

  const TriangleMesh mesh = parse_ply(bytes, "be.ply");
  ASSERT_EQ(mesh.vertex_count(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(mesh.positions[i], Eigen::Vector3f(static_cast<float>(-i), static_cast<float>(0.1 * i), zs[i]));
    EXPECT_EQ(mesh.colors[i], (Rgb8{static_cast<unsigned char>(10 * i), 20, 30}));
  }
  const std::vector<Eigen::Vector3i> expected = {{2, 1, 0}, {2, 0, 1}};
  EXPECT_EQ(mesh.triangles, expected);

  // The same bytes claiming little endian fail cleanly (list counts become absurd).
  std::vector<std::uint8_t> wrong = bytes;
  const std::string big = "binary_big_endian";
  const auto at = std::search(wrong.begin(), wrong.end(), big.begin(), big.end());
  const std::string little = "binary_little_endian";
  wrong.erase(at, at + static_cast<long>(big.size()));
  wrong.insert(at, little.begin(), little.end());
  EXPECT_THROW(parse_ply(wrong, "le.ply"), InvalidInput);
}

TEST_F(MeshIoFiles, TruncatedBinaryPlyNamesTheFile) {
  const TriangleMesh mesh = random_mesh(50, 80, true, 5);
  const std::vector<std::uint8_t> full = encode_ply(mesh);
  const std::filesystem::path path = dir_ / "cut_mesh.ply";
  for (const size_t keep : {full.size() - 1, full.size() - 13, full.size() / 2, size_t{300}, size_t{20}}) {
    write_file_atomic(path, std::span(full.data(), keep));
    expect_invalid([&] { read_ply(path); }, {path.string()});
  }
  // Every cut point: either a clean InvalidInput or (never) a crash.
  for (size_t keep = 0; keep < full.size(); ++keep) {
    EXPECT_THROW(parse_ply(std::vector<std::uint8_t>(full.begin(), full.begin() + keep), "cut.ply"),
                 InvalidInput)
        << keep;
  }
  write_file_atomic(path, std::span(full.data(), full.size() - 1));
  expect_invalid([&] { read_ply(path); }, {"truncated"});
}

TEST(MeshIo, BadFacesNameTheFace) {
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  expect_invalid([&] { parse_ply(bytes_of(header + "3 0 1 3\n"), "idx.ply"); }, {"idx.ply", "face 1", "3"});
  expect_invalid([&] { parse_ply(bytes_of(header + "3 0 -1 2\n"), "neg.ply"); }, {"neg.ply", "face 1"});
  expect_invalid([&] { parse_ply(bytes_of(header + "2 0 1\n"), "two.ply"); }, {"two.ply", "face 1"});
  expect_invalid([&] { parse_ply(bytes_of(header + "3 0 1 x\n"), "tok.ply"); },
                 {"tok.ply", "face", "1", "'x'"});
  expect_invalid([&] { parse_ply(bytes_of(header + "3 0 1\n"), "short.ply"); }, {"short.ply", "truncated"});

  // Binary: index out of range in face 0.
  TriangleMesh mesh = random_mesh(3, 1, false, 1);
  mesh.triangles = {{0, 1, 2}};
  std::vector<std::uint8_t> bytes = encode_ply(mesh);
  bytes[bytes.size() - 4] = 3;  // last index 2 -> 3
  expect_invalid([&] { parse_ply(bytes, "bin.ply"); }, {"bin.ply", "face 0", "out of range"});
}

TEST(MeshIo, BadHeadersAreInvalidInput) {
  const std::string vertex = "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n";
  expect_invalid([] { parse_ply({}, "empty.ply"); }, {"empty.ply"});
  expect_invalid(
      [] {
        parse_ply(bytes_of("\x7f"
                           "ELF\x02\x01\x01 garbage"),
                  "elf.ply");
      },
      {"elf.ply", "not a PLY"});
  expect_invalid([&] { parse_ply(bytes_of("ply\nformat ascii 1.0\n" + vertex), "noend.ply"); },
                 {"noend.ply", "end_header"});
  expect_invalid([&] { parse_ply(bytes_of("ply\nformat text 1.0\n" + vertex + "end_header\n"), "fmt.ply"); },
                 {"fmt.ply", "text"});
  expect_invalid([&] { parse_ply(bytes_of("ply\n" + vertex + "end_header\n0 0 0\n"), "nofmt.ply"); },
                 {"nofmt.ply", "format"});
  expect_invalid(
      [] { parse_ply(bytes_of("ply\nformat ascii 1.0\nproperty float x\nend_header\n"), "p.ply"); },
      {"p.ply", "line 3"});
  expect_invalid(
      [] {
        parse_ply(bytes_of("ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\n"
                           "end_header\n"),
                  "t.ply");
      },
      {"t.ply", "float128"});
  expect_invalid(
      [] { parse_ply(bytes_of("ply\nformat ascii 1.0\nelement vertex -1\nend_header\n"), "n.ply"); },
      {"n.ply", "count"});
  expect_invalid(
      [] {
        parse_ply(bytes_of("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                           "property float y\nend_header\n1 2\n"),
                  "xyz.ply");
      },
      {"xyz.ply", "'z'"});
  expect_invalid(
      [] {
        parse_ply(bytes_of("ply\nformat ascii 1.0\nelement face 1\nproperty list float int "
                           "vertex_indices\nend_header\n3 0 1 2\n"),
                  "lc.ply");
      },
      {"lc.ply", "count type"});
  expect_invalid(
      [&] { parse_ply(bytes_of("ply\nformat ascii 1.0\n" + vertex + "end_header\n0 inf 0\n"), "i.ply"); },
      {"i.ply", "vertex 0"});
}

TEST(MeshIo, HugeDeclaredCountsAreRejectedBeforeAllocating) {
  for (const char* count : {"4000000000", "1000000000", "18446744073709551615", "9223372036854775807"}) {
    for (const char* format : {"binary_little_endian", "ascii"}) {
      const std::string text = std::string("ply\nformat ") + format + " 1.0\nelement vertex " + count +
                               "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
                               count + "\nproperty list uchar int vertex_indices\nend_header\n0123456789";
      expect_invalid([&] { parse_ply(bytes_of(text), "huge.ply"); }, {"huge.ply"});
    }
  }
  // A huge skipped element, a huge list count in a skipped element.
  expect_invalid(
      [] {
        parse_ply(bytes_of("ply\nformat binary_little_endian 1.0\nelement junk 4000000000\n"
                           "property double a\nend_header\n12345678"),
                  "junk.ply");
      },
      {"junk.ply"});
  std::vector<std::uint8_t> list = bytes_of(
      "ply\nformat binary_little_endian 1.0\nelement junk 1\n"
      "property list uint double a\nend_header\n");
  list.insert(list.end(), {0xff, 0xff, 0xff, 0xff, 0, 0, 0, 0});
  expect_invalid([&] { parse_ply(list, "list.ply"); }, {"list.ply", "truncated"});
}

TEST(MeshIo, RandomCorruptionNeverCrashes) {
  const TriangleMesh mesh = random_mesh(30, 40, true, 9);
  const std::vector<std::uint8_t> binary = encode_ply(mesh);
  std::string ascii =
      "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
      "property uchar red\nproperty uchar green\nproperty uchar blue\nelement face 2\n"
      "property list uchar int vertex_indices\nend_header\n"
      "0 0 0 1 2 3\n1 0 0 4 5 6\n1 1 0 7 8 9\n0 1 0 1 1 1\n4 0 1 2 3\n3 0 2 3\n";
  const std::vector<std::uint8_t> ascii_bytes = bytes_of(ascii);
  std::mt19937 rng(42);
  int accepted = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    std::vector<std::uint8_t> bytes = trial % 2 ? binary : ascii_bytes;
    std::uniform_int_distribution<size_t> position(0, bytes.size() - 1);
    const int edits = 1 + trial % 4;
    for (int e = 0; e < edits; ++e) bytes[position(rng)] = static_cast<std::uint8_t>(rng());
    try {
      const TriangleMesh m = parse_ply(bytes, "fuzz.ply");
      for (const Eigen::Vector3i& t : m.triangles) {
        ASSERT_TRUE((t.array() >= 0).all() && (t.array() < static_cast<int>(m.vertex_count())).all());
      }
      ++accepted;
    } catch (const InvalidInput&) {
    }
    try {
      const TriangleMesh m = parse_obj(std::string(bytes.begin(), bytes.end()), "fuzz.obj");
      for (const Eigen::Vector3i& t : m.triangles) {
        ASSERT_TRUE((t.array() >= 0).all() && (t.array() < static_cast<int>(m.vertex_count())).all());
      }
      ASSERT_TRUE(m.colors.empty() || m.colors.size() == m.positions.size());
    } catch (const InvalidInput&) {
    }
  }
  EXPECT_GT(accepted, 0);
}

}  // namespace
}  // namespace zipfusion
