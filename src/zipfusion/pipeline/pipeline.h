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
#include <functional>
#include <mutex>
#include <optional>
#include <vector>

#include "zipfusion/io/capture.h"
#include "zipfusion/pipeline/reconstruct.h"

namespace zipfusion {

enum class QueuePolicy {
  kBlock,       // push waits for room: nothing is lost (offline)
  kDropOldest,  // push discards the oldest item: the newest is never late (live)
};

//! A bounded multi-producer, multi-consumer queue that can be closed. Its items live in a ring of
//! `capacity` slots made up front, so pushing and popping allocate nothing (a std::deque takes and
//! frees a block every few items as they pass through).
template <typename T>
class BoundedQueue {
 public:
  BoundedQueue(int capacity, QueuePolicy policy) : slots_(capacity < 1 ? 1 : capacity), policy_(policy) {}

  //! Adds an item; false when the queue was closed (the item is dropped). The oldest item, where
  //! kDropOldest discards one, goes to `displaced` when given (for its buffers to be reused).
  bool push(T item, std::optional<T>* displaced = nullptr) {
    std::unique_lock lock(mutex_);
    if (policy_ == QueuePolicy::kBlock) not_full_.wait(lock, [&] { return closed_ || count_ < capacity(); });
    if (closed_) return false;
    if (count_ >= capacity()) {  // kDropOldest
      std::optional<T> oldest = take_oldest();
      if (displaced != nullptr) *displaced = std::move(oldest);
      ++dropped_;
    }
    slots_[(head_ + count_) % capacity()].emplace(std::move(item));
    ++count_;
    not_empty_.notify_one();
    return true;
  }

  //! The oldest item; empty once the queue is closed and drained.
  std::optional<T> pop() {
    std::unique_lock lock(mutex_);
    not_empty_.wait(lock, [&] { return closed_ || count_ > 0; });
    if (count_ == 0) return std::nullopt;
    std::optional<T> item = take_oldest();
    not_full_.notify_all();  // a producer waiting for room, and one waiting for the queue to empty
    return item;
  }

  //! Waits until the queue is empty; false when it was closed.
  bool wait_until_empty() {
    std::unique_lock lock(mutex_);
    not_full_.wait(lock, [&] { return closed_ || count_ == 0; });
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
  int capacity() const { return static_cast<int>(slots_.size()); }

  // Moves the oldest item out of its slot and frees the slot. Precondition: locked, count_ > 0.
  std::optional<T> take_oldest() {
    std::optional<T> item = std::move(slots_[head_]);
    slots_[head_].reset();
    head_ = (head_ + 1) % capacity();
    --count_;
    return item;
  }

  std::vector<std::optional<T>> slots_;
  int head_ = 0;   // the oldest item's slot
  int count_ = 0;  // items in the queue
  const QueuePolicy policy_;
  mutable std::mutex mutex_;
  std::condition_variable not_empty_, not_full_;
  bool closed_ = false;
  long dropped_ = 0;
};

//! Where frame sets come from: fills `set` with the next one and returns true, or returns false at
//! the end of the stream. `set` holds an earlier frame set (or none): a source reuses its buffers,
//! and sets every field (index, capture time, each camera's images and flags). `decode_ms`
//! receives the time spent decoding it.
using FrameSource = std::function<bool(FrameSet& set, double& decode_ms)>;

//! A source over frames [begin, end) of a capture (a FrameSetReader): each frame set's cameras
//! decode in parallel into the buffers of the set handed in, so in the pipeline, which hands back
//! the sets it is done with, decoding allocates nothing in steady state.
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
//! it moves it out. Each frame set, once reconstructed (or skipped), goes back to the source
//! thread, which hands it to the source to fill again: at most queue_depth + 2 frame sets exist
//! at once, and in steady state none is allocated. An exception in any stage stops the
//! pipeline and is rethrown here (the first one).
PipelineStats run_pipeline(const FrameSource& source, FrameReconstructor& reconstructor, const std::function<void(PipelineFrame&)>& sink,
                           const PipelineOptions& options = {});

}  // namespace zipfusion
