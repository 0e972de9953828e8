#include "zipfusion/live/live_rig.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "zipfusion/core/error.h"

namespace zipfusion {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

}  // namespace

void LiveRigOptions::validate() const {
  if (!(max_wait_s >= 0 && max_wait_s <= 60)) throw InvalidInput("live.max_wait_s: must be in [0, 60] seconds");
  if (!(read_slice_s > 0 && read_slice_s <= 1)) throw InvalidInput("live.read_slice_s: must be in (0, 1] seconds");
}

LiveRig::LiveRig(std::vector<std::unique_ptr<LiveCamera>> cameras, const LiveRigOptions& options)
    : cameras_(std::move(cameras)), options_(options) {
  options_.validate();
  if (cameras_.empty()) throw InvalidInput("--devices: no camera selected");
  fps_ = cameras_[0]->fps();
  for (const auto& camera : cameras_) {
    if (!(camera->fps() > 0) || std::abs(camera->fps() - fps_) > 0.01 * fps_) {
      throw InvalidInput(camera->description() + ": runs at " + std::to_string(camera->fps()) + " fps, " +
                         cameras_[0]->description() + " at " + std::to_string(fps_) + " fps: a rig's cameras share one frame rate");
    }
  }
  const size_t n = cameras_.size();
  pending_.resize(n);
  pending_times_.resize(n);
  incoming_.resize(n);
  spares_.reserve(n);
  for (size_t c = 0; c < n; ++c) spares_.emplace_back(kSpareFrames);  // each reserves its own (a copy would not)
  views_.resize(n);
  ended_.assign(n, 0);
  given_up_.assign(n, 0);
  waited_s_.assign(n, 0);
  stats_.resize(n);
}

LiveRig::~LiveRig() { stop(); }

void LiveRig::stop() {
  for (const auto& camera : cameras_) camera->stop();
}

std::vector<LiveCameraStats> LiveRig::stats() const {
  std::vector<LiveCameraStats> out = stats_;
  for (size_t c = 0; c < cameras_.size(); ++c) out[c].dropped = cameras_[c]->dropped_frames();
  return out;
}

bool LiveRig::next(LiveFrameSet& set) {
  const int n = camera_count();
  const double period_s = 1.0 / fps_;
  set.cameras.resize(n);
  for (int c = 0; c < n; ++c) {
    if (!set.cameras[c]) continue;
    spares_[c].keep(*set.cameras[c]);
    set.cameras[c].reset();
  }
  auto receive = [&](int c, double timeout_s) {
    LiveFrame& frame = incoming_[c];
    spares_[c].refill(frame);
    const Clock::time_point start = Clock::now();
    const ReadStatus status = cameras_[c]->read(frame, timeout_s);
    if (status == ReadStatus::kFrame) {
      pending_times_[c].push_back(frame.time_s);
      pending_[c].push_back(std::move(frame));
      ++stats_[c].frames;
      waited_s_[c] = 0;
      given_up_[c] = 0;
    } else if (status == ReadStatus::kEnded) {
      ended_[c] = 1;
      stats_[c].ended = true;
      stats_[c].end_reason = cameras_[c]->end_reason();
    } else {
      waited_s_[c] += seconds_since(start);
      if (waited_s_[c] >= options_.max_wait_s) given_up_[c] = 1;
    }
    return status;
  };
  while (true) {
    if (options_.cancel && options_.cancel->load() && !cancelled_) {
      cancelled_ = true;
      stop();
    }
    // Cameras given up on are not waited for, but what they have delivered meanwhile is taken,
    // before each decision: a camera back from a silence then joins the set its first frame
    // belongs to, rather than that set being decided without it.
    for (int c = 0; c < n; ++c) {
      while (given_up_[c] && !ended_[c] && receive(c, 0) == ReadStatus::kFrame) {
      }
    }
    for (int c = 0; c < n; ++c) views_[c] = {.pending_times = pending_times_[c], .open = !ended_[c] && !given_up_[c]};
    next_group(views_, period_s, not_before_s_, step_);
    for (int c = 0; c < n; ++c) {
      const int k = step_.discard[c];
      if (k == 0) continue;
      for (int i = 0; i < k; ++i) spares_[c].keep(pending_[c][i]);
      pending_[c].erase(pending_[c].begin(), pending_[c].begin() + k);
      pending_times_[c].erase(pending_times_[c].begin(), pending_times_[c].begin() + k);
      stats_[c].discarded_late += k;
    }
    if (step_.status == GroupStep::kDone) {
      // Nothing pending, and no camera to wait for: each has ended or was given up on. One given
      // up on has not ended (a hiccup of the only camera, or of every one): its silence is waited
      // out, a slice of a read from each in turn, so that the stream goes on as soon as one
      // delivers again and `cancel` is heard in between.
      int alive = 0;
      for (int c = 0; c < n; ++c) alive += !ended_[c];
      if (alive == 0) return false;
      for (int c = 0; c < n; ++c) {
        if (!ended_[c]) receive(c, options_.read_slice_s / alive);
      }
      continue;
    }
    if (step_.status == GroupStep::kWait) {
      const int c = step_.wait_for;
      receive(c, std::clamp(options_.max_wait_s - waited_s_[c], 0.0, options_.read_slice_s));
      continue;
    }
    set.index = next_index_++;
    set.time_s = step_.time_s;
    set.skew_s = step_.skew_s;
    for (int c = 0; c < n; ++c) {
      waited_s_[c] = 0;
      if (!step_.member[c]) continue;
      set.cameras[c].emplace(std::move(pending_[c].front()));
      pending_[c].erase(pending_[c].begin());
      pending_times_[c].erase(pending_times_[c].begin());
      ++stats_[c].grouped;
    }
    not_before_s_ = step_.time_s + period_s / 2;
    return true;
  }
}

Rig make_live_rig(const LiveRig& live, const Rig* calibration, const std::string& calibration_source) {
  Rig rig;
  rig.fps = live.fps();
  rig.frame_count = 0;
  rig.depth_unit_m = 0.001;
  for (int c = 0; c < live.camera_count(); ++c) rig.cameras.push_back(live.camera(c).model());
  if (!calibration) return rig;
  if (calibration->cameras.size() != rig.cameras.size()) {
    throw InvalidInput(calibration_source + ": cameras: has " + std::to_string(calibration->cameras.size()) + " cameras, but " +
                       std::to_string(rig.cameras.size()) + (rig.cameras.size() == 1 ? " device is" : " devices are") + " selected");
  }
  for (size_t c = 0; c < rig.cameras.size(); ++c) {
    rig.cameras[c].name = calibration->cameras[c].name;
    take_camera_calibration(rig.cameras[c], *calibration, static_cast<int>(c), calibration_source, "the device's");
  }
  rig.volume = calibration->volume;
  rig.poses_trusted = calibration->poses_trusted;
  return rig;
}

bool read_live_frame_set(LiveRig& rig, LiveFrameSet& live, FrameSet& set, const std::vector<std::vector<int>>& depth_undistortion) {
  if (!rig.next(live)) return false;
  set.capture_time_ms = 0;
  set.cameras.resize(live.cameras.size());
  for (size_t c = 0; c < live.cameras.size(); ++c) {
    // The set's images from an earlier frame set go to the live frame, and with it back to the
    // camera; an undistorted image is written into the set's own buffer.
    CameraFrame& camera = set.cameras[c];
    std::optional<LiveFrame>& frame = live.cameras[c];
    camera.unreadable.clear();
    camera.has_depth = frame.has_value();
    camera.has_color = frame && frame->has_color;
    const bool undistorted = c < depth_undistortion.size() && !depth_undistortion[c].empty();
    if (!frame) {
      camera.depth.resize_for_overwrite(0, 0);
    } else if (undistorted) {
      undistort_depth_into(frame->depth, depth_undistortion[c], static_cast<int>(c), camera.depth);
    } else {
      std::swap(camera.depth, frame->depth);
    }
    if (camera.has_color) {
      std::swap(camera.color, frame->color);
    } else {
      camera.color.resize_for_overwrite(0, 0);
    }
  }
  return true;
}

LiveFrameSource live_frame_source(LiveRig& rig, LiveSourceOptions options) {
  struct State {
    bool started = false;
    double first_time_s = 0;
    int delivered = 0;
    LiveFrameSet live;  // the rig's last set; its frames hold the images the pipeline handed back
  };
  auto state = std::make_shared<State>();
  return [&rig, options = std::move(options), state](FrameSet& set, double& decode_ms) {
    const Clock::time_point start = Clock::now();
    if (options.max_frames > 0 && state->delivered >= options.max_frames) {
      rig.stop();
      return false;
    }
    LiveFrameSet& live = state->live;
    if (!read_live_frame_set(rig, live, set, options.depth_undistortion)) return false;
    if (!state->started) {
      state->started = true;
      state->first_time_s = live.time_s;
    }
    if (options.max_seconds > 0 && live.time_s - state->first_time_s >= options.max_seconds) {
      rig.stop();
      return false;
    }
    if (options.observe) options.observe(live);
    set.index = state->delivered++;
    decode_ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    return true;
  };
}

}  // namespace zipfusion
