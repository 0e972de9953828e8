#include "zipfusion/depth/bilateral.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include "zipfusion/core/error.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/core/row_kernel.h"
#include "zipfusion/depth/sdc_mesh.h"

namespace zipfusion {
namespace {

// Adds to the sums of `count` consecutive pixels their taps at one offset (`taps`, one per pixel,
// all with the spatial weight `spatial`). Pixels innermost, branch-free and contiguous: the loop
// vectorises (ZF_ROW_KERNEL: 16 lanes wide where the CPU has AVX-512, 8 with AVX2, 4 otherwise).
ZF_ROW_KERNEL void accumulate_taps(const float* centres, const float* taps, int count, float spatial, float inv_two_range_sigma2,
                                   float* weight_sums, float* value_sums) {
  for (int i = 0; i < count; ++i) {
    const float w = bilateral_weight(centres[i], taps[i], spatial, inv_two_range_sigma2);
    weight_sums[i] += w;
    value_sums[i] += w * taps[i];
  }
}

// The symmetric half of the square window: the weight of pixels p and q is the same seen from
// either (spatial and range terms are symmetric), so each pair is weighed once and added to both
// sums. `p` and `q` are `count` pixels of two different rows (q's already shifted by the offset);
// their sums must not overlap.
ZF_ROW_KERNEL void accumulate_pairs(const float* __restrict p, const float* __restrict q, int count, float spatial, float inv_two_range_sigma2,
                                    float* __restrict p_weights, float* __restrict p_values, float* __restrict q_weights,
                                    float* __restrict q_values) {
  for (int i = 0; i < count; ++i) {
    // bilateral_weight masks a q without depth; a p without depth must not reach q's sums either.
    const float w = static_cast<float>(p[i] > 0.0f) * bilateral_weight(p[i], q[i], spatial, inv_two_range_sigma2);
    p_weights[i] += w;
    p_values[i] += w * q[i];
    q_weights[i] += w;
    q_values[i] += w * p[i];
  }
}

// Pixels outside a row's span have no depth and so no output.
using RowSpan = BilateralRowSpan;

RowSpan depth_span(const float* row, int width) {
  const auto [first, end] = positive_span(row, width);
  return {first, end - 1};
}

// One output row from the taps that for_each_tap(add) hands out: add(tap_row, offset, spatial)
// stands for the taps tap_row[u + offset] of every pixel u of the row. `sums`: the row's weight
// and value sums (resized).
template <typename ForEachTap>
void filter_row(const float* centre_row, int width, float inv_two_range_sigma2, std::vector<float>& sums, float* out_row,
                ForEachTap&& for_each_tap) {
  std::fill(out_row, out_row + width, 0.0f);
  const RowSpan span = depth_span(centre_row, width);
  if (span.first > span.last) return;
  const int count = span.last - span.first + 1;
  sums.assign(2 * static_cast<size_t>(count), 0.0f);
  float* const weights = sums.data();
  float* const values = weights + count;
  for_each_tap([&](const float* tap_row, int offset, float spatial) {
    // Only the pixels whose tap lies inside the row.
    const int lo = std::max(span.first, -offset), hi = std::min(span.last, width - 1 - offset);
    if (lo > hi) return;
    accumulate_taps(centre_row + lo, tap_row + lo + offset, hi - lo + 1, spatial, inv_two_range_sigma2, weights + (lo - span.first),
                    values + (lo - span.first));
  });
  for (int i = 0; i < count; ++i) {
    const float centre = centre_row[span.first + i];
    out_row[span.first + i] = centre > 0 ? values[i] / weights[i] : 0.0f;
  }
}

// Windows up to this radius gather each pixel's taps (filter_row): for a subject as narrow in the
// image as a person seen whole, the pair sums' full-width blocks cost more to clear and add up than
// the few taps they save (where depth fills most of each row, the pairs win even at radius 2).
constexpr int kLargestGatheredRadius = 2;

// Rows per block of the square window's pair sums: fixed, so the order in which a pixel's sums
// are formed, and so the result, does not depend on the number of threads.
constexpr int kBlockRows = 32;

// The square window with every pair of pixels weighed once (about half the exponentials of
// gathering each pixel's 169 taps): each block of rows forms, for its rows v, the taps within
// row v (gathered, 2r+1 of them) and the pairs between row v and the r rows below (both sums);
// pairs reaching below the block go to its r overflow rows, added to the next block's first rows
// at the end.
void filter_square(const Image<float>& depth_m, const BilateralKernel& kernel, Image<float>& out, BilateralScratch& buffers, int num_threads) {
  Image<float>& scratch = buffers.sums;
  const int width = depth_m.width, height = depth_m.height, r = kernel.radius, side = 2 * r + 1;
  const float inv = kernel.inv_two_range_sigma2;
  const int blocks = (height + kBlockRows - 1) / kBlockRows;
  const size_t plane = static_cast<size_t>(kBlockRows + r) * width;  // one block's weight (or value) sums
  scratch.width = width;
  scratch.height = 0;  // not an image here: the blocks' sums
  scratch.data.resize(2 * plane * blocks);
  auto row_of = [&](int v) { return depth_m.data.data() + static_cast<size_t>(v) * width; };
  std::vector<RowSpan>& spans = buffers.row_spans;  // each row's is read by the r rows above it too
  spans.resize(height);
  for (int v = 0; v < height; ++v) spans[v] = depth_span(row_of(v), width);
  const int threads = std::max(1, std::min(num_threads, blocks));
  parallel_for(0, blocks, [&](int block) {
    float* weights = scratch.data.data() + 2 * plane * block;
    float* values = weights + plane;
    std::fill(weights, weights + 2 * plane, 0.0f);
    const int first_row = block * kBlockRows, end_row = std::min(height, first_row + kBlockRows);
    for (int v = first_row; v < end_row; ++v) {
      const RowSpan span = spans[v];
      if (span.first > span.last) continue;
      const float* row = row_of(v);
      float* row_weights = weights + static_cast<size_t>(v - first_row) * width;
      float* row_values = values + static_cast<size_t>(v - first_row) * width;
      // Within the row (the centre included): gathered, as the pairs would alias.
      for (int dx = -r; dx <= r; ++dx) {
        const int lo = std::max(span.first, -dx), hi = std::min(span.last, width - 1 - dx);
        if (lo <= hi) accumulate_taps(row + lo, row + lo + dx, hi - lo + 1, kernel.spatial[r * side + dx + r], inv, row_weights + lo, row_values + lo);
      }
      for (int dy = 1; dy <= r && v + dy < height; ++dy) {
        const RowSpan below = spans[v + dy];
        if (below.first > below.last) continue;
        const float* below_row = row_of(v + dy);
        float* below_weights = weights + static_cast<size_t>(v + dy - first_row) * width;
        float* below_values = values + static_cast<size_t>(v + dy - first_row) * width;
        for (int dx = -r; dx <= r; ++dx) {
          const int lo = std::max(span.first, below.first - dx), hi = std::min(span.last, below.last - dx);
          if (lo > hi) continue;
          accumulate_pairs(row + lo, below_row + lo + dx, hi - lo + 1, kernel.spatial[(dy + r) * side + dx + r], inv, row_weights + lo,
                           row_values + lo, below_weights + lo + dx, below_values + lo + dx);
        }
      }
    }
  }, threads);
  parallel_for(0, blocks, [&](int block) {
    const float* weights = scratch.data.data() + 2 * plane * block;
    const float* values = weights + plane;
    const int first_row = block * kBlockRows, end_row = std::min(height, first_row + kBlockRows);
    for (int v = first_row; v < end_row; ++v) {
      const float* row = row_of(v);
      float* out_row = out.data.data() + static_cast<size_t>(v) * width;
      const size_t own = static_cast<size_t>(v - first_row) * width;
      // The previous block's overflow rows hold this row's pairs with the r rows above the block.
      const bool overflow = block > 0 && v - first_row < r;
      const size_t spill = static_cast<size_t>(kBlockRows + v - first_row) * width;
      const float* previous = overflow ? scratch.data.data() + 2 * plane * (block - 1) : nullptr;
      for (int u = 0; u < width; ++u) {
        float w = weights[own + u], z = values[own + u];
        if (overflow) {
          w += previous[spill + u];
          z += previous[plane + spill + u];
        }
        out_row[u] = row[u] > 0 ? z / w : 0.0f;
      }
    }
  }, threads);
}

}  // namespace

void BilateralOptions::validate() const {
  if (!(spatial_sigma_px > 0 && std::isfinite(spatial_sigma_px))) throw InvalidInput("--bilateral-sigma-px: must be positive and finite");
  if (radius_px < 1 || radius_px > 32) throw InvalidInput("--bilateral-radius: must be in [1, 32] pixels");
  if (!(range_sigma_m > 0 && std::isfinite(range_sigma_m))) throw InvalidInput("--bilateral-range-sigma: must be positive and finite");
}

BilateralKernel::BilateralKernel(const BilateralOptions& options) : radius(options.radius_px), separable(options.separable) {
  const int side = 2 * radius + 1;
  spatial.resize(static_cast<size_t>(side) * side);
  spatial_1d.resize(side);
  const double two_sigma2 = 2 * options.spatial_sigma_px * options.spatial_sigma_px;
  for (int d = -radius; d <= radius; ++d) spatial_1d[d + radius] = static_cast<float>(std::exp(-(d * d) / two_sigma2));
  for (int dy = -radius; dy <= radius; ++dy) {
    for (int dx = -radius; dx <= radius; ++dx) {
      spatial[(dy + radius) * side + dx + radius] = static_cast<float>(std::exp(-(dx * dx + dy * dy) / two_sigma2));
    }
  }
  inv_two_range_sigma2 = static_cast<float>(1.0 / (2 * options.range_sigma_m * options.range_sigma_m));
}

void bilateral_filter(const Image<float>& depth_m, const BilateralKernel& kernel, Image<float>& out, BilateralScratch& buffers, int num_threads) {
  Image<float>& scratch = buffers.sums;
  assert(&depth_m != &out && &scratch != &out && &scratch != &depth_m);
  const int width = depth_m.width, height = depth_m.height, r = kernel.radius;
  const float inv = kernel.inv_two_range_sigma2;
  auto row_of = [width](const Image<float>& image, int v) { return image.data.data() + static_cast<size_t>(v) * width; };
  auto out_row_of = [width](Image<float>& image, int v) { return image.data.data() + static_cast<size_t>(v) * width; };
  // Rows in contiguous blocks, one per thread, each with sums of its own.
  const int threads = std::max(1, std::min(num_threads, height));
  if (buffers.row_sums.size() < static_cast<size_t>(threads)) buffers.row_sums.resize(threads);
  auto for_rows = [&](auto&& row) {
    parallel_for(0, threads, [&](int block) {
      for (int v = height * block / threads; v < height * (block + 1) / threads; ++v) row(v, buffers.row_sums[block]);
    }, threads);
  };
  auto resize = [&](Image<float>& image) {
    image.width = width;
    image.height = height;
    image.data.resize(depth_m.size());
  };
  resize(out);
  if (!kernel.separable && r <= kLargestGatheredRadius) {
    // Each pixel's taps gathered, row by row of the window, as bilateral_pixel adds them.
    for_rows([&](int v, std::vector<float>& sums) {
      filter_row(row_of(depth_m, v), width, inv, sums, out_row_of(out, v), [&](auto&& add) {
        for (int dy = std::max(-r, -v); dy <= std::min(r, height - 1 - v); ++dy) {
          for (int dx = -r; dx <= r; ++dx) add(row_of(depth_m, v + dy), dx, kernel.spatial[(dy + r) * (2 * r + 1) + dx + r]);
        }
      });
    });
    return;
  }
  if (!kernel.separable) {
    filter_square(depth_m, kernel, out, buffers, num_threads);
    return;
  }
  // A row pass into `scratch`, then a column pass over it.
  resize(scratch);
  for_rows([&](int v, std::vector<float>& sums) {
    const float* centre_row = row_of(depth_m, v);
    filter_row(centre_row, width, inv, sums, out_row_of(scratch, v), [&](auto&& add) {
      for (int dx = -r; dx <= r; ++dx) add(centre_row, dx, kernel.spatial_1d[dx + r]);
    });
  });
  for_rows([&](int v, std::vector<float>& sums) {
    filter_row(row_of(scratch, v), width, inv, sums, out_row_of(out, v), [&](auto&& add) {
      for (int dy = std::max(-r, -v); dy <= std::min(r, height - 1 - v); ++dy) add(row_of(scratch, v + dy), 0, kernel.spatial_1d[dy + r]);
    });
  });
}

void bilateral_filter(const Image<float>& depth_m, const BilateralKernel& kernel, Image<float>& out, int num_threads) {
  BilateralScratch scratch;
  bilateral_filter(depth_m, kernel, out, scratch, num_threads);
}

}  // namespace zipfusion
