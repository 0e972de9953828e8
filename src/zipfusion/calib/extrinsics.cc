#include "zipfusion/calib/extrinsics.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "zipfusion/core/calibration_targets.h"
#include "zipfusion/core/error.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/io/image_io.h"

namespace zipfusion {
namespace {

// Undistorted pixel: the detection as an ideal pinhole camera with the same K would have seen it.
Eigen::Vector2d undistort_pixel(const Intrinsics& k, const Eigen::Vector2d& pixel) {
  if (!k.has_distortion) return pixel;
  const cv::Matx33d K(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
  std::vector<cv::Point2d> in{{pixel.x(), pixel.y()}}, out;
  cv::undistortPoints(in, out, K, std::vector<double>(k.distortion.begin(), k.distortion.end()), cv::noArray(), K);
  return {out[0].x, out[0].y};
}

Eigen::Vector2d normalized(const Intrinsics& k, const Eigen::Vector2d& pixel) {
  return {(pixel.x() - k.cx) / k.fx, (pixel.y() - k.cy) / k.fy};
}

// One LED point (frame, led 0 red / 1 green) and the cameras that saw it.
struct Observation {
  int camera;
  Eigen::Vector2d pixel;  // undistorted
};

// Linear multi-view triangulation (DLT) in normalised coordinates; false when a camera would see
// the point behind it.
bool triangulate(const std::vector<Rigid3d>& cam_from_ref, const std::vector<Intrinsics>& k, const std::vector<Observation>& obs,
                 Eigen::Vector3d& point) {
  Eigen::MatrixXd a(2 * obs.size(), 4);
  for (size_t i = 0; i < obs.size(); ++i) {
    const Eigen::Matrix<double, 3, 4> p = cam_from_ref[obs[i].camera].matrix().topRows<3>();
    const Eigen::Vector2d x = normalized(k[obs[i].camera], obs[i].pixel);
    a.row(2 * i) = x.x() * p.row(2) - p.row(0);
    a.row(2 * i + 1) = x.y() * p.row(2) - p.row(1);
  }
  const Eigen::Vector4d h = Eigen::JacobiSVD<Eigen::MatrixXd>(a, Eigen::ComputeFullV).matrixV().col(3);
  if (std::abs(h.w()) < 1e-12) return false;
  point = h.head<3>() / h.w();
  for (const Observation& o : obs) {
    if ((cam_from_ref[o.camera] * point).z() <= 0) return false;
  }
  return true;
}

// Pose parameters as Ceres sees them: angle-axis (3) then translation (3) of cam_from_ref.
std::array<double, 6> to_params(const Rigid3d& cam_from_ref) {
  const Eigen::AngleAxisd aa(cam_from_ref.linear());
  const Eigen::Vector3d w = aa.angle() * aa.axis();
  return {w.x(), w.y(), w.z(), cam_from_ref.translation().x(), cam_from_ref.translation().y(), cam_from_ref.translation().z()};
}

Rigid3d from_params(const std::array<double, 6>& p) {
  const Eigen::Vector3d w(p[0], p[1], p[2]);
  Rigid3d t = Rigid3d::Identity();
  if (w.norm() > 0) t.linear() = Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
  t.translation() = Eigen::Vector3d(p[3], p[4], p[5]);
  return t;
}

struct ReprojectionResidual {
  Eigen::Vector2d pixel;
  Intrinsics k;
  template <typename T>
  bool operator()(const T* pose, const T* point, T* residual) const {
    T p[3];
    ceres::AngleAxisRotatePoint(pose, point, p);
    p[0] += pose[3];
    p[1] += pose[4];
    p[2] += pose[5];
    residual[0] = T(k.fx) * p[0] / p[2] + T(k.cx) - T(pixel.x());
    residual[1] = T(k.fy) * p[1] / p[2] + T(k.cy) - T(pixel.y());
    return true;
  }
};

// (|red − green| − D) / σ: the only thing that fixes the scale once camera 0 fixes the gauge.
struct LedDistanceResidual {
  double distance, sigma;
  template <typename T>
  bool operator()(const T* red, const T* green, T* residual) const {
    const T dx = red[0] - green[0], dy = red[1] - green[1], dz = red[2] - green[2];
    residual[0] = (ceres::sqrt(dx * dx + dy * dy + dz * dz) - T(distance)) / T(sigma);
    return true;
  }
};

double reprojection_error(const Rigid3d& cam_from_ref, const Intrinsics& k, const Eigen::Vector3d& point, const Eigen::Vector2d& pixel) {
  const Eigen::Vector3d p = cam_from_ref * point;
  return (Eigen::Vector2d(k.fx * p.x() / p.z() + k.cx, k.fy * p.y() / p.z() + k.cy) - pixel).norm();
}

// One camera has no pose to find relative to another (Ceres aborted on the empty problem).
void require_two_cameras(const Rig& rig, const std::string& rig_file) {
  if (rig.cameras.size() < 2) {
    throw InvalidInput(rig_file + ": cameras: extrinsic calibration needs at least 2 cameras, the rig has " + std::to_string(rig.cameras.size()));
  }
}

}  // namespace

void ExtrinsicOptions::validate() const {
  auto fail = [](const std::string& field, const std::string& problem) { throw InvalidInput(field + ": " + problem); };
  if (!(led_distance_m > kShortestWandM && led_distance_m < kLongestWandM)) {
    fail("--led-distance", wand_distance_rule());
  }
  if (min_common_frames < 8) fail("--min-common-frames", "must be >= 8 (the 8-point algorithm needs 8 correspondences)");
  if (!(ransac_threshold_px > 0 && ransac_threshold_px < 50)) fail("ransac_threshold_px", "must be in (0, 50) pixels");
  if (!(ransac_confidence > 0 && ransac_confidence < 1)) fail("ransac_confidence", "must be in (0, 1)");
  if (!(huber_px > 0)) fail("huber_px", "must be positive");
  if (!(distance_sigma_m > 0)) fail("distance_sigma_m", "must be positive");
  if (!(outlier_px > 0)) fail("outlier_px", "must be positive");
  if (max_iterations < 1) fail("max_iterations", "must be >= 1");
}

WandObservations detect_wand(const Capture& capture, const LedDetectionOptions& options, int num_threads,
                             const std::function<void(int, int)>& progress) {
  options.validate();
  const Rig& rig = capture.rig();
  require_two_cameras(rig, (capture.dir() / "rig.json").string());  // before the detection's minutes
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    if (!rig.cameras[c].has_color()) {
      throw InvalidInput((capture.dir() / "rig.json").string() + ": cameras[" + std::to_string(c) + "] (\"" + rig.cameras[c].name +
                         "\"): no color_intrinsics; the wand is detected in colour");
    }
  }
  WandObservations obs(capture.camera_count(), capture.frame_count());
  std::mutex unreadable_mutex;
  for (int f = 0; f < capture.frame_count(); ++f) {
    parallel_for(0, capture.camera_count(), [&](int c) {
      const std::filesystem::path file = capture.color_path(f, c);
      if (file.empty()) return;
      // A file whose bytes cannot be read or decoded costs its camera this frame, as a missing one.
      ColorImage image;
      if (std::optional<std::string> reason = undecodable_reason([&] { image = read_color_image(file); })) {
        std::lock_guard lock(unreadable_mutex);
        obs.unreadable.push_back(std::move(*reason));
        return;
      }
      const Intrinsics& k = *rig.cameras[c].color_intrinsics;
      if (image.width != k.width || image.height != k.height) {
        throw InvalidInput(file.string() + ": color_intrinsics: image is " + std::to_string(image.width) + "x" +
                           std::to_string(image.height) + ", rig.json says " + std::to_string(k.width) + "x" + std::to_string(k.height));
      }
      const WandDetection d = detect_wand_leds(image, options);
      if (!d.usable()) return;
      const size_t i = obs.at(c, f);
      obs.red[i] = d.red.pixel;
      obs.green[i] = d.green.pixel;
      obs.usable[i] = 1;
    }, num_threads);
    if (progress) progress(f + 1, capture.frame_count());
  }
  std::sort(obs.unreadable.begin(), obs.unreadable.end());
  return obs;
}

ExtrinsicResult calibrate_extrinsics(const Rig& rig, const WandObservations& observations, const ExtrinsicOptions& options) {
  options.validate();
  const int n = static_cast<int>(rig.cameras.size());
  assert(observations.cameras == n);
  require_two_cameras(rig, "rig.json");
  const int frames = observations.frames;
  std::vector<Intrinsics> k(n);
  for (int c = 0; c < n; ++c) {
    if (!rig.cameras[c].has_color()) {
      throw InvalidInput("rig.json: cameras[" + std::to_string(c) + "] (\"" + rig.cameras[c].name + "\"): no color_intrinsics; the wand is detected in colour");
    }
    k[c] = *rig.cameras[c].color_intrinsics;
  }
  // Undistorted detections, [camera][frame][led].
  std::vector<std::array<Eigen::Vector2d, 2>> pixel(static_cast<size_t>(n) * frames);
  ExtrinsicResult result;
  result.cameras.resize(n);
  for (int c = 0; c < n; ++c) {
    result.cameras[c].name = rig.cameras[c].name;
    for (int f = 0; f < frames; ++f) {
      const size_t i = observations.at(c, f);
      if (!observations.usable[i]) continue;
      ++result.cameras[c].detections;
      pixel[i] = {undistort_pixel(k[c], observations.red[i]), undistort_pixel(k[c], observations.green[i])};
    }
  }

  // 1. Pairwise relative poses: b_from_a per pair, with its inlier count.
  std::vector<Rigid3d> pair_pose;
  for (int a = 0; a < n; ++a) {
    for (int b = a + 1; b < n; ++b) {
      std::vector<int> common;
      for (int f = 0; f < frames; ++f) {
        if (observations.usable[observations.at(a, f)] && observations.usable[observations.at(b, f)]) common.push_back(f);
      }
      if (static_cast<int>(common.size()) < options.min_common_frames) continue;
      std::vector<cv::Point2d> pa, pb;
      for (int f : common) {
        for (int led = 0; led < 2; ++led) {
          pa.emplace_back(pixel[observations.at(a, f)][led].x(), pixel[observations.at(a, f)][led].y());
          pb.emplace_back(pixel[observations.at(b, f)][led].x(), pixel[observations.at(b, f)][led].y());
        }
      }
      cv::Mat inlier_mask;
      const cv::Mat fundamental = cv::findFundamentalMat(pa, pb, cv::FM_RANSAC, options.ransac_threshold_px, options.ransac_confidence, inlier_mask);
      if (fundamental.rows != 3 || fundamental.cols != 3) continue;  // degenerate (e.g. the wand never moved)
      const cv::Matx33d ka(k[a].fx, 0, k[a].cx, 0, k[a].fy, k[a].cy, 0, 0, 1), kb(k[b].fx, 0, k[b].cx, 0, k[b].fy, k[b].cy, 0, 0, 1);
      const cv::Mat essential = cv::Mat(kb.t()) * fundamental * cv::Mat(ka);
      std::vector<cv::Point2d> na, nb;
      for (size_t i = 0; i < pa.size(); ++i) {
        const Eigen::Vector2d x = normalized(k[a], {pa[i].x, pa[i].y}), y = normalized(k[b], {pb[i].x, pb[i].y});
        na.emplace_back(x.x(), x.y());
        nb.emplace_back(y.x(), y.y());
      }
      cv::Mat rotation, translation;
      const int inliers = cv::recoverPose(essential, na, nb, cv::Mat::eye(3, 3, CV_64F), rotation, translation, inlier_mask);
      if (inliers < 8) continue;
      Eigen::Matrix3d r;
      Eigen::Vector3d t;
      cv::cv2eigen(rotation, r);
      cv::cv2eigen(translation, t);
      Rigid3d b_from_a = Rigid3d::Identity();
      b_from_a.linear() = r;
      b_from_a.translation() = t;
      // Scale: the median over this pair's wands of LED distance / triangulated distance.
      const std::vector<Rigid3d> pair_cams{Rigid3d::Identity(), b_from_a};
      const std::vector<Intrinsics> pair_k{k[a], k[b]};
      std::vector<double> ratios;
      for (size_t j = 0; j < common.size(); ++j) {
        if (!inlier_mask.at<unsigned char>(2 * j) || !inlier_mask.at<unsigned char>(2 * j + 1)) continue;
        Eigen::Vector3d led[2];
        bool ok = true;
        for (int l = 0; l < 2; ++l) {
          ok = ok && triangulate(pair_cams, pair_k, {{0, {pa[2 * j + l].x, pa[2 * j + l].y}}, {1, {pb[2 * j + l].x, pb[2 * j + l].y}}}, led[l]);
        }
        const double d = ok ? (led[0] - led[1]).norm() : 0;
        if (d > 0 && std::isfinite(d)) ratios.push_back(options.led_distance_m / d);
      }
      if (ratios.size() < 4) continue;
      std::nth_element(ratios.begin(), ratios.begin() + ratios.size() / 2, ratios.end());
      b_from_a.translation() *= ratios[ratios.size() / 2];
      result.pairs.push_back({.camera_a = a, .camera_b = b, .common_frames = static_cast<int>(common.size()), .inliers = inliers,
                              .scale = ratios[ratios.size() / 2]});
      pair_pose.push_back(b_from_a);
    }
  }

  // 2. Spanning tree from camera 0 over the pairs with the most inliers (Prim, maximum weight).
  std::vector<Rigid3d> cam_from_ref(n, Rigid3d::Identity());  // ref = camera 0's colour frame
  std::vector<bool> reached(n, false);
  reached[0] = true;
  for (int added = 1; added < n; ++added) {
    int best = -1;
    for (size_t p = 0; p < result.pairs.size(); ++p) {
      const PairReport& pr = result.pairs[p];
      if (reached[pr.camera_a] == reached[pr.camera_b]) continue;
      if (best < 0 || pr.inliers > result.pairs[best].inliers) best = static_cast<int>(p);
    }
    if (best < 0) {
      std::string connected, unreached;
      for (int c = 0; c < n; ++c) (reached[c] ? connected : unreached) += (reached[c] ? connected : unreached).empty() ? rig.cameras[c].name : ", " + rig.cameras[c].name;
      throw InvalidInput("the rig is not connected: " + unreached + " share fewer than " + std::to_string(options.min_common_frames) +
                         " usable wand frames (with a consistent relative pose) with " + connected +
                         "; wave the wand where these cameras' views overlap");
    }
    PairReport& pr = result.pairs[best];
    pr.in_tree = true;
    if (reached[pr.camera_a]) {
      cam_from_ref[pr.camera_b] = pair_pose[best] * cam_from_ref[pr.camera_a];
      reached[pr.camera_b] = true;
    } else {
      cam_from_ref[pr.camera_a] = pair_pose[best].inverse() * cam_from_ref[pr.camera_b];
      reached[pr.camera_a] = true;
    }
  }

  // LED points: index 2·frame + led, triangulated from every camera that saw them.
  std::vector<std::vector<Observation>> point_obs(2 * static_cast<size_t>(frames));
  std::vector<Eigen::Vector3d> points(point_obs.size(), Eigen::Vector3d::Zero());
  std::vector<bool> has_point(point_obs.size(), false);
  for (int f = 0; f < frames; ++f) {
    for (int led = 0; led < 2; ++led) {
      std::vector<Observation>& obs = point_obs[2 * f + led];
      for (int c = 0; c < n; ++c) {
        if (observations.usable[observations.at(c, f)]) obs.push_back({c, pixel[observations.at(c, f)][led]});
      }
      has_point[2 * f + led] = obs.size() >= 2 && triangulate(cam_from_ref, k, obs, points[2 * f + led]);
    }
  }

  auto measure = [&](auto&& store) {
    std::vector<double> sum(n, 0);
    std::vector<int> count(n, 0);
    double total = 0;
    int total_count = 0;
    for (size_t p = 0; p < points.size(); ++p) {
      if (!has_point[p]) continue;
      for (const Observation& o : point_obs[p]) {
        const double e = reprojection_error(cam_from_ref[o.camera], k[o.camera], points[p], o.pixel);
        sum[o.camera] += e;
        ++count[o.camera];
        total += e;
        ++total_count;
      }
    }
    for (int c = 0; c < n; ++c) store(c, count[c] ? sum[c] / count[c] : 0.0, count[c]);
    return total_count ? total / total_count : 0.0;
  };
  result.error_before_px = measure([&](int c, double e, int) { result.cameras[c].error_before_px = e; });

  // 3. Bundle adjustment; a second pass without the observations the first found far off.
  std::vector<std::array<double, 6>> pose(n);
  for (int c = 0; c < n; ++c) pose[c] = to_params(cam_from_ref[c]);
  for (int pass = 0; pass < 2; ++pass) {
    ceres::Problem problem;
    for (size_t p = 0; p < points.size(); ++p) {
      if (!has_point[p]) continue;
      for (const Observation& o : point_obs[p]) {
        problem.AddResidualBlock(new ceres::AutoDiffCostFunction<ReprojectionResidual, 2, 6, 3>(new ReprojectionResidual{o.pixel, k[o.camera]}),
                                 new ceres::HuberLoss(options.huber_px), pose[o.camera].data(), points[p].data());
      }
    }
    for (int f = 0; f < frames; ++f) {
      if (!has_point[2 * f] || !has_point[2 * f + 1]) continue;
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<LedDistanceResidual, 1, 3, 3>(
                                   new LedDistanceResidual{options.led_distance_m, options.distance_sigma_m}),
                               nullptr, points[2 * f].data(), points[2 * f + 1].data());
    }
    problem.SetParameterBlockConstant(pose[0].data());  // the gauge
    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::DENSE_SCHUR;  // few cameras, many points
    solver.max_num_iterations = options.max_iterations;
    solver.num_threads = options.num_threads > 0 ? options.num_threads : hardware_threads();
    solver.function_tolerance = 1e-10;
    solver.parameter_tolerance = 1e-10;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    result.converged = summary.termination_type == ceres::CONVERGENCE;
    for (int c = 0; c < n; ++c) cam_from_ref[c] = from_params(pose[c]);
    if (pass == 1) break;
    int dropped = 0;
    for (size_t p = 0; p < points.size(); ++p) {
      if (!has_point[p]) continue;
      std::vector<Observation>& obs = point_obs[p];
      const auto far = [&](const Observation& o) { return reprojection_error(cam_from_ref[o.camera], k[o.camera], points[p], o.pixel) > options.outlier_px; };
      const size_t before = obs.size();
      obs.erase(std::remove_if(obs.begin(), obs.end(), far), obs.end());
      dropped += static_cast<int>(before - obs.size());
      if (obs.size() < 2) has_point[p] = false;
    }
    result.dropped_observations = dropped;
    if (dropped == 0) break;
  }
  result.error_after_px = measure([&](int c, double e, int used) {
    result.cameras[c].error_after_px = e;
    result.cameras[c].observations_used = used;
  });
  double distance_sum = 0;
  int distance_count = 0;
  for (int f = 0; f < frames; ++f) {
    if (!has_point[2 * f] || !has_point[2 * f + 1]) continue;
    distance_sum += (points[2 * f] - points[2 * f + 1]).norm();
    ++distance_count;
    result.points += 2;
  }
  result.led_distance_mean_m = distance_count ? distance_sum / distance_count : 0;

  // World poses: camera 0's colour camera keeps its input pose; depth follows colour.
  result.rig = rig;
  result.rig.poses_trusted = true;  // calibrated: reconstruct uses the poses as they are unless asked to refine
  const CameraModel& gauge = rig.cameras[0];
  const Rigid3d world_from_ref = gauge.world_from_depth * gauge.color_from_depth.inverse();
  for (int c = 0; c < n; ++c) {
    CameraModel& cam = result.rig.cameras[c];
    const Rigid3d world_from_color = world_from_ref * cam_from_ref[c].inverse();
    cam.world_from_depth = world_from_color * cam.color_from_depth;
    cam.world_from_depth.linear() = nearest_rigid(cam.world_from_depth.matrix()).linear();  // exact rotation for rig.json
  }
  return result;
}

}  // namespace zipfusion
