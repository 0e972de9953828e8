#include "zipfusion/fusion/binary_image.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstddef>

namespace zipfusion {
namespace {

// 255 where a pixel of `in` within `radius` columns and `radius` rows (inside the image) is
// nonzero (dilation: the OR of the window's pixels) or, for erosion, where every such pixel is
// (the AND), else 0. Separable: along the rows into s.rows, each row first copied as 0 or 255
// between `radius` neutral pixels (0 for the OR, 255 for the AND, so that pixels outside do not
// count), then along the columns. A radius of a few pixels takes 2·radius+1 byte-wise ORs or
// ANDs per pixel and pass, over whole rows: they vectorise.
template <bool kDilate>
void spread(const std::uint8_t* in, std::uint8_t* out, int width, int height, int radius, BinaryImageScratch& s) {
  assert(radius >= 0);
  if (width <= 0 || height <= 0) return;
  const std::uint8_t neutral = kDilate ? 0 : 255;
  auto combine = [](std::uint8_t* to, const std::uint8_t* from, int n) {
    for (int x = 0; x < n; ++x) to[x] = kDilate ? (to[x] | from[x]) : (to[x] & from[x]);
  };
  const size_t row_length = static_cast<size_t>(width);
  s.rows.resize(row_length * height);
  s.padded.assign(row_length + 2 * static_cast<size_t>(radius), neutral);
  std::uint8_t* padded = s.padded.data() + radius;
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* row = in + y * row_length;
    for (int x = 0; x < width; ++x) padded[x] = row[x] ? 255 : 0;
    std::uint8_t* spread_row = s.rows.data() + y * row_length;
    std::copy(padded - radius, padded - radius + width, spread_row);
    for (int d = -radius + 1; d <= radius; ++d) combine(spread_row, padded + d, width);
  }
  for (int y = 0; y < height; ++y) {
    const int first = std::max(0, y - radius), last = std::min(height - 1, y + radius);
    std::uint8_t* out_row = out + y * row_length;
    std::copy(s.rows.data() + first * row_length, s.rows.data() + (first + 1) * row_length, out_row);
    for (int v = first + 1; v <= last; ++v) combine(out_row, s.rows.data() + v * row_length, width);
  }
}

// OpenCV's fixed point for the chamfer distances: 16 fractional bits. The border holds kFar
// (INT_MAX), which adding a step cannot overflow in 32 unsigned bits, and the first pass holds
// every distance to kMost (INT_MAX / 4: 8192 pixels, as OpenCV reads an image without zeros).
constexpr int kDistanceShift = 16;
constexpr std::uint32_t kFar = 0x7fffffff, kMost = kFar >> 2;
std::uint32_t to_fixed(float x) { return static_cast<std::uint32_t>(std::lround(static_cast<double>(x) * (1 << kDistanceShift))); }

}  // namespace

void dilate_binary(const std::uint8_t* in, std::uint8_t* out, int width, int height, int radius, BinaryImageScratch& scratch) {
  spread<true>(in, out, width, height, radius, scratch);
}

void erode_binary(const std::uint8_t* in, std::uint8_t* out, int width, int height, int radius, BinaryImageScratch& scratch) {
  spread<false>(in, out, width, height, radius, scratch);
}

void close_binary(const std::uint8_t* in, std::uint8_t* out, int width, int height, int radius, BinaryImageScratch& scratch) {
  scratch.closed.resize(static_cast<size_t>(std::max(width, 0)) * std::max(height, 0));
  dilate_binary(in, scratch.closed.data(), width, height, radius, scratch);
  erode_binary(scratch.closed.data(), out, width, height, radius, scratch);
}

void chamfer_distance(const std::uint8_t* in, float* out, int width, int height, BinaryImageScratch& scratch) {
  if (width <= 0 || height <= 0) return;
  const std::uint32_t straight = to_fixed(0.955f), diagonal = to_fixed(1.3693f);
  const float scale = 1.0f / (1 << kDistanceShift);
  // One pixel of border all round, never reached: every pixel then has its eight neighbours.
  const int stride = width + 2;
  std::vector<std::uint32_t>& d = scratch.distances;
  d.assign(static_cast<size_t>(stride) * (height + 2), kFar);
  // Down and to the right, from the neighbours above and to the left ...
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* row = in + static_cast<std::ptrdiff_t>(y) * width;
    std::uint32_t* here = d.data() + static_cast<std::ptrdiff_t>(y + 1) * stride + 1;
    const std::uint32_t* above = here - stride;
    for (int x = 0; x < width; ++x) {
      if (!row[x]) {
        here[x] = 0;
        continue;
      }
      here[x] = std::min({above[x - 1] + diagonal, above[x] + straight, above[x + 1] + diagonal, here[x - 1] + straight, kMost});
    }
  }
  // ... then up and to the left, from those below and to the right (a pixel one straight step
  // from a zero cannot get nearer).
  for (int y = height - 1; y >= 0; --y) {
    std::uint32_t* here = d.data() + static_cast<std::ptrdiff_t>(y + 1) * stride + 1;
    const std::uint32_t* below = here + stride;
    float* row_out = out + static_cast<std::ptrdiff_t>(y) * width;
    for (int x = width - 1; x >= 0; --x) {
      std::uint32_t t = here[x];
      if (t > straight) {
        t = std::min({t, below[x + 1] + diagonal, below[x] + straight, below[x - 1] + diagonal, here[x + 1] + straight});
        here[x] = t;
      }
      row_out[x] = static_cast<float>(t) * scale;
    }
  }
}

}  // namespace zipfusion
