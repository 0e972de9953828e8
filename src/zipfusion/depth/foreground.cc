#include "zipfusion/depth/foreground.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstddef>

#include "zipfusion/core/error.h"
#include "zipfusion/core/row_kernel.h"

namespace zipfusion {

void ForegroundOptions::validate() const {
  if (!(min_depth_m >= 0 && std::isfinite(min_depth_m))) throw InvalidInput("--min-depth: must be a finite depth >= 0 metres");
  if (!(max_depth_m > min_depth_m && std::isfinite(max_depth_m))) throw InvalidInput("--max-depth: must be finite and exceed --min-depth");
  if (!(floor_noise_sigmas >= 0 && floor_noise_sigmas <= 10)) throw InvalidInput("--floor-noise: must be in [0, 10] standard deviations");
}

namespace {

// foreground_depth over one row, as a branch-free loop that vectorises (a Kinect row is 640
// pixels and every one is tested).
ZF_ROW_KERNEL void foreground_row(const unsigned short* raw, int width, int v, const ForegroundParams& params, float* out) {
  const Eigen::Vector3f row_ray = params.world_rays.row_ray(v);
  const Eigen::Vector3f origin = params.world_rays.origin, du = params.world_rays.ray_du;
  const float lo_x = params.box_min.x(), lo_y = params.box_min.y(), lo_z = params.box_min.z();
  const float hi_x = params.box_max.x(), hi_y = params.box_max.y(), hi_z = params.box_max.z();
  const float floor_sigmas = params.floor_noise_sigmas;
  const int crop = params.crop ? 1 : 0;
  for (int u = 0; u < width; ++u) {
    const float z = static_cast<float>(raw[u]) * params.depth_unit_m;
    const float uf = static_cast<float>(u);
    const float x = origin.x() + z * (row_ray.x() + uf * du.x());
    const float y = origin.y() + z * (row_ray.y() + uf * du.y());
    const float ray_z = row_ray.z() + uf * du.z();
    const float w = origin.z() + z * ray_z;
    const int in_box = static_cast<int>(x >= lo_x) & static_cast<int>(x <= hi_x) & static_cast<int>(y >= lo_y) & static_cast<int>(y <= hi_y) &
                       static_cast<int>(w >= lo_z + floor_lift_m(z, ray_z, floor_sigmas)) & static_cast<int>(w <= hi_z);
    const int keep = static_cast<int>(raw[u] != 0) & static_cast<int>(z >= params.min_depth_m) & static_cast<int>(z <= params.max_depth_m) &
                     (in_box | (1 - crop));
    out[u] = static_cast<float>(keep) * z;
  }
}

}  // namespace

ForegroundParams::ForegroundParams(double depth_unit, const CameraModel& camera, const std::optional<Box3d>& volume,
                                   const ForegroundOptions& options)
    : depth_unit_m(static_cast<float>(depth_unit)),
      min_depth_m(static_cast<float>(options.min_depth_m)),
      max_depth_m(static_cast<float>(options.max_depth_m)),
      crop(options.crop_to_volume && volume.has_value()),
      floor_noise_sigmas(static_cast<float>(options.floor_noise_sigmas)),
      world_rays(camera.depth_intrinsics, camera.world_from_depth.cast<float>()) {
  if (crop) {
    box_min = volume->min.cast<float>();
    box_max = volume->max.cast<float>();
  }
}

void extract_foreground(const DepthImage& raw, double depth_unit_m, const CameraModel& camera, const std::optional<Box3d>& volume,
                        const ForegroundOptions& options, Image<float>& depth_m) {
  depth_m.width = raw.width;
  depth_m.height = raw.height;
  depth_m.data.resize(raw.size());
  const ForegroundParams params(depth_unit_m, camera, volume, options);
  for (int v = 0; v < raw.height; ++v) {
    foreground_row(raw.data.data() + static_cast<size_t>(v) * raw.width, raw.width, v, params, depth_m.data.data() + static_cast<size_t>(v) * raw.width);
  }
}

namespace {

// One tap of the subsampled pixels [0, n) of a chunk: z = taps[i·kStep] added with `tap_weight`
// where it lies on the surface of centres[i]. The taps are gathered first: GCC vectorises a
// strided copy but not the strided load inside the sum.
template <int kStep>
[[gnu::always_inline]] inline void add_tap(const float* taps, const float* centres, int n, float tap_weight, float same_surface, float* gathered,
                                           float* weighted, float* weights) {
  for (int i = 0; i < n; ++i) gathered[i] = taps[i * kStep];
  for (int i = 0; i < n; ++i) {
    const float z = gathered[i];
    const unsigned same = static_cast<unsigned>(z > 0.0f) & static_cast<unsigned>(std::abs(z - centres[i]) < same_surface);
    const float w = select_if(same, tap_weight, 0.0f);
    weighted[i] += w * z;
    weights[i] += w;
  }
}

// subsampled_depth over pixels [u_begin, u_end) of output row v, all of whose taps lie inside the
// image: a pass per tap over a chunk of the row, adding in the element function's order, so each
// pixel gets the same float.
template <int kStep>
[[gnu::always_inline]] inline void subsample_row(const Image<float>& depth, int v, int u_begin, int u_end, float same_surface, float* out) {
  constexpr int kChunk = 256;
  float weighted[kChunk], weights[kChunk], centres[kChunk], gathered[kChunk];
  for (int chunk = u_begin; chunk < u_end; chunk += kChunk) {
    const int n = std::min(kChunk, u_end - chunk);
    const float* centre_row = depth.data.data() + static_cast<size_t>(v * kStep) * depth.width + static_cast<size_t>(chunk) * kStep;
    for (int i = 0; i < n; ++i) {
      centres[i] = centre_row[i * kStep];
      weighted[i] = 0.0f;
      weights[i] = 0.0f;
    }
    for (int dy = -(kStep - 1); dy <= kStep - 1; ++dy) {
      const float wy = static_cast<float>(kStep - std::abs(dy));
      for (int dx = -(kStep - 1); dx <= kStep - 1; ++dx) {
        const float* taps = centre_row + static_cast<std::ptrdiff_t>(dy) * depth.width + dx;
        add_tap<kStep>(taps, centres, n, wy * static_cast<float>(kStep - std::abs(dx)), same_surface, gathered, weighted, weights);
      }
    }
    for (int i = 0; i < n; ++i) out[chunk + i] = select_if(centres[i] != 0.0f, weighted[i] / weights[i], 0.0f);
  }
}

// The row kernels, one per level: a constant stride vectorises, and GCC clones no templates (so
// the template is inlined into each clone).
ZF_ROW_KERNEL void subsample_row_level1(const Image<float>& depth, int v, int u_begin, int u_end, float same_surface, float* out) {
  subsample_row<2>(depth, v, u_begin, u_end, same_surface, out);
}
ZF_ROW_KERNEL void subsample_row_level2(const Image<float>& depth, int v, int u_begin, int u_end, float same_surface, float* out) {
  subsample_row<4>(depth, v, u_begin, u_end, same_surface, out);
}
ZF_ROW_KERNEL void subsample_row_level3(const Image<float>& depth, int v, int u_begin, int u_end, float same_surface, float* out) {
  subsample_row<8>(depth, v, u_begin, u_end, same_surface, out);
}

}  // namespace

void subsample_depth(const Image<float>& depth, int level, float same_surface, Image<float>& out) {
  assert(!depth.empty() && level >= 0 && level <= 8 && same_surface > 0 && &out != &depth);
  const int step = 1 << level, reach = step - 1;
  out.width = (depth.width - 1) / step + 1;
  out.height = (depth.height - 1) / step + 1;
  out.data.resize(static_cast<size_t>(out.width) * out.height);
  // Pixels whose taps all lie inside: u·step ± reach within the width.
  const int u_begin = (reach + step - 1) / step;
  const int u_end = std::max(u_begin, (depth.width - 1 - reach) / step + 1);
  for (int v = 0; v < out.height; ++v) {
    float* row = out.data.data() + static_cast<size_t>(v) * out.width;
    auto by_element = [&](int begin, int end) {
      for (int u = begin; u < end; ++u) row[u] = subsampled_depth(u, v, depth.data.data(), depth.width, depth.height, level, same_surface);
    };
    const bool inside = v * step - reach >= 0 && v * step + reach < depth.height && u_end <= out.width;
    if (!inside || level < 1 || level > 3) {
      by_element(0, out.width);
      continue;
    }
    by_element(0, u_begin);
    if (level == 1) {
      subsample_row_level1(depth, v, u_begin, u_end, same_surface, row);
    } else if (level == 2) {
      subsample_row_level2(depth, v, u_begin, u_end, same_surface, row);
    } else {
      subsample_row_level3(depth, v, u_begin, u_end, same_surface, row);
    }
    by_element(u_end, out.width);
  }
}

}  // namespace zipfusion
