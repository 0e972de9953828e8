#pragma once
//! \file
//! A camera's delivered frames waiting to be read, oldest first, whose images go round: read()
//! swaps the oldest frame with the reader's, and the reader's old images are kept for the
//! producer to fill next, so a camera streaming at a steady pace allocates nothing per frame
//! (issue 6). When the queue is full the oldest frame is dropped (live cameras do not wait for a
//! reader that fell behind), and its images are kept too.
//!
//! Not thread-safe: the camera guards it with its own mutex (the producer is the device's event
//! thread, the consumer the rig's reader).

#include <vector>

#include "zipfusion/live/live_camera.h"

namespace zipfusion {

//! Frames whose images are done with, kept for a producer to fill again: at most `most` frames'
//! worth (after a stall a reader hands back a backlog's images, which kept would hold a stall's
//! memory for the rest of the run). Used by LiveFrameQueue and LiveRig. Not thread-safe.
class SpareLiveFrames {
 public:
  explicit SpareLiveFrames(size_t most) { frames_.reserve(most); }

  //! Keeps `frame`'s images when it holds any and there is room, and leaves `frame` empty.
  void keep(LiveFrame& frame);
  //! Gives `frame`, when it holds no images, those of a kept frame, if any.
  void refill(LiveFrame& frame);
  int size() const { return static_cast<int>(frames_.size()); }

 private:
  std::vector<LiveFrame> frames_;  // never grows past its reserved capacity
};

class LiveFrameQueue {
 public:
  //! Holds at most `capacity` frames (≥ 1; throws InvalidInput), and the images of at most
  //! kMostSpares frames read or dropped, for the producer to fill.
  static constexpr int kMostSpares = 4;
  explicit LiveFrameQueue(int capacity);

  //! Queues the filled `frame`, and leaves in `frame` the images of a frame read earlier, to be
  //! filled next (or none, until a frame has been read). Returns true when the queue was full and
  //! the oldest frame was dropped for it.
  bool push(LiveFrame& frame);
  //! Moves the oldest frame into `frame`, whose previous images are kept for the producer.
  //! Returns false, leaving `frame` as it is, when the queue is empty.
  bool pop(LiveFrame& frame);
  //! Gives `frame`, when it holds no images, those of a kept frame, if any: a producer left
  //! without images by push() (no spare then) takes what the reader has handed back since.
  void refill(LiveFrame& frame);

  int size() const { return size_; }
  bool empty() const { return size_ == 0; }
  int capacity() const { return static_cast<int>(ring_.size()); }
  //! Frames whose images are kept for reuse (for tests).
  int spare_count() const { return spares_.size(); }

 private:
  std::vector<LiveFrame> ring_;  // the queued frames from head_, size_ of them; the other slots hold nothing
  SpareLiveFrames spares_;       // images read or dropped, to fill again
  int head_ = 0, size_ = 0;
};

}  // namespace zipfusion
