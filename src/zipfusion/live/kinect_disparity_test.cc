#include "zipfusion/live/kinect_disparity.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

namespace zipfusion {
namespace {

// libfreenect's documented conversion, written out independently.
double libfreenect_mm(int raw) { return 1000.0 / (raw * -0.0030711016 + 3.3309495161); }

TEST(KinectDisparity, RawToMillimetresFollowsLibfreenectsFormula) {
  EXPECT_EQ(kinect_raw_to_mm(0), 300);     // 300.2
  EXPECT_EQ(kinect_raw_to_mm(600), 672);   // 671.9
  EXPECT_EQ(kinect_raw_to_mm(1000), 3848); // 3848.4
  EXPECT_EQ(kinect_raw_to_mm(1052), 9985);
  for (int raw = 0; raw <= 1052; ++raw) {
    EXPECT_NEAR(kinect_raw_to_mm(static_cast<std::uint16_t>(raw)), libfreenect_mm(raw), 0.5) << raw;
  }
}

TEST(KinectDisparity, NoValueAndOutOfRangeGiveZero) {
  EXPECT_EQ(kinect_raw_to_mm(kKinectRawNoValue), 0);
  EXPECT_EQ(kinect_raw_to_mm(1053), 0);  // 10.3 m: beyond FREENECT_DEPTH_MM_MAX_VALUE
  EXPECT_EQ(kinect_raw_to_mm(1084), 0);  // 531 m
  EXPECT_EQ(kinect_raw_to_mm(1085), 0);  // inverse depth negative
  EXPECT_EQ(kinect_raw_to_mm(2046), 0);
  EXPECT_EQ(kinect_raw_to_mm(65535), 0);
  EXPECT_EQ(kinect_mm_to_raw(0), kKinectRawNoValue);
  EXPECT_EQ(kinect_mm_to_raw(299), kKinectRawNoValue);  // nearer than raw 0's 300.2 mm
  EXPECT_EQ(kinect_mm_to_raw(300), 0);
  EXPECT_EQ(kinect_mm_to_raw(10001), kKinectRawNoValue);
  EXPECT_EQ(kinect_mm_to_raw(65535), kKinectRawNoValue);
  EXPECT_EQ(kinect_mm_to_raw(301), 3);  // 2.83
  EXPECT_NE(kinect_mm_to_raw(10000), kKinectRawNoValue);
}

TEST(KinectDisparity, RawToMillimetresToRawRoundTripsWhereAStepExceedsOneMillimetre) {
  for (int raw = 542; raw <= 1052; ++raw) {
    const std::uint16_t mm = kinect_raw_to_mm(static_cast<std::uint16_t>(raw));
    ASSERT_EQ(kinect_mm_to_raw(mm), raw) << "raw " << raw << " -> " << mm << " mm";
    // From raw 542 on, each step is more than a millimetre: distinct raw values, distinct depths.
    if (raw > 542) {
      ASSERT_GT(mm, kinect_raw_to_mm(static_cast<std::uint16_t>(raw - 1))) << "raw " << raw;
    }
  }
  // Below 0.6 m several raw values share a millimetre: the round trip lands on one of them.
  for (int raw = 0; raw < 542; ++raw) {
    const std::uint16_t mm = kinect_raw_to_mm(static_cast<std::uint16_t>(raw));
    EXPECT_EQ(kinect_raw_to_mm(kinect_mm_to_raw(mm)), mm) << raw;
  }
}

TEST(KinectDisparity, MillimetresToRawToMillimetresIsWithinHalfAStep) {
  double worst_ratio = 0;
  for (int mm = 300; mm <= 10000; ++mm) {
    const std::uint16_t back = kinect_raw_to_mm(kinect_mm_to_raw(static_cast<std::uint16_t>(mm)));
    ASSERT_NE(back, 0) << mm;
    const double z = mm / 1000.0;
    // Half a step (inverse depth is quantised, so the step grows across it: take it at the far
    // side) plus the millimetre rounding of the result.
    const double bound_mm = 1000 * kinect_raw_step_m(z + kinect_raw_step_m(z)) / 2 + 0.5;
    const double error_mm = std::abs(static_cast<double>(back) - mm);
    ASSERT_LE(error_mm, bound_mm) << mm;
    worst_ratio = std::max(worst_ratio, error_mm / bound_mm);
    if (mm <= 570) {
      EXPECT_EQ(back, mm);  // a step below 1 mm: exact
    }
  }
  EXPECT_GT(worst_ratio, 0.8);  // the bound is tight, not vacuous
}

TEST(KinectDisparity, StepMatchesAdjacentRawValues) {
  EXPECT_NEAR(kinect_raw_step_m(2.5), 0.019194, 1e-6);
  const std::uint16_t raw = kinect_mm_to_raw(2500);
  const double measured_mm = kinect_raw_to_mm(raw + 1) - kinect_raw_to_mm(raw);
  EXPECT_NEAR(measured_mm, 1000 * kinect_raw_step_m(2.5), 1.0);
}

TEST(KinectDisparity, FrameConversionIsTheElementFunctionPerPixel) {
  std::vector<std::uint16_t> raw = {0, 541, 542, 800, 1052, 1053, 2047, 3000};
  std::vector<std::uint16_t> mm(raw.size(), 12345);
  kinect_raw_frame_to_mm(static_cast<int>(raw.size()), raw.data(), mm.data());
  for (size_t i = 0; i < raw.size(); ++i) EXPECT_EQ(mm[i], kinect_raw_to_mm(raw[i])) << i;
  EXPECT_EQ(mm[6], 0);
}

// A device's buffer at an odd address (fakenect's is): read byte-wise, the same values.
TEST(KinectDisparity, ABufferAtAnOddAddressConvertsTheSame) {
  const std::vector<std::uint16_t> raw = {0, 541, 542, 800, 1052, 1053, 2047, 3000};
  std::vector<unsigned char> bytes(1 + 2 * raw.size());
  std::memcpy(bytes.data() + 1, raw.data(), 2 * raw.size());
  std::vector<std::uint16_t> mm(raw.size(), 12345);
  kinect_raw_bytes_to_mm(static_cast<int>(raw.size()), bytes.data() + 1, mm.data());
  for (size_t i = 0; i < raw.size(); ++i) EXPECT_EQ(mm[i], kinect_raw_to_mm(raw[i])) << i;
}

}  // namespace
}  // namespace zipfusion
