#include "zipfusion/live/replay_camera.h"

#include "zipfusion/core/error.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/live/kinect_clock.h"
#include "zipfusion/live/kinect_disparity.h"

namespace zipfusion {

void ReplayOptions::validate() const {
  if (!(fps > 0 && fps <= 1000)) throw InvalidInput("replay.fps: must be in (0, 1000]");
  if (!(max_color_age_s >= 0 && max_color_age_s < 10)) throw InvalidInput("replay.max_color_age_s: must be in [0, 10) seconds");
}

ReplayCamera::ReplayCamera(const std::filesystem::path& dir, const std::string& name, const ReplayOptions& options)
    : dir_(dir), options_(options), model_(kinect_v1_default_model(name)), entries_(read_fakenect_index(dir)) {
  options_.validate();
}

std::string ReplayCamera::end_reason() const {
  std::lock_guard lock(mutex_);
  return end_reason_;
}

ReadStatus ReplayCamera::read(LiveFrame& frame, double /*timeout_s: reading never waits*/) {
  auto end = [&](const std::string& reason) {
    std::lock_guard lock(mutex_);
    if (end_reason_.empty()) end_reason_ = reason;
    next_ = entries_.size();
    return ReadStatus::kEnded;
  };
  while (true) {
    if (stopped_) return end("stopped");
    if (next_ >= entries_.size()) return end("end of the recording (" + std::to_string(entries_.size()) + " files in INDEX.txt)");
    const FakenectIndexEntry& entry = entries_[next_++];
    if (entry.type != 'd' && entry.type != 'r') continue;
    const std::filesystem::path file = dir_ / entry.file;
    try {
      const std::vector<std::uint8_t> bytes = read_file_bytes(file);
      if (entry.type == 'r') {
        color_ = decode_fakenect_rgb(bytes, file.string());
        color_timestamp_ = entry.timestamp;
        has_color_ = true;
        continue;
      }
      const RawDepthImage raw = decode_fakenect_depth(bytes, file.string());
      frame.time_s = entry.time_s;
      frame.device_timestamp = entry.timestamp;
      frame.depth.resize(raw.width, raw.height);
      kinect_raw_frame_to_mm(static_cast<int>(raw.size()), raw.data.data(), frame.depth.data.data());
      frame.has_color = has_color_ && kinect_color_pairs_with_depth(color_timestamp_, entry.timestamp, options_.max_color_age_s);
      if (frame.has_color) frame.color = color_;
      return ReadStatus::kFrame;
    } catch (const std::exception& e) {
      return end(std::string(e.what()) + ": the recording ends here");
    }
  }
}

}  // namespace zipfusion
