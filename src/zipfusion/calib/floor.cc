#include "zipfusion/calib/floor.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include "zipfusion/core/error.h"

namespace zipfusion {
namespace {

// Fewer floor points than this is no floor: a plane through a few stray points would set the
// world's tilt. A floor seen by one camera at 640×480 every 4th pixel gives thousands.
constexpr int kFewestFloorPoints = 500;
// The depth points searched, at most (more are thinned evenly): RANSAC's cost is iterations × points.
constexpr size_t kMostPoints = 300000;
// With the cameras' centroid this close to camera 0 (one camera, or all in one place), the
// origin is put this far ahead of camera 0 instead, where it looks.
constexpr double kSameSpotM = 0.2;
constexpr double kOriginAheadM = 2.0;
// The volume starts this high above the floor, so the floor stays background (synth's choice).
constexpr double kVolumeFloorClearanceM = 0.02;
// The automatic volume's half width, as a share of the nearest camera's horizontal distance:
// samba-4cam's box is ±1 m inside a ring of 2 m, and a Kinect sees nothing nearer than ~0.5 m.
constexpr double kVolumeShareOfRing = 0.5;

struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit, pointing up
  double offset = 0;                                  // signed distance of p: normal · p + offset
  double distance(const Eigen::Vector3d& p) const { return normal.dot(p) + offset; }
};

struct DepthPoints {
  std::vector<Eigen::Vector3d> points;
  std::vector<int> camera;
};

DepthPoints gather_depth_points(const Capture& capture, const Rig& rig, const FloorOptions& options) {
  DepthPoints out;
  const int end = std::min(options.end_frame, capture.frame_count());
  for (int frame = options.first_frame; frame < end; ++frame) {
    for (int c = 0; c < capture.camera_count(); ++c) {
      const CameraFrame image = capture.load_camera_frame(frame, c);
      if (!image.has_depth) continue;
      const CameraModel& model = rig.cameras[c];
      for (int v = 0; v < image.depth.height; v += options.pixel_step) {
        for (int u = 0; u < image.depth.width; u += options.pixel_step) {
          const unsigned short raw = image.depth(u, v);
          if (raw == 0) continue;
          const double z = raw * rig.depth_unit_m;
          out.points.push_back(model.world_from_depth * unproject(model.depth_intrinsics, static_cast<float>(u), static_cast<float>(v), static_cast<float>(z)).cast<double>());
          out.camera.push_back(c);
        }
      }
    }
  }
  if (out.points.size() > kMostPoints) {
    const double stride = static_cast<double>(out.points.size()) / kMostPoints;
    DepthPoints thinned;
    for (size_t i = 0; i < kMostPoints; ++i) {
      const size_t k = static_cast<size_t>(i * stride);
      thinned.points.push_back(out.points[k]);
      thinned.camera.push_back(out.camera[k]);
    }
    out = std::move(thinned);
  }
  return out;
}

// The least-squares plane through the points within `distance` of `plane`, normal kept up.
Plane refit(const std::vector<Eigen::Vector3d>& points, const Plane& plane, double distance) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
  int count = 0;
  for (const Eigen::Vector3d& p : points) {
    if (std::abs(plane.distance(p)) >= distance) continue;
    sum += p;
    second += p * p.transpose();
    ++count;
  }
  if (count < 3) return plane;
  const Eigen::Vector3d centroid = sum / count;
  const Eigen::Matrix3d covariance = second / count - centroid * centroid.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  Eigen::Vector3d normal = solver.eigenvectors().col(0);  // smallest eigenvalue first
  if (normal.dot(plane.normal) < 0) normal = -normal;
  return {normal, -normal.dot(centroid)};
}

}  // namespace

void FloorOptions::validate() const {
  auto fail = [](const std::string& field, const std::string& problem) { throw InvalidInput(field + ": " + problem); };
  if (first_frame < 0 || end_frame <= first_frame) fail("frames", "need 0 <= first < end");
  if (pixel_step < 1 || pixel_step > 64) fail("pixel-step", "must be in [1, 64]");
  if (!(inlier_distance_m > 0.001 && inlier_distance_m < 0.5)) fail("inlier-distance", "must be in (0.001, 0.5) metres");
  if (!(max_tilt_deg > 0 && max_tilt_deg < 90)) fail("max-tilt", "must be in (0, 90) degrees");
  if (!(min_camera_height_m >= 0 && min_camera_height_m < 10)) fail("min-camera-height", "must be in [0, 10) metres");
  if (ransac_iterations < 1 || ransac_iterations > 1000000) fail("ransac-iterations", "must be in [1, 1000000]");
  if (!(volume_half_width_m == 0 || (volume_half_width_m >= 0.1 && volume_half_width_m <= 50))) {
    fail("volume-half-width", "must be 0 (automatic) or in [0.1, 50] metres");
  }
  if (!(volume_height_m >= 0.1 && volume_height_m <= 20)) fail("volume-height", "must be in [0.1, 20] metres");
}

FloorResult level_rig_to_floor(const Capture& capture, const Rig& rig, const std::string& rig_source, const FloorOptions& options) {
  options.validate();
  const std::string source = capture.dir().string();
  if (rig.cameras.size() != static_cast<size_t>(capture.camera_count())) {
    throw InvalidInput(rig_source + ": cameras: has " + std::to_string(rig.cameras.size()) + " cameras, the capture " +
                       std::to_string(capture.camera_count()));
  }
  for (int c = 0; c < capture.camera_count(); ++c) {
    const CameraModel &ours = rig.cameras[c], &captured = capture.rig().cameras[c];
    const std::string field = rig_source + ": cameras[" + std::to_string(c) + "].";
    if (ours.name != captured.name) throw InvalidInput(field + "name: \"" + ours.name + "\" is not the capture's \"" + captured.name + "\"");
    const Intrinsics &k = ours.depth_intrinsics, &captured_k = captured.depth_intrinsics;
    if (k.width != captured_k.width || k.height != captured_k.height) {
      throw InvalidInput(field + "depth_intrinsics: " + std::to_string(k.width) + "x" + std::to_string(k.height) + ", but the capture's depth is " +
                         std::to_string(captured_k.width) + "x" + std::to_string(captured_k.height));
    }
  }
  if (options.first_frame >= capture.frame_count()) {
    throw InvalidInput(source + ": frames: the capture has " + std::to_string(capture.frame_count()) + " frames");
  }

  // Up, as the cameras see it: the mean of their image-up directions (−y of the depth camera).
  Eigen::Vector3d up = Eigen::Vector3d::Zero();
  for (const CameraModel& model : rig.cameras) up += model.world_from_depth.linear() * -Eigen::Vector3d::UnitY();
  if (up.norm() < 0.1 * static_cast<double>(rig.cameras.size())) {
    throw InvalidInput(source + ": the cameras do not agree on which way is up (turned on their sides or upside down): no floor can be told from a wall");
  }
  up.normalize();

  const DepthPoints depth = gather_depth_points(capture, rig, options);
  FloorResult result;
  result.points = static_cast<int>(depth.points.size());
  if (depth.points.size() < static_cast<size_t>(kFewestFloorPoints)) {
    throw InvalidInput(source + ": too little depth in frames " + std::to_string(options.first_frame) + " to " +
                       std::to_string(std::min(options.end_frame, capture.frame_count()) - 1) + " to find the floor (" +
                       std::to_string(depth.points.size()) + " points)");
  }

  // RANSAC over planes that face up and lie below every camera.
  const double cos_max_tilt = std::cos(options.max_tilt_deg * std::numbers::pi / 180);
  std::mt19937 rng(options.seed);
  std::uniform_int_distribution<size_t> pick(0, depth.points.size() - 1);
  Plane best;
  int best_count = 0;
  for (int iteration = 0; iteration < options.ransac_iterations; ++iteration) {
    const Eigen::Vector3d& a = depth.points[pick(rng)];
    const Eigen::Vector3d& b = depth.points[pick(rng)];
    const Eigen::Vector3d& c = depth.points[pick(rng)];
    Eigen::Vector3d normal = (b - a).cross(c - a);
    if (normal.norm() < 1e-9) continue;
    normal.normalize();
    if (normal.dot(up) < 0) normal = -normal;
    if (normal.dot(up) < cos_max_tilt) continue;
    const Plane plane{normal, -normal.dot(a)};
    const bool below_cameras = std::all_of(rig.cameras.begin(), rig.cameras.end(), [&](const CameraModel& m) {
      return plane.distance(m.world_from_depth.translation()) >= options.min_camera_height_m;
    });
    if (!below_cameras) continue;
    int count = 0;
    for (const Eigen::Vector3d& p : depth.points) count += std::abs(plane.distance(p)) < options.inlier_distance_m;
    if (count > best_count) {
      best_count = count;
      best = plane;
    }
  }
  if (best_count < kFewestFloorPoints) {
    throw InvalidInput(source + ": no floor found: no plane within " + std::to_string(static_cast<int>(options.max_tilt_deg)) +
                       " degrees of level, below every camera, holds " + std::to_string(kFewestFloorPoints) + " depth points (the best: " +
                       std::to_string(best_count) + " of " + std::to_string(depth.points.size()) + "); frame the floor in some camera's view");
  }
  // Least squares on the inliers, twice (the second with the refined plane's inliers).
  Plane floor = refit(depth.points, best, options.inlier_distance_m);
  floor = refit(depth.points, floor, options.inlier_distance_m);

  // The new world: z up from the floor; the origin under the cameras' centroid; camera 0 on −y.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const CameraModel& model : rig.cameras) centroid += model.world_from_depth.translation();
  centroid /= static_cast<double>(rig.cameras.size());
  const Eigen::Vector3d& z_axis = floor.normal;
  auto horizontal = [&](const Eigen::Vector3d& v) -> Eigen::Vector3d { return v - v.dot(z_axis) * z_axis; };
  Eigen::Vector3d origin = centroid - floor.distance(centroid) * z_axis;
  const Rigid3d& camera0 = rig.cameras[0].world_from_depth;
  Eigen::Vector3d y_axis = -horizontal(camera0.translation() - origin);
  if (y_axis.norm() < kSameSpotM) {
    const Eigen::Vector3d ahead = horizontal(camera0.linear() * Eigen::Vector3d::UnitZ());
    if (ahead.norm() < 1e-6) throw InvalidInput(source + ": " + rig.cameras[0].name + " looks straight down: no direction to put the origin in");
    y_axis = ahead.normalized();
    origin += kOriginAheadM * y_axis;
  } else {
    y_axis.normalize();
  }
  const Eigen::Vector3d x_axis = y_axis.cross(z_axis);
  Eigen::Matrix3d new_from_old_rotation;
  new_from_old_rotation.row(0) = x_axis.transpose();
  new_from_old_rotation.row(1) = y_axis.transpose();
  new_from_old_rotation.row(2) = z_axis.transpose();
  Rigid3d new_from_old = Rigid3d::Identity();
  new_from_old.linear() = new_from_old_rotation;
  new_from_old.translation() = -(new_from_old_rotation * origin);

  result.rig = rig;
  result.new_from_old = new_from_old;
  for (CameraModel& model : result.rig.cameras) model.world_from_depth = new_from_old * model.world_from_depth;

  double squares = 0;
  std::vector<int> camera_floor_points(rig.cameras.size(), 0);
  for (size_t i = 0; i < depth.points.size(); ++i) {
    const double d = floor.distance(depth.points[i]);
    if (std::abs(d) >= options.inlier_distance_m) continue;
    ++result.floor_points;
    squares += d * d;
    ++camera_floor_points[depth.camera[i]];
  }
  result.floor_rms_m = result.floor_points ? std::sqrt(squares / result.floor_points) : 0;

  double nearest = std::numeric_limits<double>::infinity();
  for (size_t c = 0; c < result.rig.cameras.size(); ++c) {
    const Rigid3d& pose = result.rig.cameras[c].world_from_depth;
    const Eigen::Vector3d centre = pose.translation();
    const Eigen::Vector3d axis = pose.linear() * Eigen::Vector3d::UnitZ();
    FloorCameraReport report{.name = result.rig.cameras[c].name,
                             .height_m = centre.z(),
                             .tilt_down_deg = std::asin(std::clamp(-axis.z(), -1.0, 1.0)) * 180 / std::numbers::pi,
                             .distance_m = centre.head<2>().norm(),
                             .floor_points = camera_floor_points[c]};
    nearest = std::min(nearest, report.distance_m);
    result.cameras.push_back(report);
  }
  if (options.set_volume) {
    const double half = options.volume_half_width_m > 0 ? options.volume_half_width_m : kVolumeShareOfRing * nearest;
    if (half < 0.1) {
      throw InvalidInput(source + ": a camera stands within " + std::to_string(static_cast<int>(std::round(nearest * 100))) +
                         " cm of the origin: give the volume's size (volume-half-width)");
    }
    result.rig.volume = Box3d{{-half, -half, kVolumeFloorClearanceM}, {half, half, options.volume_height_m}};
  } else {
    result.rig.volume.reset();
  }
  return result;
}

}  // namespace zipfusion
