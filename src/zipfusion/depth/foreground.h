#pragma once
//! \file
//! Foreground extraction (issue 3, paper Section III-B): raw depth to metres, keeping only what
//! lies in the sensor's working range and, when the rig has a capture volume, inside it (this
//! removes floor, walls and other people).

#include <algorithm>
#include <cmath>
#include <optional>

#include "zipfusion/core/depth_noise.h"
#include "zipfusion/core/geometry.h"
#include "zipfusion/core/image.h"
#include "zipfusion/io/rig.h"

namespace zipfusion {

struct ForegroundOptions {
  double min_depth_m = 0.4;  // metres; Kinect v1 near limit (paper Section III-B)
  double max_depth_m = 4.5;  // metres; beyond it Kinect v1 depth is too coarse (σ > 2.7 cm)
  bool crop_to_volume = true;  // drop points outside the rig's `volume`
  //! The volume's bottom rises, pixel by pixel, until it clears this many standard deviations of
  //! the pixel's height noise (floor_lift_m); 0 keeps the bottom where rig.json puts it.
  double floor_noise_sigmas = 3.0;

  void validate() const;  // throws InvalidInput naming the field
};

//! What foreground_depth needs of one camera, precomputed once per frame.
struct ForegroundParams {
  float depth_unit_m = 0.001f;
  float min_depth_m = 0.4f;
  float max_depth_m = 4.5f;
  bool crop = false;  // test the world point against [box_min, box_max]
  float floor_noise_sigmas = 0.0f;
  PixelRays world_rays;  // depth pixel → world
  Eigen::Vector3f box_min = Eigen::Vector3f::Zero();
  Eigen::Vector3f box_max = Eigen::Vector3f::Zero();

  ForegroundParams(double depth_unit, const CameraModel& camera, const std::optional<Box3d>& volume, const ForegroundOptions& options);
};

//! Element function: how far the volume's bottom rises for a point at depth z metres on a pixel
//! whose world ray climbs `ray_z` metres per metre of depth (PixelRays, world z up). The depth's
//! noise along the ray (kinect_axial_sigma_m) moves the point's height by σ·|ray_z|. The floor is
//! taken to lie kVolumeFloorClearanceM below the bottom, as `calibrate floor` and `synth` put it,
//! so the bottom rises by what `sigmas` times that noise exceeds the clearance. A camera 2.6 m up
//! sees the floor 3–4 m away with a height noise of about 14 mm: a fixed 2 cm let a tenth of its
//! floor into the volume, as specks around the subject. A ring at Kinect height keeps its bottom
//! where its subject stands (3σ is about 1.5 cm there; a few millimetres at the far corners).
inline float floor_lift_m(float z, float ray_z, float sigmas) {
  return std::max(0.0f, sigmas * kinect_axial_sigma_m(z) * std::abs(ray_z) - static_cast<float>(kVolumeFloorClearanceM));
}

//! Element function: depth in metres of pixel (u, v) with raw value `raw`, or 0 when it is not
//! foreground.
inline float foreground_depth(int u, int v, unsigned short raw, const ForegroundParams& params) {
  const float z = static_cast<float>(raw) * params.depth_unit_m;
  if (raw == 0 || z < params.min_depth_m || z > params.max_depth_m) return 0.0f;
  if (params.crop) {
    const Eigen::Vector3f ray = params.world_rays.ray(u, v);
    const Eigen::Vector3f p = params.world_rays.origin + z * ray;
    Eigen::Vector3f box_min = params.box_min;
    box_min.z() += floor_lift_m(z, ray.z(), params.floor_noise_sigmas);
    if ((p.array() < box_min.array()).any() || (p.array() > params.box_max.array()).any()) return 0.0f;
  }
  return z;
}

//! Fills `depth_m` (resized to the raw image) with foreground depth in metres, 0 elsewhere.
void extract_foreground(const DepthImage& raw, double depth_unit_m, const CameraModel& camera, const std::optional<Box3d>& volume,
                        const ForegroundOptions& options, Image<float>& depth_m);

//! Element function: the depth of pixel (u, v) of a depth image (width × height, metres, 0 = none)
//! subsampled by step = 2^level, that is of pixel (u·step, v·step), as the tent-weighted mean
//! (weights (step − |dx|)·(step − |dy|)) of the pixels within step − 1 of it that lie on its
//! surface (nonzero and within `same_surface` metres of its depth, the SDC threshold of
//! full-resolution neighbours, also for the farther taps of levels 2 and 3: on a steep surface
//! those drop out, and fewer pixels are averaged); 0 where that pixel is 0. Taking every step-th
//! pixel alone would discard three quarters of the measurements at level 1; the mean keeps their
//! averaging (the Kinect's noise is σ ≈ 6–14 mm at 2–3 m in the simulator's model) without mixing
//! a surface with the one behind it. The pixel stays where it was, so the subsampled intrinsics
//! (subsampled_intrinsics) describe it. Preconditions: same_surface > 0 (the centre then weighs
//! step² and the mean is defined); (u·step, v·step) inside the image.
inline float subsampled_depth(int u, int v, const float* depth, int width, int height, int level, float same_surface) {
  const int step = 1 << level, x0 = u * step, y0 = v * step;
  const float centre = depth[y0 * width + x0];
  if (centre == 0.0f) return 0.0f;
  float weighted = 0.0f, weights = 0.0f;
  for (int dy = -(step - 1); dy <= step - 1; ++dy) {
    const int y = y0 + dy;
    if (y < 0 || y >= height) continue;
    const float wy = static_cast<float>(step - std::abs(dy));
    for (int dx = -(step - 1); dx <= step - 1; ++dx) {
      const int x = x0 + dx;
      if (x < 0 || x >= width) continue;
      const float z = depth[y * width + x];
      // Branch-free: a pixel of another surface (or none) adds exactly 0.
      const float w = z > 0.0f && std::abs(z - centre) < same_surface ? wy * static_cast<float>(step - std::abs(dx)) : 0.0f;
      weighted += w * z;
      weights += w;
    }
  }
  return weighted / weights;
}

//! `out` (resized to the subsampled size, (width − 1) / 2^level + 1 by the same for height) =
//! subsampled_depth at every pixel; levels 1–3 by row kernels (the border pixels, whose taps reach
//! outside, by the element function), others by the element function alone. Preconditions:
//! `depth` not empty, 0 ≤ level ≤ 8, same_surface > 0, `out` not `depth`.
void subsample_depth(const Image<float>& depth, int level, float same_surface, Image<float>& out);

}  // namespace zipfusion
