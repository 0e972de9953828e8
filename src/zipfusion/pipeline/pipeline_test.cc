#include "zipfusion/pipeline/pipeline.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <stdexcept>
#include <thread>

#include "zipfusion/core/error.h"
#include "zipfusion/synth/synth.h"

namespace zipfusion {
namespace {

TEST(BoundedQueue, BlockingQueueLosesNothingAndKeepsOrder) {
  BoundedQueue<int> queue(2, QueuePolicy::kBlock);
  std::jthread producer([&] {
    for (int i = 0; i < 1000; ++i) queue.push(i);
    queue.close();
  });
  int expected = 0;
  while (std::optional<int> item = queue.pop()) EXPECT_EQ(*item, expected++);
  EXPECT_EQ(expected, 1000);
  EXPECT_EQ(queue.dropped(), 0);
}

TEST(BoundedQueue, WaitUntilEmptyReturnsOnceDrainedAndFalseOnceClosed) {
  BoundedQueue<int> queue(2, QueuePolicy::kBlock);
  queue.push(1);
  std::jthread consumer([&] { EXPECT_EQ(queue.pop(), 1); });
  EXPECT_TRUE(queue.wait_until_empty());
  consumer.join();
  std::jthread closer([&] { queue.close(); });
  queue.push(2);  // not empty: only the close ends the wait
  EXPECT_FALSE(queue.wait_until_empty());
}

TEST(BoundedQueue, LiveQueueDropsTheOldest) {
  BoundedQueue<int> queue(3, QueuePolicy::kDropOldest);
  std::vector<int> displaced_items;  // handed back, for the pipeline to reuse their buffers
  for (int i = 0; i < 10; ++i) {
    std::optional<int> displaced;
    EXPECT_TRUE(queue.push(i, &displaced));  // never waits
    if (displaced) displaced_items.push_back(*displaced);
  }
  EXPECT_EQ(queue.dropped(), 7);
  EXPECT_EQ(displaced_items, (std::vector<int>{0, 1, 2, 3, 4, 5, 6}));
  queue.close();
  EXPECT_FALSE(queue.push(10));
  for (int expected : {7, 8, 9}) EXPECT_EQ(queue.pop(), expected);
  EXPECT_EQ(queue.pop(), std::nullopt);
}

// Frame sets without depth: the pipeline's plumbing, not the reconstruction, is under test.
FrameSource empty_frames(int count, int cameras, std::atomic<int>* produced = nullptr) {
  auto next = std::make_shared<int>(0);
  return [=](FrameSet& set, double& decode_ms) {
    if (*next >= count) return false;
    decode_ms = 0;
    if (produced) ++*produced;
    set = FrameSet{};
    set.index = (*next)++;
    set.cameras.resize(cameras);
    return true;
  };
}

class PipelineTest : public ::testing::Test {
 protected:
  Rig rig = make_ring_rig(SynthOptions{.cameras = 3});
  FrameReconstructor reconstructor{rig, {}};
};

TEST_F(PipelineTest, OfflineDeliversEveryFrameInOrder) {
  std::vector<int> seen;
  const PipelineStats stats = run_pipeline(empty_frames(50, 3), reconstructor, [&](PipelineFrame& frame) {
    seen.push_back(frame.index);
    EXPECT_EQ(frame.result.cameras_used, 0);
  });
  ASSERT_EQ(seen.size(), 50u);
  for (int i = 0; i < 50; ++i) EXPECT_EQ(seen[i], i);
  EXPECT_EQ(stats.frames, 50);
  EXPECT_EQ(stats.dropped, 0);
}

TEST_F(PipelineTest, SinkErrorStopsThePipelineAndIsRethrown) {
  std::atomic<int> produced = 0;
  int sunk = 0;
  EXPECT_THROW(run_pipeline(empty_frames(1000, 3, &produced), reconstructor,
                            [&](PipelineFrame& frame) {
                              if (frame.index == 5) throw std::runtime_error("disk full");
                              ++sunk;
                            }),
               std::runtime_error);
  EXPECT_EQ(sunk, 5);
  EXPECT_LT(produced, 20) << "the source kept decoding after the sink failed";
}

TEST_F(PipelineTest, SourceErrorIsRethrown) {
  auto failing = [n = 0](FrameSet& set, double&) mutable {
    if (++n == 4) throw InvalidInput("frame 3: corrupt");
    set.cameras.resize(3);
    return true;
  };
  EXPECT_THROW(run_pipeline(failing, reconstructor, [](PipelineFrame&) {}), InvalidInput);
}

TEST_F(PipelineTest, ReconstructionStageErrorIsRethrownAndEveryThreadEnds) {
  // An error on the reconstruction thread (here in the hook before each frame) must stop the
  // source, which would otherwise block on its full queue for ever.
  std::atomic<int> produced = 0;
  PipelineOptions options;
  options.before_reconstruct = [](const FrameSet& frames, FrameReconstructor&) {
    if (frames.index == 3) throw std::runtime_error("pose update failed");
  };
  std::vector<int> sunk;
  EXPECT_THROW(run_pipeline(empty_frames(1000, 3, &produced), reconstructor, [&](PipelineFrame& frame) { sunk.push_back(frame.index); }, options),
               std::runtime_error);
  EXPECT_LT(produced, 20);
  EXPECT_LE(sunk.size(), 3u);
}

TEST_F(PipelineTest, LiveSourceDropsFramesWhenTheSinkIsSlow) {
  const PipelineStats stats = run_pipeline(
      empty_frames(200, 3), reconstructor, [](PipelineFrame&) { std::this_thread::sleep_for(std::chrono::milliseconds(2)); },
      {.queue_depth = 1, .source_policy = QueuePolicy::kDropOldest});
  EXPECT_GT(stats.dropped, 0);
  EXPECT_EQ(stats.frames + stats.dropped, 200);
}

TEST_F(PipelineTest, LiveReconstructionTakesAFrameSetOnlyWhenTheSinkHasRoom) {
  // A mesh finished while another waits for a busy sink would age by a whole sink call, and so
  // would the frame set behind it. Counted in sink calls, not time: between the reconstruction
  // taking a frame set and the sink starting on its mesh, at most one sink call may end.
  std::atomic<int> sink_calls_done = 0;
  std::vector<int> done_when_taken(200, -1);
  PipelineOptions options{.queue_depth = 1, .source_policy = QueuePolicy::kDropOldest, .take_when_sink_ready = true};
  options.before_reconstruct = [&](const FrameSet& frames, FrameReconstructor&) { done_when_taken[frames.index] = sink_calls_done; };
  int most_calls_waited = 0;
  int sunk = 0;
  FrameSource frames_every_200us = [source = empty_frames(200, 3)](FrameSet& set, double& decode_ms) {
    std::this_thread::sleep_for(std::chrono::microseconds(200));  // a camera: the frames keep coming
    return source(set, decode_ms);
  };
  run_pipeline(
      frames_every_200us, reconstructor,
      [&](PipelineFrame& frame) {
        most_calls_waited = std::max(most_calls_waited, sink_calls_done - done_when_taken[frame.index]);
        ++sunk;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        ++sink_calls_done;
      },
      options);
  EXPECT_GT(sunk, 10);
  EXPECT_LE(most_calls_waited, 1);
}

TEST_F(PipelineTest, UnwantedFrameSetsAreNotMadeButKeepTheirPlaceInTheSequence) {
  PipelineOptions options;
  int offered = 0;  // background registration sees every frame set, made or not
  options.before_reconstruct = [&](const FrameSet&, FrameReconstructor&) { ++offered; };
  options.wants_frame = [n = 0]() mutable { return n++ % 3 == 0; };  // a sink that wants every third
  std::vector<long> sequences;
  const PipelineStats stats = run_pipeline(empty_frames(30, 3), reconstructor, [&](PipelineFrame& frame) {
    sequences.push_back(frame.sequence);
    EXPECT_EQ(frame.index, frame.sequence);
  }, options);
  EXPECT_EQ(stats.frames, 10);
  EXPECT_EQ(stats.unwanted, 20);
  EXPECT_EQ(offered, 30);
  ASSERT_EQ(sequences.size(), 10u);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(sequences[i], 3 * i);
}

}  // namespace
}  // namespace zipfusion
