#pragma once
//! \file
//! Pinhole camera with optional OpenCV radial-tangential distortion (k1, k2, p1, p2, k3).
//! Axes as OpenCV: x right, y down, z forward; pixel centres at integer coordinates.
//! Projection functions are plain inline element functions (no allocation, no exceptions) so a
//! CUDA port can call them as they are.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>

namespace zipfusion {

//! The focal length, in pixels, of a Kinect v1's depth camera at 640×480: what options given in
//! pixels (the SDC threshold, registration's levels) are set for; a camera of focal length f
//! scales them by f/580.
inline constexpr double kKinectV1DepthFocalPx = 580.0;

struct Intrinsics {
  int width = 0;    // pixels
  int height = 0;   // pixels
  double fx = 0;    // focal length, pixels
  double fy = 0;    // focal length, pixels
  double cx = 0;    // principal point, pixels
  double cy = 0;    // principal point, pixels
  std::array<double, 5> distortion{};  // k1 k2 p1 p2 k3 (OpenCV order); all zero = none
  bool has_distortion = false;         // whether rig.json gave "distortion"

  friend bool operator==(const Intrinsics&, const Intrinsics&) = default;
};

//! Normalised image coordinates (x/z, y/z) → distorted normalised coordinates.
inline Eigen::Vector2d distort(const Intrinsics& k, const Eigen::Vector2d& xy) {
  const auto& d = k.distortion;
  const double x = xy.x(), y = xy.y();
  const double r2 = x * x + y * y;
  const double radial = 1 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
  return {x * radial + 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x),
          y * radial + d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y};
}

//! Where the radial distortion stops growing inside the image, as a share of the way from the
//! principal point to the farthest corner (0: it grows all the way, as it must). Past that radius
//! r·(1 + k1 r² + k2 r⁴ + k3 r⁶) shrinks again, so rays further out land back on pixels nearer the
//! centre: undistorted depth would repeat a ring of the image, colour be sampled from the wrong
//! place. A calibrated lens does not fold inside its own image; coefficients that do are a typo or
//! a fit that ran away.
inline double distortion_fold_share(const Intrinsics& k) {
  const auto& d = k.distortion;
  const double dx = std::max(k.cx + 0.5, k.width - 0.5 - k.cx) / k.fx, dy = std::max(k.cy + 0.5, k.height - 0.5 - k.cy) / k.fy;
  const double farthest = std::hypot(dx, dy);  // normalised radius of the farthest corner
  constexpr int kSteps = 1000;
  for (int i = 1; i <= kSteps; ++i) {
    const double r = farthest * i / kSteps, r2 = r * r;
    const double slope = 1 + r2 * (3 * d[0] + r2 * (5 * d[1] + r2 * 7 * d[4]));  // d/dr of the radial part
    if (slope <= 0) return static_cast<double>(i) / kSteps;
  }
  return 0;
}

//! The most distortion_stretch_range may reach either way (1/3 to 3) before a rig.json reader
//! refuses the coefficients: past any lens the five-coefficient model describes.
inline constexpr double kMostDistortionStretch = 3;

//! How far distortion moves the points of the image, at most: the smallest and the largest ratio
//! |distort(p)| / |p| over a grid of normalised points p spanning the image (to its farthest
//! corner from the principal point each way). A lens moves a point by a few per cent of its
//! distance from the centre, a wide one by a few tens; coefficients that scale distances by
//! several times (1e9 typed for 1e-9) would squeeze the camera's whole image into a few pixels of
//! the undistorted one, and its surface would silently vanish.
inline std::pair<double, double> distortion_stretch_range(const Intrinsics& k) {
  const double left = (k.cx + 0.5) / k.fx, right = (k.width - 0.5 - k.cx) / k.fx;
  const double top = (k.cy + 0.5) / k.fy, bottom = (k.height - 0.5 - k.cy) / k.fy;
  constexpr int kSteps = 32;
  double least = 1, most = 1;
  for (int i = 0; i <= kSteps; ++i) {
    for (int j = 0; j <= kSteps; ++j) {
      const Eigen::Vector2d p(-left + (left + right) * i / kSteps, -top + (top + bottom) * j / kSteps);
      const double r = p.norm();
      if (r < 1e-9) continue;
      const double ratio = distort(k, p).norm() / r;
      if (!std::isfinite(ratio)) return {least, std::numeric_limits<double>::infinity()};  // overflowed
      least = std::min(least, ratio);
      most = std::max(most, ratio);
    }
  }
  return {least, most};
}

//! Whether a distortion_stretch_range lies within kMostDistortionStretch either way.
inline bool stretch_of_a_lens(const std::pair<double, double>& range) {
  return range.first >= 1 / kMostDistortionStretch && range.second <= kMostDistortionStretch;
}

//! What a distortion_stretch_range beyond a lens's does, for the refusals of rig.json's reader and
//! of `calibrate intrinsics`: "moves points of the image to 0.2–1.01 times their distance …".
inline std::string distortion_stretch_problem(const std::pair<double, double>& range) {
  char text[200];
  std::snprintf(text, sizeof text,
                "moves points of the image to %.3g–%.3g times their distance from the principal point (a lens: within 1/%g–%g times)",
                range.first, range.second, kMostDistortionStretch, kMostDistortionStretch);
  return text;
}

//! Pixel of a point in the camera frame. Precondition: p.z() > 0. Distortion applied when present.
inline Eigen::Vector2d project(const Intrinsics& k, const Eigen::Vector3d& p_in_cam) {
  Eigen::Vector2d xy(p_in_cam.x() / p_in_cam.z(), p_in_cam.y() / p_in_cam.z());
  if (k.has_distortion) xy = distort(k, xy);
  return {k.fx * xy.x() + k.cx, k.fy * xy.y() + k.cy};
}

//! Float fast path without distortion, for per-pixel kernels.
inline Eigen::Vector2f project_pinhole(const Intrinsics& k, const Eigen::Vector3f& p_in_cam) {
  return {static_cast<float>(k.fx) * p_in_cam.x() / p_in_cam.z() + static_cast<float>(k.cx),
          static_cast<float>(k.fy) * p_in_cam.y() / p_in_cam.z() + static_cast<float>(k.cy)};
}

//! Point in the camera frame at pixel (u, v) with depth z along the optical axis (undistorted
//! pinhole: depth cameras deliver undistorted depth maps).
inline Eigen::Vector3f unproject(const Intrinsics& k, float u, float v, float z) {
  return {(u - static_cast<float>(k.cx)) * z / static_cast<float>(k.fx),
          (v - static_cast<float>(k.cy)) * z / static_cast<float>(k.fy), z};
}

//! The intrinsics of every 2^level-th pixel (from pixel 0): pixel u of the subsampled image is
//! pixel u·2^level of the original, so focal lengths and principal point scale by 2^−level.
//! Distortion is dropped (depth maps are undistorted).
inline Intrinsics subsampled_intrinsics(const Intrinsics& k, int level) {
  const double scale = 1.0 / (1 << level);
  Intrinsics out = k;
  out.width = (k.width - 1) / (1 << level) + 1;
  out.height = (k.height - 1) / (1 << level) + 1;
  out.fx *= scale;
  out.fy *= scale;
  out.cx *= scale;
  out.cy *= scale;
  out.has_distortion = false;
  out.distortion = {};
  return out;
}

//! The rays of a pinhole camera's pixels, expressed in another frame (`frame_from_cam`): the point
//! at pixel (u, v) with depth z along the optical axis is origin + z·(ray0 + u·ray_du + v·ray_dv).
//! Precomputed once per camera, it turns unproject-and-transform into a few multiply-adds per
//! pixel with no division (per-pixel kernels). Undistorted pinhole, like unproject.
struct PixelRays {
  Eigen::Vector3f origin = Eigen::Vector3f::Zero();
  Eigen::Vector3f ray0 = Eigen::Vector3f::UnitZ();
  Eigen::Vector3f ray_du = Eigen::Vector3f::Zero();
  Eigen::Vector3f ray_dv = Eigen::Vector3f::Zero();

  PixelRays() = default;
  PixelRays(const Intrinsics& k, const Eigen::Isometry3f& frame_from_cam) {
    const Eigen::Matrix3f r = frame_from_cam.linear();
    const float inv_fx = static_cast<float>(1.0 / k.fx), inv_fy = static_cast<float>(1.0 / k.fy);
    origin = frame_from_cam.translation();
    ray0 = r * Eigen::Vector3f(static_cast<float>(-k.cx / k.fx), static_cast<float>(-k.cy / k.fy), 1.0f);
    ray_du = r.col(0) * inv_fx;
    ray_dv = r.col(1) * inv_fy;
  }

  //! The ray of the pixels of row v: ray(u, v) = row_ray(v) + u·ray_du.
  Eigen::Vector3f row_ray(int v) const { return ray0 + static_cast<float>(v) * ray_dv; }
  //! Pixel (u, v)'s ray: the point at depth z is origin + z·ray(u, v).
  Eigen::Vector3f ray(int u, int v) const { return row_ray(v) + static_cast<float>(u) * ray_du; }
  Eigen::Vector3f point(int u, int v, float z) const { return origin + z * ray(u, v); }
};

}  // namespace zipfusion
