#pragma once
//! \file
//! Stage timings on the steady clock.

#include <chrono>

namespace zipfusion {

//! Milliseconds elapsed since `start` on the steady clock.
inline double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace zipfusion
