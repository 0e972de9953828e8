#include "zipfusion/pipeline/pipeline.h"

#include <chrono>
#include <exception>
#include <memory>
#include <thread>

#include "zipfusion/core/parallel.h"
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

}  // namespace

FrameSource capture_source(const Capture& capture, int begin, int end) {
  auto next = std::make_shared<int>(begin);
  return [&capture, next, end](double& decode_ms) -> std::optional<FrameSet> {
    if (*next >= end) return std::nullopt;
    const Clock::time_point start = Clock::now();
    FrameSet set;
    set.index = (*next)++;
    set.cameras.resize(capture.camera_count());
    parallel_for(0, capture.camera_count(), [&](int c) { set.cameras[c] = capture.load_camera_frame(set.index, c); });
    decode_ms = ms_since(start);
    return set;
  };
}

PipelineStats run_pipeline(const FrameSource& source, FrameReconstructor& reconstructor, const std::function<void(PipelineFrame&)>& sink,
                           const PipelineOptions& options) {
  BoundedQueue<DecodedFrame> decoded(options.queue_depth, options.source_policy);
  BoundedQueue<PipelineFrame> reconstructed(options.queue_depth, QueuePolicy::kBlock);
  FirstError error;
  PipelineStats stats;
  const Clock::time_point start = Clock::now();

  std::jthread source_thread([&] {
    try {
      while (true) {
        DecodedFrame item;
        std::optional<FrameSet> frames = source(item.decode_ms);
        if (!frames) break;
        item.frames = std::move(*frames);
        if (!decoded.push(std::move(item))) break;  // closed: a later stage failed
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
        continue;
      }
      PipelineFrame frame{.index = item->frames.index,
                          .sequence = sequence,
                          .capture_time_ms = item->frames.capture_time_ms,
                          .decode_ms = item->decode_ms,
                          .result = reconstructor.reconstruct(item->frames)};
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
