#pragma once
//! \file
//! What a calibration target may be: shared by what calibrates from targets (calib) and what
//! renders them (synth), so that every target synth writes can be calibrated from.

#include <cstdio>
#include <string>

namespace zipfusion {

//! Inner corners of a checkerboard, each way: OpenCV's detector needs three; a board of more
//! than 100 is no printable one (and the bound keeps corner counts far from overflow).
inline constexpr int kFewestBoardCorners = 3;
inline constexpr int kMostBoardCorners = 100;

//! Distance between the wand's two LEDs, metres (exclusive bounds). At 5 cm the LEDs are still
//! 6 px apart at 4.5 m through a 525 px lens, where LED detection tells them apart; a bar of 5 m
//! is longer than the volume it is waved through.
inline constexpr double kShortestWandM = 0.05;
inline constexpr double kLongestWandM = 5.0;

//! What an LED distance outside (kShortestWandM, kLongestWandM) is told.
inline std::string wand_distance_rule() {
  char text[64];
  std::snprintf(text, sizeof text, "must be in (%g, %g) metres", kShortestWandM, kLongestWandM);
  return text;
}

}  // namespace zipfusion
