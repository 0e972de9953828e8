#pragma once
//! \file
//! The calibration wand's red and green LEDs in a colour frame (paper Section IV-A; Svoboda et al.
//! 2005 use the same kind of bright-spot detection). A pixel belongs to an LED when its own channel
//! is bright and clearly dominates the other two (colour ratio), so white lamps, yellow indicators
//! and a lit room do not pass. Bright blobs (any channel above min_level and well above the room's
//! median: a saturated LED core is nearly white) must be LED-sized and round, and mostly of the LED's colour. Exactly one blob
//! per colour is required: a missing or ambiguous LED is reported, never guessed. The position is
//! the centroid of the blob weighted by how much its channel dominates (sub-pixel).
//! Pure functions; thread safe.

#include <Eigen/Core>

#include "zipfusion/core/image.h"

namespace zipfusion {

struct LedDetectionOptions {
  int min_level = 110;           // 8-bit: a blob pixel has a channel at least this bright …
  int min_contrast = 60;         // … and at least this far above the image's median brightness
  double min_dominance = 1.6;    // an LED-coloured pixel: its channel >= this × each other channel
  double min_colored_share = 0.2;  // share of a blob's pixels that must be LED-coloured
  int min_area_px = 2;           // blob area range, pixels (a lamp's glare or a poster is larger)
  int max_area_px = 600;
  double min_fill = 0.4;         // blob area / bounding-box area (round, not a streak)
  double max_aspect = 2.5;       // longer / shorter bounding-box side
  double weight_floor = 15;      // 8-bit: dominance below this does not weigh in the centroid (noise)
  double min_separation_px = 6;  // red and green closer than this overlap: the frame is skipped

  void validate() const;  // throws InvalidInput naming the field
};

enum class LedStatus { kFound, kMissing, kAmbiguous };

struct LedSpot {
  LedStatus status = LedStatus::kMissing;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // sub-pixel centre, valid when found
  int candidates = 0;                               // blobs that passed the shape checks
};

struct WandDetection {
  LedSpot red, green;
  bool overlapping = false;  // both found but closer than min_separation_px
  //! Both LEDs found, once each, apart: the frame can be used.
  bool usable() const { return red.status == LedStatus::kFound && green.status == LedStatus::kFound && !overlapping; }
};

WandDetection detect_wand_leds(const ColorImage& image, const LedDetectionOptions& options = {});

}  // namespace zipfusion
