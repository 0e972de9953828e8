#pragma once
//! \file
//! Foreground extraction (issue 3, paper Section III-B): raw depth to metres, keeping only what
//! lies in the sensor's working range and, when the rig has a capture volume, inside it (this
//! removes floor, walls and other people).

#include <optional>

#include "zipfusion/core/geometry.h"
#include "zipfusion/core/image.h"
#include "zipfusion/io/rig.h"

namespace zipfusion {

struct ForegroundOptions {
  double min_depth_m = 0.4;  // metres; Kinect v1 near limit (paper Section III-B)
  double max_depth_m = 4.5;  // metres; beyond it Kinect v1 depth is too coarse (σ > 2.7 cm)
  bool crop_to_volume = true;  // drop points outside the rig's `volume`

  void validate() const;  // throws InvalidInput naming the field
};

//! What foreground_depth needs of one camera, precomputed once per frame.
struct ForegroundParams {
  float depth_unit_m = 0.001f;
  float min_depth_m = 0.4f;
  float max_depth_m = 4.5f;
  bool crop = false;  // test the world point against [box_min, box_max]
  PixelRays world_rays;  // depth pixel → world
  Eigen::Vector3f box_min = Eigen::Vector3f::Zero();
  Eigen::Vector3f box_max = Eigen::Vector3f::Zero();

  ForegroundParams(double depth_unit, const CameraModel& camera, const std::optional<Box3d>& volume, const ForegroundOptions& options);
};

//! Element function: depth in metres of pixel (u, v) with raw value `raw`, or 0 when it is not
//! foreground.
inline float foreground_depth(int u, int v, unsigned short raw, const ForegroundParams& params) {
  const float z = static_cast<float>(raw) * params.depth_unit_m;
  if (raw == 0 || z < params.min_depth_m || z > params.max_depth_m) return 0.0f;
  if (params.crop) {
    const Eigen::Vector3f p = params.world_rays.point(u, v, z);
    if ((p.array() < params.box_min.array()).any() || (p.array() > params.box_max.array()).any()) return 0.0f;
  }
  return z;
}

//! Fills `depth_m` (resized to the raw image) with foreground depth in metres, 0 elsewhere.
void extract_foreground(const DepthImage& raw, double depth_unit_m, const CameraModel& camera, const std::optional<Box3d>& volume,
                        const ForegroundOptions& options, Image<float>& depth_m);

//! Element function: the depth of pixel (u, v) of `depth` subsampled by step = 2^level, that is of
//! pixel (u·step, v·step), as the tent-weighted mean (weights (step − |dx|)·(step − |dy|)) of the
//! pixels within step − 1 of it that lie on its surface (nonzero and within `same_surface` metres
//! of its depth); 0 where that pixel is 0. Taking every step-th pixel alone would discard three
//! quarters of the measurements at level 1; the mean keeps their averaging (the Kinect's noise is
//! σ ≈ 5–9 mm at 2–3 m) without mixing a surface with the one behind it. The pixel stays where it
//! was, so the subsampled intrinsics (subsampled_intrinsics) describe it.
float subsampled_depth(const Image<float>& depth, int u, int v, int level, float same_surface);

//! `out` (resized to the subsampled size, (width − 1) / 2^level + 1 by the same for height) =
//! subsampled_depth at every pixel.
void subsample_depth(const Image<float>& depth, int level, float same_surface, Image<float>& out);

}  // namespace zipfusion
