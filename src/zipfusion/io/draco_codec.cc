#include "zipfusion/io/draco_codec.h"

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>

#include "zipfusion/core/error.h"

namespace zipfusion {

void DracoOptions::validate() const {
  if (position_bits < 1 || position_bits > 30) throw InvalidInput("--position-bits: must be in [1, 30]");
  if (compression_level < 0 || compression_level > 10) throw InvalidInput("--compression-level: must be in [0, 10]");
}

float QuantizationBox::max_error(int bits) const {
  // Each coordinate rounds to the nearest of 2^bits − 1 steps over the range: at most half a step.
  return 0.5f * step(bits) * std::sqrt(3.0f);
}

QuantizationBox quantization_box(const TriangleMesh& mesh, const std::optional<Box3d>& volume) {
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity()), hi = -lo;
  if (volume) {
    lo = volume->min.cast<float>();
    hi = volume->max.cast<float>();
  }
  for (const Eigen::Vector3f& p : mesh.positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  if (!(lo.array() <= hi.array()).all()) return {};  // no volume, no vertices
  return {lo, std::max((hi - lo).maxCoeff(), 1e-6f)};
}

bool draco_can_quantise(const QuantizationBox& box) {
  // Draco quantises over the box without checking it (fuzzing found both): an infinite range
  // crashed its encoder, and its decoder's q · (range / (2^bits − 1)) rounds past a float's
  // largest value for a range near it (3.4e38 decoded to infinities). A quarter of the largest
  // float keeps the product and the sum with the origin finite.
  constexpr float kMost = std::numeric_limits<float>::max() / 4;
  return box.origin.allFinite() && std::isfinite(box.range) && box.range > 0 && box.range <= kMost &&
         (box.origin.array().abs() + box.range <= kMost).all();
}

std::string encode_draco(const TriangleMesh& mesh, const QuantizationBox& box, const DracoOptions& options) {
  options.validate();
  // Draco's Edgebreaker drops a face with a repeated corner and refuses a mesh of only those
  // (fuzzing found the refusal): they are left out at every level, and a mesh with none else is
  // empty. Draco's sequential decoder (compression level 0) refused what its encoder wrote for
  // points that no face uses (fuzzing found it): only the used vertices are encoded, in their
  // order.
  auto repeats_a_corner = [](const Eigen::Vector3i& t) { return t[0] == t[1] || t[1] == t[2] || t[0] == t[2]; };
  std::vector<int> point_of_vertex(mesh.positions.size(), -1);
  size_t faces = 0;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    if (repeats_a_corner(t)) continue;
    point_of_vertex[t[0]] = point_of_vertex[t[1]] = point_of_vertex[t[2]] = 0;
    ++faces;
  }
  if (faces == 0) return {};  // Draco has no encoding of an empty mesh
  if (!draco_can_quantise(box)) {
    char what[160];
    std::snprintf(what, sizeof what, "draco: the quantisation box (origin %g %g %g, range %g) is not within a quarter of a float's range", box.origin.x(),
                  box.origin.y(), box.origin.z(), box.range);
    throw InvalidInput(what);
  }
  int points = 0;
  for (int& point : point_of_vertex) {
    if (point == 0) point = points++;
  }
  draco::Mesh out;
  out.set_num_points(points);
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false, sizeof(float) * 3, 0);
  draco::PointAttribute* positions = out.attribute(out.AddAttribute(position, true, points));
  const bool colors = options.colors && mesh.has_colors();
  draco::PointAttribute* color_attribute = nullptr;
  if (colors) {
    draco::GeometryAttribute color;
    color.Init(draco::GeometryAttribute::COLOR, nullptr, 3, draco::DT_UINT8, true, 3, 0);
    color_attribute = out.attribute(out.AddAttribute(color, true, points));
  }
  for (size_t i = 0; i < point_of_vertex.size(); ++i) {
    if (point_of_vertex[i] < 0) continue;
    const draco::AttributeValueIndex point(point_of_vertex[i]);
    positions->SetAttributeValue(point, mesh.positions[i].data());
    if (colors) color_attribute->SetAttributeValue(point, &mesh.colors[i]);
  }
  out.SetNumFaces(faces);
  draco::FaceIndex face(0);
  for (const Eigen::Vector3i& t : mesh.triangles) {
    if (repeats_a_corner(t)) continue;
    out.SetFace(face++, {draco::PointIndex(point_of_vertex[t[0]]), draco::PointIndex(point_of_vertex[t[1]]), draco::PointIndex(point_of_vertex[t[2]])});
  }
  draco::Encoder encoder;
  const int speed = 10 - options.compression_level;
  encoder.SetSpeedOptions(speed, speed);
  encoder.SetAttributeExplicitQuantization(draco::GeometryAttribute::POSITION, options.position_bits, 3, box.origin.data(), box.range);
  draco::EncoderBuffer buffer;
  const draco::Status status = encoder.EncodeMeshToBuffer(out, &buffer);
  if (!status.ok()) throw IoError(std::string("draco: cannot encode the mesh: ") + status.error_msg());
  return std::string(buffer.data(), buffer.size());
}

namespace {

// Draco (1.5.5, Debian's) allocates what a stream's header claims before reading any further: 103
// bytes claiming 175 million faces took 15 s and gigabytes (fuzzing found it). The counts of a
// bitstream 2.2 mesh (what Draco 1.5 writes, in the order its decoders read them) are read here
// first and bounded: 2^23 (8.4 million) is more than the separate meshes of ten 640×480 cameras
// (6.1 million triangles), and Draco's tables for it take about 200 MB.
constexpr std::uint32_t kMostDracoElements = 1u << 23;

class DracoHeaderReader {
 public:
  DracoHeaderReader(const std::string& bytes, const std::string& source) : bytes_(bytes), source_(source) {}

  std::uint8_t byte(const char* field) {
    if (at_ >= bytes_.size()) throw InvalidInput(source_ + ": not a Draco mesh: ends before " + field);
    return static_cast<std::uint8_t>(bytes_[at_++]);
  }
  // A LEB128 count (Draco's varUI32), at most kMostDracoElements.
  std::uint32_t count(const char* field) {
    std::uint64_t value = 0;
    for (int shift = 0;; shift += 7) {
      const std::uint8_t b = byte(field);
      if (shift > 28) throw InvalidInput(source_ + ": not a Draco mesh: " + field + " is not a 32-bit number");
      value |= static_cast<std::uint64_t>(b & 0x7f) << shift;
      if (!(b & 0x80)) break;
    }
    if (value > kMostDracoElements) {
      throw InvalidInput(source_ + ": Draco " + field + " " + std::to_string(value) + " is more than " + std::to_string(kMostDracoElements));
    }
    return static_cast<std::uint32_t>(value);
  }

 private:
  const std::string& bytes_;
  const std::string& source_;
  size_t at_ = 0;
};

void check_draco_header(const std::string& bytes, const std::string& source) {
  DracoHeaderReader in(bytes, source);
  for (const char c : std::string("DRACO")) {
    if (in.byte("the magic") != static_cast<std::uint8_t>(c)) throw InvalidInput(source + ": not a Draco mesh: no DRACO magic");
  }
  const int major = in.byte("the version"), minor = in.byte("the version");
  if (major != 2 || minor != 2) {
    throw InvalidInput(source + ": Draco bitstream " + std::to_string(major) + "." + std::to_string(minor) + ": only 2.2 (Draco 1.5) is read");
  }
  if (in.byte("the encoder type") != 1) throw InvalidInput(source + ": Draco: not a triangle mesh");
  const int method = in.byte("the encoder method");
  const int flags = in.byte("the flags") | (in.byte("the flags") << 8);
  if (flags & 0x8000) throw InvalidInput(source + ": Draco: metadata is not read");
  if (method == 0) {  // sequential
    in.count("face count");
    in.count("point count");
  } else if (method == 1) {  // Edgebreaker (2.2 has no count of new vertices, which 2.1 had)
    in.byte("the traversal type");
    const std::uint32_t vertices = in.count("vertex count");
    in.count("face count");
    in.byte("the attribute data count");
    in.count("symbol count");
    const std::uint32_t splits = in.count("split symbol count");
    // Draco sizes its vertex tables for both together.
    if (vertices + splits > kMostDracoElements) {
      throw InvalidInput(source + ": Draco vertex and split symbol counts " + std::to_string(vertices) + " + " + std::to_string(splits) + " are more than " +
                         std::to_string(kMostDracoElements));
    }
  } else {
    throw InvalidInput(source + ": Draco encoder method " + std::to_string(method) + " is not one of Draco's");
  }
}

}  // namespace

TriangleMesh decode_draco(const std::string& bytes, const std::string& source) {
  if (bytes.empty()) return {};
  check_draco_header(bytes, source);
  draco::DecoderBuffer buffer;
  buffer.Init(bytes.data(), bytes.size());
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) throw InvalidInput(source + ": not a Draco mesh: " + decoded.status().error_msg());
  const std::unique_ptr<draco::Mesh> in = std::move(decoded).value();
  // Values are read as stored (32-bit float positions, 8-bit colours), not through Draco's
  // conversions, which read the attribute's `normalized` flag as a bool whatever byte the stream
  // held (undefined behaviour that fuzzing found).
  const draco::PointAttribute* positions = in->GetNamedAttribute(draco::GeometryAttribute::POSITION);
  if (positions == nullptr || positions->num_components() != 3 || positions->data_type() != draco::DT_FLOAT32) {
    throw InvalidInput(source + ": POSITION: missing or not three 32-bit floats");
  }
  const draco::PointAttribute* colors = in->GetNamedAttribute(draco::GeometryAttribute::COLOR);
  if (colors != nullptr && (colors->num_components() < 3 || colors->num_components() > 4 || colors->data_type() != draco::DT_UINT8)) {
    throw InvalidInput(source + ": COLOR: not three or four 8-bit values");
  }
  TriangleMesh mesh;
  if (in->num_points() > static_cast<std::uint32_t>(std::numeric_limits<int>::max())) throw InvalidInput(source + ": more points than an int counts");
  const int points = static_cast<int>(in->num_points());
  mesh.positions.resize(points);
  if (colors != nullptr) mesh.colors.resize(points);
  for (int i = 0; i < points; ++i) {
    const draco::PointIndex point(i);
    std::array<float, 3> xyz;
    if (!positions->GetValue<float, 3>(positions->mapped_index(point), &xyz)) {
      throw InvalidInput(source + ": POSITION: value " + std::to_string(i) + " cannot be read");
    }
    mesh.positions[i] = Eigen::Vector3f(xyz[0], xyz[1], xyz[2]);
    if (!mesh.positions[i].allFinite()) throw InvalidInput(source + ": POSITION: value " + std::to_string(i) + " is not finite");
    if (colors != nullptr) {
      std::array<std::uint8_t, 3> rgb;
      if (!colors->GetValue<std::uint8_t, 3>(colors->mapped_index(point), &rgb)) {
        throw InvalidInput(source + ": COLOR: value " + std::to_string(i) + " cannot be read");
      }
      mesh.colors[i] = {rgb[0], rgb[1], rgb[2]};
    }
  }
  mesh.triangles.resize(in->num_faces());
  for (draco::FaceIndex f(0); f < in->num_faces(); ++f) {
    const draco::Mesh::Face& face = in->face(f);
    // Draco does not check that a face's corners are among the points it decoded.
    for (const draco::PointIndex& corner : face) {
      if (corner.value() >= in->num_points()) {
        throw InvalidInput(source + ": face " + std::to_string(f.value()) + ": corner " + std::to_string(corner.value()) + " is not one of the " +
                           std::to_string(points) + " points");
      }
    }
    mesh.triangles[f.value()] = Eigen::Vector3i(static_cast<int>(face[0].value()), static_cast<int>(face[1].value()), static_cast<int>(face[2].value()));
  }
  return mesh;
}

}  // namespace zipfusion
