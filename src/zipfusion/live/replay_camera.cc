#include "zipfusion/live/replay_camera.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>

#include "zipfusion/core/error.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/live/kinect_clock.h"
#include "zipfusion/live/kinect_disparity.h"

namespace zipfusion {

ReplayTimeline replay_timeline(const std::vector<std::filesystem::path>& dumps, double fps) {
  double first = std::numeric_limits<double>::infinity(), last = -std::numeric_limits<double>::infinity();
  for (const std::filesystem::path& dump : dumps) {
    for (const FakenectIndexEntry& entry : read_fakenect_index(dump)) {
      first = std::min(first, entry.time_s);
      last = std::max(last, entry.time_s);
    }
  }
  if (!(first <= last)) return ReplayTimeline{.first_s = 0, .period_s = 1.0 / fps};  // no entries: nothing to play
  return ReplayTimeline{.first_s = first, .period_s = last - first + 1.0 / fps};
}

void ReplayOptions::validate() const {
  if (!(fps >= 0.001 && fps <= 1000)) throw InvalidInput("replay.fps: must be in [0.001, 1000]");  // rig.json's range
  if (!(max_color_age_s >= 0 && max_color_age_s < 10)) throw InvalidInput("replay.max_color_age_s: must be in [0, 10) seconds");
  // A pass of a year is no recording's; the bound keeps the shifted times and ticks finite.
  if ((loop || paced) && !(timeline.period_s > 0 && timeline.period_s < 3.2e7)) {
    throw InvalidInput("replay.timeline.period_s: must be in (0, 3.2e7) seconds");
  }
  if (paced && !timeline.start) throw InvalidInput("replay.timeline.start: required when paced");
}

ReplayCamera::ReplayCamera(const std::filesystem::path& dir, const std::string& name, const ReplayOptions& options)
    : dir_(dir), options_(options), model_(kinect_v1_default_model(name)), entries_(read_fakenect_index(dir)) {
  options_.validate();
  for (const FakenectIndexEntry& entry : entries_) paths_.push_back((dir_ / entry.file).string());
  pass_ticks_ = static_cast<std::uint32_t>(std::llround(std::fmod(options_.timeline.period_s * kKinectClockHz, 4294967296.0)));
}

std::string ReplayCamera::end_reason() const {
  std::lock_guard lock(mutex_);
  return end_reason_;
}

ReadStatus ReplayCamera::end(const std::string& reason) {
  std::lock_guard lock(mutex_);
  if (end_reason_.empty()) end_reason_ = reason;
  ended_ = true;
  return ReadStatus::kEnded;
}

std::chrono::steady_clock::time_point ReplayStart::at() {
  std::lock_guard lock(mutex_);
  if (!at_) at_ = std::chrono::steady_clock::now();
  return *at_;
}

std::chrono::steady_clock::time_point ReplayCamera::due(double time_s) const {
  using namespace std::chrono;
  return options_.timeline.start->at() + duration_cast<steady_clock::duration>(duration<double>(time_s - options_.timeline.first_s));
}

ReadStatus ReplayCamera::read(LiveFrame& frame, double timeout_s) {
  if (!options_.paced) return read_next(frame);
  using namespace std::chrono;
  const auto deadline = steady_clock::now() + duration_cast<steady_clock::duration>(duration<double>(std::max(0.0, timeout_s)));
  if (!has_pending_) {
    const ReadStatus status = read_next(pending_);
    if (status != ReadStatus::kFrame) return status;
    has_pending_ = true;
  }
  // Waits for the frame's time, or the timeout, in short sleeps, so that stop() is heard within one.
  constexpr auto kLongestSleep = milliseconds(20);
  const auto frame_due = due(pending_.time_s);
  const auto until = std::min(frame_due, deadline);
  while (true) {
    if (stopped_) break;  // the frame already read is delivered, as a device's queued frames are
    const auto now = steady_clock::now();
    if (now >= until) break;
    std::this_thread::sleep_for(std::min<steady_clock::duration>(until - now, kLongestSleep));
  }
  if (!stopped_ && steady_clock::now() < frame_due) return ReadStatus::kTimeout;
  std::swap(frame, pending_);
  has_pending_ = false;
  return ReadStatus::kFrame;
}

ReadStatus ReplayCamera::read_next(LiveFrame& frame) {
  while (true) {
    if (ended_) return ReadStatus::kEnded;
    if (stopped_) return end("stopped");
    if (next_ >= entries_.size()) {
      if (!options_.loop || depth_this_pass_ == 0) return end("end of the recording (" + std::to_string(entries_.size()) + " files in INDEX.txt)");
      next_ = 0;
      ++pass_;
      depth_this_pass_ = 0;
      has_color_ = false;  // the last pass's last colour is no colour of this pass's first depth
    }
    const std::string& file = paths_[next_];
    const FakenectIndexEntry& entry = entries_[next_++];
    if (entry.type != 'd' && entry.type != 'r') continue;
    // This pass's times: the recording's, shifted by the passes before (the device clock wraps).
    const double time_s = entry.time_s + pass_ * options_.timeline.period_s;
    const std::uint32_t timestamp = entry.timestamp + static_cast<std::uint32_t>(pass_) * pass_ticks_;
    try {
      // Into kept buffers, and the frame's own images: a replay read by a rig that hands its
      // frames back allocates nothing per frame.
      read_file_bytes(file, bytes_);
      if (entry.type == 'r') {
        decode_fakenect_rgb(bytes_, file, color_);
        color_timestamp_ = timestamp;
        has_color_ = true;
        continue;
      }
      decode_fakenect_depth(bytes_, file, raw_);
      frame.time_s = time_s;
      frame.device_timestamp = timestamp;
      frame.depth.resize_for_overwrite(raw_.width, raw_.height);
      kinect_raw_frame_to_mm(static_cast<int>(raw_.size()), raw_.data.data(), frame.depth.data.data());
      frame.has_color = has_color_ && kinect_color_pairs_with_depth(color_timestamp_, timestamp, options_.max_color_age_s);
      if (frame.has_color) frame.color = color_;
      ++depth_this_pass_;
      return ReadStatus::kFrame;
    } catch (const std::exception& e) {
      return end(std::string(e.what()) + ": the recording ends here");
    }
  }
}

}  // namespace zipfusion
