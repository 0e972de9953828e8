#include "zipfusion/synth/kinect_model.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "zipfusion/core/error.h"
#include "zipfusion/core/parallel.h"

namespace zipfusion {
namespace {

constexpr float kInfinity = std::numeric_limits<float>::infinity();

enum Stream : std::uint64_t { kEdge = 1, kHoleSeed, kHoleRadius, kNoiseA, kNoiseB };

inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// Element function: is pixel (u, v) at depth z hidden from the projector? The projector shares
// the camera's rows, so the point lands on the same row at u − f·b/z.
inline bool in_projector_shadow(int u, int v, float z, const Image<float>& projector_depth, const Intrinsics& k,
                                double baseline_m) {
  const double u_proj = u - k.fx * baseline_m / z;
  const int u0 = static_cast<int>(std::floor(u_proj));
  // Hidden only when both neighbouring projector pixels see something clearly nearer, so
  // silhouette pixels are not shadowed by sampling alone.
  const float tolerance = std::max(0.01f, 0.01f * z);
  for (int du = 0; du <= 1; ++du) {
    const int uu = u0 + du;
    if (uu < 0 || uu >= projector_depth.width) return false;  // outside the pattern's image: lit
    if (!(projector_depth(uu, v) < z - tolerance)) return false;
  }
  return true;
}

// Element function: the largest depth difference to an 8-neighbour (infinite next to nothing).
inline float max_neighbour_jump(int u, int v, const Image<float>& depth) {
  const float z = depth(u, v);
  float jump = 0;
  for (int dv = -1; dv <= 1; ++dv) {
    for (int du = -1; du <= 1; ++du) {
      if (!depth.contains(u + du, v + dv)) continue;
      const float n = depth(u + du, v + dv);
      jump = std::max(jump, std::isinf(n) ? kInfinity : std::abs(n - z));
    }
  }
  return jump;
}
}  // namespace

double hash_uniform(std::uint64_t seed, std::uint64_t index, std::uint64_t stream) {
  const std::uint64_t h = splitmix64(splitmix64(seed ^ (stream * 0xd1b54a32d192ed03ULL)) ^ index);
  return static_cast<double>(h >> 11) * (1.0 / 9007199254740992.0);
}

double hash_normal(std::uint64_t seed, std::uint64_t index, std::uint64_t stream) {
  // Box–Muller on two independent uniforms of this counter.
  const double u1 = 1.0 - hash_uniform(seed, index, stream);  // (0, 1]
  const double u2 = hash_uniform(seed, index, stream + 0x100);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

KinectNoiseOptions KinectNoiseOptions::none() {
  return {.projector_shadows = false, .edge_dropout = false, .random_holes = false, .axial_noise = false,
          .disparity_quantization = false};
}

void KinectNoiseOptions::validate() const {
  auto fail = [](const char* field, const char* problem) { throw InvalidInput(std::string("noise.") + field + ": " + problem); };
  if (!(baseline_m > 0)) fail("baseline_m", "must be positive");
  if (!(edge_jump_m > 0)) fail("edge_jump_m", "must be positive");
  if (!(edge_dropout_probability >= 0 && edge_dropout_probability <= 1)) fail("edge_dropout_probability", "must be in [0, 1]");
  if (!(hole_seed_density >= 0 && hole_seed_density < 1)) fail("hole_seed_density", "must be in [0, 1)");
  if (hole_max_radius_px < 0 || hole_max_radius_px > 50) fail("hole_max_radius_px", "must be in [0, 50]");
  if (!(disparity_step_px > 0)) fail("disparity_step_px", "must be positive");
  if (!(min_range_m >= 0 && max_range_m > min_range_m)) fail("max_range_m", "must exceed min_range_m >= 0");
}

DepthImage simulate_kinect_depth(const Image<float>& true_depth, const Image<float>& projector_depth, const Intrinsics& k,
                                 const KinectNoiseOptions& options, double depth_unit_m, std::uint64_t seed) {
  const int width = true_depth.width, height = true_depth.height;
  const double focal = k.fx;
  const double disparity_scale = focal * options.baseline_m;  // disparity (px) = this / z

  // Holes first: a mask of discs around random seeds.
  Image<unsigned char> hole(width, height, 0);
  if (options.random_holes) {
    for (int i = 0; i < width * height; ++i) {
      if (hash_uniform(seed, i, kHoleSeed) >= options.hole_seed_density) continue;
      const int radius = static_cast<int>(hash_uniform(seed, i, kHoleRadius) * (options.hole_max_radius_px + 1));
      const int cu = i % width, cv = i / width;
      for (int dv = -radius; dv <= radius; ++dv) {
        for (int du = -radius; du <= radius; ++du) {
          if (du * du + dv * dv <= radius * radius && hole.contains(cu + du, cv + dv)) hole(cu + du, cv + dv) = 1;
        }
      }
    }
  }

  DepthImage out(width, height, 0);
  parallel_for(0, height, [&](int v) {
    for (int u = 0; u < width; ++u) {
      const size_t i = static_cast<size_t>(v) * width + u;
      double z = true_depth(u, v);
      if (!std::isfinite(z) || z <= 0) continue;
      if (options.projector_shadows && !projector_depth.empty() &&
          in_projector_shadow(u, v, static_cast<float>(z), projector_depth, k, options.baseline_m)) {
        continue;
      }
      if (options.edge_dropout && max_neighbour_jump(u, v, true_depth) > options.edge_jump_m &&
          hash_uniform(seed, i, kEdge) < options.edge_dropout_probability) {
        continue;
      }
      if (hole(u, v)) continue;
      if (options.axial_noise) z += kinect_axial_sigma_m(z) * hash_normal(seed, i, kNoiseA);
      if (options.disparity_quantization && z > 0) {
        const double disparity = disparity_scale / z;
        const double quantized = std::round(disparity / options.disparity_step_px) * options.disparity_step_px;
        if (quantized <= 0) continue;
        z = disparity_scale / quantized;
      }
      if (z < options.min_range_m || z > options.max_range_m) continue;
      const double raw = std::round(z / depth_unit_m);
      if (raw >= 1 && raw <= 65535) out(u, v) = static_cast<unsigned short>(raw);
    }
  });
  return out;
}

}  // namespace zipfusion
