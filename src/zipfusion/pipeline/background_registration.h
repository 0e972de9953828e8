#pragma once
//! \file
//! Registration in a background thread (paper Section III-A): the frame pipeline offers every
//! frame set; every `every_frames` frames, when the worker is idle, a copy of that frame set (depth
//! and colour) joins a window of the last `window_frames` handed over and the worker refines all poses
//! by GPA-ICP (starting from the poses it last published) while reconstruction goes on. New poses
//! are published by swapping one pointer; the pipeline picks them up between frames.
//!
//! Thread safety: offer() and latest_poses() may be called from one pipeline thread while the
//! worker runs; neither waits for a refinement (the only lock guards a pointer swap and a copy
//! hand-over, and offer() takes it only when the worker is idle). The destructor stops the worker
//! (waiting for a refinement in progress to end).

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "zipfusion/io/capture.h"
#include "zipfusion/io/rig.h"
#include "zipfusion/registration/gpa_icp.h"

namespace zipfusion {

struct BackgroundRegistrationOptions {
  int every_frames = 30;    // frames between two hand-overs (one second at 30 fps)
  int window_frames = 4;    // frame sets handed over, refined together (the subject has moved between them)
  RegistrationOptions registration{.finest_level = 2, .num_threads = 1};  // 3→2 levels: ~40 ms per frame set, one core
  // A refinement on fewer frame sets than the poses have been refined on (the most of
  // `start_frame_sets` and every published window) is published only where it lowers the residual
  // by at least this share: at poses `--register once` had refined, a window of one frame set slid
  // cameras 10–40 mm while its residual moved by under 1 % (docs/design.md). In [0, 1).
  double min_improvement = 0.05;
  // The frame sets the starting poses were refined on, counted at the worker's finest level (four
  // per set for each level finer); 0 for poses as given.
  double start_frame_sets = 0;

  void validate() const;  // throws InvalidInput naming the field
};

//! Poses published by the worker, with a counter that grows with each refinement.
struct PublishedPoses {
  int version = 0;                      // 0: the initial poses
  int frame = -1;                       // newest frame the refinement used
  std::vector<Rigid3d> world_from_depth;
  RegistrationResult result;            // the refinement that produced them (empty for version 0)
};

class BackgroundRegistration {
 public:
  //! Throws InvalidInput when the options are invalid. Starts the worker thread.
  BackgroundRegistration(const Rig& rig, const BackgroundRegistrationOptions& options);
  ~BackgroundRegistration();
  BackgroundRegistration(const BackgroundRegistration&) = delete;
  BackgroundRegistration& operator=(const BackgroundRegistration&) = delete;

  //! Offers the newest frame set; copies it when a hand-over is due and the worker is idle,
  //! otherwise returns at once.
  void offer(const FrameSet& frames);

  //! The newest published poses (never null).
  std::shared_ptr<const PublishedPoses> latest_poses() const;

  //! Blocks until the worker has finished everything handed over so far (tests, end of a run).
  void wait_idle();

 private:
  void run();

  Rig rig_;
  BackgroundRegistrationOptions options_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable idle_;
  std::shared_ptr<const PublishedPoses> published_;
  std::vector<FrameSet> window_;    // guarded by mutex_; the worker copies it out
  std::vector<FrameSet> refining_;  // the worker's copy (worker thread only)
  // Written under mutex_; offer() reads them before taking it.
  std::atomic<bool> pending_ = false;  // a hand-over waits for the worker
  std::atomic<bool> busy_ = false;     // the worker is refining
  bool stop_ = false;
  int offered_ = 0;               // frames offered so far (pipeline thread only)
  double published_frame_sets_ = 0;  // what the published poses were refined on (worker thread only)
  std::jthread worker_;
};

}  // namespace zipfusion
