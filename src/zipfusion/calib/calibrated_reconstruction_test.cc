// The last target: a rig calibrated from the synthetic wand, then used to reconstruct the
// subject, scores within 0.5 mm mean accuracy of the same frame reconstructed with the true poses.

#include <gtest/gtest.h>

#include <cstdio>

#include "zipfusion/calib/extrinsics.h"
#include "zipfusion/core/parallel.h"
#include "zipfusion/eval/eval.h"
#include "zipfusion/pipeline/reconstruct.h"
#include "zipfusion/synth/calib_targets.h"

namespace zipfusion {
namespace {

Rig calibrate_from_wand(const SynthOptions& rig_options) {
  const Rig truth = make_ring_rig(rig_options);
  const Rig start = miscalibrate(truth, rig_options);
  const WandOptions wand{.frames = 300};
  const WandSequence sequence = make_wand_sequence(Box3d{{-1, -1, 0.02}, {1, 1, 2.2}}, wand);
  const int n = static_cast<int>(truth.cameras.size());
  WandObservations obs(n, wand.frames);
  parallel_for(0, n * wand.frames, [&](int i) {
    const int c = i % n, f = i / n;
    const CameraModel& cam = truth.cameras[c];
    const Rigid3d color_from_world = cam.color_from_depth * cam.world_from_depth.inverse();
    const WandDetection d = detect_wand_leds(render_wand_view(*cam.color_intrinsics, color_from_world, sequence, f, c, wand));
    if (!d.usable()) return;
    obs.red[obs.at(c, f)] = d.red.pixel;
    obs.green[obs.at(c, f)] = d.green.pixel;
    obs.usable[obs.at(c, f)] = 1;
  });
  return calibrate_extrinsics(start, obs).rig;
}

TEST(CalibratedReconstruction, ScoresWithinHalfAMillimetreOfTheTruePoses) {
  const SynthOptions options{.frames = 1, .cameras = 4, .miscalibrate_deg = 2, .miscalibrate_m = 0.05};
  Rig true_rig = make_ring_rig(options);
  const TriangleMesh truth = subject_mesh(options, 0);
  true_rig.volume = synthetic_capture_volume(truth);
  Rig calibrated = calibrate_from_wand(options);
  calibrated.volume = true_rig.volume;
  Rig miscalibrated = miscalibrate(true_rig, options);

  FrameSet frames{.index = 0, .cameras = {}};
  for (int c = 0; c < options.cameras; ++c) {
    SyntheticView view = render_view(truth, true_rig, c, 0, options);
    frames.cameras.push_back({.has_depth = true, .depth = std::move(view.depth), .has_color = true, .color = std::move(view.color)});
  }
  auto accuracy_mm = [&](const Rig& rig) {
    FrameReconstructor reconstructor(rig, {});
    return evaluate_frame(reconstructor.reconstruct(frames).mesh, truth, true_rig, true_rig.volume).accuracy_mean_mm;
  };
  const double with_truth = accuracy_mm(true_rig), with_calibration = accuracy_mm(calibrated), uncalibrated = accuracy_mm(miscalibrated);
  std::printf("mean accuracy: true poses %.3f mm, calibrated %.3f mm, uncalibrated (2 deg / 5 cm) %.3f mm\n", with_truth,
              with_calibration, uncalibrated);
  EXPECT_LT(std::abs(with_calibration - with_truth), 0.5);
  EXPECT_GT(uncalibrated, with_truth + 0.5);  // the test can tell a bad rig
}

}  // namespace
}  // namespace zipfusion
