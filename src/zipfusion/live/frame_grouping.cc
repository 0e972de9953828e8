#include "zipfusion/live/frame_grouping.h"

#include <algorithm>
#include <cassert>

namespace zipfusion {

void next_group(std::span<const StreamView> streams, double period_s, double not_before_s, GroupStep& step) {
  assert(period_s > 0);
  const int n = static_cast<int>(streams.size());
  step.status = GroupStep::kDone;
  step.wait_for = -1;
  step.time_s = step.skew_s = 0;
  step.member.clear();
  step.discard.assign(n, 0);
  // Skip what is too late; find the anchor: the earliest remaining pending frame.
  int anchor = -1;
  double t0 = 0;
  for (int c = 0; c < n; ++c) {
    const std::span<const double> times = streams[c].pending_times;
    int skip = 0;
    while (skip < static_cast<int>(times.size()) && times[skip] < not_before_s) ++skip;
    step.discard[c] = skip;
    if (skip < static_cast<int>(times.size()) && (anchor < 0 || times[skip] < t0)) {
      anchor = c;
      t0 = times[skip];
    }
  }
  // An open camera with nothing pending might still deliver a frame earlier than the anchor or
  // within its window: the set cannot be decided without it.
  for (int c = 0; c < n; ++c) {
    if (streams[c].open && step.discard[c] == static_cast<int>(streams[c].pending_times.size())) {
      step.status = GroupStep::kWait;
      step.wait_for = c;
      return;
    }
  }
  if (anchor < 0) return;  // kDone
  step.status = GroupStep::kReady;
  step.time_s = t0;
  step.member.assign(n, 0);
  double latest = t0;
  const double window_end = t0 + period_s / 2;
  for (int c = 0; c < n; ++c) {
    const std::span<const double> times = streams[c].pending_times;
    const int first = step.discard[c];
    if (first < static_cast<int>(times.size()) && times[first] < window_end) {
      step.member[c] = 1;
      latest = std::max(latest, times[first]);
    }
  }
  step.skew_s = latest - t0;
}

std::vector<FrameGroup> group_frames(const std::vector<std::vector<double>>& times, double period_s) {
  const int n = static_cast<int>(times.size());
  std::vector<size_t> next(n, 0);
  std::vector<StreamView> views(n);
  std::vector<FrameGroup> groups;
  double not_before = -std::numeric_limits<double>::infinity();
  while (true) {
    for (int c = 0; c < n; ++c) views[c] = {.pending_times = std::span(times[c]).subspan(next[c]), .open = false};
    const GroupStep step = next_group(views, period_s, not_before);
    for (int c = 0; c < n; ++c) next[c] += step.discard[c];
    if (step.status != GroupStep::kReady) break;
    FrameGroup group{.time_s = step.time_s, .skew_s = step.skew_s, .frame = std::vector<int>(n, -1)};
    for (int c = 0; c < n; ++c) {
      if (step.member[c]) group.frame[c] = static_cast<int>(next[c]++);
    }
    groups.push_back(std::move(group));
    not_before = step.time_s + period_s / 2;
  }
  return groups;
}

}  // namespace zipfusion
