#include "zipfusion/io/draco_codec.h"

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>

#include <algorithm>
#include <cmath>

#include "zipfusion/core/error.h"

namespace zipfusion {

void DracoOptions::validate() const {
  if (position_bits < 1 || position_bits > 30) throw InvalidInput("position-bits: must be in [1, 30]");
  if (compression_level < 0 || compression_level > 10) throw InvalidInput("compression-level: must be in [0, 10]");
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

std::string encode_draco(const TriangleMesh& mesh, const QuantizationBox& box, const DracoOptions& options) {
  options.validate();
  if (mesh.triangles.empty()) return {};  // Draco has no encoding of an empty mesh
  draco::Mesh out;
  const int vertices = static_cast<int>(mesh.positions.size());
  out.set_num_points(vertices);
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false, sizeof(float) * 3, 0);
  draco::PointAttribute* positions = out.attribute(out.AddAttribute(position, true, vertices));
  for (int i = 0; i < vertices; ++i) positions->SetAttributeValue(draco::AttributeValueIndex(i), mesh.positions[i].data());
  if (options.colors && mesh.has_colors()) {
    draco::GeometryAttribute color;
    color.Init(draco::GeometryAttribute::COLOR, nullptr, 3, draco::DT_UINT8, true, 3, 0);
    draco::PointAttribute* colors = out.attribute(out.AddAttribute(color, true, vertices));
    for (int i = 0; i < vertices; ++i) colors->SetAttributeValue(draco::AttributeValueIndex(i), &mesh.colors[i]);
  }
  out.SetNumFaces(mesh.triangles.size());
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Eigen::Vector3i& tri = mesh.triangles[t];
    out.SetFace(draco::FaceIndex(static_cast<std::uint32_t>(t)),
                {draco::PointIndex(tri[0]), draco::PointIndex(tri[1]), draco::PointIndex(tri[2])});
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

TriangleMesh decode_draco(const std::string& bytes, const std::string& source) {
  if (bytes.empty()) return {};
  draco::DecoderBuffer buffer;
  buffer.Init(bytes.data(), bytes.size());
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) throw InvalidInput(source + ": not a Draco mesh: " + decoded.status().error_msg());
  const std::unique_ptr<draco::Mesh> in = std::move(decoded).value();
  const draco::PointAttribute* positions = in->GetNamedAttribute(draco::GeometryAttribute::POSITION);
  if (positions == nullptr || positions->num_components() != 3) throw InvalidInput(source + ": POSITION: missing or not 3-D");
  const draco::PointAttribute* colors = in->GetNamedAttribute(draco::GeometryAttribute::COLOR);
  TriangleMesh mesh;
  const int points = static_cast<int>(in->num_points());
  mesh.positions.resize(points);
  if (colors != nullptr) mesh.colors.resize(points);
  for (int i = 0; i < points; ++i) {
    const draco::PointIndex point(i);
    if (!positions->ConvertValue<float, 3>(positions->mapped_index(point), mesh.positions[i].data())) {
      throw InvalidInput(source + ": POSITION: value " + std::to_string(i) + " cannot be read");
    }
    if (colors != nullptr) {
      std::uint8_t rgb[4] = {128, 128, 128, 255};
      if (!colors->ConvertValue<std::uint8_t>(colors->mapped_index(point), std::min<int>(colors->num_components(), 4), rgb)) {
        throw InvalidInput(source + ": COLOR: value " + std::to_string(i) + " cannot be read");
      }
      mesh.colors[i] = {rgb[0], rgb[1], rgb[2]};
    }
  }
  mesh.triangles.resize(in->num_faces());
  for (draco::FaceIndex f(0); f < in->num_faces(); ++f) {
    const draco::Mesh::Face& face = in->face(f);
    mesh.triangles[f.value()] = Eigen::Vector3i(static_cast<int>(face[0].value()), static_cast<int>(face[1].value()), static_cast<int>(face[2].value()));
  }
  return mesh;
}

}  // namespace zipfusion
