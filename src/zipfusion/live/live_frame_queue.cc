#include "zipfusion/live/live_frame_queue.h"

#include <utility>

#include "zipfusion/core/error.h"

namespace zipfusion {

LiveFrameQueue::LiveFrameQueue(int capacity) {
  if (capacity < 1) throw InvalidInput("live frame queue: capacity must be at least 1");
  ring_.resize(capacity);
  // A spare comes from a read, or from a drop that the same push takes back: never more than the
  // ring holds.
  spares_.reserve(static_cast<size_t>(capacity));
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

bool LiveFrameQueue::pop(LiveFrame& frame) {
  if (size_ == 0) return false;
  std::swap(ring_[head_], frame);
  keep(ring_[head_]);
  head_ = (head_ + 1) % capacity();
  --size_;
  return true;
}

}  // namespace zipfusion
