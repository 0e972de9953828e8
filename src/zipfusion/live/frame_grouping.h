#pragma once
//! \file
//! Grouping the frames of N cameras into frame sets by timestamp: a pure function, so the live
//! rig's decisions can be tested on hand-made timestamp sequences.
//!
//! Rule: the earliest frame not yet grouped (over all cameras) anchors the next set at time t0;
//! every other camera joins with its earliest ungrouped frame when that frame is earlier than
//! t0 + period/2, and is absent from the set otherwise. So the members of a set lie within half a
//! frame period of each other, each frame joins at most one set, and a camera that misses a frame
//! or stops is simply absent from the sets it is not in. A frame earlier than the previous set's
//! t0 + period/2 arrived too late for its set (or is a second frame of one camera within half a
//! period) and is discarded, so sets are strictly ordered in time.
//!
//! Live, a set is decided only when every camera that may still deliver has a frame waiting (its
//! next frame might belong to the set); next_group() then says whom to wait for.

#include <limits>
#include <span>
#include <vector>

namespace zipfusion {

//! One camera's stream as the grouping sees it.
struct StreamView {
  std::span<const double> pending_times;  // its frames not yet grouped, ascending, seconds
  bool open = true;                       // more frames may still come (false: ended, or not waited for any longer)
};

struct GroupStep {
  enum Status {
    kReady,  // a frame set: time_s, skew_s, member
    kWait,   // camera wait_for may still deliver a frame that belongs to the next set
    kDone,   // nothing pending and no stream open
  };
  Status status = kDone;
  int wait_for = -1;           // kWait: the camera to wait for
  double time_s = 0;           // kReady: t0, the anchor's time
  double skew_s = 0;           // kReady: latest member time minus earliest
  std::vector<char> member;    // kReady: per camera, 1 when its first pending frame is in the set
  std::vector<int> discard;    // per camera: leading pending frames to discard first (too late); any status
};

//! The next grouping decision. `not_before_s`: the previous set's t0 + period_s/2 (−infinity
//! before the first set); pending frames earlier than it are reported in `discard` and ignored.
//! Precondition: period_s > 0, each pending_times ascending. Written into `step`, whose vectors
//! keep their memory from one decision to the next (the live rig decides one per frame).
void next_group(std::span<const StreamView> streams, double period_s, double not_before_s, GroupStep& step);
inline GroupStep next_group(std::span<const StreamView> streams, double period_s,
                            double not_before_s = -std::numeric_limits<double>::infinity()) {
  GroupStep step;
  next_group(streams, period_s, not_before_s, step);
  return step;
}

//! One frame set of group_frames().
struct FrameGroup {
  double time_s = 0;
  double skew_s = 0;
  std::vector<int> frame;  // per camera: index into its time sequence, or -1 when absent
};

//! Groups complete timestamp sequences (every stream ended) by repeated next_group(); frames
//! discarded as too late appear in no group.
std::vector<FrameGroup> group_frames(const std::vector<std::vector<double>>& times, double period_s);

}  // namespace zipfusion
