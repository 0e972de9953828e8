// LED detection on synthetic wand views: sub-pixel accuracy against the true projections, and
// distractors, occlusions and reflections turned into skipped frames rather than guesses.

#include "zipfusion/calib/led_detection.h"

#include <gtest/gtest.h>

#include "zipfusion/core/error_test_util.h"
#include "zipfusion/synth/calib_targets.h"

namespace zipfusion {
namespace {

struct Scene {
  Intrinsics k{.width = 640, .height = 480, .fx = 525, .fy = 525, .cx = 319.5, .cy = 239.5};
  Rigid3d color_from_world = look_at({2.5, 0.3, 1.3}, {0, 0, 0.9}).inverse();
  WandSequence sequence;
  explicit Scene(const WandOptions& options) : sequence(make_wand_sequence(Box3d{{-1, -1, 0.02}, {1, 1, 2.2}}, options)) {}
  bool in_view(const Eigen::Vector3d& world) const {
    const Eigen::Vector2d p = project(k, color_from_world * world);
    return p.x() > 5 && p.y() > 5 && p.x() < k.width - 6 && p.y() < k.height - 6;
  }
};

TEST(LedDetection, FindsBothLedsToATenthOfAPixelDespiteLampsAndAPoster) {
  const WandOptions options{.frames = 60, .led_jitter_px = 0, .occlusion_probability = 0, .reflection_probability = 0, .lamps = 6};
  const Scene scene(options);
  int frames_in_view = 0, usable = 0;
  double worst = 0, sum = 0;
  for (int f = 0; f < options.frames; ++f) {
    if (!scene.in_view(scene.sequence.red[f]) || !scene.in_view(scene.sequence.green[f])) continue;
    ++frames_in_view;
    const WandDetection d = detect_wand_leds(render_wand_view(scene.k, scene.color_from_world, scene.sequence, f, 0, options));
    if (!d.usable()) continue;
    ++usable;
    for (const auto& [spot, world] : {std::pair{d.red, scene.sequence.red[f]}, std::pair{d.green, scene.sequence.green[f]}}) {
      const double error = (spot.pixel - project(scene.k, scene.color_from_world * world)).norm();
      worst = std::max(worst, error);
      sum += error;
    }
  }
  ASSERT_GT(frames_in_view, 40);
  // Only the frames where the two LEDs overlap in the image may be lost.
  EXPECT_GE(usable, frames_in_view - 3);
  EXPECT_LT(sum / (2 * usable), 0.06);
  EXPECT_LT(worst, 0.2);
}

TEST(LedDetection, ReportsOccludedLedsAsMissingAndReflectionsAsAmbiguous) {
  WandOptions options{.frames = 20, .occlusion_probability = 0, .reflection_probability = 1};
  const Scene scene(options);
  // A reflection may land on the poster or outside the image; most must make the frame ambiguous.
  int in_view = 0, ambiguous = 0;
  for (int f = 0; f < options.frames; ++f) {
    const WandDetection d = detect_wand_leds(render_wand_view(scene.k, scene.color_from_world, scene.sequence, f, 0, options));
    if (!scene.in_view(scene.sequence.red[f]) || !scene.in_view(scene.sequence.green[f])) continue;
    ++in_view;
    if (d.red.status == LedStatus::kAmbiguous || d.green.status == LedStatus::kAmbiguous) {
      ++ambiguous;
      EXPECT_FALSE(d.usable()) << "frame " << f;
    }
  }
  ASSERT_GE(in_view, options.frames / 2);  // else the share below says little
  EXPECT_GE(ambiguous, in_view * 8 / 10);
  options.reflection_probability = 0;
  options.occlusion_probability = 0.999;
  for (int f = 0; f < 5; ++f) {
    const WandDetection d = detect_wand_leds(render_wand_view(scene.k, scene.color_from_world, scene.sequence, f, 0, options));
    EXPECT_EQ(d.red.status, LedStatus::kMissing);
    EXPECT_EQ(d.green.status, LedStatus::kMissing);
  }
}

TEST(LedDetection, IgnoresALitRoom) {
  // A bright, warm room (level 90, noise 4): the colour-ratio test still isolates the LEDs.
  const WandOptions options{.frames = 30, .led_jitter_px = 0, .occlusion_probability = 0, .reflection_probability = 0,
                            .background_level = 90, .color_noise_sigma = 4};
  const Scene scene(options);
  int usable = 0, in_view = 0;
  for (int f = 0; f < options.frames; ++f) {
    if (!scene.in_view(scene.sequence.red[f]) || !scene.in_view(scene.sequence.green[f])) continue;
    ++in_view;
    const WandDetection d = detect_wand_leds(render_wand_view(scene.k, scene.color_from_world, scene.sequence, f, 0, options));
    if (!d.usable()) continue;
    ++usable;
    EXPECT_LT((d.red.pixel - project(scene.k, scene.color_from_world * scene.sequence.red[f])).norm(), 0.3);
  }
  // The green LED's blue leak leaves few green-dominated pixels on a bright bluish wall when it is
  // far away: those frames are skipped (not guessed); most remain.
  ASSERT_GE(in_view, options.frames / 2);
  EXPECT_GE(usable, in_view * 8 / 10);
}

TEST(LedDetection, ValidateNamesTheField) {
  const std::string message = invalid_input_message([] { LedDetectionOptions{.min_dominance = 0.5}.validate(); });
  EXPECT_NE(message.find("min_dominance"), std::string::npos) << message;
}

}  // namespace
}  // namespace zipfusion
