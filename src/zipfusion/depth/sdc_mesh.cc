#include "zipfusion/depth/sdc_mesh.h"

#include <cmath>

#include "zipfusion/core/error.h"
#include "zipfusion/core/row_kernel.h"

namespace zipfusion {

void SdcOptions::validate() const {
  if (!(max_depth_jump_m > 0 && max_depth_jump_m < 1)) throw InvalidInput("--max-depth-jump: must be in (0, 1) metres");
  if (!(growth_depth_m == 0 || (growth_depth_m >= 0.1 && growth_depth_m <= 20)))
    throw InvalidInput("--max-depth-jump-growth: must be 0 (constant) or in [0.1, 20] metres");
}

ZF_ROW_KERNEL void sdc_row(const float* depth, int width, int count, DepthJump max_jump, std::uint8_t* bits) {
  const float* below = depth + width;
  for (int i = 0; i < count; ++i) {
    const float p = depth[i], r = depth[i + 1], b = below[i], d = below[i + 1];
    auto close = [max_jump](float x, float y) { return static_cast<int>(std::abs(x - y) < max_jump.between(x, y)); };
    const int shared = static_cast<int>(r > 0) & static_cast<int>(b > 0) & close(r, b);
    const int upper = shared & static_cast<int>(p > 0) & close(p, r) & close(p, b);
    const int lower = shared & static_cast<int>(d > 0) & close(r, d) & close(b, d);
    bits[i] = static_cast<std::uint8_t>(upper * kUpperTriangle + lower * kLowerTriangle);
  }
}

void sdc_row_between_spans(const float* depth, int width, int v, std::pair<int, int> above, std::pair<int, int> here, DepthJump max_jump,
                           std::uint8_t* bits) {
  const int first = std::max(above.first - 1, here.first), end = std::min(above.second - 1, here.second);
  if (first >= end) return;
  const size_t cells = static_cast<size_t>(v - 1) * width + first;
  sdc_row(depth + cells, width, end - first, max_jump, bits + cells);
}

ZF_ROW_KERNEL int count_triangles(const std::uint8_t* bits, int count) {
  int triangles = 0;
  for (int i = 0; i < count; ++i) triangles += (bits[i] & kUpperTriangle) + ((bits[i] & kLowerTriangle) >> 1);
  return triangles;
}

int DepthMesh::triangle_count() const {
  // Every triangle lies in the depth box.
  const PixelBox b = box();
  int count = 0;
  for (int v = b.v0; v < b.v1; ++v) count += count_triangles(triangles.data() + static_cast<size_t>(v) * width + b.u0, b.u1 - b.u0);
  return count;
}

void reset_depth_mesh(DepthMesh& mesh, int width, int height, bool clear_depth) {
  const size_t count = static_cast<size_t>(width) * height;
  if (mesh.width != width || mesh.height != height || mesh.triangles.size() != count || (clear_depth && mesh.depth.size() != count)) {
    mesh.width = width;
    mesh.height = height;
    if (clear_depth) mesh.depth.assign(count, 0.0f);
    mesh.triangles.assign(count, 0);
  } else {
    const PixelBox box = mesh.box();
    for (int v = box.v0; v < box.v1; ++v) {
      const size_t row = static_cast<size_t>(v) * width;
      if (clear_depth) std::fill(mesh.depth.begin() + row + box.u0, mesh.depth.begin() + row + box.u1, 0.0f);
      std::fill(mesh.triangles.begin() + row + box.u0, mesh.triangles.begin() + row + box.u1, 0);
    }
  }
  mesh.depth_box = {};
}

namespace {

// triangulate_sdc once `out.depth` holds the depth image, width × height (`out`'s triangles and
// depth box still those of its previous image).
void triangulate_own_depth(int width, int height, const Intrinsics& k, const Rigid3f& world_from_depth, const SdcOptions& options,
                           DepthMesh& out) {
  reset_depth_mesh(out, width, height, false);
  out.rays = PixelRays(k, world_from_depth);
  PixelBox box{width, height, 0, 0};
  const DepthJump max_jump = depth_jump(options);
  // Row by row: once row v's span of pixels with depth is known, the cells of row v − 1 are formed
  // (the rest of the box keeps the bits reset_depth_mesh cleared).
  std::pair<int, int> above{0, 0};
  for (int v = 0; v < height; ++v) {
    const std::pair<int, int> here = positive_span(out.depth.data() + static_cast<size_t>(v) * width, width);
    if (here.first < here.second) box = {std::min(box.u0, here.first), std::min(box.v0, v), std::max(box.u1, here.second), v + 1};
    sdc_row_between_spans(out.depth.data(), width, v, above, here, max_jump, out.triangles.data());
    above = here;
  }
  if (box.empty()) box = {};
  out.depth_box = box;
}

}  // namespace

void triangulate_sdc(const Image<float>& depth_m, const Intrinsics& k, const Rigid3f& world_from_depth, const SdcOptions& options,
                     DepthMesh& out) {
  out.depth.assign(depth_m.data.begin(), depth_m.data.end());
  triangulate_own_depth(depth_m.width, depth_m.height, k, world_from_depth, options, out);
}

void triangulate_sdc_taking_depth(Image<float>& depth_m, const Intrinsics& k, const Rigid3f& world_from_depth, const SdcOptions& options,
                                  DepthMesh& out) {
  out.depth.swap(depth_m.data);
  depth_m.data.resize(out.depth.size());  // the mesh's previous buffer, of the same size after the first frame
  triangulate_own_depth(depth_m.width, depth_m.height, k, world_from_depth, options, out);
}

void append_depth_mesh(const DepthMesh& mesh, const std::vector<Rgb8>& colors, TriangleMesh& out, std::vector<int>& vertex_of_pixel) {
  const int count = mesh.width * mesh.height;
  vertex_of_pixel.assign(count, -1);
  const bool with_colors = !colors.empty();
  auto vertex = [&](int pixel) {
    int& index = vertex_of_pixel[pixel];
    if (index < 0) {
      index = static_cast<int>(out.positions.size());
      out.positions.push_back(mesh.point(pixel));
      if (with_colors) out.colors.push_back(colors[pixel]);
    }
    return index;
  };
  for_each_triangle(mesh, [&](const int* v) { out.triangles.emplace_back(vertex(v[0]), vertex(v[1]), vertex(v[2])); });
}

}  // namespace zipfusion
