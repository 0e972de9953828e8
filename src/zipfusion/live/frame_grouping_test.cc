#include "zipfusion/live/frame_grouping.h"

#include <gtest/gtest.h>

#include <cmath>

namespace zipfusion {
namespace {

constexpr double kPeriod = 1.0 / 30;

std::vector<double> regular(int frames, double offset_s, double period_s = kPeriod) {
  std::vector<double> t;
  for (int i = 0; i < frames; ++i) t.push_back(offset_s + i * period_s);
  return t;
}

TEST(FrameGrouping, JitteredCamerasPairFrameByFrame) {
  std::vector<std::vector<double>> times = {regular(10, 0), regular(10, 0), regular(10, 0.004)};
  const double jitter[10] = {0.003, -0.002, 0.001, -0.003, 0.0025, 0, -0.001, 0.002, -0.0025, 0.003};
  for (int i = 0; i < 10; ++i) times[1][i] += jitter[i];
  const std::vector<FrameGroup> groups = group_frames(times, kPeriod);
  ASSERT_EQ(groups.size(), 10u);
  double max_skew = 0;
  for (int i = 0; i < 10; ++i) {
    EXPECT_EQ(groups[i].frame, (std::vector<int>{i, i, i})) << i;
    const double earliest = std::min({times[0][i], times[1][i], times[2][i]});
    const double latest = std::max({times[0][i], times[1][i], times[2][i]});
    EXPECT_DOUBLE_EQ(groups[i].time_s, earliest);
    EXPECT_NEAR(groups[i].skew_s, latest - earliest, 1e-12);
    if (i > 0) {
      EXPECT_GT(groups[i].time_s, groups[i - 1].time_s);
    }
    max_skew = std::max(max_skew, groups[i].skew_s);
  }
  EXPECT_NEAR(max_skew, 0.007, 1e-9);  // frame 3: camera 1 at -3 ms, camera 2 at +4 ms
}

TEST(FrameGrouping, AMissingFrameLeavesOnlyThatCameraOut) {
  std::vector<std::vector<double>> times = {regular(8, 0), regular(8, 0.002)};
  times[1].erase(times[1].begin() + 4);
  const std::vector<FrameGroup> groups = group_frames(times, kPeriod);
  ASSERT_EQ(groups.size(), 8u);
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ(groups[i].frame[0], i);
    EXPECT_EQ(groups[i].frame[1], i < 4 ? i : i == 4 ? -1 : i - 1) << i;
  }
  EXPECT_DOUBLE_EQ(groups[4].skew_s, 0);
}

TEST(FrameGrouping, ACameraThatStopsIsAbsentFromLaterSets) {
  const std::vector<std::vector<double>> times = {regular(10, 0.001), regular(4, 0), regular(10, 0.003)};
  const std::vector<FrameGroup> groups = group_frames(times, kPeriod);
  ASSERT_EQ(groups.size(), 10u);
  for (int i = 0; i < 10; ++i) {
    EXPECT_EQ(groups[i].frame, (std::vector<int>{i, i < 4 ? i : -1, i})) << i;
    EXPECT_NEAR(groups[i].skew_s, i < 4 ? 0.003 : 0.002, 1e-12) << i;
  }
}

TEST(FrameGrouping, CamerasMoreThanHalfAPeriodApartPairWithTheNearerFrame) {
  // Camera 1 runs 20 ms behind camera 0 (more than half of 33.3 ms): its frame k pairs with camera
  // 0's frame k + 1, 13.3 ms away, never with frame k, 20 ms away.
  const std::vector<std::vector<double>> times = {regular(10, 0), regular(10, 0.020)};
  const std::vector<FrameGroup> groups = group_frames(times, kPeriod);
  ASSERT_EQ(groups.size(), 11u);
  EXPECT_EQ(groups[0].frame, (std::vector<int>{0, -1}));
  for (int k = 0; k < 9; ++k) {
    EXPECT_EQ(groups[k + 1].frame, (std::vector<int>{k + 1, k})) << k;
    EXPECT_NEAR(groups[k + 1].skew_s, kPeriod - 0.020, 1e-12);
  }
  EXPECT_EQ(groups[10].frame, (std::vector<int>{-1, 9}));
}

TEST(FrameGrouping, ASecondFrameWithinHalfAPeriodIsDiscarded) {
  std::vector<std::vector<double>> times = {regular(5, 0), regular(5, 0.001)};
  times[0].insert(times[0].begin() + 3, times[0][2] + 0.005);  // a duplicate 5 ms after frame 2
  const std::vector<FrameGroup> groups = group_frames(times, kPeriod);
  ASSERT_EQ(groups.size(), 5u);
  EXPECT_EQ(groups[2].frame, (std::vector<int>{2, 2}));
  EXPECT_EQ(groups[3].frame, (std::vector<int>{4, 3}));  // index 3, the duplicate, is in no set
}

TEST(FrameGrouping, WaitsForAnOpenCameraWithNothingPending) {
  const std::vector<double> a = {1.0, 1.0 + kPeriod}, empty;
  std::vector<StreamView> views = {{.pending_times = a, .open = true}, {.pending_times = empty, .open = true}};
  GroupStep step = next_group(views, kPeriod);
  EXPECT_EQ(step.status, GroupStep::kWait);
  EXPECT_EQ(step.wait_for, 1);
  // Given up on (or ended): the set is decided without it.
  views[1].open = false;
  step = next_group(views, kPeriod);
  ASSERT_EQ(step.status, GroupStep::kReady);
  EXPECT_DOUBLE_EQ(step.time_s, 1.0);
  EXPECT_EQ(step.member, (std::vector<char>{1, 0}));
  // An open camera whose pending frame is beyond the window needs no waiting either.
  const std::vector<double> later = {1.025};
  views[1] = {.pending_times = later, .open = true};
  step = next_group(views, kPeriod);
  ASSERT_EQ(step.status, GroupStep::kReady);
  EXPECT_EQ(step.member, (std::vector<char>{1, 0}));
  views = {{.pending_times = empty, .open = false}, {.pending_times = empty, .open = false}};
  EXPECT_EQ(next_group(views, kPeriod).status, GroupStep::kDone);
}

TEST(FrameGrouping, FramesTooLateForTheirSetAreDiscarded) {
  // The previous set was anchored at 1.0: a frame at 1.01 (< 1.0 + period/2) came too late.
  const std::vector<double> a = {1.0 + kPeriod}, b = {1.01, 1.0 + kPeriod + 0.002};
  const std::vector<StreamView> views = {{.pending_times = a, .open = true}, {.pending_times = b, .open = true}};
  const GroupStep step = next_group(views, kPeriod, 1.0 + kPeriod / 2);
  ASSERT_EQ(step.status, GroupStep::kReady);
  EXPECT_EQ(step.discard, (std::vector<int>{0, 1}));
  EXPECT_EQ(step.member, (std::vector<char>{1, 1}));
  EXPECT_NEAR(step.skew_s, 0.002, 1e-12);
  // Only a late frame pending from an open camera: discard it and wait for that camera.
  const std::vector<double> only_late = {1.01};
  const std::vector<StreamView> waiting = {{.pending_times = a, .open = true}, {.pending_times = only_late, .open = true}};
  const GroupStep wait = next_group(waiting, kPeriod, 1.0 + kPeriod / 2);
  EXPECT_EQ(wait.status, GroupStep::kWait);
  EXPECT_EQ(wait.wait_for, 1);
  EXPECT_EQ(wait.discard, (std::vector<int>{0, 1}));
}

}  // namespace
}  // namespace zipfusion
