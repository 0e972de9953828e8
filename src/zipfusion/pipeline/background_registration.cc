#include "zipfusion/pipeline/background_registration.h"

#include <algorithm>

#include "zipfusion/core/error.h"

namespace zipfusion {

void BackgroundRegistrationOptions::validate() const {
  if (every_frames < 1) throw InvalidInput("--register-every: must be at least 1 frame");
  if (window_frames < 1 || window_frames > 64) throw InvalidInput("--register-window: must be in [1, 64] frames");
  if (!(min_improvement >= 0 && min_improvement < 1)) throw InvalidInput("--register-min-improvement: must be in [0, 1)");
  if (!(start_frame_sets >= 0)) throw InvalidInput("BackgroundRegistrationOptions::start_frame_sets: must be >= 0");
  registration.validate();
}

BackgroundRegistration::BackgroundRegistration(const Rig& rig, const BackgroundRegistrationOptions& options) : rig_(rig), options_(options) {
  options_.validate();
  published_frame_sets_ = options_.start_frame_sets;
  window_.reserve(options_.window_frames);
  auto initial = std::make_shared<PublishedPoses>();
  initial->world_from_depth = world_from_depth_poses(rig);
  published_ = std::move(initial);
  worker_ = std::jthread([this] { run(); });
}

BackgroundRegistration::~BackgroundRegistration() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
}

void BackgroundRegistration::offer(const FrameSet& frames) {
  const bool due = offered_++ % options_.every_frames == 0;
  // The worker still at it: skip, never wait. Read before locking, so that the lock is taken
  // only while the worker is idle, when it holds the lock for moments (checking its wait). A lock
  // that was merely tried failed where the worker held it for such a moment, and dropped the
  // hand-over of an idle worker (the first one, as the worker started: under ThreadSanitizer's
  // slower threads every time).
  if (!due || busy_ || pending_) return;
  std::unique_lock lock(mutex_);
  if (busy_ || pending_) return;  // between the worker's two writes as it took a hand-over
  if (static_cast<int>(window_.size()) < options_.window_frames) {
    window_.push_back(frames);
  } else {
    // The oldest goes to the back and takes the copy into its own images: once the window is
    // full, a hand-over allocates nothing on the pipeline's thread.
    std::rotate(window_.begin(), window_.begin() + 1, window_.end());
    window_.back() = frames;
  }
  pending_ = true;
  lock.unlock();
  wake_.notify_one();
}

std::shared_ptr<const PublishedPoses> BackgroundRegistration::latest_poses() const {
  std::lock_guard lock(mutex_);
  return published_;
}

void BackgroundRegistration::wait_idle() {
  std::unique_lock lock(mutex_);
  idle_.wait(lock, [this] { return !pending_ && !busy_; });
}

void BackgroundRegistration::run() {
  for (;;) {
    std::vector<FrameSet>& window = refining_;  // copied into the images of the window before
    std::shared_ptr<const PublishedPoses> start;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return stop_ || pending_; });
      if (stop_) return;
      window = window_;
      start = published_;
      pending_ = false;
      busy_ = true;
    }
    Rig rig = rig_;
    for (size_t c = 0; c < rig.cameras.size(); ++c) rig.cameras[c].world_from_depth = start->world_from_depth[c];
    std::shared_ptr<PublishedPoses> next;
    try {
      std::vector<std::vector<Image<float>>> depth;
      for (const FrameSet& set : window) depth.push_back(registration_depth(rig, set, options_.registration));
      RegistrationOptions registration = options_.registration;
      registration.measure_fixed = false;  // what is published is decided by the residuals below
      RegistrationResult result = register_rig(rig, depth, registration);
      // Published where the surfaces agree at least as well as before where both poses gave
      // correspondences, and every camera that had some still has: a window where the cameras
      // barely overlap must not move a good calibration. A window of fewer frame sets than the
      // poses have been refined on (the most of any refinement so far) must lower the residual
      // clearly (min_improvement): at poses already right the residual is the sensor's noise,
      // and a refinement that barely lowers it has slid the cameras along what its few frames
      // leave loose. A camera whose depth met nowhere before and now meets counts as a gain, where
      // the others' residual did not rise.
      double before = 0, after = 0;
      bool lost = false, matched = false, gained = false;
      for (size_t c = 0; c < result.rmse_after_m.size(); ++c) {
        lost = lost || (result.correspondences_before[c] > 0 && result.correspondences_after[c] == 0);
        gained = gained || (result.correspondences_before[c] == 0 && result.correspondences_after[c] > 0);
        matched = matched || result.correspondences_after[c] > 0;
        if (result.correspondences_before[c] == 0 || result.correspondences_after[c] == 0) continue;
        before += result.rmse_before_m[c];
        after += result.rmse_after_m[c];
      }
      const bool as_much_evidence = static_cast<double>(window.size()) >= published_frame_sets_;
      const bool compared = before > 0;  // some camera had correspondences at both poses
      const bool improved = compared && after <= (as_much_evidence ? 1.0 : 1 - options_.min_improvement) * before;
      if ((improved || (gained && (!compared || after <= before))) && !lost && matched) {
        // The bar is not lowered: a bump followed by a still rig must not go back to chasing noise.
        published_frame_sets_ = std::max(published_frame_sets_, static_cast<double>(window.size()));
        next = std::make_shared<PublishedPoses>();
        next->world_from_depth = result.world_from_depth;
        next->result = std::move(result);
        next->version = start->version + 1;
        next->frame = window.back().index;
      }
    } catch (const std::exception&) {
      // Keep the poses we have; the pipeline goes on with them.
    }
    {
      std::lock_guard lock(mutex_);
      if (next) published_ = std::move(next);
      busy_ = false;
    }
    idle_.notify_all();
  }
}

}  // namespace zipfusion
