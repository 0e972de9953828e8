#pragma once
//! \file
//! Synthetic rig captures with ground truth: a subject (the built-in walking, waving human or a
//! mesh sequence from disk) seen by N Kinect-v1-like cameras on a circle, rendered with the sensor
//! model of kinect_model.h, written in the `zipfusion.rig/1` format.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

#include "zipfusion/core/mesh.h"
#include "zipfusion/io/rig.h"
#include "zipfusion/synth/human.h"
#include "zipfusion/synth/kinect_model.h"

namespace zipfusion {

struct SynthOptions {
  int frames = 30;                  // frames to render
  double fps = 30;                  // frames per second (also the subject's clock)
  int cameras = 4;                  // cameras on the circle, >= 1
  double radius_m = 2.5;            // circle radius, metres
  double camera_height_m = 1.3;     // camera height above the floor, metres
  double target_height_m = 0.9;     // height of the point every camera looks at, metres
  int depth_width = 640;            // image size; the Kinect's field of view is kept (focal lengths
  int depth_height = 480;           // scale with the width), colour scales alike
  std::string subject_pattern;      // printf pattern of a .ply/.obj sequence ("dir/%06d.ply"); empty = built-in human
  HumanOptions human;
  KinectNoiseOptions noise;
  double color_noise_sigma = 3.0;   // colour sensor noise, 8-bit levels (0 = off)
  std::string color_extension = ".jpg";  // ".jpg" or ".png"
  int jpeg_quality = 90;            // 1..100
  bool floor = true;                // render the floor z = 0 (background, outside `volume`)
  double miscalibrate_deg = 0;      // rotation of each written pose but camera 0's, degrees
  double miscalibrate_m = 0;        // translation of each written pose but camera 0's, metres
  std::uint64_t seed = 1;           // all randomness derives from it
  int num_threads = 0;              // 0 = all hardware threads

  void validate() const;  // throws InvalidInput naming the field
};

//! The rig the options describe, with true poses: camera k at angle 45° + k·360°/N on the circle,
//! looking at (0, 0, target_height_m); Kinect v1 intrinsics (depth 640×480 f 580, colour 640×480 f
//! 525 2.5 cm to the depth camera's +x), both scaled to depth_width × depth_height.
Rig make_ring_rig(const SynthOptions& options);

//! The rig as written to rig.json: poses of cameras 1..N−1 each moved by exactly
//! miscalibrate_deg about a random axis and miscalibrate_m in a random direction.
Rig miscalibrate(const Rig& true_rig, const SynthOptions& options);

//! samba-4cam's capture volume: x, y in ±1 m, z from kVolumeFloorClearanceM (0.02) to 2.2 m.
inline Box3d samba_capture_volume() { return {{-1.0, -1.0, kVolumeFloorClearanceM}, {1.0, 1.0, 2.2}}; }

//! The capture volume written to rig.json: samba_capture_volume, grown to hold the subject's first
//! frame with 0.3 m to spare; the floor stays below it.
Box3d synthetic_capture_volume(const TriangleMesh& first_subject);

//! The subject's true surface at a frame (world coordinates, coloured).
TriangleMesh subject_mesh(const SynthOptions& options, int frame);

//! One camera's synthetic images of a frame.
struct SyntheticView {
  DepthImage depth;
  ColorImage color;
};

//! Renders what camera `camera` of `true_rig` records of `subject` (plus the floor).
SyntheticView render_view(const TriangleMesh& subject, const Rig& true_rig, int camera, int frame,
                          const SynthOptions& options);

//! The depth image of render_view alone.
DepthImage render_depth_view(const TriangleMesh& subject, const Rig& true_rig, int camera, int frame, const SynthOptions& options);

struct SynthResult {
  Rig rig;       // as written to rig.json
  Rig true_rig;  // as written to ground_truth/rig.json
};

//! Writes the capture to `out_dir`, which must not exist yet (or be empty). Everything is written
//! into a sibling temporary folder that is renamed into place at the end, so a failure leaves
//! nothing half-written. `progress(done, total)` is called after each frame.
SynthResult write_synthetic_capture(const std::filesystem::path& out_dir, const SynthOptions& options,
                                    const std::function<void(int, int)>& progress = {});

}  // namespace zipfusion
