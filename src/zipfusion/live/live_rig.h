#pragma once
//! \file
//! LiveRig: N live cameras as one stream of frame sets, grouped by timestamp (frame_grouping.h:
//! members within half a frame period, the skew reported), and the pipeline's FrameSource over it
//! (`reconstruct --live`, and `serve --live`). Uses core and io only: the pipeline
//! takes the source without the live layer knowing the pipeline.
//!
//! A class: the grouping's pending frames and each camera's state live across calls. next() and
//! stats() are called from one thread; stop() from any (it is what a Ctrl-C handler's flag
//! leads to, through LiveRigOptions::cancel).

#include <atomic>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "zipfusion/io/capture.h"
#include "zipfusion/live/frame_grouping.h"
#include "zipfusion/live/live_camera.h"
#include "zipfusion/live/live_frame_queue.h"

namespace zipfusion {

struct LiveRigOptions {
  double max_wait_s = 0.25;   // real time waited for a camera's next frame before a set is decided without it, seconds
  double read_slice_s = 0.05; // longest single wait, so `cancel` is noticed within it, seconds
  //! When it turns true, every camera stops; frames already received still come out as sets, then
  //! next() returns false. May be null. Must outlive the rig.
  const std::atomic<bool>* cancel = nullptr;

  void validate() const;  // throws InvalidInput naming the field
};

//! One frame set of a live rig.
struct LiveFrameSet {
  int index = 0;        // 0, 1, 2, ... in the order next() returns them
  double time_s = 0;    // the set's anchor time (its earliest frame), on the rig's clock
  double skew_s = 0;    // latest member's time minus the earliest's, seconds (< half a period)
  std::vector<std::optional<LiveFrame>> cameras;  // per camera; empty where the camera has no frame in this set
};

struct LiveCameraStats {
  long frames = 0;           // frames received from the camera
  long grouped = 0;          // of those, frames put into a set
  long discarded_late = 0;   // frames that came after their set was decided (or a second frame within half a period)
  long dropped = 0;          // frames the camera discarded itself because reading fell behind
  bool ended = false;
  std::string end_reason;
};

class LiveRig {
 public:
  //! Takes the cameras (at least one; their fps must agree within 1 %). Throws InvalidInput.
  explicit LiveRig(std::vector<std::unique_ptr<LiveCamera>> cameras, const LiveRigOptions& options = {});
  ~LiveRig();
  LiveRig(const LiveRig&) = delete;
  LiveRig& operator=(const LiveRig&) = delete;

  int camera_count() const { return static_cast<int>(cameras_.size()); }
  const LiveCamera& camera(int c) const { return *cameras_.at(c); }
  double fps() const { return fps_; }

  //! The next frame set into `set`, waiting for the cameras as needed; false once every stream
  //! has ended (or was stopped) and every received frame was handed out. The frames `set` held
  //! (the set handed out before) go back to their cameras to be filled again, so a caller that
  //! keeps passing the same set gets a steady stream without allocating.
  bool next(LiveFrameSet& set);
  //! Stops every camera (thread-safe); next() then hands out what was already received.
  void stop();

  std::vector<LiveCameraStats> stats() const;

 private:
  std::vector<std::unique_ptr<LiveCamera>> cameras_;
  LiveRigOptions options_;
  double fps_ = 30;
  static constexpr size_t kSpareFrames = 8;  // a camera's images kept to fill again, at most

  std::vector<std::vector<LiveFrame>> pending_;
  std::vector<std::vector<double>> pending_times_;
  std::vector<LiveFrame> incoming_;             // per camera: what the next read() fills
  std::vector<SpareLiveFrames> spares_;  // per camera: images to give back through read()
  std::vector<StreamView> views_;
  GroupStep step_;
  std::vector<char> ended_, given_up_;
  std::vector<double> waited_s_;
  std::vector<LiveCameraStats> stats_;
  double not_before_s_ = -std::numeric_limits<double>::infinity();
  int next_index_ = 0;
  bool cancelled_ = false;
};

//! rig.json for a live rig: the cameras' models (names, intrinsics, color_from_depth) and fps,
//! frame_count 0, depth_unit_m 0.001. With a calibration (another rig.json), camera i takes its
//! name and its whole calibration from the calibration's camera i (take_camera_calibration:
//! intrinsics with their distortion, color_from_depth, world_from_depth), and the rig its volume
//! and poses_trusted, as `reconstruct --rig` does with a capture; without one, the devices'
//! intrinsics stay, poses are identity and poses_trusted false. Throws InvalidInput naming
//! `calibration_source` and the field when the camera counts, image sizes or colour differ.
//! Depth through distorted intrinsics must be undistorted: LiveSourceOptions::depth_undistortion.
Rig make_live_rig(const LiveRig& rig, const Rig* calibration = nullptr, const std::string& calibration_source = "");

struct LiveSourceOptions {
  int max_frames = 0;         // frame sets to deliver, 0 = no limit
  double max_seconds = 0;     // stop at the first set this long after the first set's time, 0 = no limit
  //! Called on the source thread with every set before it goes to the pipeline (statistics,
  //! skew reporting); empty = nothing.
  std::function<void(const LiveFrameSet&)> observe;
  //! Per camera, the depth_undistortion_map of its calibrated depth intrinsics (empty or missing:
  //! the depth as the device delivers it); depth_undistortion_maps(rig) makes them.
  std::vector<std::vector<int>> depth_undistortion;
};

//! One frame set of `rig` into `set` as live_frame_source delivers it (depth undistorted with
//! `depth_undistortion`, the images swapped), but without its limits, numbering or observer: for
//! frame sets taken before the pipeline starts (`--register once` on live input). `live` is the
//! caller's, kept between calls. False once every stream has ended (rig.next).
bool read_live_frame_set(LiveRig& rig, LiveFrameSet& live, FrameSet& set, const std::vector<std::vector<int>>& depth_undistortion);

//! The type of pipeline.h's FrameSource, spelled out because the live layer sits below the
//! pipeline (it is the same std::function type: run_pipeline takes it as it is).
using LiveFrameSource = std::function<bool(FrameSet& set, double& decode_ms)>;

//! The pipeline's FrameSource over a live rig (use PipelineOptions::source_policy =
//! QueuePolicy::kDropOldest: the cameras do not wait). Frame sets carry depth in millimetres
//! (depth_unit_m 0.001) and colour; `decode_ms` is the time spent waiting for and grouping the
//! set. The devices' images are swapped with `set`'s, whose images go back to the cameras to be
//! filled again (a depth image that is undistorted is written into the set's own buffer), so a
//! pipeline that recycles its frame sets gets a steady stream without allocating. The rig must
//! outlive the source; the source stops the rig when a limit is reached.
LiveFrameSource live_frame_source(LiveRig& rig, LiveSourceOptions options = {});

}  // namespace zipfusion
