#include "zipfusion/fusion/surface_fit.h"

#include <algorithm>
#include <cmath>

#include "zipfusion/core/row_kernel.h"

namespace zipfusion {
namespace {

// The plane from the sums over a window's pixels on the surface (count, Σx, Σy, Σx², Σy², Σxy,
// Σz, Σxz, Σyz, x and y from the window's centre pixel).
SurfaceFit fit_from_sums(float n, float sx, float sy, float sxx, float syy, float sxy, float sz, float sxz, float syz) {
  SurfaceFit fit;
  fit.depth = sz / n, fit.cu = sx / n, fit.cv = sy / n;
  // The slope from the centred sums.
  const float cxx = sxx - sx * fit.cu, cyy = syy - sy * fit.cv, cxy = sxy - sx * fit.cv;
  const float cxz = sxz - sx * fit.depth, cyz = syz - sy * fit.depth;
  const float det = cxx * cyy - cxy * cxy;
  if (det > 1e-3f * (cxx + cyy) * (cxx + cyy)) {
    fit.du = (cxz * cyy - cyz * cxy) / det;
    fit.dv = (cyz * cxx - cxz * cxy) / det;
    fit.sloped = true;
  }
  return fit;
}

// Windows gathered and summed together: their depths stay in the first-level cache between the
// two (at most 25 × 128 floats).
constexpr int kChunk = 128;
constexpr int kMostSide = 5;  // windows up to 5 × 5; wider ones go one at a time

// The depths of the (2·radius + 1)² grid around `pixel`, `spacing` apart, row by row, into
// column `column` of `samples` (row k of the grid's samples at k · kChunk); 0 outside the image,
// which adds nothing to any sum (the element functions skip those pixels).
void gather_window(const DepthMesh& mesh, int pixel, int radius, int spacing, float* samples, int column) {
  const int side = 2 * radius + 1;
  const int u = pixel % mesh.width, v = pixel / mesh.width;
  const int reach = radius * spacing;
  if (u >= reach && v >= reach && u + reach < mesh.width && v + reach < mesh.height) {  // most windows
    const float* row = mesh.depth.data() + pixel - reach * mesh.width - reach;
    float* out = samples + column;
    for (int j = 0; j < side; ++j, row += spacing * mesh.width) {
      for (int k = 0; k < side; ++k, out += kChunk) *out = row[k * spacing];
    }
    return;
  }
  for (int j = 0; j < side; ++j) {
    const int y = v + (j - radius) * spacing;
    float* out = samples + j * side * kChunk + column;
    if (y < 0 || y >= mesh.height) {
      for (int k = 0; k < side; ++k) out[k * kChunk] = 0.0f;
      continue;
    }
    const float* row = mesh.depth.data() + static_cast<size_t>(y) * mesh.width;
    for (int k = 0; k < side; ++k) {
      const int x = u + (k - radius) * spacing;
      out[k * kChunk] = x >= 0 && x < mesh.width ? row[x] : 0.0f;
    }
  }
}

// fit_surface's sums for `count` (≤ kChunk) gathered windows, added in the element function's
// order (each row of the grid left to right, then the rows top to bottom) for each window; the
// windows are the vector lanes. `sums`: 9 rows of kChunk (n, sx, sy, sxx, syy, sxy, sz, sxz, syz).
ZF_ROW_KERNEL void plane_sums(const float* samples, int radius, int spacing, const float* centre, float same_surface, int count,
                              float* sums) {
  const int side = 2 * radius + 1;
  float* n = sums;
  float* sx = sums + kChunk;
  float* sy = sums + 2 * kChunk;
  float* sxx = sums + 3 * kChunk;
  float* syy = sums + 4 * kChunk;
  float* sxy = sums + 5 * kChunk;
  float* sz = sums + 6 * kChunk;
  float* sxz = sums + 7 * kChunk;
  float* syz = sums + 8 * kChunk;
  for (int i = 0; i < 9 * kChunk; ++i) sums[i] = 0.0f;
  float rn[kChunk], rx[kChunk], rxx[kChunk], rz[kChunk], rxz[kChunk];
  for (int j = 0; j < side; ++j) {
    for (int i = 0; i < count; ++i) rn[i] = rx[i] = rxx[i] = rz[i] = rxz[i] = 0.0f;
    for (int k = 0; k < side; ++k) {
      const float dx = static_cast<float>((k - radius) * spacing);
      const float* z = samples + (j * side + k) * kChunk;
      for (int i = 0; i < count; ++i) {
        const unsigned same = (z[i] > 0.0f) & (std::abs(z[i] - centre[i]) < same_surface);
        const float w = select_if(same, 1.0f, 0.0f), wz = select_if(same, z[i], 0.0f);
        rn[i] += w, rx[i] += w * dx, rxx[i] += w * dx * dx, rz[i] += wz, rxz[i] += wz * dx;
      }
    }
    const float dy = static_cast<float>((j - radius) * spacing);
    for (int i = 0; i < count; ++i) {
      n[i] += rn[i], sx[i] += rx[i], sy[i] += rn[i] * dy, sxx[i] += rxx[i], syy[i] += rn[i] * dy * dy, sxy[i] += rx[i] * dy;
      sz[i] += rz[i], sxz[i] += rxz[i], syz[i] += rz[i] * dy;
    }
  }
}

// smoothed_depth's sum and count for `count` (≤ kChunk) gathered windows, in its order.
ZF_ROW_KERNEL void mean_sums(const float* samples, int radius, const float* centre, float same_surface, int count, float* sum,
                             float* number) {
  const int side = 2 * radius + 1;
  for (int i = 0; i < count; ++i) sum[i] = number[i] = 0.0f;
  for (int k = 0; k < side * side; ++k) {
    const float* z = samples + k * kChunk;
    for (int i = 0; i < count; ++i) {
      const unsigned same = (z[i] > 0.0f) & (std::abs(z[i] - centre[i]) < same_surface);
      sum[i] += select_if(same, z[i], 0.0f);
      number[i] += select_if(same, 1.0f, 0.0f);
    }
  }
}

// Calls f(first, count, samples, centre) for each chunk of `pixels` after gathering its windows.
template <typename F>
void for_each_gathered_chunk(const MeshView& view, std::span<const int> pixels, int radius, int spacing, F&& f) {
  float samples[kMostSide * kMostSide * kChunk], centre[kChunk];
  const DepthMesh& mesh = *view.mesh;
  for (size_t first = 0; first < pixels.size(); first += kChunk) {
    const int count = static_cast<int>(std::min<size_t>(kChunk, pixels.size() - first));
    for (int i = 0; i < count; ++i) {
      gather_window(mesh, pixels[first + i], radius, spacing, samples, i);
      centre[i] = mesh.depth[pixels[first + i]];
    }
    f(first, count, samples, centre);
  }
}

}  // namespace

SurfaceFit fit_surface(const MeshView& view, int pixel, int radius, int spacing) {
  const DepthMesh& mesh = *view.mesh;
  const int u = pixel % mesh.width, v = pixel / mesh.width;
  const float centre = mesh.depth[pixel];
  float n = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0, sz = 0, sxz = 0, syz = 0;
  const int reach = radius * spacing;
  const int x0 = u - std::min(u, reach) / spacing * spacing, x1 = u + std::min(mesh.width - 1 - u, reach) / spacing * spacing;
  const int y0 = v - std::min(v, reach) / spacing * spacing, y1 = v + std::min(mesh.height - 1 - v, reach) / spacing * spacing;
  for (int y = y0; y <= y1; y += spacing) {
    const float* row = mesh.depth.data() + y * mesh.width;
    // The row's sums first, then weighed by its offset dy (half the work per pixel).
    float rn = 0, rx = 0, rxx = 0, rz = 0, rxz = 0;
    float dx = static_cast<float>(x0 - u);
    for (int x = x0; x <= x1; x += spacing, dx += static_cast<float>(spacing)) {
      // Without branches (which pixels belong is unpredictable at a border).
      const float z = row[x];
      const bool same = (z > 0) & (std::abs(z - centre) < view.same_surface);
      const float w = same ? 1.0f : 0.0f, wz = same ? z : 0.0f;
      rn += w, rx += w * dx, rxx += w * dx * dx, rz += wz, rxz += wz * dx;
    }
    const float dy = static_cast<float>(y - v);
    n += rn, sx += rx, sy += rn * dy, sxx += rxx, syy += rn * dy * dy, sxy += rx * dy;
    sz += rz, sxz += rxz, syz += rz * dy;
  }
  return fit_from_sums(n, sx, sy, sxx, syy, sxy, sz, sxz, syz);
}

float smoothed_depth(const MeshView& view, int pixel, int radius) {
  const float same_surface = view.same_surface;
  const DepthMesh& mesh = *view.mesh;
  const int u = pixel % mesh.width, v = pixel / mesh.width;
  const float centre = mesh.depth[pixel];
  float sum = 0;
  int count = 0;
  // Without branches (which pixels belong is unpredictable at a border): a pixel left out adds
  // exactly 0, so the sum is the same as adding only the others, in the same order.
  auto add = [&](float z) {
    const bool same = z > 0 && std::abs(z - centre) < same_surface;
    sum += same ? z : 0.0f;
    count += same;
  };
  if (u >= radius && v >= radius && u + radius < mesh.width && v + radius < mesh.height) {
    const float* row = mesh.depth.data() + pixel - radius * mesh.width - radius;
    for (int y = 0; y <= 2 * radius; ++y, row += mesh.width) {
      for (int x = 0; x <= 2 * radius; ++x) add(row[x]);
    }
  } else {
    for (int y = std::max(0, v - radius); y <= std::min(mesh.height - 1, v + radius); ++y) {
      const float* row = mesh.depth.data() + y * mesh.width;
      for (int x = std::max(0, u - radius); x <= std::min(mesh.width - 1, u + radius); ++x) add(row[x]);
    }
  }
  return sum / static_cast<float>(count);
}

void fit_surfaces(const MeshView& view, std::span<const int> pixels, int radius, int spacing, SurfaceFit* out) {
  if (2 * radius + 1 > kMostSide) {
    for (size_t k = 0; k < pixels.size(); ++k) out[k] = fit_surface(view, pixels[k], radius, spacing);
    return;
  }
  float sums[9 * kChunk];
  for_each_gathered_chunk(view, pixels, radius, spacing, [&](size_t first, int count, const float* samples, const float* centre) {
    plane_sums(samples, radius, spacing, centre, view.same_surface, count, sums);
    for (int i = 0; i < count; ++i) {
      const float* s = sums + i;
      out[first + i] = fit_from_sums(s[0], s[kChunk], s[2 * kChunk], s[3 * kChunk], s[4 * kChunk], s[5 * kChunk], s[6 * kChunk],
                                     s[7 * kChunk], s[8 * kChunk]);
    }
  });
}

void smoothed_depths(const MeshView& view, std::span<const int> pixels, int radius, float* out) {
  if (2 * radius + 1 > kMostSide) {
    for (size_t k = 0; k < pixels.size(); ++k) out[k] = smoothed_depth(view, pixels[k], radius);
    return;
  }
  float sum[kChunk], number[kChunk];
  for_each_gathered_chunk(view, pixels, radius, 1, [&](size_t first, int count, const float* samples, const float* centre) {
    mean_sums(samples, radius, centre, view.same_surface, count, sum, number);
    for (int i = 0; i < count; ++i) out[first + i] = sum[i] / number[i];
  });
}

}  // namespace zipfusion
