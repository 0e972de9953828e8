#include "zipfusion/calib/floor.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>

#include "zipfusion/core/error.h"

namespace zipfusion {
namespace {

// Fewer floor points than this is no floor: a plane through a few stray points would set the
// world's tilt. A floor seen by one camera at 640×480 every 4th pixel gives thousands.
constexpr int kFewestFloorPoints = 500;
// The depth points searched, at most (more are thinned evenly): RANSAC's cost is iterations ×
// points. Gathered, at most four times as many (the pixel step grows with the frames asked).
constexpr size_t kMostPoints = 300000;
// A level plane below the best one with at least this share of its points is preferred: the
// floor under a table top that fills the view.
constexpr double kLowerPlaneShare = 0.2;
constexpr double kParallelDeg = 10;
// ... and lies this far below it at least (a table top stands 0.4 m and more above the floor;
// a Kinect's depth noise is a few centimetres), in at most this many steps.
constexpr double kLowerPlaneStepM = 0.3;
constexpr int kMostStepsDown = 3;
// The second least-squares fit keeps the points within this many RMS of the first, and within
// at least this distance.
constexpr double kRefitRmsFactor = 2.5;
constexpr double kClosestRefitM = 0.005;
// Where the cameras look: the optical axes, laid flat on the floor, meet in a point when they
// spread over more than about 37° (two axes: 1 − cos 37° = 0.2 per axis); an axis flatter than
// this (a camera looking nearly straight down) counts as the point below the camera.
constexpr double kSpreadPerAxis = 0.1;
constexpr double kSteepAxis = 0.2;  // horizontal length of the unit optical axis
// Otherwise (one camera, or cameras looking the same way) the origin goes this far ahead of
// the cameras, where a subject stands.
constexpr double kOriginAheadM = 2.0;
// The automatic volume's half width, as a share of the nearest camera's horizontal distance:
// samba-4cam's box is ±1 m inside a ring of 2 m, and a Kinect sees nothing nearer than ~0.5 m.
constexpr double kVolumeShareOfRing = 0.5;

struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit
  double offset = 0;                                  // signed distance of p: normal · p + offset
  double distance(const Eigen::Vector3d& p) const { return normal.dot(p) + offset; }
  void flip() {
    normal = -normal;
    offset = -offset;
  }
};

struct DepthPoints {
  std::vector<Eigen::Vector3d> points;
  std::vector<int> camera;
  std::vector<std::string> unreadable;
  long long beyond_range = 0;  // sampled depth farther than max_depth_m, not used
};

DepthPoints gather_depth_points(const Capture& capture, const FloorOptions& options) {
  const Rig& rig = capture.rig();
  DepthPoints out;
  const int end = std::min(options.end_frame, capture.frame_count());
  // The frames' pixels, at most 4·kMostPoints of them: the step grows with the frames.
  double pixels = 0;
  for (const CameraModel& model : rig.cameras) pixels += static_cast<double>(model.depth_intrinsics.width) * model.depth_intrinsics.height;
  pixels *= end - options.first_frame;
  int step = options.pixel_step;
  while (pixels / (static_cast<double>(step) * step) > 4.0 * kMostPoints) ++step;
  for (int frame = options.first_frame; frame < end; ++frame) {
    for (int c = 0; c < capture.camera_count(); ++c) {
      const CameraFrame image = capture.load_camera_frame(frame, c);
      out.unreadable.insert(out.unreadable.end(), image.unreadable.begin(), image.unreadable.end());
      if (!image.has_depth) continue;
      const CameraModel& model = rig.cameras[c];
      for (int v = 0; v < image.depth.height; v += step) {
        for (int u = 0; u < image.depth.width; u += step) {
          const unsigned short raw = image.depth(u, v);
          if (raw == 0) continue;
          const auto z = static_cast<float>(raw * rig.depth_unit_m);
          if (z > options.max_depth_m) {
            ++out.beyond_range;
            continue;
          }
          out.points.push_back(model.world_from_depth * unproject(model.depth_intrinsics, static_cast<float>(u), static_cast<float>(v), z).cast<double>());
          out.camera.push_back(c);
        }
      }
    }
  }
  if (out.points.size() > kMostPoints) {
    const double stride = static_cast<double>(out.points.size()) / kMostPoints;
    for (size_t i = 0; i < kMostPoints; ++i) {
      const auto k = static_cast<size_t>(i * stride);
      out.points[i] = out.points[k];
      out.camera[i] = out.camera[k];
    }
    out.points.resize(kMostPoints);
    out.camera.resize(kMostPoints);
  }
  return out;
}

// The least-squares plane through the points within `distance` of `plane`, facing as it does.
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

// Why `plane` cannot be the floor, or empty when it can; a plane that can is turned to face the
// cameras (its normal is then up). Every camera must stand on one side of it, at least
// min_camera_height_m away, and its normal lie within max_tilt_deg of the cameras' up axis.
std::string floor_problem(Plane& plane, const Rig& rig, const Eigen::Vector3d& up_axis, const FloorOptions& options) {
  double sum = 0;
  for (const CameraModel& model : rig.cameras) sum += plane.distance(model.world_from_depth.translation());
  if (sum < 0) plane.flip();
  double lowest = std::numeric_limits<double>::infinity();
  size_t lowest_camera = 0;
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    const double d = plane.distance(rig.cameras[c].world_from_depth.translation());
    if (d < lowest) lowest = d, lowest_camera = c;
  }
  char text[200];
  if (lowest < 0) {
    std::snprintf(text, sizeof text, "the cameras stand on both sides of it (%s %.2f m below)", rig.cameras[lowest_camera].name.c_str(), -lowest);
    return text;
  }
  if (lowest < options.min_camera_height_m) {
    std::snprintf(text, sizeof text, "%s is only %.2f m above it (every camera must stand at least %.2f m above the floor)",
                  rig.cameras[lowest_camera].name.c_str(), lowest, options.min_camera_height_m);
    return text;
  }
  const double tilt_deg = std::acos(std::clamp(plane.normal.dot(up_axis), -1.0, 1.0)) * 180 / std::numbers::pi;
  if (tilt_deg > options.max_tilt_deg) {
    std::snprintf(text, sizeof text, "its up side is %.0f degrees from the cameras' up direction (at most %.0f: a wall, a ceiling, or cameras on their sides?)",
                  tilt_deg, options.max_tilt_deg);
    return text;
  }
  return {};
}

struct PlaneCount {
  Plane plane;
  int count = 0;
};

// RANSAC over the points of `indices`: the plane with most points within the inlier distance
// among those `accept` takes (it may turn them).
template <typename Accept>
PlaneCount find_plane(const std::vector<Eigen::Vector3d>& points, const std::vector<int>& indices, const FloorOptions& options,
                      std::mt19937& rng, Accept&& accept) {
  PlaneCount best;
  if (indices.size() < 3) return best;
  std::uniform_int_distribution<size_t> pick(0, indices.size() - 1);
  for (int iteration = 0; iteration < options.ransac_iterations; ++iteration) {
    const Eigen::Vector3d& a = points[indices[pick(rng)]];
    const Eigen::Vector3d& b = points[indices[pick(rng)]];
    const Eigen::Vector3d& c = points[indices[pick(rng)]];
    const Eigen::Vector3d normal = (b - a).cross(c - a);
    if (normal.norm() < 1e-9) continue;
    Plane plane{normal.normalized(), 0};
    plane.offset = -plane.normal.dot(a);
    if (!accept(plane)) continue;
    int count = 0;
    for (int i : indices) count += std::abs(plane.distance(points[i])) < options.inlier_distance_m;
    if (count > best.count) best = {plane, count};
  }
  return best;
}

// Where the cameras look, on the floor: the point nearest to all optical axes laid flat (in the
// floor's coordinates e1, e2), or, where they do not meet, kOriginAheadM ahead of the cameras.
Eigen::Vector3d looked_at_on_floor(const Rig& rig, const Plane& floor) {
  const Eigen::Vector3d& z = floor.normal;
  const Eigen::Vector3d e1 = z.unitOrthogonal(), e2 = z.cross(e1);
  auto flat = [&](const Eigen::Vector3d& v) { return Eigen::Vector2d(e1.dot(v), e2.dot(v)); };
  Eigen::Matrix2d normal_matrix = Eigen::Matrix2d::Zero();
  Eigen::Vector2d rhs = Eigen::Vector2d::Zero(), centroid = Eigen::Vector2d::Zero(), ahead = Eigen::Vector2d::Zero();
  for (const CameraModel& model : rig.cameras) {
    const Eigen::Vector2d centre = flat(model.world_from_depth.translation());
    const Eigen::Vector2d axis = flat(model.world_from_depth.linear() * Eigen::Vector3d::UnitZ());
    centroid += centre;
    // A camera looking nearly straight down looks at the floor below it: a point, not a line.
    const Eigen::Matrix2d weight = axis.norm() < kSteepAxis ? Eigen::Matrix2d::Identity()
                                                            : Eigen::Matrix2d(Eigen::Matrix2d::Identity() - axis.normalized() * axis.normalized().transpose());
    normal_matrix += weight;
    rhs += weight * centre;
    if (axis.norm() >= kSteepAxis) ahead += axis.normalized();
  }
  const double cameras = static_cast<double>(rig.cameras.size());
  centroid /= cameras;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(normal_matrix);
  Eigen::Vector2d point;
  if (solver.eigenvalues()(0) >= kSpreadPerAxis * cameras) {
    point = normal_matrix.ldlt().solve(rhs);
  } else {
    // Cameras facing each other along one line look at the middle between them.
    point = centroid + (ahead.norm() > 0.5 * cameras ? Eigen::Vector2d(kOriginAheadM * ahead.normalized()) : Eigen::Vector2d::Zero());
  }
  // On the floor: the plane's point nearest the origin, moved within it.
  return -floor.offset * z + point.x() * e1 + point.y() * e2;
}

}  // namespace

void FloorOptions::validate() const {
  auto fail = [](const std::string& field, const std::string& problem) { throw InvalidInput(field + ": " + problem); };
  if (first_frame < 0 || end_frame <= first_frame) fail("--frames", "need 0 <= first < end");
  if (pixel_step < 1 || pixel_step > 64) fail("pixel_step", "must be in [1, 64]");
  if (!(inlier_distance_m > 0.001 && inlier_distance_m < 0.5)) fail("--inlier-distance", "must be in (0.001, 0.5) metres");
  if (!(max_tilt_deg > 0 && max_tilt_deg < 90)) fail("max_tilt_deg", "must be in (0, 90) degrees");
  if (!(min_camera_height_m >= 0 && min_camera_height_m < 10)) fail("min_camera_height_m", "must be in [0, 10) metres");
  if (!(max_depth_m > 0.5 && max_depth_m <= 100)) fail("max_depth_m", "must be in (0.5, 100] metres");
  if (ransac_iterations < 1 || ransac_iterations > 1000000) fail("ransac_iterations", "must be in [1, 1000000]");
  if (!(volume_half_width_m == 0 || (volume_half_width_m >= 0.1 && volume_half_width_m <= 50))) {
    fail("--volume-half-width", "must be 0 (automatic) or in [0.1, 50] metres");
  }
  if (!(volume_height_m >= 0.1 && volume_height_m <= 20)) fail("--volume-height", "must be in [0.1, 20] metres");
}

FloorResult level_rig_to_floor(const Capture& capture, const FloorOptions& options) {
  options.validate();
  const std::string source = capture.dir().string();
  const Rig& rig = capture.rig();
  if (options.first_frame >= capture.frame_count()) {
    throw InvalidInput(source + ": frames: the capture has " + std::to_string(capture.frame_count()) + " frames");
  }

  // Up, as the cameras see it: the principal direction of their image-up directions (−y of each
  // depth camera), where tilts down around a ring cancel, turned the way most cameras' up points:
  // a camera mounted upside down among upright ones agrees, and a ceiling (which faces the
  // cameras too) or a wall in front of a camera tilted down is not taken for the floor.
  Eigen::Matrix3d up_scatter = Eigen::Matrix3d::Zero();
  std::vector<Eigen::Vector3d> camera_ups;
  for (const CameraModel& model : rig.cameras) {
    camera_ups.push_back(model.world_from_depth.linear() * -Eigen::Vector3d::UnitY());
    up_scatter += camera_ups.back() * camera_ups.back().transpose();
  }
  Eigen::Vector3d up_axis = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(up_scatter).eigenvectors().col(2);  // largest
  int agreeing = 0;
  for (const Eigen::Vector3d& up : camera_ups) agreeing += up.dot(up_axis) > 0 ? 1 : -1;
  if (agreeing == 0) {
    throw InvalidInput(source + ": as many cameras are mounted upside down as upright: which way is up is not known");
  }
  if (agreeing < 0) up_axis = -up_axis;

  const DepthPoints depth = gather_depth_points(capture, options);
  FloorResult result;
  result.unreadable = depth.unreadable;
  result.points = static_cast<int>(depth.points.size());
  const int last_frame = std::min(options.end_frame, capture.frame_count()) - 1;
  if (depth.points.size() < static_cast<size_t>(kFewestFloorPoints)) {
    char farthest[32];
    std::snprintf(farthest, sizeof farthest, "%g m", options.max_depth_m);
    throw InvalidInput(source + ": too little depth in frames " + std::to_string(options.first_frame) + " to " + std::to_string(last_frame) +
                       " to find the floor (" + std::to_string(depth.points.size()) + " points" +
                       (depth.beyond_range > 0 ? "; " + std::to_string(depth.beyond_range) + " farther than " + std::string(farthest) + " left out" : "") + ")");
  }

  // RANSAC over the planes that can be the floor; then, below the best, a level plane with a
  // fair share of its points is preferred (the floor under a table top), as long as there is one.
  std::mt19937 rng(options.seed);
  auto can_be_floor = [&](Plane& plane) { return floor_problem(plane, rig, up_axis, options).empty(); };
  std::vector<int> all(depth.points.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  PlaneCount best = find_plane(depth.points, all, options, rng, can_be_floor);
  if (best.count < kFewestFloorPoints) {
    // Say why the largest plane in view is not the floor.
    PlaneCount largest = find_plane(depth.points, all, options, rng, [](Plane&) { return true; });
    const std::string why = largest.count >= kFewestFloorPoints ? floor_problem(largest.plane, rig, up_axis, options) : "";
    throw InvalidInput(source + ": no floor found in frames " + std::to_string(options.first_frame) + " to " + std::to_string(last_frame) +
                       (why.empty() ? ": no plane holds " + std::to_string(kFewestFloorPoints) + " depth points"
                                    : ": the largest plane (" + std::to_string(largest.count) + " of " + std::to_string(depth.points.size()) +
                                          " depth points) is not the floor: " + why) +
                       "; frame the floor in some camera's view");
  }
  // Each step down searches only the points below the last pick, a whole step lower: the steps
  // end, and depth noise under the floor is no lower floor.
  const double cos_parallel = std::cos(kParallelDeg * std::numbers::pi / 180);
  const Plane largest_plane = best.plane;
  bool stepped_down = false;
  std::vector<int> candidates = all;
  for (int step = 0; options.prefer_lower_plane && step < kMostStepsDown; ++step) {
    std::vector<int> below;
    for (int i : candidates) {
      if (best.plane.distance(depth.points[i]) < -kLowerPlaneStepM) below.push_back(i);
    }
    const PlaneCount lower = find_plane(depth.points, below, options, rng, [&](Plane& plane) {
      return can_be_floor(plane) && plane.normal.dot(best.plane.normal) >= cos_parallel;
    });
    if (lower.count < std::max<double>(kFewestFloorPoints, kLowerPlaneShare * best.count)) break;
    best = lower;
    stepped_down = true;
    candidates = std::move(below);
  }
  // Least squares on the inliers, twice (the second with the refined plane's inliers); the fit
  // must still be a floor.
  Plane floor = refit(depth.points, best.plane, options.inlier_distance_m);
  // The second fit takes the points within 2.5 times the first fit's RMS (not less than 5 mm): where
  // a wall meets the floor, the wall's foot within the inlier distance would tilt the fit.
  double first_squares = 0;
  int near = 0;
  for (const Eigen::Vector3d& p : depth.points) {
    const double d = floor.distance(p);
    if (std::abs(d) < options.inlier_distance_m) first_squares += d * d, ++near;
  }
  const double rms = near ? std::sqrt(first_squares / near) : options.inlier_distance_m;
  floor = refit(depth.points, floor, std::clamp(kRefitRmsFactor * rms, kClosestRefitM, options.inlier_distance_m));
  if (const std::string why = floor_problem(floor, rig, up_axis, options); !why.empty()) {
    throw InvalidInput(source + ": the floor's least-squares fit is not a floor: " + why + "; try a smaller --inlier-distance");
  }

  // The new world: z up from the floor, the origin where the cameras look, camera 0 on −y.
  const Eigen::Vector3d& z_axis = floor.normal;
  auto horizontal = [&](const Eigen::Vector3d& v) -> Eigen::Vector3d { return v - v.dot(z_axis) * z_axis; };
  const Eigen::Vector3d origin = looked_at_on_floor(rig, floor);
  const Rigid3d& camera0 = rig.cameras[0].world_from_depth;
  Eigen::Vector3d y_axis = -horizontal(camera0.translation() - origin);
  if (y_axis.norm() < 0.01) y_axis = horizontal(camera0.linear() * Eigen::Vector3d::UnitZ());  // camera 0 right above it
  if (y_axis.norm() < 1e-6) y_axis = z_axis.unitOrthogonal();  // and looking straight down
  y_axis.normalize();
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
  // Both planes fitted alike (least squares), measured where the origin lies on the floor.
  if (stepped_down) result.largest_plane_above_m = -refit(depth.points, largest_plane, options.inlier_distance_m).distance(origin);

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
