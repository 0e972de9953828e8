#include "zipfusion/fusion/binary_image.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace zipfusion {
namespace {

// Along each row: out = 255 where a pixel within `radius` columns (inside the row) is `wanted`
// (nonzero, or zero), else 0. Two passes, each counting the columns since the last wanted pixel.
void spread_rows(const std::uint8_t* in, std::uint8_t* out, int width, int height, int radius, bool want_nonzero) {
  const int far = width + radius + 1;
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* row = in + static_cast<std::ptrdiff_t>(y) * width;
    std::uint8_t* row_out = out + static_cast<std::ptrdiff_t>(y) * width;
    int gap = far;
    for (int x = 0; x < width; ++x) {
      gap = ((row[x] != 0) == want_nonzero) ? 0 : gap + 1;
      row_out[x] = gap <= radius ? 255 : 0;
    }
    gap = far;
    for (int x = width - 1; x >= 0; --x) {
      gap = ((row[x] != 0) == want_nonzero) ? 0 : gap + 1;
      if (gap <= radius) row_out[x] = 255;
    }
  }
}

// Along each column, the same for pixels equal to 255 in `in`: a pass down, then up, a row at a
// time, each column's count of rows since its last such pixel in `gaps`.
void spread_columns(const std::uint8_t* in, std::uint8_t* out, int width, int height, int radius, std::vector<std::uint16_t>& gaps) {
  const std::uint16_t far = static_cast<std::uint16_t>(std::min(radius + 1, 65535));
  gaps.assign(static_cast<size_t>(width), far);
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* row = in + static_cast<std::ptrdiff_t>(y) * width;
    std::uint8_t* row_out = out + static_cast<std::ptrdiff_t>(y) * width;
    for (int x = 0; x < width; ++x) {
      gaps[x] = row[x] ? 0 : static_cast<std::uint16_t>(std::min<int>(gaps[x] + 1, far));
      row_out[x] = gaps[x] <= radius ? 255 : 0;
    }
  }
  std::fill(gaps.begin(), gaps.end(), far);
  for (int y = height - 1; y >= 0; --y) {
    const std::uint8_t* row = in + static_cast<std::ptrdiff_t>(y) * width;
    std::uint8_t* row_out = out + static_cast<std::ptrdiff_t>(y) * width;
    for (int x = 0; x < width; ++x) {
      gaps[x] = row[x] ? 0 : static_cast<std::uint16_t>(std::min<int>(gaps[x] + 1, far));
      row_out[x] |= gaps[x] <= radius ? 255 : 0;
    }
  }
}

// The square's test is separable: a pixel wanted within the square lies within `radius` columns
// of a pixel of its row that is within `radius` rows of it.
void spread(const std::uint8_t* in, std::uint8_t* out, int width, int height, int radius, bool want_nonzero, BinaryImageScratch& s) {
  if (width <= 0 || height <= 0) return;
  s.rows.resize(static_cast<size_t>(width) * height);
  spread_rows(in, s.rows.data(), width, height, radius, want_nonzero);
  spread_columns(s.rows.data(), out, width, height, radius, s.gaps);
}

// OpenCV's fixed point for the chamfer distances: 16 fractional bits. The border holds kFar
// (INT_MAX), which adding a step cannot overflow in 32 unsigned bits, and the first pass holds
// every distance to kMost (INT_MAX / 4: 8192 pixels, as OpenCV reads an image without zeros).
constexpr int kDistanceShift = 16;
constexpr std::uint32_t kFar = 0x7fffffff, kMost = kFar >> 2;
std::uint32_t to_fixed(float x) { return static_cast<std::uint32_t>(std::lround(static_cast<double>(x) * (1 << kDistanceShift))); }

}  // namespace

void dilate_binary(const std::uint8_t* in, std::uint8_t* out, int width, int height, int radius, BinaryImageScratch& scratch) {
  spread(in, out, width, height, radius, true, scratch);
}

void erode_binary(const std::uint8_t* in, std::uint8_t* out, int width, int height, int radius, BinaryImageScratch& scratch) {
  spread(in, out, width, height, radius, false, scratch);
  for (size_t k = 0, n = static_cast<size_t>(width) * height; k < n; ++k) out[k] = 255 - out[k];
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
