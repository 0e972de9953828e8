#pragma once
//! \file
//! A fakenect dump replayed as a LiveCamera without libfreenect: several dumps (one per Kinect,
//! recorded on one PC, so their <seconds> share a clock) make a multi-camera rig for tests and for
//! recordings made with fakenect-record. Frames come as fast as they can be read, time_s the
//! dump's <seconds>; or, for a live stream of recordings, paced as the devices delivered them
//! and looped (ReplayOptions::paced, loop), all dumps of a rig on one time line.
//!
//! Depth is converted from raw 11-bit values by kinect_raw_to_mm (kinect_disparity.h); each
//! depth frame is paired with the latest colour frame before it in INDEX.txt when the device
//! stamped the two at most `max_color_age_s` apart (kinect_color_pairs_with_depth), as a live
//! KinectCamera pairs them. A file that is missing, truncated or malformed ends the stream there
//! (end_reason() names it), as a recording cut off by an unplugged device or a crash would.
//! The model is kinect_v1_default_model(). Thread safety: as LiveCamera.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "zipfusion/live/fakenect_dump.h"
#include "zipfusion/live/live_camera.h"

namespace zipfusion {

//! When a time line starts playing, shared by the rig's cameras: the first paced read of any of
//! them fixes it (unless it was given), so that the time between opening the cameras and reading
//! them (starting a server, a pipeline) does not pile up frames that would then come at once.
class ReplayStart {
 public:
  ReplayStart() = default;
  explicit ReplayStart(std::chrono::steady_clock::time_point at) : at_(at) {}
  std::chrono::steady_clock::time_point at();  // the start; the first call without one sets it to now

 private:
  std::mutex mutex_;
  std::optional<std::chrono::steady_clock::time_point> at_;
};

//! The time line the dumps of one rig share: from the earliest <seconds> of any dump to the
//! latest, plus one frame period (a pass of a loop), and when it starts playing.
struct ReplayTimeline {
  double first_s = 0;   // recording time, seconds
  double period_s = 0;  // one pass, seconds
  std::shared_ptr<ReplayStart> start = std::make_shared<ReplayStart>();  // shared by the copies
};

//! The time line of these dumps (their INDEX.txt; throws as read_fakenect_index), starting at the
//! first paced read.
ReplayTimeline replay_timeline(const std::vector<std::filesystem::path>& dumps, double fps);

struct ReplayOptions {
  double fps = 30;                // nominal frame rate of the recording
  double max_color_age_s = 0.04;  // colour stamped at most this far from the depth (the device clock) pairs with it, seconds
  //! Played again and again: pass k's times (time_s, device_timestamp) shifted by k·timeline.period_s,
  //! so that they keep rising and the rig's cameras stay grouped.
  bool loop = false;
  //! A depth frame recorded at t is delivered at timeline.start->at() + (t − timeline.first_s)
  //! (+ the passes), as the device delivered it, not as fast as it is read.
  bool paced = false;
  ReplayTimeline timeline;        // used by loop and paced: the rig's (replay_timeline)

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
  ReadStatus read_next(LiveFrame& frame);  // the next depth frame, unpaced
  ReadStatus end(const std::string& reason);  // ends the stream (the first reason stays)
  std::chrono::steady_clock::time_point due(double time_s) const;  // when a frame of this (pass's) time is delivered, paced

  std::filesystem::path dir_;
  ReplayOptions options_;
  CameraModel model_;
  std::vector<FakenectIndexEntry> entries_;
  std::vector<std::string> paths_;  // per entry: dir_ / file, made once (a path a frame would allocate)
  size_t next_ = 0;
  int pass_ = 0;                   // passes of the loop completed
  int depth_this_pass_ = 0;        // depth frames delivered in this pass (a loop without any would spin)
  std::uint32_t pass_ticks_ = 0;   // a pass in device clock ticks (mod 2^32, as the clock wraps)
  bool ended_ = false;
  bool has_color_ = false;
  ColorImage color_;
  std::vector<std::uint8_t> bytes_;  // the file being decoded (its buffer kept)
  RawDepthImage raw_;                // the depth being converted (its buffer kept)
  bool has_pending_ = false;       // paced: the next frame, read and waiting for its time
  LiveFrame pending_;
  std::uint32_t color_timestamp_ = 0;
  std::atomic<bool> stopped_{false};
  mutable std::mutex mutex_;  // guards end_reason_
  std::string end_reason_;
};

}  // namespace zipfusion
