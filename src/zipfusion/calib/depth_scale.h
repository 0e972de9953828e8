#pragma once
//! \file
//! The rig's scale as its depth cameras measure it. Colour cameras fix the rig only up to scale;
//! the wand's LED distance (extrinsics.h) supplies it, and a wrong length there scales every
//! camera's distance from the gauge camera. Depth cameras measure lengths themselves: the surfaces
//! two of them see meet only where the rig has its true size. With every camera's offset from the
//! gauge's centre multiplied by s (`scale_rig`), each camera's depth pixels are carried into the
//! others and compared with the depth measured there; the s at which they agree best is the factor
//! the rig is off by. A plane alone (the floor) agrees at every s and measures nothing: a person
//! or furniture that two cameras see, facing partly along the line between them, does. Cameras
//! that face each other are not compared (their shared surfaces fix no size), and cameras 120°
//! apart around a person share too little for a measurement at 320×240 most of the time
//! (docs/design.md).
//! Thread safety: pure functions; parallel inside (`num_threads`).

#include <string>
#include <vector>

#include "zipfusion/io/capture.h"
#include "zipfusion/io/rig.h"

namespace zipfusion {

struct DepthScaleOptions {
  int frames = 8;                  // frames spread evenly over the capture whose depth is compared
  int pixel_step = 4;              // every pixel_step-th pixel of every pixel_step-th row at 640 pixels wide (scaled with the width)
  double min_depth_m = 0.4;        // depth outside [min, max] is not used (a Kinect's range)
  double max_depth_m = 4.5;
  double lowest_scale = 0.25;      // the factors searched, every 1.5 %, the outer 4.5 % as shoulders only
  double highest_scale = 4.0;
  double max_view_angle_deg = 80;  // a point is compared where its surface faces the other camera at most this obliquely
  // Cameras whose optical axes lie further apart are not compared: facing each other, they share
  // only surfaces parallel to the line between them (the body's sides), which fix no size, and
  // the floor's far edges, which fix it only roughly (2 % off on a 2-camera ring).
  double max_pair_angle_deg = 135;
  // σ of the Gaussian weight of a depth difference, metres: a Kinect v1's noise at 2.5–3 m is
  // 1.0–1.3 cm, and two cameras' readings differ by √2 of it.
  double agreement_m = 0.02;
  // A measurement needs at least this much agreement (summed weights) at its best factor, and
  // that many times the agreement 4.5 % to either side: surfaces that fix the size agree within a
  // percent or two of it, while a plane's agreement changes only slowly, with how much of it two
  // cameras share.
  double min_agreement = 300;
  double min_peak_ratio = 1.1;
  int num_threads = 0;             // 0 = all hardware threads

  void validate() const;  // throws InvalidInput naming the field
};

struct DepthScaleResult {
  bool measured = false;
  std::string not_measured;        // why not, when not (e.g. "no depth in frames 0–119")
  double scale = 1;                // the rig's offsets from the gauge times this agree best with the depth
  double agreement = 0;            // summed weights at `scale`
  int samples = 0;                 // depth points compared (all frames and cameras: pixels with a normal)
  std::vector<int> frames;         // the frames compared
  std::vector<std::string> unreadable;  // "FILE: reason" for each depth file that could not be read (not used)
};

//! The rig with every camera's offset from camera `gauge` multiplied by `scale`: colour cameras'
//! centres about the gauge's colour centre (the wand calibrates colour cameras; each depth camera
//! follows through its color_from_depth), depth centres for cameras without colour. Orientations
//! and the gauge's pose are unchanged.
Rig scale_rig(const Rig& rig, int gauge, double scale);

//! How much larger the rig `rig` (the capture's cameras, e.g. calibrate_extrinsics' result) must
//! be for its depth cameras' surfaces in `capture` to meet. Not measured when the frames hold no
//! depth that two cameras see, or only surfaces that agree at every factor (a plane).
DepthScaleResult measure_depth_scale(const Capture& capture, const Rig& rig, int gauge, const DepthScaleOptions& options = {});

}  // namespace zipfusion
