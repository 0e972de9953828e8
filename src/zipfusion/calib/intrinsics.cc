#include "zipfusion/calib/intrinsics.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "zipfusion/core/error.h"

namespace zipfusion {
namespace {

struct Calibration {
  cv::Mat camera_matrix, distortion;
  double rms = 0;
  std::vector<double> view_rms;
};

Calibration run_calibration(const std::vector<std::vector<cv::Point2f>>& image_points, const BoardOptions& board, int width,
                            int height, const IntrinsicOptions& options) {
  std::vector<cv::Point3f> object;
  for (int r = 0; r < board.inner_rows; ++r) {
    for (int c = 0; c < board.inner_columns; ++c) object.emplace_back(c * board.square_m, r * board.square_m, 0.0f);
  }
  const std::vector<std::vector<cv::Point3f>> object_points(image_points.size(), object);
  Calibration cal;
  std::vector<cv::Mat> rvecs, tvecs;
  // Tangential terms trade off against the principal point (2 px of cx on 15 clean views), and
  // k3 against k1, k2; both are negligible on Kinect-class lenses, so only k1, k2 are estimated.
  int flags = cv::CALIB_FIX_K3 | cv::CALIB_ZERO_TANGENT_DIST;
  if (!options.estimate_distortion) flags |= cv::CALIB_FIX_K1 | cv::CALIB_FIX_K2;
  cal.rms = cv::calibrateCamera(object_points, image_points, cv::Size(width, height), cal.camera_matrix, cal.distortion, rvecs, tvecs,
                                flags, cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-12));
  for (size_t v = 0; v < image_points.size(); ++v) {
    std::vector<cv::Point2f> projected;
    cv::projectPoints(object, rvecs[v], tvecs[v], cal.camera_matrix, cal.distortion, projected);
    double sum = 0;
    for (size_t i = 0; i < projected.size(); ++i) {
      const cv::Point2f d = projected[i] - image_points[v][i];
      sum += d.dot(d);
    }
    cal.view_rms.push_back(std::sqrt(sum / projected.size()));
  }
  return cal;
}

}  // namespace

void BoardOptions::validate() const {
  if (inner_columns < 2 || inner_rows < 2) throw InvalidInput("board: needs at least 2x2 inner corners");
  if (!(square_m > 0 && square_m < 10)) throw InvalidInput("square: must be in (0, 10) metres");
}

void IntrinsicOptions::validate() const {
  if (!(reject_factor > 1)) throw InvalidInput("reject_factor: must be > 1");
  if (!(reject_min_px >= 0)) throw InvalidInput("reject_min_px: must be >= 0");
  if (min_views < 3) throw InvalidInput("min_views: must be >= 3 (Zhang's method needs three views)");
}

std::optional<std::vector<Eigen::Vector2d>> detect_board_corners(const ColorImage& image, const BoardOptions& board) {
  board.validate();
  cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<Rgb8*>(image.data.data())), gray;
  cv::cvtColor(rgb, gray, cv::COLOR_RGB2GRAY);
  const cv::Size pattern(board.inner_columns, board.inner_rows);
  std::vector<cv::Point2f> corners;
  if (!cv::findChessboardCorners(gray, pattern, corners, cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE)) return std::nullopt;
  // 11×11 window: inside one square for squares of 12 px and more on the image.
  cv::cornerSubPix(gray, corners, cv::Size(5, 5), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 50, 1e-4));
  std::vector<Eigen::Vector2d> out;
  for (const cv::Point2f& p : corners) out.emplace_back(p.x, p.y);
  return out;
}

IntrinsicResult calibrate_intrinsics(const std::vector<std::optional<std::vector<Eigen::Vector2d>>>& corners,
                                     const std::vector<std::string>& names, int width, int height, const BoardOptions& board,
                                     const IntrinsicOptions& options) {
  board.validate();
  options.validate();
  assert(corners.size() == names.size());
  IntrinsicResult result;
  std::vector<std::vector<cv::Point2f>> image_points;
  std::vector<size_t> view_of;  // index into `corners` of each calibrated view
  for (size_t v = 0; v < corners.size(); ++v) {
    result.views.push_back({.name = names[v], .board_found = corners[v].has_value()});
    if (!corners[v]) continue;
    std::vector<cv::Point2f> points;
    for (const Eigen::Vector2d& p : *corners[v]) points.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
    image_points.push_back(std::move(points));
    view_of.push_back(v);
  }
  auto too_few = [&](size_t usable, const std::string& why) {
    if (static_cast<int>(usable) < options.min_views) {
      throw InvalidInput("calibrate intrinsics: " + std::to_string(usable) + " usable board views " + why + ", need at least " +
                         std::to_string(options.min_views));
    }
  };
  too_few(image_points.size(), "(the board was found in " + std::to_string(image_points.size()) + " of " + std::to_string(corners.size()) + " images)");

  Calibration cal = run_calibration(image_points, board, width, height, options);
  std::vector<double> sorted = cal.view_rms;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double threshold = std::max(options.reject_factor * sorted[sorted.size() / 2], options.reject_min_px);
  std::vector<std::vector<cv::Point2f>> kept;
  for (size_t i = 0; i < image_points.size(); ++i) {
    ViewReport& report = result.views[view_of[i]];
    report.rms_px = cal.view_rms[i];
    report.used = cal.view_rms[i] <= threshold;
    if (report.used) {
      kept.push_back(image_points[i]);
    } else {
      result.rejected.push_back(report.name);
    }
  }
  if (!result.rejected.empty()) {
    too_few(kept.size(), "after rejecting " + std::to_string(result.rejected.size()) + " views");
    cal = run_calibration(kept, board, width, height, options);
  }
  result.rms_px = cal.rms;
  Intrinsics& k = result.intrinsics;
  k.width = width;
  k.height = height;
  k.fx = cal.camera_matrix.at<double>(0, 0);
  k.fy = cal.camera_matrix.at<double>(1, 1);
  k.cx = cal.camera_matrix.at<double>(0, 2);
  k.cy = cal.camera_matrix.at<double>(1, 2);
  k.has_distortion = options.estimate_distortion;
  for (int i = 0; i < 5; ++i) k.distortion[i] = options.estimate_distortion ? cal.distortion.at<double>(i) : 0.0;
  return result;
}

}  // namespace zipfusion
