#pragma once
//! \file
//! The world frame from the floor: after the wand (extrinsics.h) the rig's poses are right
//! relative to each other, but the world is whatever camera 0's pose in the input rig.json made
//! it (the identity: camera 0's optical frame). The floor, seen in the cameras' depth, fixes the
//! rest: the world's z axis is the floor's normal (up), z = 0 is the floor, the origin is the
//! point on the floor the cameras look at (where their optical axes, laid flat, meet; for one
//! camera, or cameras looking one way, 2 m ahead of them), and camera 0 stands on the −y axis. A
//! capture volume over the floor around the origin goes with it.
//!
//! The floor is the plane found by RANSAC over the depth points of all cameras (a few frames):
//! the one with the most points within `inlier_distance_m` among planes that every camera
//! stands at least `min_camera_height_m` above, on one side, and whose up side (towards the
//! cameras) lies within `max_tilt_deg` of the cameras' up direction (the principal direction of
//! their image-up directions, turned the way most of them point: a camera mounted upside down
//! among upright ones agrees, a ceiling or a wall ahead is no floor); a level plane at least
//! 0.3 m below it with a fifth of its points is preferred (a table top above the floor; unless
//! FloorOptions::prefer_lower_plane is false: a stage); the pick
//! is refitted by least squares to its inliers and checked again. Thread safety: pure functions.

#include <string>
#include <vector>

#include "zipfusion/io/capture.h"
#include "zipfusion/io/rig.h"

namespace zipfusion {

struct FloorOptions {
  int first_frame = 0, end_frame = 5;  // frames whose depth is searched (end excluded)
  int pixel_step = 4;                  // every pixel_step-th pixel of every pixel_step-th row
  double inlier_distance_m = 0.03;     // RANSAC: a point this close to a plane is on it (a Kinect's noise at 3 m is ~2.5 cm)
  double max_tilt_deg = 60;            // a floor's normal lies within this of the cameras' up axis (degrees)
  double min_camera_height_m = 0.2;    // every camera stands at least this high above the floor
  //! Depth beyond this is no measurement of a floor: consumer depth cameras reach 4–10 m, and a
  //! saturated 16-bit value (65.535 m in millimetres) made a "floor" 35 m below every camera.
  double max_depth_m = 10;
  //! Below the largest plane that can be the floor, a level plane with a fifth of its points is
  //! the floor (the floor under a table top). false: the largest plane is (a stage the subject
  //! stands on, with the room's floor around and below it; a floor around a pit).
  bool prefer_lower_plane = true;
  int ransac_iterations = 500;        // planes tried
  unsigned seed = 1;                  // of RANSAC's draws (the result is the same for the same input)
  bool set_volume = true;              // write the capture volume below (else keep none)
  double volume_half_width_m = 0;      // the volume's x and y half-size; 0: 0.5 × the nearest camera's horizontal distance from the origin
  double volume_height_m = 2.2;        // the volume spans z from 0.02 m (above the floor) to this

  void validate() const;  // throws InvalidInput naming the field
};

struct FloorCameraReport {
  std::string name;
  double height_m = 0;         // of the depth camera's centre above the floor
  double tilt_down_deg = 0;    // of its optical axis below the horizontal
  double distance_m = 0;       // horizontal, from the origin
  int floor_points = 0;        // of the floor's inliers, this camera's
};

struct FloorResult {
  Rig rig;                     // the input rig in the new world frame (relative poses unchanged), with the volume
  Rigid3d new_from_old = Rigid3d::Identity();  // the world change applied to every pose
  int points = 0;              // depth points searched
  int floor_points = 0;        // within inlier_distance_m of the fitted floor
  double floor_rms_m = 0;      // of those points' distances to it
  //! How far above the floor the largest plane that could be the floor lies: 0 when the floor is
  //! that plane, else the table top (or stage) the floor was taken from below.
  double largest_plane_above_m = 0;
  std::vector<FloorCameraReport> cameras;
  std::vector<std::string> unreadable;  // "FILE: reason" for each depth file that could not be read (its frame not used)
};

//! Finds the floor in `capture`'s depth, seen through its rig (a calibrated one with
//! Capture::use_calibration), and re-expresses that rig in the floor's world frame. Throws
//! InvalidInput naming the capture when its frames in range hold too little depth or no plane
//! qualifies as the floor.
FloorResult level_rig_to_floor(const Capture& capture, const FloorOptions& options = {});

}  // namespace zipfusion
