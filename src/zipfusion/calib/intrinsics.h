#pragma once
//! \file
//! A colour camera's intrinsics from checkerboard views (paper Section IV-A-1: Zhang's method).
//! Corners by OpenCV findChessboardCorners refined by cornerSubPix; the calibration by
//! calibrateCamera. Views whose own RMS reprojection error is far above the others' (a blurred
//! frame, a misdetected board) are rejected, named, and the calibration repeated without them.
//! Pure functions; thread safe.

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "zipfusion/core/camera.h"
#include "zipfusion/core/image.h"

namespace zipfusion {

struct BoardOptions {
  int inner_columns = 9;   // inner corners along a row
  int inner_rows = 6;      // inner corners along a column
  double square_m = 0.025; // square side, metres

  void validate() const;   // throws InvalidInput naming the field
};

//! The board's inner corners in an image, row by row, sub-pixel; nullopt when the whole board is
//! not found.
std::optional<std::vector<Eigen::Vector2d>> detect_board_corners(const ColorImage& image, const BoardOptions& board);

//! The inner corners (columns, rows) of the largest checkerboard in the image whatever its size,
//! ordered the way `board` is (the longer side first when board's columns are), or nullopt: for
//! telling a user whose --board finds nothing what the images show (squares counted instead of
//! inner corners is the usual slip). A board partly hidden may come out smaller than it is.
std::optional<std::pair<int, int>> largest_board_in(const ColorImage& image, const BoardOptions& board);

struct IntrinsicOptions {
  bool estimate_distortion = true;  // radial k1, k2 (p1, p2, k3 stay 0: they trade off against cx, cy and k1, k2)
  double reject_factor = 3.0;       // a view is rejected when its RMS > this × the median view RMS …
  double reject_min_px = 0.5;       // … and above this many pixels (good views all sit far below)
  int min_views = 3;                // fewer usable views is an error

  void validate() const;  // throws InvalidInput naming the field
};

struct ViewReport {
  std::string name;          // as given by the caller (the file)
  bool board_found = false;
  bool used = false;         // false: board not found, or rejected
  double rms_px = 0;         // RMS reprojection error of this view's corners (first calibration), pixels
};

struct IntrinsicResult {
  Intrinsics intrinsics;     // with distortion when estimated
  double rms_px = 0;         // overall RMS reprojection error of the used views, pixels
  std::vector<ViewReport> views;
  std::vector<std::string> rejected;  // names of the views rejected for their error
  std::vector<std::string> duplicates;  // names of the views left out as copies of an earlier one (corners within 1 px)
};

//! Calibrates from corner sets (one per view, nullopt where the board was not found), all from
//! images of `width` × `height`. Throws InvalidInput when fewer than min_views remain.
IntrinsicResult calibrate_intrinsics(const std::vector<std::optional<std::vector<Eigen::Vector2d>>>& corners,
                                     const std::vector<std::string>& names, int width, int height, const BoardOptions& board,
                                     const IntrinsicOptions& options = {});

}  // namespace zipfusion
