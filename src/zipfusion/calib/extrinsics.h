#pragma once
//! \file
//! The whole rig's poses from a two-LED wand (paper Section IV-A, after Svoboda et al. 2005 and
//! Kurillo et al. 2008):
//!  1. every camera pair with enough common detections: fundamental matrix by the 8-point
//!     algorithm with RANSAC, essential matrix from the colour intrinsics, relative pose; the scale
//!     from the known LED distance (median over the pair's triangulated wands);
//!  2. a spanning tree over the pairs with the most inliers gives a consistent initial rig; every
//!     LED seen by two or more cameras is triangulated;
//!  3. sparse bundle adjustment (Ceres) over all poses and LED points with a Huber loss, camera 0
//!     fixed (the gauge) and one LED-distance residual per frame (the scale); observations far off
//!     after a first pass are dropped and the adjustment repeated.
//! Poses are found for the colour cameras; each depth camera follows through its color_from_depth.
//! Camera 0 keeps the pose it has in the input rig, so the world frame stays the input's.
//! Lens distortion, when the rig gives it, is removed from the detections first.
//! Thread safety: pure functions.

#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "zipfusion/calib/led_detection.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/rig.h"

namespace zipfusion {

//! Usable wand detections: red and green pixel per camera and frame (structure of arrays, index
//! camera * frames + frame), with a flag; frames where a LED was missing or ambiguous are unflagged.
struct WandObservations {
  int cameras = 0;
  int frames = 0;
  std::vector<Eigen::Vector2d> red, green;  // colour-image pixels
  std::vector<unsigned char> usable;        // 1 = both LEDs found once each
  std::vector<std::string> unreadable;      // "FILE: reason" for each colour file that could not be read or decoded (its frame unusable), sorted

  WandObservations() = default;
  WandObservations(int camera_count, int frame_count)
      : cameras(camera_count), frames(frame_count), red(static_cast<size_t>(camera_count) * frame_count, Eigen::Vector2d::Zero()),
        green(red.size(), Eigen::Vector2d::Zero()), usable(red.size(), 0) {}
  size_t at(int camera, int frame) const { return static_cast<size_t>(camera) * frames + frame; }
};

//! Detects the wand in every colour frame of a capture. Throws InvalidInput for a camera without
//! colour (the wand is seen in colour) and for a frame of another size than rig.json's; missing
//! frame files, and files that cannot be read or decoded (listed in `unreadable`), leave the frame
//! unusable. `progress(done, total)` after each frame.
WandObservations detect_wand(const Capture& capture, const LedDetectionOptions& options = {}, int num_threads = 0,
                             const std::function<void(int, int)>& progress = {});

struct ExtrinsicOptions {
  double led_distance_m = 0.445;     // distance between the LEDs, metres (the paper's wand)
  int min_common_frames = 15;        // a pair needs this many frames both cameras saw the wand in
  double ransac_threshold_px = 1.0;  // 8-point RANSAC: largest distance to the epipolar line, pixels
  double ransac_confidence = 0.999;
  double huber_px = 1.0;             // bundle adjustment: Huber loss scale, pixels
  double distance_sigma_m = 0.0005;  // weight of a frame's LED-distance residual: its σ, metres
  double outlier_px = 3.0;           // after the first pass, observations further off are dropped, pixels
  int max_iterations = 200;          // Levenberg-Marquardt iterations per pass
  int num_threads = 0;               // 0 = all hardware threads

  void validate() const;  // throws InvalidInput naming the field
};

struct CameraCalibrationReport {
  std::string name;
  int detections = 0;               // frames with a usable wand detection
  int observations_used = 0;        // LED observations in the final adjustment
  double error_before_px = 0;       // mean reprojection error of the initial (pairwise) rig, pixels
  double error_after_px = 0;        // after bundle adjustment, pixels
};

struct PairReport {
  int camera_a = 0, camera_b = 0;
  int common_frames = 0;
  int inliers = 0;                  // LED correspondences consistent with the relative pose
  double scale = 0;                 // metres per unit of the pair's essential-matrix translation
  bool in_tree = false;             // used for the initial rig
};

struct ExtrinsicResult {
  Rig rig;                          // the input rig with new world_from_depth
  std::vector<CameraCalibrationReport> cameras;
  std::vector<PairReport> pairs;    // every pair with enough common frames
  int points = 0;                   // LED points in the adjustment
  double error_before_px = 0;       // over all observations
  double error_after_px = 0;
  double led_distance_mean_m = 0;   // mean distance between the adjusted LED points of a frame
  int dropped_observations = 0;     // beyond outlier_px after the first pass
  bool converged = false;
};

//! Calibrates the rig's poses from wand observations. Throws InvalidInput when a camera has no
//! colour, when the cameras are not connected by pairs with enough common detections (naming the
//! cameras that cannot be reached from camera 0), or when the observations do not fit.
ExtrinsicResult calibrate_extrinsics(const Rig& rig, const WandObservations& observations, const ExtrinsicOptions& options = {});

}  // namespace zipfusion
