// Pairing a Kinect's colour with its depth by the device's clock.

#include "zipfusion/live/kinect_clock.h"

#include <gtest/gtest.h>

#include <cstdint>

namespace zipfusion {
namespace {

constexpr std::uint32_t kFrameTicks = 2000000;  // 1/30 s of the 60 MHz clock

TEST(KinectClock, ColourPairsWithDepthStampedWithinTheMaximumAge) {
  const std::uint32_t depth = 5000000;
  EXPECT_TRUE(kinect_color_pairs_with_depth(depth - 60000, depth, 0.04));  // 1 ms before
  EXPECT_TRUE(kinect_color_pairs_with_depth(depth + 60000, depth, 0.04));  // 1 ms after
  EXPECT_TRUE(kinect_color_pairs_with_depth(depth - 2399999, depth, 0.04));  // just within 40 ms
  EXPECT_FALSE(kinect_color_pairs_with_depth(depth - 2400001, depth, 0.04));  // just beyond
  EXPECT_FALSE(kinect_color_pairs_with_depth(depth - 2 * kFrameTicks, depth, 0.04));  // two frames old
  EXPECT_FALSE(kinect_color_pairs_with_depth(depth + 2 * kFrameTicks, depth, 0.04));
  EXPECT_FALSE(kinect_color_pairs_with_depth(depth - 60000, depth, 0.0));
}

TEST(KinectClock, ColourPairsAcrossTheClocksWrap) {
  // The 32-bit clock wraps every 71.6 s: colour just before the wrap, depth just after.
  const std::uint32_t color = 0xFFFFFFFFu - 29999, depth = 30000;
  EXPECT_TRUE(kinect_color_pairs_with_depth(color, depth, 0.04));
  EXPECT_TRUE(kinect_color_pairs_with_depth(depth, color, 0.04));
  EXPECT_FALSE(kinect_color_pairs_with_depth(color - 2 * kFrameTicks, depth, 0.04));
  // Half the clock's range away is the farthest a difference can be, never "close".
  EXPECT_FALSE(kinect_color_pairs_with_depth(depth + 0x80000000u, depth, 0.04));
}

}  // namespace
}  // namespace zipfusion
