#include "zipfusion/core/geometry.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <thread>

#include "zipfusion/core/camera.h"
#include "zipfusion/core/parallel.h"

namespace zipfusion {
namespace {

TEST(Geometry, RigidCheckAcceptsRotationsAndRejectsTheRest) {
  Rigid3d t = Rigid3d::Identity();
  t.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  t.translation() = Eigen::Vector3d(1, -2, 0.5);
  EXPECT_TRUE(is_rigid(t.matrix()));

  Eigen::Matrix4d scaled = t.matrix();
  scaled.topLeftCorner<3, 3>() *= 1.01;
  EXPECT_FALSE(is_rigid(scaled));

  Eigen::Matrix4d mirrored = t.matrix();
  mirrored.col(0) *= -1;
  EXPECT_FALSE(is_rigid(mirrored));

  Eigen::Matrix4d bad_row = t.matrix();
  bad_row(3, 0) = 0.1;
  EXPECT_FALSE(is_rigid(bad_row));
}

TEST(Geometry, NearestRigidRemovesRounding) {
  Rigid3d t = Rigid3d::Identity();
  t.linear() = Eigen::AngleAxisd(1.1, Eigen::Vector3d(0, 1, 1).normalized()).toRotationMatrix();
  Eigen::Matrix4d rounded = t.matrix();
  rounded.topLeftCorner<3, 3>() = (rounded.topLeftCorner<3, 3>() * 1e5).array().round() / 1e5;
  const Rigid3d fixed = nearest_rigid(rounded);
  EXPECT_NEAR((fixed.linear().transpose() * fixed.linear() - Eigen::Matrix3d::Identity()).norm(), 0, 1e-12);
  EXPECT_NEAR((fixed.linear() - t.linear()).norm(), 0, 1e-4);
}

TEST(Geometry, LookAtMatchesOpenCvAxes) {
  // The samba-4cam cam0 pose: 2 m from the centre, 1.3 m high, looking at (0, 0, 1).
  const Rigid3d pose = look_at({1.41421356, 1.41421356, 1.3}, {0, 0, 1.0});
  EXPECT_NEAR(pose.linear()(0, 0), -0.707106781, 1e-6);
  EXPECT_NEAR(pose.linear()(0, 1), 0.10489254, 1e-6);
  EXPECT_NEAR(pose.linear()(2, 1), -0.988936353, 1e-6);
  EXPECT_NEAR(pose.linear()(2, 2), -0.148340453, 1e-6);
  // The target projects to the image centre.
  const Intrinsics k{.width = 640, .height = 480, .fx = 580, .fy = 580, .cx = 319.5, .cy = 239.5};
  const Eigen::Vector2d pixel = project(k, pose.inverse() * Eigen::Vector3d(0, 0, 1.0));
  EXPECT_NEAR(pixel.x(), 319.5, 1e-9);
  EXPECT_NEAR(pixel.y(), 239.5, 1e-9);
}

TEST(Geometry, FloorAndCeilToIntMatchTheLibrary) {
  for (float x : {-1e6f, -2.5f, -2.0f, -1.0f, -0.999f, -1e-7f, 0.0f, 1e-7f, 0.5f, 1.0f, 2.999f, 3.0f, 1e6f + 0.5f}) {
    EXPECT_EQ(floor_to_int(x), static_cast<int>(std::floor(x))) << x;
    EXPECT_EQ(ceil_to_int(x), static_cast<int>(std::ceil(x))) << x;
  }
}

TEST(Camera, ProjectUnprojectRoundTrip) {
  const Intrinsics k{.width = 640, .height = 480, .fx = 580, .fy = 570, .cx = 320.2, .cy = 241.7};
  const Eigen::Vector3f p = unproject(k, 100.25f, 400.5f, 2.5f);
  const Eigen::Vector2f pixel = project_pinhole(k, p);
  EXPECT_NEAR(pixel.x(), 100.25f, 1e-4);
  EXPECT_NEAR(pixel.y(), 400.5f, 1e-4);
  EXPECT_FLOAT_EQ(p.z(), 2.5f);
}

TEST(Camera, DistortionFollowsOpenCvModel) {
  Intrinsics k{.width = 640, .height = 480, .fx = 500, .fy = 500, .cx = 320, .cy = 240};
  k.distortion = {0.1, -0.05, 0.001, -0.002, 0.01};
  k.has_distortion = true;
  const double x = 0.3, y = -0.2, r2 = x * x + y * y;
  const double radial = 1 + 0.1 * r2 - 0.05 * r2 * r2 + 0.01 * r2 * r2 * r2;
  const double xd = x * radial + 2 * 0.001 * x * y + -0.002 * (r2 + 2 * x * x);
  const double yd = y * radial + 0.001 * (r2 + 2 * y * y) + 2 * -0.002 * x * y;
  const Eigen::Vector2d pixel = project(k, Eigen::Vector3d(x * 2, y * 2, 2));
  EXPECT_NEAR(pixel.x(), 500 * xd + 320, 1e-9);
  EXPECT_NEAR(pixel.y(), 500 * yd + 240, 1e-9);
}

TEST(Parallel, VisitsEveryIndexOnceAndRethrows) {
  std::vector<int> visits(1000, 0);
  parallel_for(0, 1000, [&](int i) { visits[i]++; }, 4);
  for (int v : visits) EXPECT_EQ(v, 1);
  EXPECT_THROW(parallel_for(0, 100, [](int i) { if (i == 57) throw std::runtime_error("x"); }, 3), std::runtime_error);
  // The pool survives an exception.
  std::atomic<int> sum = 0;
  parallel_for(0, 100, [&](int i) { sum += i; });
  EXPECT_EQ(sum, 4950);
}

TEST(Parallel, CallerRunsOnlyItsOwnBlocks) {
  // A call must not run another call's queued block: its time would include that block's.
  // Caller A occupies itself and a worker; caller B runs its first block and leaves its second
  // queued; then this thread's call must run its own blocks, not B's queued one.
  std::atomic<bool> release = false;
  std::atomic<int> a_started = 0;
  std::atomic<bool> b_started = false;
  std::atomic<bool> b_second_on_main = false;
  const std::thread::id main_thread = std::this_thread::get_id();
  const int blocks = std::min(2, hardware_threads());
  std::jthread a([&] {
    parallel_for(0, blocks, [&](int) {
      ++a_started;
      while (!release) std::this_thread::yield();
    });
  });
  while (a_started < blocks) std::this_thread::yield();
  std::jthread b([&] {
    parallel_for(0, 2, [&](int i) {
      if (i == 0) {
        b_started = true;
        while (!release) std::this_thread::yield();
      } else {
        b_second_on_main = std::this_thread::get_id() == main_thread;
      }
    });
  });
  while (!b_started) std::this_thread::yield();
  std::atomic<int> done = 0;
  parallel_for(0, 2, [&](int) { ++done; });
  release = true;
  a.join();
  b.join();
  EXPECT_EQ(done, 2);
  EXPECT_FALSE(b_second_on_main);
}

TEST(Parallel, NestedAndConcurrentCallsFinish) {
  // Calls from inside a body and from several threads at once share the pool; none may wait
  // forever on a worker that waits on it.
  std::atomic<long> sum = 0;
  std::vector<std::jthread> callers;
  for (int t = 0; t < 4; ++t) {
    callers.emplace_back([&] {
      parallel_for(0, 8, [&](int i) { parallel_for(0, 100, [&](int j) { sum += i * 100 + j; }); });
    });
  }
  callers.clear();
  EXPECT_EQ(sum, 4 * (799L * 800 / 2));
}

}  // namespace
}  // namespace zipfusion
