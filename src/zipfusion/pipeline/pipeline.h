#pragma once
//! \file
//! The frame pipeline: a source thread decodes frame sets, the calling thread reconstructs them
//! (each stage over all cameras in parallel), a sink thread consumes the meshes (writes them,
//! or compresses and streams them: serve). Stages are joined by bounded queues, so a slow sink holds back the
//! reconstruction and a slow reconstruction holds back decoding, with memory bounded by the
//! queue depth.
//!
//! Offline (a capture on disk) every frame is processed: a full queue makes its producer wait.
//! Live (a device that will not wait) the source queue drops its oldest frame set instead, so the
//! pipeline shows the newest frames and never falls behind; the drops are counted in the stats.
//! A stream (`take_when_sink_ready`) also takes its next frame set only once the sink has taken
//! the previous mesh: a mesh waiting for a busy sink (compression) only ages, and the frame set
//! taken after it would age with it.
//!
//! Thread safety: run_pipeline() owns its threads and joins them before it returns; the source is
//! called from one thread, the sink from another, which also hands each mesh back to the
//! reconstructor (FrameReconstructor::recycle) while it reconstructs the next.

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>

#include "zipfusion/io/capture.h"
#include "zipfusion/pipeline/reconstruct.h"

namespace zipfusion {

enum class QueuePolicy {
  kBlock,       // push waits for room: nothing is lost (offline)
  kDropOldest,  // push discards the oldest item: the newest is never late (live)
};

//! A bounded multi-producer, multi-consumer queue that can be closed.
template <typename T>
class BoundedQueue {
 public:
  BoundedQueue(int capacity, QueuePolicy policy) : capacity_(capacity < 1 ? 1 : capacity), policy_(policy) {}

  //! Adds an item; false when the queue was closed (the item is dropped).
  bool push(T item) {
    std::unique_lock lock(mutex_);
    if (policy_ == QueuePolicy::kBlock) not_full_.wait(lock, [&] { return closed_ || static_cast<int>(items_.size()) < capacity_; });
    if (closed_) return false;
    if (static_cast<int>(items_.size()) >= capacity_) {  // kDropOldest
      items_.pop_front();
      ++dropped_;
    }
    items_.push_back(std::move(item));
    not_empty_.notify_one();
    return true;
  }

  //! The oldest item; empty once the queue is closed and drained.
  std::optional<T> pop() {
    std::unique_lock lock(mutex_);
    not_empty_.wait(lock, [&] { return closed_ || !items_.empty(); });
    if (items_.empty()) return std::nullopt;
    T item = std::move(items_.front());
    items_.pop_front();
    not_full_.notify_all();  // a producer waiting for room, and one waiting for the queue to empty
    return item;
  }

  //! Waits until the queue is empty; false when it was closed.
  bool wait_until_empty() {
    std::unique_lock lock(mutex_);
    not_full_.wait(lock, [&] { return closed_ || items_.empty(); });
    return !closed_;
  }

  //! No more pushes; pop() returns what is left, then nothing.
  void close() {
    std::lock_guard lock(mutex_);
    closed_ = true;
    not_empty_.notify_all();
    not_full_.notify_all();
  }

  long dropped() const {
    std::lock_guard lock(mutex_);
    return dropped_;
  }

 private:
  const int capacity_;
  const QueuePolicy policy_;
  mutable std::mutex mutex_;
  std::condition_variable not_empty_, not_full_;
  std::deque<T> items_;
  bool closed_ = false;
  long dropped_ = 0;
};

//! Where frame sets come from: returns the next one, or nothing at the end of the stream.
//! `decode_ms` receives the time spent decoding it.
using FrameSource = std::function<std::optional<FrameSet>(double& decode_ms)>;

//! A source over frames [begin, end) of a capture; each frame set's cameras decode in parallel.
FrameSource capture_source(const Capture& capture, int begin, int end);

//! One reconstructed frame set, as the sink sees it.
struct PipelineFrame {
  int index = 0;
  long sequence = 0;           // frame sets the reconstruction took before this one, made or unwanted
  double capture_time_ms = 0;  // the frame set's, carried through
  double decode_ms = 0;
  FrameResult result;
};

struct PipelineOptions {
  int queue_depth = 2;  // frame sets waiting between two stages
  QueuePolicy source_policy = QueuePolicy::kBlock;
  //! Called on the reconstruction thread for each frame set taken, made or not (e.g. to swap in
  //! poses refined by BackgroundRegistration and offer it the frame set); empty = nothing. Must
  //! not block.
  std::function<void(const FrameSet&, FrameReconstructor&)> before_reconstruct;
  //! Called on the reconstruction thread for each frame set taken, after before_reconstruct:
  //! false skips it, unmade (a stream nobody can be sent a frame now); true commits its mesh to
  //! the sink. Empty = every frame set is wanted. Must not block.
  std::function<bool()> wants_frame;
  //! Take the next frame set only once the sink has taken the previous mesh (a live stream:
  //! latency before throughput; a writer keeps the queue's slack for its stalls).
  bool take_when_sink_ready = false;
};

struct PipelineStats {
  int frames = 0;          // frame sets reconstructed and handed to the sink
  long dropped = 0;        // frame sets the source queue discarded (live only)
  long unwanted = 0;       // frame sets skipped because the sink wanted none (wants_frame)
  double wall_ms = 0;      // first decode to last sink call
};

//! Runs source → reconstructor → sink until the source ends. After the sink returns, the frame's
//! mesh goes back to the reconstructor for reuse (FrameReconstructor::recycle): a sink that keeps
//! it moves it out. An exception in any stage stops the
//! pipeline and is rethrown here (the first one).
PipelineStats run_pipeline(const FrameSource& source, FrameReconstructor& reconstructor, const std::function<void(PipelineFrame&)>& sink,
                           const PipelineOptions& options = {});

}  // namespace zipfusion
