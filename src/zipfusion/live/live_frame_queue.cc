#include "zipfusion/live/live_frame_queue.h"

#include <algorithm>
#include <utility>

#include "zipfusion/core/error.h"

namespace zipfusion {

LiveFrameQueue::LiveFrameQueue(int capacity) {
  if (capacity < 1) throw InvalidInput("live frame queue: capacity must be at least 1");
  ring_.resize(capacity);
  // A steady stream needs one or two: the reader hands back a frame's images for each it takes.
  // After a stall the reader hands back a backlog's worth; kept, they would hold a stall's memory
  // for the rest of the run (60 frames, 90 MB at 640×480).
  spares_.reserve(static_cast<size_t>(std::min(capacity, kMostSpares)));
}

void LiveFrameQueue::keep(LiveFrame& frame) {
  if (frame.holds_images() && spares_.size() < spares_.capacity()) spares_.push_back(std::move(frame));
  frame = LiveFrame{};
}

bool LiveFrameQueue::push(LiveFrame& frame) {
  const int capacity = this->capacity();
  bool dropped = false;
  if (size_ == capacity) {
    keep(ring_[head_]);
    head_ = (head_ + 1) % capacity;
    --size_;
    dropped = true;
  }
  std::swap(ring_[(head_ + size_) % capacity], frame);  // a slot outside the queue holds nothing
  ++size_;
  if (!spares_.empty()) {
    frame = std::move(spares_.back());
    spares_.pop_back();
  }
  return dropped;
}

void LiveFrameQueue::refill(LiveFrame& frame) {
  if (frame.holds_images() || spares_.empty()) return;
  frame = std::move(spares_.back());
  spares_.pop_back();
}

bool LiveFrameQueue::pop(LiveFrame& frame) {
  if (size_ == 0) return false;
  std::swap(ring_[head_], frame);
  keep(ring_[head_]);
  head_ = (head_ + 1) % capacity();
  --size_;
  return true;
}

}  // namespace zipfusion
