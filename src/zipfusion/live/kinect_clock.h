#pragma once
//! \file
//! A Kinect v1's own clock: libfreenect stamps each depth and colour frame with the device's
//! 60 MHz counter (32 bits, wrapping every 71.6 s), one counter for both streams of a device
//! (OpenKinect's protocol notes; libfreenect issue #681). Pairing a depth frame with colour by
//! these stamps holds however late the host runs the callbacks or reads a dump; the host's
//! arrival times stretch when the machine is busy.

#include <cmath>
#include <cstdint>

namespace zipfusion {

inline constexpr double kKinectClockHz = 60e6;  // ticks a second of a Kinect v1's depth and colour timestamps

//! Whether colour stamped `color_timestamp` pairs with depth stamped `depth_timestamp` (one
//! device's clock): at most max_age_s apart, either way round, right across the clock's wrap.
inline bool kinect_color_pairs_with_depth(std::uint32_t color_timestamp, std::uint32_t depth_timestamp, double max_age_s) {
  // The difference modulo 2^32, read as signed.
  const auto ticks_apart = static_cast<std::int32_t>(depth_timestamp - color_timestamp);
  return std::abs(static_cast<double>(ticks_apart)) <= max_age_s * kKinectClockHz;
}

}  // namespace zipfusion
