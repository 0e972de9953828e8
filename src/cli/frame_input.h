#pragma once
// Where `reconstruct` and `serve` take frame sets from: a capture on disk, or live cameras
// (--live: Kinect v1 devices or fakenect dumps replayed), with the rig for them.

#include <CLI/CLI.hpp>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "cli/frame_range.h"
#include "cli/live_devices.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/live/live_rig.h"
#include "zipfusion/pipeline/pipeline.h"

namespace zipfusion::cli {

struct InputArgs {
  std::string capture;
  std::string frames;
  bool live = false;
  LiveDeviceArgs devices;
  double seconds = 0;
};

//! CAPTURE (positional, not with --live), --frames, --live, the device options, --seconds.
void add_input_options(CLI::App* cmd, InputArgs& args);

struct Input {
  std::optional<Capture> capture;
  std::unique_ptr<LiveRig> live;
  Rig rig;
  FrameRange range;       // capture: the frames; live: [0, --frames) or [0, 0) without a limit
  FrameSource source;     // capture: every frame as fast as it decodes; live: as the cameras deliver
  //! Live: a frame set taken before the pipeline starts (the poses' refinement on the first live
  //! sets), not counted by --frames or --seconds, nor numbered; the first call says so on stdout.
  //! Empty for a capture.
  std::function<bool(FrameSet&)> take_before_start;
  std::mutex skew_mutex;  // live: per frame set skew, written by the source thread
  std::vector<double> skew_ms;
  std::mutex unreadable_mutex;  // capture: written by the source thread
  std::map<int, std::vector<std::string>> unreadable;  // capture: per frame set, its frame files that could not be decoded

  //! The frame set's skew between the cameras (live), or a negative value.
  double skew_of(int index);
  //! The frame set's unreadable frame files (CameraFrame::unreadable): their cameras were left out of it.
  std::vector<std::string> unreadable_of(int index);
  //! Every unreadable frame file so far.
  int unreadable_count();
};

//! A command's frame files that cannot be decoded (CameraFrame::unreadable), frame set by frame set.
//! Each is a warning line, "COMMAND: warning: FILE: reason; CAMERA left out of frame set N" (or
//! "has no colour in"), up to kListed, then only counted. Until some depth of the capture has
//! decoded, a frame set without any depth and with a file that failed is an error instead: every
//! file is then probably unreadable (Git LFS pointers, no read permission), which going on would
//! turn into empty meshes and a warning per file.
class UnreadableFrames {
 public:
  explicit UnreadableFrames(std::string command) : command_(std::move(command)) {}
  //! Warns of `set`'s unreadable files and returns them (unreadable_files); throws InvalidInput as above.
  std::vector<std::string> report(const Rig& rig, const FrameSet& set);
  static constexpr int kListed = 20;  // warning lines, then a count

 private:
  std::string command_;
  int count_ = 0;  // files reported so far
  bool depth_decoded_ = false;
};

//! Capture::open for `command`, with a warning line ("COMMAND: warning: …; the ground truth is not
//! used") where the capture's optional ground_truth/rig.json cannot be used.
Capture open_capture(const std::string& dir, const std::string& command);

//! Opens the capture or the cameras. `rig_path` (--rig): poses for the capture, or the
//! calibration of live cameras. Throws InvalidInput naming the option. A capture's source warns
//! of each unreadable frame file as `command` and keeps them in `in.unreadable`.
void open_input(InputArgs& args, const std::string& rig_path, const std::string& command, Input& in);

}  // namespace zipfusion::cli
