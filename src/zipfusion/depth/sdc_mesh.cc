#include "zipfusion/depth/sdc_mesh.h"

#include "zipfusion/core/error.h"

namespace zipfusion {

void SdcOptions::validate() const {
  if (!(max_depth_jump_m > 0 && max_depth_jump_m < 1)) throw InvalidInput("max-depth-jump: must be in (0, 1) metres");
}

int DepthMesh::triangle_count() const {
  int count = 0;
  for_each_nonempty_cell(triangles, [&](int, std::uint8_t bits) { count += (bits & kUpperTriangle ? 1 : 0) + (bits & kLowerTriangle ? 1 : 0); });
  return count;
}

void triangulate_sdc(const Image<float>& depth_m, const Intrinsics& k, const Rigid3f& world_from_depth, const SdcOptions& options,
                     DepthMesh& out) {
  out.width = depth_m.width;
  out.height = depth_m.height;
  const int count = static_cast<int>(depth_m.size());
  out.depth.assign(depth_m.data.begin(), depth_m.data.end());
  out.points.resize(count);
  out.triangles.resize(count);
  const float max_jump = static_cast<float>(options.max_depth_jump_m);
  for (int i = 0; i < count; ++i) {
    const float z = depth_m.data[i];
    if (z > 0) out.points[i] = world_from_depth * unproject(k, static_cast<float>(i % out.width), static_cast<float>(i / out.width), z);
    out.triangles[i] = sdc_cell(i, out.depth.data(), out.width, out.height, max_jump);
  }
}

void append_depth_mesh(const DepthMesh& mesh, const std::vector<Rgb8>& colors, TriangleMesh& out, std::vector<int>& vertex_of_pixel) {
  const int count = mesh.width * mesh.height;
  vertex_of_pixel.assign(count, -1);
  const bool with_colors = !colors.empty();
  auto vertex = [&](int pixel) {
    int& index = vertex_of_pixel[pixel];
    if (index < 0) {
      index = static_cast<int>(out.positions.size());
      out.positions.push_back(mesh.points[pixel]);
      if (with_colors) out.colors.push_back(colors[pixel]);
    }
    return index;
  };
  for_each_triangle(mesh, [&](const int* v) { out.triangles.emplace_back(vertex(v[0]), vertex(v[1]), vertex(v[2])); });
}

}  // namespace zipfusion
