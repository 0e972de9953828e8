#pragma once
//! \file
//! Kinect v1 cameras through libfreenect (Debian's libfreenect-dev), any number on one PC, as
//! LiveCameras. One libfreenect context serves all of them from one event thread; each camera's
//! frames wait in its own bounded queue until read.
//!
//! Depth: in millimetres as the device reports it (FREENECT_DEPTH_MM, or FREENECT_DEPTH_REGISTERED:
//! aligned to the colour image), or as 11-bit raw disparity (FREENECT_DEPTH_11BIT) converted by
//! kinect_raw_to_mm (kinect_disparity.h). fakenect, libfreenect's replay library, emulates only
//! the raw stream and has no registration data, so `kAuto` picks millimetres where the loaded
//! library can register depth and raw otherwise (tested by looking the registration function up
//! at run time: under fakenect the process runs against fakenect's libfreenect.so, which lacks it).
//!
//! Camera model: with registration data, the depth focal length from the device's zero plane
//! (reference_distance / (2 · reference_pixel_size) at 640×480, libfreenect's own conversion)
//! and the colour camera dcmos_rcmos_dist beside the depth camera; colour intrinsics are the
//! standard Kinect v1 ones (f 525 px). Without it (raw, fakenect) kinect_v1_default_model(). In
//! registered mode depth lies on the colour camera's pixel grid: depth intrinsics = colour
//! intrinsics and color_from_depth = identity.
//!
//! Timestamps: time_s is the host's steady clock when libfreenect handed the depth frame over (the
//! devices' own clocks are not shared); device_timestamp is libfreenect's. Each depth frame
//! carries the newest colour frame received if the device stamped the two at most
//! max_color_age_s apart (kinect_color_pairs_with_depth, kinect_clock.h), and no colour otherwise.
//!
//! End of a stream: a camera without a depth frame for stall_timeout_s (start_timeout_s before its
//! first) is taken as unplugged and ends; the others go on. When libfreenect's event processing
//! fails (under fakenect: the end of the recording) every stream ends.
//!
//! Thread safety: as LiveCamera; the cameras of one open_kinect_cameras() call share a context,
//! which lives until the last of them is destroyed.

#include <memory>
#include <string>
#include <vector>

#include "zipfusion/live/live_camera.h"

namespace zipfusion {

enum class KinectDepthFormat {
  kAuto,         // millimetres where the library registers depth, raw otherwise (fakenect)
  kMillimetres,  // FREENECT_DEPTH_MM: the depth camera's own pixel grid
  kRegistered,   // FREENECT_DEPTH_REGISTERED: depth on the colour camera's pixel grid
  kRaw,          // FREENECT_DEPTH_11BIT, converted by kinect_raw_to_mm
};

struct KinectOptions {
  KinectDepthFormat depth_format = KinectDepthFormat::kAuto;
  int max_queued_frames = 60;      // per camera, frames held for a reader that falls behind (2 s at 30 fps); beyond, the oldest is dropped and counted
  double stall_timeout_s = 2.0;    // no depth frame for this long ends the camera's stream (unplugged), seconds
  double start_timeout_s = 5.0;    // the same before its first frame, seconds
  double max_color_age_s = 0.04;   // colour stamped at most this far from a depth frame (the device clock) pairs with it, seconds

  void validate() const;  // throws InvalidInput naming the field
};

struct KinectDevice {
  int index = 0;
  std::string serial;  // empty where the library cannot list serials (fakenect)
};

//! The Kinect v1 cameras libfreenect sees (fakenect: one). Throws IoError when libfreenect
//! cannot start (no USB access).
std::vector<KinectDevice> list_kinect_devices();

//! Opens and starts the selected devices: "all", or a comma-separated list of indices ("0,2") or
//! serials, in the order given; they are named cam0, cam1, ... in that order. Throws InvalidInput
//! naming --devices (an unknown index or serial, a duplicate, a depth format the library cannot
//! deliver) and IoError (no device, a device that cannot be opened or started).
std::vector<std::unique_ptr<LiveCamera>> open_kinect_cameras(const std::string& selection, const KinectOptions& options = {});

}  // namespace zipfusion
