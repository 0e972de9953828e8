#pragma once
//! \file
//! Rigid transforms and small geometric helpers. Transforms are named by frames:
//! `world_from_depth` maps a point in the depth camera's frame to the world.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace zipfusion {

using Rigid3d = Eigen::Isometry3d;
using Rigid3f = Eigen::Isometry3f;

//! True when m is a rigid transform: bottom row (0 0 0 1), orthonormal rotation (|RᵀR − I| ≤ tol
//! entry-wise), det(R) = +1 within tol.
bool is_rigid(const Eigen::Matrix4d& m, double tolerance = 1e-4);

//! The nearest exact rigid transform to m (rotation re-orthonormalised by SVD). m should already
//! pass is_rigid; this removes the rounding of a text file.
Rigid3d nearest_rigid(const Eigen::Matrix4d& m);

//! Rotation angle of a rigid transform, degrees.
double rotation_angle_deg(const Rigid3d& t);

//! Camera pose that looks from `eye` at `target` with OpenCV axes (x right, y down, z forward) in a
//! z-up world. Precondition: the viewing direction is not vertical.
Rigid3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target);

//! Element functions: ⌊x⌋ and ⌈x⌉ as ints, for |x| < 2³¹, by truncation corrected by one.
//! Without SSE4.1 (the default x86-64 target), std::floor compiles to a longer sequence; in the
//! zipper's per-triangle tests it was a fifth of the ownership test's instructions.
inline int floor_to_int(float x) {
  const int i = static_cast<int>(x);
  return i - (x < static_cast<float>(i));
}
inline int ceil_to_int(float x) {
  const int i = static_cast<int>(x);
  return i + (x > static_cast<float>(i));
}

//! Axis-aligned box.
struct Box3d {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
  bool contains(const Eigen::Vector3d& p) const {
    return (p.array() >= min.array()).all() && (p.array() <= max.array()).all();
  }
};

}  // namespace zipfusion
