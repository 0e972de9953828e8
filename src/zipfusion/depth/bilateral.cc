#include "zipfusion/depth/bilateral.h"

#include <cassert>
#include <cmath>

#include "zipfusion/core/error.h"
#include "zipfusion/core/parallel.h"

namespace zipfusion {
namespace {
constexpr int kRangeLutSize = 1024;
}

void BilateralOptions::validate() const {
  if (!(spatial_sigma_px > 0)) throw InvalidInput("bilateral-sigma-px: must be positive");
  if (radius_px < 1 || radius_px > 32) throw InvalidInput("bilateral-radius: must be in [1, 32] pixels");
  if (!(range_sigma_m > 0)) throw InvalidInput("bilateral-range-sigma: must be positive");
}

BilateralKernel::BilateralKernel(const BilateralOptions& options) : radius(options.radius_px), separable(options.separable) {
  const int side = 2 * radius + 1;
  spatial.resize(static_cast<size_t>(side) * side);
  spatial_1d.resize(side);
  for (int d = -radius; d <= radius; ++d) {
    spatial_1d[d + radius] = static_cast<float>(std::exp(-(d * d) / (2 * options.spatial_sigma_px * options.spatial_sigma_px)));
  }
  const double two_sigma2 = 2 * options.spatial_sigma_px * options.spatial_sigma_px;
  for (int dy = -radius; dy <= radius; ++dy) {
    for (int dx = -radius; dx <= radius; ++dx) {
      spatial[(dy + radius) * side + dx + radius] = static_cast<float>(std::exp(-(dx * dx + dy * dy) / two_sigma2));
    }
  }
  const double max_diff = 3 * options.range_sigma_m;
  range_lut_scale = static_cast<float>(kRangeLutSize / max_diff);
  range.resize(kRangeLutSize);
  for (int i = 0; i < kRangeLutSize; ++i) {
    const double diff = (i + 0.5) / range_lut_scale;
    range[i] = static_cast<float>(std::exp(-diff * diff / (2 * options.range_sigma_m * options.range_sigma_m)));
  }
}

void bilateral_filter(const Image<float>& depth_m, const BilateralKernel& kernel, Image<float>& out, Image<float>& scratch, int num_threads) {
  assert(&depth_m != &out && &scratch != &out && &scratch != &depth_m);
  const int width = depth_m.width, height = depth_m.height;
  out.resize(width, height);
  if (!kernel.separable) {
    parallel_for(0, height, [&](int v) {
      for (int u = 0; u < width; ++u) out.data[static_cast<size_t>(v) * width + u] = bilateral_pixel(u, v, depth_m.data.data(), width, height, kernel);
    }, num_threads);
    return;
  }
  scratch.resize(width, height);
  parallel_for(0, height, [&](int v) {
    for (int u = 0; u < width; ++u) {
      scratch.data[static_cast<size_t>(v) * width + u] = bilateral_pixel_1d(u, v, depth_m.data.data(), width, height, 1, kernel);
    }
  }, num_threads);
  parallel_for(0, height, [&](int v) {
    for (int u = 0; u < width; ++u) {
      out.data[static_cast<size_t>(v) * width + u] = bilateral_pixel_1d(u, v, scratch.data.data(), width, height, width, kernel);
    }
  }, num_threads);
}

void bilateral_filter(const Image<float>& depth_m, const BilateralKernel& kernel, Image<float>& out, int num_threads) {
  Image<float> scratch;
  bilateral_filter(depth_m, kernel, out, scratch, num_threads);
}

}  // namespace zipfusion
