#include "zipfusion/pipeline/pipeline.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <memory>
#include <thread>

#include "zipfusion/core/stopwatch.h"

namespace zipfusion {
namespace {

using Clock = std::chrono::steady_clock;

struct DecodedFrame {
  FrameSet frames;
  double decode_ms = 0;
};

// The first exception of any stage; later ones are consequences (closed queues) and dropped.
class FirstError {
 public:
  void set(std::exception_ptr error) {
    std::lock_guard lock(mutex_);
    if (!error_) error_ = error;
  }
  void rethrow() const {
    if (error_) std::rethrow_exception(error_);
  }

 private:
  std::mutex mutex_;
  std::exception_ptr error_;
};

// Frame sets the reconstruction is done with (or the live queue dropped), for the source to fill
// again. Never more than the pipeline holds at once (a set being filled, the queue's, the one being
// reconstructed), so the list never grows past what it reserved.
class SpareFrameSets {
 public:
  explicit SpareFrameSets(int most) : most_(static_cast<size_t>(most)) { spares_.reserve(most_); }

  // A spare, or a new empty set when there is none (the first frame sets).
  FrameSet take() {
    std::lock_guard lock(mutex_);
    if (spares_.empty()) return {};
    FrameSet set = std::move(spares_.back());
    spares_.pop_back();
    return set;
  }

  void give(FrameSet&& set) {
    std::lock_guard lock(mutex_);
    if (spares_.size() < most_) spares_.push_back(std::move(set));
  }

 private:
  const size_t most_;
  std::mutex mutex_;
  std::vector<FrameSet> spares_;
};

}  // namespace

FrameSource capture_source(const Capture& capture, int begin, int end) {
  struct State {
    FrameSetReader reader;
    int next;
  };
  auto state = std::make_shared<State>(State{FrameSetReader(capture), begin});
  return [state, end](FrameSet& set, double& decode_ms) {
    if (state->next >= end) return false;
    const Clock::time_point start = Clock::now();
    state->reader.read(state->next++, set);
    decode_ms = ms_since(start);
    return true;
  };
}

PipelineStats run_pipeline(const FrameSource& source, FrameReconstructor& reconstructor, const std::function<void(PipelineFrame&)>& sink,
                           const PipelineOptions& options) {
  BoundedQueue<DecodedFrame> decoded(options.queue_depth, options.source_policy);
  BoundedQueue<PipelineFrame> reconstructed(options.queue_depth, QueuePolicy::kBlock);
  SpareFrameSets spares(std::max(options.queue_depth, 1) + 2);
  FirstError error;
  PipelineStats stats;
  const Clock::time_point start = Clock::now();

  std::jthread source_thread([&] {
    try {
      while (true) {
        DecodedFrame item;
        item.frames = spares.take();
        if (!source(item.frames, item.decode_ms)) break;
        std::optional<DecodedFrame> dropped;
        if (!decoded.push(std::move(item), &dropped)) break;  // closed: a later stage failed
        if (dropped) spares.give(std::move(dropped->frames));
      }
    } catch (...) {
      error.set(std::current_exception());
      reconstructed.close();
    }
    decoded.close();
  });
  // Should starting the sink thread fail, the queues are closed before the source thread is
  // joined, so it cannot stay blocked on a full queue.
  struct CloseQueues {
    BoundedQueue<DecodedFrame>& decoded;
    BoundedQueue<PipelineFrame>& reconstructed;
    ~CloseQueues() {
      decoded.close();
      reconstructed.close();
    }
  } close_queues{decoded, reconstructed};
  std::jthread sink_thread([&] {
    try {
      while (std::optional<PipelineFrame> frame = reconstructed.pop()) {
        sink(*frame);
        reconstructor.recycle(std::move(frame->result.mesh));
      }
    } catch (...) {
      error.set(std::current_exception());
      decoded.close();  // unblocks the source; the reconstruction loop sees the closed queue
      reconstructed.close();
    }
  });

  long taken = 0;
  try {
    while (true) {
      if (options.take_when_sink_ready && !reconstructed.wait_until_empty()) break;
      std::optional<DecodedFrame> item = decoded.pop();
      if (!item) break;
      const long sequence = taken++;
      if (options.before_reconstruct) options.before_reconstruct(item->frames, reconstructor);
      if (options.wants_frame && !options.wants_frame()) {
        ++stats.unwanted;
        spares.give(std::move(item->frames));
        continue;
      }
      PipelineFrame frame{.index = item->frames.index,
                          .sequence = sequence,
                          .capture_time_ms = item->frames.capture_time_ms,
                          .decode_ms = item->decode_ms,
                          .result = reconstructor.reconstruct(item->frames)};
      spares.give(std::move(item->frames));
      if (!reconstructed.push(std::move(frame))) break;
      ++stats.frames;
    }
  } catch (...) {
    error.set(std::current_exception());
    decoded.close();
  }
  reconstructed.close();
  source_thread.join();
  sink_thread.join();
  stats.dropped = decoded.dropped();
  stats.wall_ms = ms_since(start);
  error.rethrow();
  return stats;
}

}  // namespace zipfusion
