#pragma once
//! \file
//! A fakenect dump replayed as a LiveCamera without libfreenect: several dumps (one per Kinect,
//! recorded on one PC, so their <seconds> share a clock) make a multi-camera rig for tests and for
//! recordings made with fakenect-record. Frames come as fast as they can be read (no pacing);
//! time_s is the dump's <seconds>.
//!
//! Depth is converted from raw 11-bit values by kinect_raw_to_mm (kinect_disparity.h); each
//! depth frame is paired with the latest colour frame before it in INDEX.txt when the device
//! stamped the two at most `max_color_age_s` apart (kinect_color_pairs_with_depth), as a live
//! KinectCamera pairs them. A file that is missing, truncated or malformed ends the stream there
//! (end_reason() names it), as a recording cut off by an unplugged device or a crash would.
//! The model is kinect_v1_default_model(). Thread safety: as LiveCamera.

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

#include "zipfusion/live/fakenect_dump.h"
#include "zipfusion/live/live_camera.h"

namespace zipfusion {

struct ReplayOptions {
  double fps = 30;                // nominal frame rate of the recording
  double max_color_age_s = 0.04;  // colour stamped at most this far from the depth (the device clock) pairs with it, seconds

  void validate() const;  // throws InvalidInput naming the field
};

class ReplayCamera final : public LiveCamera {
 public:
  //! Reads dir/INDEX.txt (throws IoError / InvalidInput naming it). `name` is the camera's folder.
  ReplayCamera(const std::filesystem::path& dir, const std::string& name, const ReplayOptions& options = {});

  const CameraModel& model() const override { return model_; }
  std::string description() const override { return "fakenect dump " + dir_.string(); }
  double fps() const override { return options_.fps; }
  ReadStatus read(LiveFrame& frame, double timeout_s) override;
  void stop() override { stopped_ = true; }
  std::string end_reason() const override;
  long dropped_frames() const override { return 0; }

 private:
  std::filesystem::path dir_;
  ReplayOptions options_;
  CameraModel model_;
  std::vector<FakenectIndexEntry> entries_;
  size_t next_ = 0;
  bool has_color_ = false;
  ColorImage color_;
  std::uint32_t color_timestamp_ = 0;
  std::atomic<bool> stopped_{false};
  mutable std::mutex mutex_;  // guards end_reason_
  std::string end_reason_;
};

}  // namespace zipfusion
