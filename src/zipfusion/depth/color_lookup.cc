#include "zipfusion/depth/color_lookup.h"

#include <algorithm>
#include <cassert>
#include <cstring>

#include "zipfusion/core/row_kernel.h"

namespace zipfusion {
namespace {

// A pinhole colour camera's coordinates of the points z·(ray + u·ray_du) + origin, u = u0 + i:
// the operations of PixelRays::point and project_pinhole in their order, so the floats are
// at()'s; −1 (outside every image) where the point is not in front of the camera.
ZF_ROW_KERNEL void project_pinhole_row(const Eigen::Vector3f& row_ray, const Eigen::Vector3f& ray_du, const Eigen::Vector3f& origin, float fx,
                                       float fy, float cx, float cy, int u0, int n, const float* z, float* x, float* y) {
  // Scalars in locals: read through the references inside the loop, they might alias x or y, and
  // the loop would not vectorise.
  const float rx = row_ray.x(), ry = row_ray.y(), rz = row_ray.z(), dx = ray_du.x(), dy = ray_du.y(), dz = ray_du.z();
  const float ox = origin.x(), oy = origin.y(), oz = origin.z();
  for (int i = 0; i < n; ++i) {
    const float u = static_cast<float>(u0 + i);
    const float px = ox + z[i] * (rx + u * dx);
    const float py = oy + z[i] * (ry + u * dy);
    const float pz = oz + z[i] * (rz + u * dz);
    // Divided in every lane, then selected (select_if): GCC does not vectorise a division under
    // the condition.
    const float xi = fx * px / pz + cx, yi = fy * py / pz + cy;
    const unsigned behind = !(pz > 0.0f);
    x[i] = select_if(behind, -1.0f, xi);
    y[i] = select_if(behind, -1.0f, yi);
  }
}

// The two pixels `pixel` and `pixel` + `right` (right 0 or 1) of an image of `size` ≥ 8 bytes, as
// the low three bytes of two words: one eight-byte read, moved back from the image's end where
// it would pass it.
inline void pixel_pair(const std::uint8_t* bytes, int size, int pixel, int right, std::uint32_t& first, std::uint32_t& second) {
  const int offset = std::min(3 * pixel, size - 8);
  std::uint64_t word;
  std::memcpy(&word, bytes + offset, sizeof word);
  const int shift = 8 * (3 * pixel - offset);
  first = static_cast<std::uint32_t>(word >> shift) & 0xFFFFFF;
  second = right ? static_cast<std::uint32_t>(word >> (shift + 24)) & 0xFFFFFF : first;
}

// One channel (`shift` 0, 8, 16) of sample_bilinear's mix of four packed pixels.
inline std::uint32_t mix_channel(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d, int wx, int wy, int shift) {
  auto channel = [shift](std::uint32_t packed) { return static_cast<int>((packed >> shift) & 0xFF); };
  return static_cast<std::uint32_t>(bilinear_mix(channel(a), channel(b), channel(c), channel(d), wx, wy) & 0xFF) << shift;
}

// sample_bilinear's colours at (x[i], y[i]), i < count ≤ ColorLookup::kRowChunk, packed
// (ColorLookup::pack_rgb): the same integer arithmetic in every lane, and its bounds test as a
// select (lanes outside read pixel 0). In three loops: GCC vectorises the first and the last,
// not the reads of three-byte pixels between them.
ZF_ROW_KERNEL void sample_bilinear_row(const std::uint8_t* __restrict bytes, int width, int height, const float* __restrict x,
                                       const float* __restrict y, int count, std::uint32_t* __restrict packed) {
  constexpr int kChunk = ColorLookup::kRowChunk;
  assert(count <= kChunk);
  assert(3 * width * height >= 8);
  const float last_x = static_cast<float>(width) - 1.0f, last_y = static_cast<float>(height) - 1.0f;
  std::uint32_t keep[kChunk];
  int top_left[kChunk], right[kChunk], down[kChunk], wx[kChunk], wy[kChunk];
  for (int i = 0; i < count; ++i) {
    const unsigned inside = (x[i] >= 0.0f) & (y[i] >= 0.0f) & (x[i] <= last_x) & (y[i] <= last_y);
    const float sx = select_if(inside, x[i], 0.0f), sy = select_if(inside, y[i], 0.0f);
    const int x0 = static_cast<int>(sx), y0 = static_cast<int>(sy);
    keep[i] = 0u - inside;
    top_left[i] = y0 * width + x0;
    right[i] = std::min(x0 + 1, width - 1) - x0;  // 0 or 1
    down[i] = (std::min(y0 + 1, height - 1) - y0) * width;
    wx[i] = static_cast<int>((sx - static_cast<float>(x0)) * 256.0f + 0.5f);
    wy[i] = static_cast<int>((sy - static_cast<float>(y0)) * 256.0f + 0.5f);
  }
  std::uint32_t a[kChunk], b[kChunk], c[kChunk], d[kChunk];
  const int size = 3 * width * height;
  for (int i = 0; i < count; ++i) {
    pixel_pair(bytes, size, top_left[i], right[i], a[i], b[i]);
    pixel_pair(bytes, size, top_left[i] + down[i], right[i], c[i], d[i]);
  }
  const std::uint32_t no_color = ColorLookup::pack_rgb(kNoColor);
  for (int i = 0; i < count; ++i) {
    const std::uint32_t color = mix_channel(a[i], b[i], c[i], d[i], wx[i], wy[i], 0) | mix_channel(a[i], b[i], c[i], d[i], wx[i], wy[i], 8) |
                                mix_channel(a[i], b[i], c[i], d[i], wx[i], wy[i], 16);
    packed[i] = (color & keep[i]) | (no_color & ~keep[i]);
  }
}

}  // namespace

void ColorLookup::sample_row(const float* x, const float* y, int count, std::uint32_t* packed) const {
  static_assert(sizeof(Rgb8) == 3, "pixels are three bytes");
  assert(count <= kRowChunk);
  if (3 * image_->size() < 8) {  // fewer bytes than one read of the row kernel
    for (int i = 0; i < count; ++i) packed[i] = pack_rgb(sample(x[i], y[i]));
    return;
  }
  sample_bilinear_row(reinterpret_cast<const std::uint8_t*>(image_->data.data()), image_->width, image_->height, x, y, count, packed);
}

void ColorLookup::project_row(int v, int u0, int count, const float* z, float* x, float* y) const {
  if (color_k_->has_distortion) {
    for (int i = 0; i < count; ++i) {
      const Eigen::Vector3f p_color = rays_.point(u0 + i, v, z[i]);
      const Eigen::Vector2f pixel = p_color.z() > 0 ? project(*color_k_, p_color.cast<double>()).cast<float>() : Eigen::Vector2f(-1, -1);
      x[i] = pixel.x();
      y[i] = pixel.y();
    }
    return;
  }
  project_pinhole_row(rays_.row_ray(v), rays_.ray_du, rays_.origin, static_cast<float>(color_k_->fx), static_cast<float>(color_k_->fy),
                      static_cast<float>(color_k_->cx), static_cast<float>(color_k_->cy), u0, count, z, x, y);
}

void lookup_colors(const DepthMesh& mesh, const CameraModel& camera, const ColorImage* color, std::vector<Rgb8>& out) {
  const int count = mesh.width * mesh.height;
  // kNoColor is grey 128 in every byte, so a memset fills it (a loop over 3-byte pixels was a
  // sixth of this function's time).
  static_assert(sizeof(Rgb8) == 3 && kNoColor.r == 128 && kNoColor.g == 128 && kNoColor.b == 128);
  out.resize(count);
  std::memset(static_cast<void*>(out.data()), 128, out.size() * sizeof(Rgb8));
  const ColorLookup lookup(camera, color);
  if (!lookup.has_image()) return;
  const PixelBox box = mesh.box();
  for (int v = box.v0; v < box.v1; ++v) {
    const float* depth = mesh.depth.data() + static_cast<size_t>(v) * mesh.width;
    Rgb8* colors = out.data() + static_cast<size_t>(v) * mesh.width;
    lookup.for_each_color_in_row(v, box.u0, box.u1, depth, [&](int u) { return depth[u] > 0; }, [&](int u, Rgb8 c) { colors[u] = c; });
  }
}

}  // namespace zipfusion
