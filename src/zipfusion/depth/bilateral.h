#pragma once
//! \file
//! Bilateral filter of depth (paper Section III-B): smooths the Kinect's noise and disparity
//! steps within a surface while keeping depth edges. Missing depth (0) neither contributes nor
//! gets filled, so foreground never mixes with holes or background.

#include <algorithm>
#include <vector>

#include "zipfusion/core/image.h"

namespace zipfusion {

struct BilateralOptions {
  double spatial_sigma_px = 4.0;  // pixels (paper)
  int radius_px = 6;              // pixels (paper)
  double range_sigma_m = 0.05;    // metres (paper: 50 mm)
  bool separable = false;         // a row pass then a column pass (2·(2r+1) taps, not (2r+1)²)

  void validate() const;  // throws InvalidInput naming the field
};

//! Precomputed weights of one filter configuration, shared by all pixels and threads.
struct BilateralKernel {
  int radius = 0;
  bool separable = false;
  std::vector<float> spatial;      // (2r+1)², row-major
  std::vector<float> spatial_1d;   // 2r+1: the same Gaussian along one axis
  float inv_two_range_sigma2 = 0;  // 1 / (2σ_r²), per m²

  explicit BilateralKernel(const BilateralOptions& options);
};

//! Element function: exp(−t) for 0 ≤ t ≤ 4.5 (the range weight out to 3σ), as exp(−t/8)⁸ with the
//! inner exponential by its Taylor series: relative error below 0.7 %, no table and no branch, so
//! the filter's loops vectorise.
inline float exp_neg(float t) {
  const float x = t * 0.125f;
  float e = 1.0f - x * (1.0f - x * (0.5f - x * (1.0f / 6.0f - x * (1.0f / 24.0f))));
  e *= e;
  e *= e;
  return e * e;
}

//! Element function: the weight of a neighbour with depth z for a centre with depth `centre`:
//! spatial weight × range weight, 0 when the neighbour has no depth or lies beyond 3σ_r.
inline float bilateral_weight(float centre, float z, float spatial, float inv_two_range_sigma2) {
  const float d = z - centre;
  const float t = d * d * inv_two_range_sigma2;
  // Computed either way and masked, not branched on: the loops over pixels vectorise.
  const float inside = static_cast<float>(static_cast<int>(z > 0.0f) & static_cast<int>(t < 4.5f));
  return inside * spatial * exp_neg(t * inside);  // t · 0 keeps the polynomial in range where masked
}

//! Element function: filtered depth of pixel (u, v) with the square window; 0 where the input is
//! 0. The reference form of the filter (a CUDA port maps it to a thread per pixel);
//! bilateral_filter forms the same sums with the taps outermost, which the CPU vectorises.
inline float bilateral_pixel(int u, int v, const float* depth, int width, int height, const BilateralKernel& kernel) {
  const float centre = depth[v * width + u];
  if (centre <= 0.0f) return 0.0f;
  const int r = kernel.radius;
  const int v0 = v - r < 0 ? 0 : v - r, v1 = v + r >= height ? height - 1 : v + r;
  const int u0 = u - r < 0 ? 0 : u - r, u1 = u + r >= width ? width - 1 : u + r;
  float weight_sum = 0.0f, value_sum = 0.0f;
  for (int y = v0; y <= v1; ++y) {
    const float* row = depth + y * width;
    const float* spatial_row = kernel.spatial.data() + (y - v + r) * (2 * r + 1) + (r - u);
    for (int x = u0; x <= u1; ++x) {
      const float w = bilateral_weight(centre, row[x], spatial_row[x], kernel.inv_two_range_sigma2);
      weight_sum += w;
      value_sum += w * row[x];
    }
  }
  return value_sum / weight_sum;
}

//! The first and last pixel with depth of a row (first > last: none).
struct BilateralRowSpan {
  int first = 0, last = -1;
};

//! Buffers bilateral_filter reuses from one call to the next: once grown, it allocates nothing.
struct BilateralScratch {
  Image<float> sums;                         // the square window's per-block sums, or the separable row pass
  std::vector<BilateralRowSpan> row_spans;   // square window: each row's
  std::vector<std::vector<float>> row_sums;  // separable and radius ≤ 2: per block of rows, weights then values
};

//! Filters `depth_m` (metres, 0 = none) into `out` (resized). `out` must not alias the input;
//! `scratch` serves one call at a time.
void bilateral_filter(const Image<float>& depth_m, const BilateralKernel& kernel, Image<float>& out, BilateralScratch& scratch,
                      int num_threads = 1);

//! As above, with scratch buffers of its own.
void bilateral_filter(const Image<float>& depth_m, const BilateralKernel& kernel, Image<float>& out, int num_threads = 1);

}  // namespace zipfusion
