#pragma once
//! \file
//! Bilateral filter of depth (paper Section III-B): smooths the Kinect's noise and disparity
//! steps within a surface while keeping depth edges. Missing depth (0) neither contributes nor
//! gets filled, so foreground never mixes with holes or background.

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
  std::vector<float> spatial;     // (2r+1)², row-major
  std::vector<float> spatial_1d;  // 2r+1: the same Gaussian along one axis
  float range_lut_scale = 0;   // LUT index per metre of |Δz|
  std::vector<float> range;    // exp(−Δz²/2σ²) tabulated up to 3σ (0 beyond)

  explicit BilateralKernel(const BilateralOptions& options);
};

//! Element function: filtered depth of pixel (u, v); 0 where the input is 0.
inline float bilateral_pixel(int u, int v, const float* depth, int width, int height, const BilateralKernel& kernel) {
  const float centre = depth[v * width + u];
  if (centre <= 0.0f) return 0.0f;
  const int r = kernel.radius;
  const int v0 = v - r < 0 ? 0 : v - r, v1 = v + r >= height ? height - 1 : v + r;
  const int u0 = u - r < 0 ? 0 : u - r, u1 = u + r >= width ? width - 1 : u + r;
  const int lut_last = static_cast<int>(kernel.range.size()) - 1;
  float weight_sum = 0.0f, value_sum = 0.0f;
  for (int y = v0; y <= v1; ++y) {
    const float* row = depth + y * width;
    const float* spatial_row = kernel.spatial.data() + (y - v + r) * (2 * r + 1) + (r - u);
    for (int x = u0; x <= u1; ++x) {
      const float z = row[x];
      if (z <= 0.0f) continue;
      const float diff = z > centre ? z - centre : centre - z;
      const int bin = static_cast<int>(diff * kernel.range_lut_scale);
      if (bin > lut_last) continue;
      const float w = spatial_row[x] * kernel.range[bin];
      weight_sum += w;
      value_sum += w * z;
    }
  }
  return value_sum / weight_sum;
}

//! Element function: one pass of the separable filter at pixel (u, v): along the row (`step` 1)
//! or the column (`step` = width); 0 where the input is 0.
inline float bilateral_pixel_1d(int u, int v, const float* depth, int width, int height, int step, const BilateralKernel& kernel) {
  const float centre = depth[v * width + u];
  if (centre <= 0.0f) return 0.0f;
  const int r = kernel.radius;
  const int position = step == 1 ? u : v, size = step == 1 ? width : height;
  const int first = position - r < 0 ? -position : -r, last = position + r >= size ? size - 1 - position : r;
  const int lut_last = static_cast<int>(kernel.range.size()) - 1;
  const float* origin = depth + v * width + u;
  float weight_sum = 0.0f, value_sum = 0.0f;
  for (int k = first; k <= last; ++k) {
    const float z = origin[k * step];
    if (z <= 0.0f) continue;
    const float diff = z > centre ? z - centre : centre - z;
    const int bin = static_cast<int>(diff * kernel.range_lut_scale);
    if (bin > lut_last) continue;
    const float w = kernel.spatial_1d[k + r] * kernel.range[bin];
    weight_sum += w;
    value_sum += w * z;
  }
  return value_sum / weight_sum;
}

//! Filters `depth_m` (metres, 0 = none) into `out` (resized). `out` must not alias the input;
//! `scratch` holds the separable filter's row pass.
void bilateral_filter(const Image<float>& depth_m, const BilateralKernel& kernel, Image<float>& out, Image<float>& scratch,
                      int num_threads = 1);

//! As above, with a scratch image of its own.
void bilateral_filter(const Image<float>& depth_m, const BilateralKernel& kernel, Image<float>& out, int num_threads = 1);

}  // namespace zipfusion
