#include "zipfusion/live/live_frame_queue.h"

#include <algorithm>
#include <utility>

#include "zipfusion/core/error.h"

namespace zipfusion {

void SpareLiveFrames::keep(LiveFrame& frame) {
  if (frame.holds_images() && frames_.size() < frames_.capacity()) frames_.push_back(std::move(frame));
  frame = LiveFrame{};
}

void SpareLiveFrames::refill(LiveFrame& frame) {
  if (frame.holds_images() || frames_.empty()) return;
  frame = std::move(frames_.back());
  frames_.pop_back();
}

// A steady stream needs one or two spares: the reader hands back a frame's images for each it
// takes. A backlog's worth (60 frames, 90 MB at 640×480) is not kept.
LiveFrameQueue::LiveFrameQueue(int capacity) : spares_(static_cast<size_t>(std::clamp(capacity, 0, kMostSpares))) {
  if (capacity < 1) throw InvalidInput("live frame queue: capacity must be at least 1");
  ring_.resize(capacity);
}

bool LiveFrameQueue::push(LiveFrame& frame) {
  const int capacity = this->capacity();
  bool dropped = false;
  if (size_ == capacity) {
    spares_.keep(ring_[head_]);
    head_ = (head_ + 1) % capacity;
    --size_;
    dropped = true;
  }
  std::swap(ring_[(head_ + size_) % capacity], frame);  // a slot outside the queue holds nothing
  ++size_;
  spares_.refill(frame);
  return dropped;
}

void LiveFrameQueue::refill(LiveFrame& frame) { spares_.refill(frame); }

bool LiveFrameQueue::pop(LiveFrame& frame) {
  if (size_ == 0) return false;
  std::swap(ring_[head_], frame);
  spares_.keep(ring_[head_]);
  head_ = (head_ + 1) % capacity();
  --size_;
  return true;
}

}  // namespace zipfusion
