#pragma once
//! \file
//! The Kinect v1 raw-disparity model: libfreenect's FREENECT_DEPTH_11BIT values to millimetres
//! and back. One model for everything in zipfusion that meets raw Kinect values: the live source
//! under fakenect (which delivers only the 11-bit stream) and `synth --fakenect`, which writes
//! them. docs/design.md ("Live capture") says why this one.
//!
//! Model (libfreenect's documented conversion for 11-bit raw values, after N. Burrus'
//! calibration): inverse depth is linear in the raw value,
//!     1 / z[m] = 3.3309495161 − 0.0030711016 · raw,
//! so one raw step is z²·0.0030711016 m⁻¹ of depth: 19 mm at 2.5 m, 0.8 mm at 0.5 m.
//! 2047 (FREENECT_DEPTH_RAW_NO_VALUE) means no measurement.
//!
//! Element functions: no allocation, exceptions or STL, callable from a CUDA kernel as they are.

#include <cstdint>
#include <cstring>

namespace zipfusion {

inline constexpr double kKinectRawInverseDepthOffset = 3.3309495161;  // 1/z at raw 0, 1/m
inline constexpr double kKinectRawInverseDepthScale = 0.0030711016;   // 1/z lost per raw unit, 1/m
inline constexpr std::uint16_t kKinectRawNoValue = 2047;              // FREENECT_DEPTH_RAW_NO_VALUE
inline constexpr std::uint16_t kKinectMaxDepthMm = 10000;             // FREENECT_DEPTH_MM_MAX_VALUE

//! Depth in millimetres (rounded) of an 11-bit raw value; 0 for no value and for raw values whose
//! depth lies beyond kKinectMaxDepthMm (raw ≥ 1053) or is not finite (raw ≥ 1085).
inline std::uint16_t kinect_raw_to_mm(std::uint16_t raw) {
  if (raw >= kKinectRawNoValue) return 0;
  const double inverse_depth = kKinectRawInverseDepthOffset - kKinectRawInverseDepthScale * raw;  // 1/m
  if (!(inverse_depth * kKinectMaxDepthMm >= 1000.0)) return 0;
  return static_cast<std::uint16_t>(1000.0 / inverse_depth + 0.5);
}

//! The raw value whose depth is nearest to `mm` in inverse depth (what the sensor quantises);
//! kKinectRawNoValue for 0 and for depths outside the raw range (nearer than 300 mm, or beyond
//! kKinectMaxDepthMm). For every raw value r with a depth of at least 0.6 m (raw ≥ 542, where a
//! step exceeds 1 mm), kinect_mm_to_raw(kinect_raw_to_mm(r)) == r.
inline std::uint16_t kinect_mm_to_raw(std::uint16_t mm) {
  if (mm == 0 || mm > kKinectMaxDepthMm) return kKinectRawNoValue;
  const double raw = (kKinectRawInverseDepthOffset - 1000.0 / mm) / kKinectRawInverseDepthScale;
  if (raw < 0) return mm >= kinect_raw_to_mm(0) ? 0 : kKinectRawNoValue;  // 300 mm rounds from raw 0's 300.2 mm
  const int rounded = static_cast<int>(raw + 0.5);
  return kinect_raw_to_mm(static_cast<std::uint16_t>(rounded)) == 0 ? kKinectRawNoValue : static_cast<std::uint16_t>(rounded);
}

//! Depth between two adjacent raw values at depth z: z²·0.0030711016 (metres, z in metres).
inline double kinect_raw_step_m(double z) { return z * z * kKinectRawInverseDepthScale; }

//! Converts a whole 11-bit raw frame (n pixels) to millimetres: one element function call per pixel.
inline void kinect_raw_frame_to_mm(int n, const std::uint16_t* raw, std::uint16_t* mm) {
  for (int i = 0; i < n; ++i) mm[i] = kinect_raw_to_mm(raw[i]);
}

//! The same from a device's buffer of host-order 16-bit values that need not be aligned for
//! them: fakenect hands over its file's bytes after the header, at an odd address.
inline void kinect_raw_bytes_to_mm(int n, const void* raw, std::uint16_t* mm) {
  const auto* bytes = static_cast<const unsigned char*>(raw);
  for (int i = 0; i < n; ++i) {
    std::uint16_t value;
    std::memcpy(&value, bytes + 2 * static_cast<long>(i), sizeof value);  // an unaligned load, not a call
    mm[i] = kinect_raw_to_mm(value);
  }
}

}  // namespace zipfusion
