// LiveRig over cameras that deliver on a real clock: a camera silent for longer than
// `max_wait_s` is left out of the sets meanwhile and rejoins when it delivers again; when every
// camera is silent (the only one, or all of them) the stream waits, and ends only when every
// camera has ended or the rig is cancelled.

#include "zipfusion/live/live_rig.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

namespace zipfusion {
namespace {

using Clock = std::chrono::steady_clock;

// Delivers a frame at each of `times` (seconds after `start`, on the device clock too), as a
// device would: a read before a frame is due waits for it, or times out. Ends after the last
// frame, or when stopped; `end_after_last` false keeps it silent but open instead.
class PacedCamera final : public LiveCamera {
 public:
  PacedCamera(int index, Clock::time_point start, std::vector<double> times, bool end_after_last = true)
      : start_(start), times_(std::move(times)), end_after_last_(end_after_last) {
    model_.name = "cam" + std::to_string(index);
  }
  const CameraModel& model() const override { return model_; }
  std::string description() const override { return "paced " + model_.name; }
  double fps() const override { return 30; }
  ReadStatus read(LiveFrame& frame, double timeout_s) override {
    const Clock::time_point deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout_s));
    if (stopped_ || (end_after_last_ && next_ >= times_.size())) return ReadStatus::kEnded;
    const Clock::time_point due = next_ < times_.size() ? at(times_[next_]) : Clock::time_point::max();
    while (!stopped_ && Clock::now() < std::min(due, deadline)) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    if (stopped_) return ReadStatus::kEnded;
    if (Clock::now() < due) return ReadStatus::kTimeout;
    frame.time_s = times_[next_++];
    frame.device_timestamp = static_cast<std::uint32_t>(next_);
    frame.depth.resize_for_overwrite(4, 4);
    frame.has_color = false;
    return ReadStatus::kFrame;
  }
  void stop() override { stopped_ = true; }
  std::string end_reason() const override { return stopped_ ? "stopped" : "end of the list"; }
  long dropped_frames() const override { return 0; }

 private:
  Clock::time_point at(double s) const { return start_ + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s)); }

  CameraModel model_;
  Clock::time_point start_;
  std::vector<double> times_;
  bool end_after_last_;
  size_t next_ = 0;
  std::atomic<bool> stopped_{false};
};

// Frames k / 30 s for k in [0, frames), without those in [gap_begin, gap_end).
std::vector<double> frame_times(int frames, int gap_begin = 0, int gap_end = 0) {
  std::vector<double> times;
  for (int k = 0; k < frames; ++k) {
    if (k < gap_begin || k >= gap_end) times.push_back(k / 30.0);
  }
  return times;
}

struct Delivered {
  int sets = 0;
  std::vector<int> in_sets;  // per camera: sets holding a frame of it
};

Delivered read_all(LiveRig& rig) {
  Delivered out;
  out.in_sets.assign(rig.camera_count(), 0);
  LiveFrameSet set;
  while (rig.next(set)) {
    EXPECT_EQ(set.index, out.sets);
    ++out.sets;
    for (int c = 0; c < rig.camera_count(); ++c) out.in_sets[c] += set.cameras[c].has_value();
  }
  return out;
}

// The only camera is silent for 0.4 s (12 frames' time), longer than max_wait_s (0.25 s): the
// stream waits it out and every frame comes out as a set. It used to end there, after 5 sets of
// 18, as if the camera had ended.
TEST(LiveRig, TheOnlyCameraSilentForAWhileDoesNotEndTheStream) {
  const Clock::time_point start = Clock::now() + std::chrono::milliseconds(20);
  std::vector<std::unique_ptr<LiveCamera>> cameras;
  cameras.push_back(std::make_unique<PacedCamera>(0, start, frame_times(30, 5, 17)));
  LiveRig rig(std::move(cameras));
  const Delivered delivered = read_all(rig);
  EXPECT_EQ(delivered.sets, 18);
  EXPECT_EQ(rig.stats()[0].grouped, 18);
  EXPECT_TRUE(rig.stats()[0].ended);
}

// Two cameras silent at once, for 0.4 s: the same.
TEST(LiveRig, EveryCameraSilentAtOnceDoesNotEndTheStream) {
  const Clock::time_point start = Clock::now() + std::chrono::milliseconds(20);
  std::vector<std::unique_ptr<LiveCamera>> cameras;
  for (int c = 0; c < 2; ++c) cameras.push_back(std::make_unique<PacedCamera>(c, start, frame_times(30, 5, 17)));
  LiveRig rig(std::move(cameras));
  const Delivered delivered = read_all(rig);
  EXPECT_EQ(delivered.sets, 18);
  EXPECT_EQ(delivered.in_sets, (std::vector<int>{18, 18}));
}

// One camera of two silent for 0.4 s: the sets meanwhile are decided without it (once it has been
// waited for max_wait_s), and it is back in the sets from its next frame.
TEST(LiveRig, ACameraSilentForAWhileIsLeftOutThenRejoins) {
  const Clock::time_point start = Clock::now() + std::chrono::milliseconds(20);
  std::vector<std::unique_ptr<LiveCamera>> cameras;
  cameras.push_back(std::make_unique<PacedCamera>(0, start, frame_times(30)));
  cameras.push_back(std::make_unique<PacedCamera>(1, start, frame_times(30, 5, 17)));
  LiveRig rig(std::move(cameras));
  const Delivered delivered = read_all(rig);
  EXPECT_EQ(delivered.sets, 30);
  EXPECT_EQ(delivered.in_sets, (std::vector<int>{30, 18}));
  EXPECT_EQ(rig.stats()[1].discarded_late, 0);
}

// A camera that stops delivering without ending: the stream waits until it is cancelled, then
// ends within a read slice or two.
TEST(LiveRig, CancelEndsAStreamWhoseCamerasAreSilent) {
  const Clock::time_point start = Clock::now() + std::chrono::milliseconds(20);
  std::atomic<bool> cancel = false;
  std::vector<std::unique_ptr<LiveCamera>> cameras;
  cameras.push_back(std::make_unique<PacedCamera>(0, start, frame_times(3), /*end_after_last=*/false));
  LiveRig rig(std::move(cameras), {.cancel = &cancel});
  Clock::time_point cancelled_at = Clock::time_point::max();
  std::jthread canceller([&] {
    std::this_thread::sleep_until(start + std::chrono::milliseconds(800));
    cancelled_at = Clock::now();
    cancel = true;
  });
  const Delivered delivered = read_all(rig);
  const Clock::time_point ended_at = Clock::now();
  canceller.join();
  EXPECT_EQ(delivered.sets, 3);
  EXPECT_GE(ended_at, cancelled_at);  // it waited for the camera until cancelled
  EXPECT_LT(ended_at - cancelled_at, std::chrono::seconds(2));
  EXPECT_EQ(rig.stats()[0].end_reason, "stopped");
}

}  // namespace
}  // namespace zipfusion
