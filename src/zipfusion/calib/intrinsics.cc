#include "zipfusion/calib/intrinsics.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "zipfusion/core/calibration_targets.h"
#include "zipfusion/core/error.h"

namespace zipfusion {
namespace {

// OpenCV's sector-based board detector draws on the thread's random numbers (cv::theRNG), so its
// result would depend on what ran before on the thread: seeded for each detection, restored after.
constexpr std::uint64_t kOpenCvSeed = 0x5eed0fb0a4dULL;
constexpr std::uint64_t kBoardSizeDraws = 3;
class SeededOpenCvRng {
 public:
  explicit SeededOpenCvRng(std::uint64_t seed) : saved_(cv::theRNG().state) { cv::theRNG().state = seed; }
  ~SeededOpenCvRng() { cv::theRNG().state = saved_; }
  SeededOpenCvRng(const SeededOpenCvRng&) = delete;
  SeededOpenCvRng& operator=(const SeededOpenCvRng&) = delete;

 private:
  std::uint64_t saved_;
};

// A board's inner corners, either way round.
struct BoardSize {
  int longer = 0, shorter = 0;
  explicit BoardSize(cv::Size size) : longer(std::max(size.width, size.height)), shorter(std::min(size.width, size.height)) {}
  bool exceeds(const BoardSize& other) const { return longer > other.longer || shorter > other.shorter; }
};

// `image` in grey for OpenCV's board detectors, or nullopt when it is too small for a board of
// `pattern` inner corners: the squares must be a few pixels wide to be found at all, and OpenCV's
// adaptive threshold fails an assertion on images of 8×8 pixels and less.
std::optional<cv::Mat> gray_for_board(const ColorImage& image, cv::Size pattern) {
  if (image.width < 4 * (pattern.width + 1) || image.height < 4 * (pattern.height + 1)) return std::nullopt;
  cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<Rgb8*>(image.data.data())), gray;
  cv::cvtColor(rgb, gray, cv::COLOR_RGB2GRAY);
  return gray;
}

// The whole grid of inner corners that the board of `seed` size OpenCV's sector-based detector
// finds belongs to (CALIB_CB_LARGER grows it; its meta output is the grid), or nullopt. Uses the
// thread's OpenCV random numbers: seed them (SeededOpenCvRng).
std::optional<BoardSize> grown_grid(const cv::Mat& gray, cv::Size seed) {
  std::vector<cv::Point2f> corners;
  cv::Mat meta;
  if (!cv::findChessboardCornersSB(gray, seed, corners, cv::CALIB_CB_LARGER, meta) || meta.empty()) return std::nullopt;
  return BoardSize(meta.size());
}

// The growing draws on OpenCV's random numbers and now and then stops short: the largest grid of
// a few fixed draws (each seeded, the thread's generator restored after).
std::optional<BoardSize> largest_grown_grid(const cv::Mat& gray, cv::Size seed) {
  std::optional<BoardSize> largest;
  for (std::uint64_t draw = 0; draw < kBoardSizeDraws; ++draw) {
    const SeededOpenCvRng seeded(kOpenCvSeed + draw);
    const std::optional<BoardSize> grid = grown_grid(gray, seed);
    if (grid && (!largest || grid->longer * grid->shorter > largest->longer * largest->shorter)) largest = grid;
  }
  return largest;
}

// The shortest distance between neighbouring corners of the grid (along a row or a column), pixels.
double shortest_corner_spacing(const std::vector<cv::Point2f>& corners, cv::Size pattern) {
  double shortest = std::numeric_limits<double>::infinity();
  for (int r = 0; r < pattern.height; ++r) {
    for (int c = 0; c < pattern.width; ++c) {
      const cv::Point2f& p = corners[r * pattern.width + c];
      if (c + 1 < pattern.width) shortest = std::min(shortest, cv::norm(corners[r * pattern.width + c + 1] - p));
      if (r + 1 < pattern.height) shortest = std::min(shortest, cv::norm(corners[(r + 1) * pattern.width + c] - p));
    }
  }
  return shortest;
}

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

// Two views whose corners lie this close on average (pixels) are one pose of the board.
constexpr double kSameViewPx = 1.0;

void BoardOptions::validate() const {
  if (inner_columns < kFewestBoardCorners || inner_rows < kFewestBoardCorners || inner_columns > kMostBoardCorners || inner_rows > kMostBoardCorners) {
    throw InvalidInput("--board: needs " + std::to_string(kFewestBoardCorners) + " to " + std::to_string(kMostBoardCorners) +
                       " inner corners each way, got " + std::to_string(inner_columns) + "x" + std::to_string(inner_rows));
  }
  if (!(square_m > 0 && square_m < 10)) throw InvalidInput("--square: must be in (0, 10) metres");
}

void IntrinsicOptions::validate() const {
  if (!(reject_factor > 1)) throw InvalidInput("reject_factor: must be > 1");
  if (!(reject_min_px >= 0)) throw InvalidInput("reject_min_px: must be >= 0");
  if (min_views < 3) throw InvalidInput("min_views: must be >= 3 (Zhang's method needs three views)");
}

std::optional<std::vector<Eigen::Vector2d>> detect_board_corners(const ColorImage& image, const BoardOptions& board) {
  board.validate();
  const cv::Size pattern(board.inner_columns, board.inner_rows);
  const std::optional<cv::Mat> gray_image = gray_for_board(image, pattern);
  if (!gray_image) return std::nullopt;
  const cv::Mat& gray = *gray_image;
  std::vector<cv::Point2f> corners;
  // OpenCV's sector-based detector: it finds boards of 5 px squares at 320x240, which the older
  // quadrilateral detector (findChessboardCorners) missed in 6 of 20 views, and gives up in 0.1 s
  // on a board larger than the pattern, which the older one searched for 9 s an image (a wrong
  // --board). The older one is no fallback for that reason. CALIB_CB_EXHAUSTIVE: boards blurred
  // over 3 px at 640x480 (1.5 px at 320x240) in 19 of 20 views, against 17 (18) without it and
  // 12 with the older detector, at about the same time; CALIB_CB_NORMALIZE_IMAGE lost a third.
  const SeededOpenCvRng seeded(kOpenCvSeed);
  if (!cv::findChessboardCornersSB(gray, pattern, corners, cv::CALIB_CB_EXHAUSTIVE)) return std::nullopt;
  // It also matches a piece of a larger board (a --board of 5x4 on a 9x6 one: fx 8678 against
  // 530, written): the grid grown from what it found must be the pattern itself.
  const std::optional<BoardSize> grid = largest_grown_grid(gray, pattern);
  if (grid && grid->exceeds(BoardSize(pattern))) return std::nullopt;
  // The corners are refined by cornerSubPix (the sector-based detector's own were 0.3-1 % off
  // in fx and cy on the synthetic boards, these 0.1 %), in a window that stays inside
  // one square: 11x11 for squares of 12 px and more, smaller for smaller squares (one over the
  // next corner pulled small boards 1.6 px off).
  const int half_window = std::clamp(static_cast<int>(0.4 * shortest_corner_spacing(corners, pattern)), 2, 5);
  cv::cornerSubPix(gray, corners, cv::Size(half_window, half_window), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 50, 1e-4));
  std::vector<Eigen::Vector2d> out;
  for (const cv::Point2f& p : corners) out.emplace_back(p.x, p.y);
  return out;
}

std::optional<std::pair<int, int>> largest_board_in(const ColorImage& image, const BoardOptions& board) {
  const cv::Size smallest(kFewestBoardCorners, kFewestBoardCorners);
  const std::optional<cv::Mat> gray = gray_for_board(image, smallest);
  if (!gray) return std::nullopt;
  const std::optional<BoardSize> largest = largest_grown_grid(*gray, smallest);
  if (!largest) return std::nullopt;
  // Either way round, as --board is given.
  const bool columns_first = board.inner_columns >= board.inner_rows;
  return columns_first ? std::pair{largest->longer, largest->shorter} : std::pair{largest->shorter, largest->longer};
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
  // Copies of one view (the same image twice, or a board that did not move) add no pose: with
  // fewer than three distinct poses Zhang's method is degenerate, and its result looks good (four
  // copies of one view gave fx 243 against a true 265, at an RMS of 0.05 px).
  auto same_view = [&](const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b) {
    double sum = 0;
    for (size_t i = 0; i < a.size(); ++i) sum += (a[i] - b[i]).norm();
    return sum < kSameViewPx * static_cast<double>(a.size());
  };
  for (size_t v = 0; v < corners.size(); ++v) {
    result.views.push_back({.name = names[v], .board_found = corners[v].has_value()});
    if (!corners[v]) continue;
    const auto earlier = std::find_if(view_of.begin(), view_of.end(), [&](size_t u) { return same_view(*corners[u], *corners[v]); });
    if (earlier != view_of.end()) {
      result.duplicates.push_back(names[v]);
      continue;
    }
    std::vector<cv::Point2f> points;
    for (const Eigen::Vector2d& p : *corners[v]) points.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
    image_points.push_back(std::move(points));
    view_of.push_back(v);
  }
  auto too_few = [&](size_t usable, const std::string& why) {
    if (static_cast<int>(usable) < options.min_views) {
      throw InvalidInput("calibrate intrinsics: " + std::to_string(usable) + (usable == 1 ? " usable board view " : " usable board views ") + why + ", need at least " +
                         std::to_string(options.min_views));
    }
  };
  too_few(image_points.size(), "(the board was found in " + std::to_string(image_points.size() + result.duplicates.size()) + " of " +
                                   std::to_string(corners.size()) + " images" +
                                   (result.duplicates.empty() ? "" : ", " + std::to_string(result.duplicates.size()) + " of them copies of another view") + ")");

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
  // A fit that folds inside the image would be refused by every rig.json reader (io/rig.cc): say so
  // here, with what helps, rather than write it.
  if (const double fold = distortion_fold_share(k); fold > 0) {
    char problem[256];
    std::snprintf(problem, sizeof problem,
                  "calibrate intrinsics: the fitted distortion (k1 %.4f, k2 %.4f) folds back at %.0f %% of the way to the image's farthest "
                  "corner; add views with the board near the corners, or leave distortion out (--no-distortion)",
                  k.distortion[0], k.distortion[1], 100.0 * fold);
    throw InvalidInput(problem);
  }
  if (const auto stretch = distortion_stretch_range(k); !stretch_of_a_lens(stretch)) {
    throw InvalidInput("calibrate intrinsics: the fitted distortion " + distortion_stretch_problem(stretch) +
                       "; add views with the board near the corners, or leave distortion out (--no-distortion)");
  }
  return result;
}

}  // namespace zipfusion
