#pragma once
//! \file
//! Global registration of all cameras at once (paper Section III-A): GPA-ICP. Correspondences are
//! mutual closest points (nanoflann k-d trees) between every two cameras' clouds of the same
//! frame, within a distance that shrinks over the iterations; one joint solve then moves every
//! camera (the first camera with usable depth fixed as the gauge) so that corresponding points meet. Generalised Procrustes
//! Analysis minimises each correspondence tuple's squared distances to its centroid, which for
//! pairs is half their squared distance; here that objective is measured along the surface normal
//! (symmetric point-to-plane: the two points' mean normal) and solved jointly by one Gauss-Newton
//! step per iteration, so errors are spread over the ring rather than chained.
//!
//! Against the Kinect's noise (docs/design.md, "Registration"): each sample's point and normal come
//! from a quadratic fit of inverse depth (disparity) in a small window, each correspondence is
//! weighted by the sensor's axial noise σ(z) along the normal, pairs seen at grazing angles (biased)
//! are dropped, the worst residuals of each pair are trimmed, the floor just below the capture
//! volume joins in (static, it fixes the tilt; counted once over the frames), and several frames
//! (where the subject has moved) add their correspondences to the same solve.
//! Coarse to fine: depth sampled every 2^L·f/580 pixels (2^L for a Kinect v1 at 640×480, so the
//! levels are angles, whatever the resolution), at most `iterations_per_level` per level (paper: 4).
//!
//! Thread safety: the functions are pure; parallel inside (`num_threads`).

#include <atomic>
#include <vector>

#include "zipfusion/core/geometry.h"
#include "zipfusion/core/image.h"
#include "zipfusion/depth/bilateral.h"
#include "zipfusion/depth/foreground.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/rig.h"

namespace zipfusion {

//! How points and normals are taken from noisy depth (docs/design.md, "Registration").
enum class RegistrationSurface {
  kDisparityFit,  // quadratic fit of inverse depth in a window: planes exact, curvature unbiased
  kBilateral,     // the paper's bilateral filter, normals by central differences (biased on oblique curved surfaces)
  kRaw,           // raw depth, normals by central differences
};

struct RegistrationOptions {
  int coarsest_level = 3;          // L: the first level samples every 2^L·f/580 pixels (paper: coarse to fine); 80×60 of a 640×480 Kinect converges from 2°/5 cm
  int finest_level = 1;            // the last level; 0 = full resolution (no more accurate at 640×480, 4× slower)
  int iterations_per_level = 4;    // paper: at most 4
  double start_distance_m = 0.15;  // metres: correspondence distance at the first iteration (covers ~2°/5 cm)
  double end_distance_m = 0.015;   // metres: at the last iteration (geometric shrink in between)
  double max_normal_angle_deg = 45;  // degrees: corresponding points' normals must agree this well
  double max_view_angle_deg = 75;    // degrees: points seen more obliquely (noisy, silhouettes) are not used
  double max_pair_view_angle_deg = 68;  // degrees, point-to-plane: a correspondence whose mean normal either camera sees more obliquely is dropped (biased: the more oblique surface lies farther)
  double min_noise_cos = 0.4;      // σ along the normal is σ(z)·max(|cos θ|, this): grazing pairs would otherwise weigh the most
  int normal_step_px = 4;          // pixels (full resolution), kBilateral and kRaw: normals from neighbours this far apart, at least the stride
  double trim_fraction = 0.03;     // share of each pair's correspondences in a frame with the largest |residual|/σ dropped
  bool point_to_plane = true;      // false: point-to-point (the plain GPA of the paper)
  bool noise_weights = true;       // weight by 1/σ² from the Kinect v1 axial noise σ(z) (Nguyen et al. 2012)
  RegistrationSurface surface = RegistrationSurface::kDisparityFit;
  int fit_radius_px = 3;           // pixels (full resolution): half-width of the disparity fit at the finest level (coarser: at least the stride)
  double fit_gate_m = 0.05;        // metres: window pixels farther in depth from the centre belong to another surface
  BilateralOptions filter;         // kBilateral only: paper's values
  ForegroundOptions foreground{.floor_noise_sigmas = 0};  // the floor is wanted here (below_volume_m), its noise too
  double below_volume_m = 0.3;     // metres: the volume crop reaches this far below the volume, so the floor (static, seen by all) pins the cameras' tilt
  bool floor_counts_once = true;   // the floor's correspondences (both points below the volume's min z, world z up; none without a volume) weigh 1/F over F frames: it is the same in every frame set
  int min_correspondences = 50;    // a pair with fewer over all its frames (before trimming; the floor's count 1/F) does not count
  double converged_rad = 1e-5;     // a level ends when no camera moves more than this (radians and metres)
  bool measure_fixed = true;       // RegistrationResult::least_fixed_m (one more matching pass over the finest level); false: all 0
  int num_threads = 0;             // 0 = all hardware threads
  //! When it turns true (Ctrl-C), the refinement ends at the next step with the poses as given,
  //! no camera joined to the gauge (RegistrationResult::cancelled). May be null; must outlive the call.
  const std::atomic<bool>* cancel = nullptr;

  void validate() const;  // throws InvalidInput naming `zipfusion register`'s option (--trim) or, where it has none, the field
};

struct RegistrationResult {
  int gauge = 0;                           // the camera whose pose is held: the first with depth (has_depth)
  std::vector<char> has_depth;             // per camera: usable depth (samples at the finest level) in some frame
  std::vector<Rigid3d> world_from_depth;   // refined poses; the gauge's unchanged
  std::vector<double> rmse_before_m;       // per camera: point-to-plane RMS of its correspondences at the input poses (0 where none)
  std::vector<int> correspondences_before; // per camera, at the input poses
  std::vector<double> rmse_after_m;        // the same at the refined poses (finest level, end distance)
  std::vector<int> correspondences_after;  // per camera, at the refined poses
  // Per camera: tied to the gauge through pairs that share correspondences at the refined poses
  // (directly or through other cameras). A camera that is not was registered to nothing that
  // places it against the gauge (two groups that overlap only among themselves are not one rig):
  // it keeps its starting pose.
  std::vector<char> joined_to_gauge;
  // Per camera: how far its pose could slide along the direction its final correspondences fix
  // least, the formal standard deviation there (metres; a turn about its own centre counts times
  // a 2 m lever arm), from the normal equations at the refined poses with every other camera free
  // but the gauge, scaled by the residuals' mean (r/σ)² (quieter depth than the noise model fixes
  // them better). A camera tied only by the floor (little fixes its slide along it) has about a
  // hundred times the figure of one the person holds too (gpa_icp_test). 0 for the gauge, and
  // for all with measure_fixed false.
  std::vector<double> least_fixed_m;
  int iterations = 0;                      // Gauss-Newton steps taken over all levels
  bool converged = false;                  // the finest level's last step moved less than converged_rad
  bool cancelled = false;                  // RegistrationOptions::cancel ended it: the poses are as given
};

//! Foreground depth in metres (bilateral-filtered with kBilateral) of every camera of one
//! frame set; a camera without depth gets an empty image. Uses the rig's poses for the volume crop.
std::vector<Image<float>> registration_depth(const Rig& rig, const FrameSet& frames, const RegistrationOptions& options);

//! Refines the poses of all cameras from depth_m[frame][camera] (metres, 0 = none; empty image =
//! camera absent from that frame) starting at `rig`'s poses. Precondition: every frame has
//! rig.cameras.size() images; options valid. Cameras not joined to the gauge keep their pose.
RegistrationResult register_rig(const Rig& rig, const std::vector<std::vector<Image<float>>>& depth_m, const RegistrationOptions& options);

//! Error of one camera's pose relative to camera `reference`, against the truth: the camera's
//! centre and rotation as seen from the reference camera.
struct RelativePoseError {
  double translation_m = 0;
  double rotation_deg = 0;
};
std::vector<RelativePoseError> relative_pose_errors(const std::vector<Rigid3d>& world_from_depth, const std::vector<Rigid3d>& true_world_from_depth,
                                                    int reference = 0);

//! The largest translation and the largest rotation error of relative_pose_errors (each over all
//! cameras, so possibly of different cameras).
RelativePoseError worst_relative_pose_error(const std::vector<Rigid3d>& world_from_depth, const std::vector<Rigid3d>& true_world_from_depth);

//! Element function: sample `index` of a depth map subsampled by `stride` (grid width
//! ceil(width/stride)). Writes the point and its unit normal (towards the camera) in the camera
//! frame and returns true when the depth there and at the four neighbours `step` pixels away is
//! valid, the neighbours lie on the same surface (depth within max_jump_m) and the surface is seen
//! at most max_view_angle from its normal (cos_max_view is its cosine).
inline bool surface_sample(int index, const float* depth, int width, int height, int stride, int step, const Intrinsics& k,
                           float max_jump_m, float cos_max_view, Eigen::Vector3f* point, Eigen::Vector3f* normal) {
  const int grid_width = (width + stride - 1) / stride;
  const int u = (index % grid_width) * stride, v = (index / grid_width) * stride;
  if (u - step < 0 || v - step < 0 || u + step >= width || v + step >= height) return false;
  const float z = depth[v * width + u];
  if (z <= 0.0f) return false;
  const float zl = depth[v * width + u - step], zr = depth[v * width + u + step];
  const float zu = depth[(v - step) * width + u], zd = depth[(v + step) * width + u];
  if (zl <= 0.0f || zr <= 0.0f || zu <= 0.0f || zd <= 0.0f) return false;
  const auto far = [&](float a) { return a > z + max_jump_m || a < z - max_jump_m; };
  if (far(zl) || far(zr) || far(zu) || far(zd)) return false;
  const auto fu = static_cast<float>(u), fv = static_cast<float>(v), fs = static_cast<float>(step);
  const Eigen::Vector3f dx = unproject(k, fu + fs, fv, zr) - unproject(k, fu - fs, fv, zl);
  const Eigen::Vector3f dy = unproject(k, fu, fv + fs, zd) - unproject(k, fu, fv - fs, zu);
  Eigen::Vector3f n = dx.cross(dy);
  const float length = n.norm();
  if (!(length > 0.0f)) return false;
  n /= length;
  const Eigen::Vector3f p = unproject(k, fu, fv, z);
  float facing = -n.dot(p) / p.norm();
  if (facing < 0.0f) {
    n = -n;
    facing = -facing;
  }
  if (facing < cos_max_view) return false;
  *point = p;
  *normal = n;
  return true;
}

//! Element function: sample `index` of a depth map subsampled by `stride`, from a least-squares
//! fit of inverse depth w = 1/z as a quadratic in (du, dv) over the window of half-width `radius`
//! (pixels within gate_m of the centre's depth). Inverse depth is linear in the pixel coordinates
//! on a plane and is what the Kinect measures (disparity), so the fit neither flattens curved
//! surfaces seen obliquely (a depth average does) nor weights near and far ends of the window
//! differently. Returns false when under 60 % of the window is usable or the fit is degenerate;
//! otherwise writes the fitted point at the pixel and its unit normal (towards the camera).
inline bool disparity_fit_sample(int index, const float* depth, int width, int height, int stride, int radius, float gate_m, const Intrinsics& k,
                                 float cos_max_view, Eigen::Vector3f* point, Eigen::Vector3f* normal) {
  const int grid_width = (width + stride - 1) / stride;
  const int u = (index % grid_width) * stride, v = (index / grid_width) * stride;
  if (u - radius < 0 || v - radius < 0 || u + radius >= width || v + radius >= height) return false;
  const float zc = depth[v * width + u];
  if (zc <= 0.0f) return false;
  // Moments Σ x^i y^j (i + j ≤ 4) of the used pixels and Σ basis·w: the normal equations of the
  // fit of w = c0 + c1 x + c2 y + c3 x² + c4 xy + c5 y², x and y in units of the radius.
  float m00 = 0, m10 = 0, m01 = 0, m20 = 0, m11 = 0, m02 = 0, m30 = 0, m21 = 0, m12 = 0, m03 = 0, m40 = 0, m31 = 0, m22 = 0, m13 = 0, m04 = 0;
  float b0 = 0, b1 = 0, b2 = 0, b3 = 0, b4 = 0, b5 = 0;
  const float scale = 1.0f / static_cast<float>(radius);
  for (int dv = -radius; dv <= radius; ++dv) {
    const float* row = depth + (v + dv) * width + u;
    const float y = static_cast<float>(dv) * scale, y2 = y * y;
    for (int du = -radius; du <= radius; ++du) {
      const float z = row[du];
      if (z <= 0.0f || z > zc + gate_m || z < zc - gate_m) continue;
      const float x = static_cast<float>(du) * scale, x2 = x * x, w = 1.0f / z;
      m00 += 1; m10 += x; m01 += y; m20 += x2; m11 += x * y; m02 += y2;
      m30 += x2 * x; m21 += x2 * y; m12 += x * y2; m03 += y2 * y;
      m40 += x2 * x2; m31 += x2 * x * y; m22 += x2 * y2; m13 += x * y2 * y; m04 += y2 * y2;
      b0 += w; b1 += w * x; b2 += w * y; b3 += w * x2; b4 += w * x * y; b5 += w * y2;
    }
  }
  const int side = 2 * radius + 1;
  if (m00 * 10 < static_cast<float>(side * side * 6)) return false;
  Eigen::Matrix<double, 6, 6> ata;
  ata << m00, m10, m01, m20, m11, m02,
         m10, m20, m11, m30, m21, m12,
         m01, m11, m02, m21, m12, m03,
         m20, m30, m21, m40, m31, m22,
         m11, m21, m12, m31, m22, m13,
         m02, m12, m03, m22, m13, m04;
  const Eigen::Matrix<double, 6, 1> atb(b0, b1, b2, b3, b4, b5);
  const Eigen::Matrix<double, 6, 1> c = ata.ldlt().solve(atb);
  const double w = c[0], wu = c[1] * scale, wv = c[2] * scale;  // inverse depth and its derivatives per pixel
  if (!(w > 0) || !std::isfinite(w)) return false;
  // P(u, v) = ray(u, v) / w with ray = ((u − cx)/fx, (v − cy)/fy, 1); tangents by the product rule.
  const Eigen::Vector3d ray((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
  const Eigen::Vector3d tu = Eigen::Vector3d(1.0 / k.fx, 0, 0) / w - ray * (wu / (w * w));
  const Eigen::Vector3d tv = Eigen::Vector3d(0, 1.0 / k.fy, 0) / w - ray * (wv / (w * w));
  Eigen::Vector3d n = tu.cross(tv);
  const double length = n.norm();
  if (!(length > 0)) return false;
  n /= length;
  double facing = -n.dot(ray) / ray.norm();
  if (facing < 0) {
    n = -n;
    facing = -facing;
  }
  if (facing < cos_max_view) return false;
  *point = (ray / w).cast<float>();
  *normal = n.cast<float>();
  return true;
}

}  // namespace zipfusion
