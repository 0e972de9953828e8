#pragma once
//! \file
//! Synthetic calibration data with known truth (paper Section IV-A): a two-LED wand (red and green
//! LED a fixed distance apart) waved through the capture volume in a dim room with distractors, as
//! every camera's colour camera sees it; and checkerboard views with known intrinsics.
//! Everything is a pure function of the options and the seed; thread safe.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <vector>

#include "zipfusion/core/camera.h"
#include "zipfusion/core/geometry.h"
#include "zipfusion/core/image.h"
#include "zipfusion/synth/synth.h"

namespace zipfusion {

struct WandOptions {
  int frames = 300;                  // frames of the sequence
  double led_distance_m = 0.445;     // distance between the two LEDs, metres (the paper's wand)
  double led_jitter_px = 0.3;        // detection noise: each LED is drawn this far off its true projection (σ per axis), pixels
  double led_glow_radius_m = 0.006;  // σ of the LED's glow on the sensor, metres at the LED (at least 1.2 px is drawn)
  double occlusion_probability = 0.04;  // per camera, frame and LED: hidden (a hand, the subject)
  double reflection_probability = 0.03;  // per camera and frame: a second, LED-like red or green spot (ambiguous frame)
  int lamps = 5;                     // static distractors per camera: white, yellow spots and a red poster
  double background_level = 22;      // dim room, 8-bit level
  double color_noise_sigma = 2.0;    // sensor noise, 8-bit levels
  std::uint64_t seed = 1;

  void validate() const;  // throws InvalidInput naming the field
};

//! The LEDs' true world positions, one per frame.
struct WandSequence {
  std::vector<Eigen::Vector3d> red, green;
};

//! A smooth sweep of the wand through `volume` (shrunk by 0.3 m, the floor avoided): its centre on a
//! Lissajous curve, its direction turning, so the LEDs fill the volume and every camera pair shares
//! many of them.
WandSequence make_wand_sequence(const Box3d& volume, const WandOptions& options);

//! What a colour camera records of frame `frame`: dim background with noise, static lamps, the
//! visible LEDs. `camera` only selects the random streams (distractors, occlusion).
ColorImage render_wand_view(const Intrinsics& k, const Rigid3d& color_from_world, const WandSequence& sequence, int frame,
                            int camera, const WandOptions& options);

//! A wand capture of the ring rig `rig_options` describes: rig.json (poses perturbed by
//! rig_options.miscalibrate_*, camera 0 true), colour PNGs, depth PNGs of the person waving the
//! wand (rig_options' subject, noise and floor; the wand is too thin for depth),
//! ground_truth/rig.json and ground_truth/wand.json (the true LED positions). Written into a
//! temporary sibling folder and renamed into place; `out_dir` must not exist or be empty.
SynthResult write_wand_capture(const std::filesystem::path& out_dir, const SynthOptions& rig_options,
                               const WandOptions& options, const std::function<void(int, int)>& progress = {});

struct CheckerboardOptions {
  int views = 20;                 // board views to render
  int inner_columns = 9;          // inner corners along the board's x
  int inner_rows = 6;             // inner corners along the board's y
  double square_m = 0.025;        // square side, metres
  bool white_margin = true;       // a square's width of white around the squares (false: printed to the edge, the wall behind)
  Intrinsics intrinsics{.width = 640, .height = 480, .fx = 530, .fy = 526, .cx = 322.5, .cy = 236.0};  // the truth
  // Board centre's distance from the camera, metres; 0 (both): from the board's size, so that it
  // fills 55 % down to 29 % of the image (0.45–0.85 m for the default board and camera).
  double min_distance_m = 0;
  double max_distance_m = 0;
  double max_tilt_deg = 35;       // board tilt about its x and y axes, degrees
  double color_noise_sigma = 2.0; // 8-bit levels
  int supersampling = 3;          // samples per pixel and axis (anti-aliasing: sub-pixel corners)
  std::uint64_t seed = 1;
  int num_threads = 0;            // 0 = all hardware threads

  void validate() const;  // throws InvalidInput naming the field
};

struct CheckerboardView {
  ColorImage image;
  Rigid3d cam_from_board;  // board frame: origin at the first inner corner, x along a row, z into the board
};

//! Renders board views with the whole board in the image (no distortion).
std::vector<CheckerboardView> render_checkerboard_views(const CheckerboardOptions& options);

//! Writes view_000.png … and truth.json (intrinsics, board) into `out_dir` (created; must not
//! hold files already).
void write_checkerboard_views(const std::filesystem::path& out_dir, const CheckerboardOptions& options);

}  // namespace zipfusion
