// LiveFrameQueue: oldest first, the oldest dropped when full, and the images going round between
// the producer and the reader, so that a steady stream allocates nothing (every allocation of
// this test binary is counted).

#include "zipfusion/live/live_frame_queue.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "zipfusion/core/allocation_count_test_util.h"
#include "zipfusion/core/error.h"

namespace zipfusion {
namespace {

LiveFrame frame_at(double time_s, int width = 64, int height = 48) {
  LiveFrame frame;
  frame.time_s = time_s;
  frame.depth.resize(width, height, static_cast<std::uint16_t>(1000 + time_s));
  frame.has_color = true;
  frame.color.resize(width, height, Rgb8{1, 2, 3});
  return frame;
}

TEST(LiveFrameQueue, GivesTheOldestFirstAndDropsTheOldestWhenFull) {
  LiveFrameQueue queue(3);
  std::vector<bool> dropped;
  for (int t = 0; t < 5; ++t) {
    LiveFrame frame = frame_at(t);
    dropped.push_back(queue.push(frame));
  }
  EXPECT_EQ(dropped, (std::vector<bool>{false, false, false, true, true}));
  EXPECT_EQ(queue.size(), 3);
  LiveFrame read = frame_at(-1);
  for (int t = 2; t < 5; ++t) {
    ASSERT_TRUE(queue.pop(read));
    EXPECT_EQ(read.time_s, t);
    EXPECT_EQ(read.depth.data.front(), 1000 + t);  // the pixels came with their frame
  }
  EXPECT_FALSE(queue.pop(read));
  EXPECT_EQ(read.time_s, 4);  // an empty queue leaves the reader's frame as it was
  EXPECT_TRUE(queue.empty());
}

// A producer that push() left without images (no spare then) takes the images the reader hands
// back later, before it fills its next frame, instead of allocating new ones.
TEST(LiveFrameQueue, AProducerLeftWithoutImagesTakesThoseHandedBackSince) {
  LiveFrameQueue queue(4);
  LiveFrame producer = frame_at(0);
  queue.push(producer);
  ASSERT_FALSE(producer.holds_images());
  queue.refill(producer);
  EXPECT_FALSE(producer.holds_images());  // nothing handed back yet
  LiveFrame reader = frame_at(-1);
  const std::uint16_t* readers = reader.depth.data.data();
  ASSERT_TRUE(queue.pop(reader));
  queue.refill(producer);
  EXPECT_EQ(producer.depth.data.data(), readers);
  EXPECT_EQ(queue.spare_count(), 0);
  LiveFrame next = frame_at(1);
  queue.push(next);
  reader = frame_at(-2);
  ASSERT_TRUE(queue.pop(reader));
  ASSERT_EQ(queue.spare_count(), 1);
  LiveFrame holding = frame_at(2);
  const std::uint16_t* own = holding.depth.data.data();
  queue.refill(holding);  // a frame that holds images keeps its own, and the spare stays
  EXPECT_EQ(holding.depth.data.data(), own);
  EXPECT_EQ(queue.spare_count(), 1);
}

TEST(LiveFrameQueue, TheReadersImagesAreFilledNext) {
  LiveFrameQueue queue(4);
  LiveFrame producer = frame_at(0);
  const std::uint16_t* first = producer.depth.data.data();
  queue.push(producer);
  EXPECT_FALSE(producer.holds_images());  // nothing read yet: nothing to give the producer
  LiveFrame reader = frame_at(-1);
  const std::uint16_t* readers = reader.depth.data.data();
  const Rgb8* readers_color = reader.color.data.data();
  ASSERT_TRUE(queue.pop(reader));
  EXPECT_EQ(reader.depth.data.data(), first);  // swapped out, not copied
  EXPECT_EQ(queue.spare_count(), 1);
  producer = frame_at(1);
  queue.push(producer);
  EXPECT_EQ(producer.depth.data.data(), readers);  // the reader's old images, to fill next
  EXPECT_EQ(producer.color.data.data(), readers_color);
  EXPECT_EQ(queue.spare_count(), 0);
}

TEST(LiveFrameQueue, ADroppedFramesImagesAreFilledAgain) {
  LiveFrameQueue queue(1);
  LiveFrame producer = frame_at(0);
  const std::uint16_t* oldest = producer.depth.data.data();
  queue.push(producer);
  producer = frame_at(1);
  EXPECT_TRUE(queue.push(producer));
  EXPECT_EQ(producer.depth.data.data(), oldest);
  LiveFrame reader;
  ASSERT_TRUE(queue.pop(reader));
  EXPECT_EQ(reader.time_s, 1);
}

// Spares come from reads and drops: never more than kMostSpares, however many frames a stalled
// reader takes at once and whatever images it brings (a backlog's images are not kept for the run).
TEST(LiveFrameQueue, KeepsAFewSpareImagesAfterABacklog) {
  for (int capacity : {2, 8}) {
    LiveFrameQueue queue(capacity);
    for (int round = 0; round < 3; ++round) {
      for (int t = 0; t < 10; ++t) {
        LiveFrame producer = frame_at(t);  // a producer that brings its own images every time
        queue.push(producer);
      }
      LiveFrame reader = frame_at(-1);  // and a reader that does
      while (queue.pop(reader)) reader = frame_at(-1);
      EXPECT_EQ(queue.spare_count(), std::min(capacity, LiveFrameQueue::kMostSpares)) << "capacity " << capacity;
    }
  }
}

// A device at 30 Hz read at its pace, now and then a frame behind or dropped: after the first
// frames nothing is allocated, in the queue or for the images.
TEST(LiveFrameQueue, ASteadyStreamAllocatesNothing) {
  LiveFrameQueue queue(3);
  LiveFrame producer, reader;
  auto produce = [&](double t) {
    producer.time_s = t;
    producer.depth.resize_for_overwrite(640, 480);
    producer.depth.data[0] = static_cast<std::uint16_t>(t);
    producer.has_color = true;
    producer.color.resize_for_overwrite(640, 480);
    queue.push(producer);
  };
  long long before = 0;
  int t = 0, read = 0;
  for (int round = 0; round < 40; ++round) {
    if (round == 10) before = g_allocations.load();
    produce(t++);
    if (round % 7 == 3) produce(t++);  // two frames before the reader comes
    if (round % 11 == 5) {
      for (int k = 0; k < 4; ++k) produce(t++);  // the reader stalls: the queue drops
    }
    while (queue.pop(reader)) {
      EXPECT_EQ(reader.depth.data[0], static_cast<std::uint16_t>(reader.time_s));
      ++read;
    }
  }
  EXPECT_EQ(g_allocations.load() - before, 0);
  EXPECT_GT(read, 40);
}

TEST(LiveFrameQueue, RefusesNoRoom) { EXPECT_THROW(LiveFrameQueue(0), InvalidInput); }

}  // namespace
}  // namespace zipfusion
