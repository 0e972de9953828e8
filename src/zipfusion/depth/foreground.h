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

//! Element function: depth in metres of pixel `index`, or 0 when it is not foreground.
inline float foreground_depth(int index, const unsigned short* raw, int width, float depth_unit_m, float min_depth_m,
                              float max_depth_m, const Intrinsics& k, const Rigid3f& world_from_depth, const Box3d* volume) {
  const float z = raw[index] * depth_unit_m;
  if (raw[index] == 0 || z < min_depth_m || z > max_depth_m) return 0.0f;
  if (volume != nullptr) {
    const Eigen::Vector3f p = world_from_depth * unproject(k, static_cast<float>(index % width), static_cast<float>(index / width), z);
    if ((p.array() < volume->min.cast<float>().array()).any() || (p.array() > volume->max.cast<float>().array()).any()) return 0.0f;
  }
  return z;
}

//! Fills `depth_m` (resized to the raw image) with foreground depth in metres, 0 elsewhere.
void extract_foreground(const DepthImage& raw, double depth_unit_m, const CameraModel& camera, const std::optional<Box3d>& volume,
                        const ForegroundOptions& options, Image<float>& depth_m);

}  // namespace zipfusion
