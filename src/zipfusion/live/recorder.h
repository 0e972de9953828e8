#pragma once
//! \file
//! Recording a live rig to a rig capture (`zipfusion record`), written incrementally so that at
//! every moment the folder is a valid capture of what has been recorded: a crash or Ctrl-C leaves
//! a capture that Capture::open accepts (strict, when no camera missed a frame).
//!
//! Per frame set n: every camera's depth PNG (millimetres) and colour file are encoded and
//! written under hidden temporary names (".000042.png.part", which the format ignores), then
//! renamed into place, then a line per camera is appended to timestamps.csv, then rig.json is
//! rewritten atomically with frame_count n + 1. A camera absent from a set has no file in it (the
//! format allows missing frames). The only window in which the folder is not a valid capture is
//! between the last rename of a set and rig.json's rename (microseconds; only a kill -9 or power
//! loss can hit it: the files of that one set then exceed frame_count, and deleting them restores
//! the capture).
//!
//! timestamps.csv (a zipfusion extension beside the format's files): the header
//! "frame,camera,time_s,device_timestamp", then one line per frame file written: the frame set,
//! the camera's name, its frame's time in seconds since the first set's anchor, and the device's
//! timestamp. Lines for frames ≥ rig.json's frame_count (a crash between the two) are to be
//! ignored, as is an incomplete last line.

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "zipfusion/io/rig.h"
#include "zipfusion/live/live_rig.h"

namespace zipfusion {

struct RecordOptions {
  int max_frames = 0;                     // frame sets to record, 0 = until every stream ends or is stopped
  double max_seconds = 0;                 // record sets whose anchor is less than this after the first's, seconds; 0 = no limit
  std::string color_extension = ".jpg";   // ".jpg" or ".png"
  int jpeg_quality = 90;                  // 1..100
  int num_threads = 0;                    // encoding threads, 0 = all cores
  //! Called after each frame set is on disk (rig.json included), on the recording thread.
  std::function<void(const LiveFrameSet&)> progress;

  void validate() const;  // throws InvalidInput naming the field
};

struct RecordResult {
  int frame_sets = 0;                 // frame sets written (rig.json's frame_count)
  std::vector<int> frames_written;    // per camera: depth frames written
  double max_skew_s = 0;              // over the sets with two or more cameras, seconds
  double mean_skew_s = 0;
  double duration_s = 0;              // last set's anchor minus the first's, seconds
  bool limit_reached = false;         // stopped by max_frames or max_seconds (not by the streams' end)
  std::vector<LiveCameraStats> cameras;  // the rig's statistics at the end
};

//! Records `live` into `out_dir` (which must not exist or be empty: InvalidInput naming --out).
//! `rig` is rig.json's content apart from frame_count (make_live_rig()); its cameras must match
//! the live rig's. Returns when a limit is reached (the rig is then stopped) or the rig's stream
//! ends (every camera ended or was stopped, e.g. through LiveRigOptions::cancel). Throws IoError
//! naming the file when writing fails; what was recorded until then stays a valid capture.
RecordResult record_capture(LiveRig& live, const Rig& rig, const std::filesystem::path& out_dir, const RecordOptions& options = {});

//! One line of timestamps.csv.
struct RecordedTimestamp {
  int frame = 0;
  std::string camera;
  double time_s = 0;
  std::uint32_t device_timestamp = 0;
};

//! Reads CAPTURE/timestamps.csv, keeping lines whose frame is below `frame_count` and dropping an
//! incomplete last line. Throws IoError when missing, InvalidInput naming the line when malformed.
std::vector<RecordedTimestamp> read_recorded_timestamps(const std::filesystem::path& capture_dir, int frame_count);

}  // namespace zipfusion
