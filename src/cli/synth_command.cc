// zipfusion synth: write a synthetic multi-Kinect capture with ground truth.

#include <cstdio>
#include <iostream>
#include <memory>

#include "cli/commands.h"
#include "zipfusion/core/error.h"
#include "zipfusion/synth/calib_targets.h"
#include "zipfusion/synth/fakenect_scene.h"
#include "zipfusion/synth/synth.h"

namespace zipfusion::cli {
namespace {

struct SynthArgs {
  std::string out;
  std::string miscalibrate;
  std::string resolution = "640x480";
  std::string color_format = "jpg";
  bool color_noise_given = false;  // --color-noise on the command line: --noise none leaves it
  std::string noise = "kinect";
  SynthOptions options;
  bool wand = false, checkerboard = false;
  std::string fakenect;
  FakenectSceneOptions fakenect_options;
  WandOptions wand_options;
  int views = 20;
  std::string board = "9x6";
  double square_m = 0.025;
  bool no_shadows = false, no_edge_dropout = false, no_holes = false, no_axial_noise = false, no_quantization = false, no_floor = false;
};

void parse_miscalibration(const std::string& text, SynthOptions& options) {
  if (text.empty()) return;
  double degrees = 0, metres = 0;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%lf,%lf%c", &degrees, &metres, &tail) != 2) {
    throw InvalidInput("--miscalibrate: expected DEG,M (e.g. 0.5,0.01), got \"" + text + "\"");
  }
  options.miscalibrate_deg = degrees;
  options.miscalibrate_m = metres;
}

void parse_resolution(const std::string& text, SynthOptions& options) {
  int width = 0, height = 0;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%dx%d%c", &width, &height, &tail) != 2) {
    throw InvalidInput("--resolution: expected WxH (e.g. 320x240), got \"" + text + "\"");
  }
  options.depth_width = width;
  options.depth_height = height;
}

void run_synth(SynthArgs& args) {
  SynthOptions& options = args.options;
  parse_miscalibration(args.miscalibrate, options);
  parse_resolution(args.resolution, options);
  options.color_extension = "." + args.color_format;
  if (args.noise == "none") {
    options.noise = KinectNoiseOptions::none();
    if (!args.color_noise_given) options.color_noise_sigma = 0;  // an explicit --color-noise still counts
  }
  if (args.no_shadows) options.noise.projector_shadows = false;
  if (args.no_edge_dropout) options.noise.edge_dropout = false;
  if (args.no_holes) options.noise.random_holes = false;
  if (args.no_axial_noise) options.noise.axial_noise = false;
  if (args.no_quantization) options.noise.disparity_quantization = false;
  if (args.no_floor) options.floor = false;

  if (!args.fakenect.empty()) {
    if (!args.out.empty()) throw InvalidInput("--out, --fakenect: choose one (--fakenect DIR is where the dump goes)");
    const FakenectSceneResult result =
        write_fakenect_scene(args.fakenect, options, args.fakenect_options, [](int done, int total) { show_progress("synth", done, total); });
    std::cout << "wrote " << args.fakenect << ": fakenect dump of camera " << args.fakenect_options.camera << ", " << result.frames_listed
              << " of " << options.frames << " frames in INDEX.txt; the truth (depth before raw encoding, colour, timestamps) in "
              << args.fakenect << "/truth\n";
    return;
  }
  if (args.out.empty()) throw InvalidInput("--out: required (or --fakenect DIR)");
  if (args.checkerboard) {
    options.validate();  // --resolution, --threads, --color-noise as for a capture
    if (options.depth_width < 64 || options.depth_height < 48) {
      throw InvalidInput("--resolution: checkerboard views need at least 64x48, got " + args.resolution);
    }
    CheckerboardOptions board{.views = args.views, .square_m = args.square_m, .seed = options.seed, .num_threads = options.num_threads};
    if (args.color_noise_given) board.color_noise_sigma = options.color_noise_sigma;  // its own default otherwise
    char tail = 0;
    if (std::sscanf(args.board.c_str(), "%dx%d%c", &board.inner_columns, &board.inner_rows, &tail) != 2) {
      throw InvalidInput("--board: expected COLUMNSxROWS of inner corners (e.g. 9x6), got \"" + args.board + "\"");
    }
    board.intrinsics.width = options.depth_width;
    board.intrinsics.height = options.depth_height;
    board.intrinsics.fx *= options.depth_width / 640.0;
    board.intrinsics.fy *= options.depth_width / 640.0;
    board.intrinsics.cx *= options.depth_width / 640.0;
    board.intrinsics.cy *= options.depth_height / 480.0;
    write_checkerboard_views(args.out, board);
    const Intrinsics& k = board.intrinsics;
    std::printf("wrote %s: %d checkerboard views (%dx%d inner corners, %.3f m squares), true fx %.2f fy %.2f cx %.2f cy %.2f in %s/truth.json\n",
                args.out.c_str(), board.views, board.inner_columns, board.inner_rows, board.square_m, k.fx, k.fy, k.cx, k.cy,
                args.out.c_str());
    return;
  }
  if (args.wand) {
    args.wand_options.seed = options.seed;
    if (args.color_noise_given) args.wand_options.color_noise_sigma = options.color_noise_sigma;
    const SynthResult result = write_wand_capture(args.out, options, args.wand_options,
                                                  [](int done, int total) { show_progress("synth", done, total); });
    std::cout << "wrote " << args.out << ": wand capture, " << result.rig.cameras.size() << " cameras x " << args.wand_options.frames
              << " frames, true poses in " << args.out << "/ground_truth\n";
    return;
  }
  const SynthResult result = write_synthetic_capture(args.out, options, [](int done, int total) { show_progress("synth", done, total); });
  std::cout << "wrote " << args.out << ": " << result.rig.cameras.size() << " cameras x " << options.frames
            << " frames, ground truth in " << args.out << "/ground_truth\n";
}

}  // namespace

void add_synth_command(CLI::App& app) {
  auto args = std::make_shared<SynthArgs>();
  SynthOptions& o = args->options;
  CLI::App* cmd = app.add_subcommand("synth", "Write a synthetic multi-Kinect capture of a moving person, with ground truth");
  cmd->add_option("--out", args->out, "Output capture folder (new, or an empty folder)");
  cmd->add_option("--fakenect", args->fakenect,
                  "Write a fakenect dump (INDEX.txt, raw 11-bit depth PGM, RGB PPM, as fakenect-record writes them) of one camera of "
                  "the scene instead, with the truth in DIR/truth; replay it with: fakenect DIR zipfusion record --devices all ...");
  cmd->add_option("--camera", args->fakenect_options.camera, "--fakenect: which camera of the ring is recorded")->capture_default_str();
  cmd->add_option("--truncate", args->fakenect_options.truncate_at,
                  "--fakenect: INDEX.txt ends after frame N's colour image, as a device unplugged mid-recording leaves it (-1 = complete)")
      ->capture_default_str();
  cmd->add_option("--frames", o.frames, "Frames to render")->capture_default_str();
  cmd->add_flag("--wand", args->wand,
                "Write a calibration capture instead: a red and a green LED waved through the volume in a dim room with "
                "distractors (colour PNGs; depth of the person waving it and the floor); --frames sets its length (default 300 with --wand)");
  cmd->add_option("--led-distance", args->wand_options.led_distance_m, "--wand: distance between the LEDs, metres")->capture_default_str();
  cmd->add_option("--led-jitter", args->wand_options.led_jitter_px, "--wand: detection noise, pixels (sigma per axis)")->capture_default_str();
  cmd->add_flag("--checkerboard", args->checkerboard, "Write checkerboard views with known intrinsics (PNGs + truth.json) instead");
  cmd->add_option("--views", args->views, "--checkerboard: views to render")->capture_default_str();
  cmd->add_option("--board", args->board, "--checkerboard: inner corners COLUMNSxROWS")->capture_default_str();
  cmd->add_option("--square", args->square_m, "--checkerboard: square side, metres")->capture_default_str();
  cmd->add_option("--fps", o.fps, "Frames per second")->capture_default_str();
  cmd->add_option("--cameras", o.cameras, "Cameras on the circle")->capture_default_str();
  cmd->add_option("--radius", o.radius_m, "Circle radius, metres")->capture_default_str();
  cmd->add_option("--height", o.camera_height_m, "Camera height above the floor, metres")->capture_default_str();
  cmd->add_option("--target-height", o.target_height_m, "Height the cameras look at, metres")->capture_default_str();
  cmd->add_option("--resolution", args->resolution, "Depth and colour image size WxH (the field of view stays the Kinect's)")
      ->capture_default_str();
  cmd->add_option("--subject", o.subject_pattern,
                  "Mesh sequence instead of the built-in human: printf pattern of .ply/.obj files, e.g. 'dir/%06d.ply'");
  cmd->add_option("--miscalibrate", args->miscalibrate,
                  "DEG,M: perturb the poses written to rig.json (all cameras but the first) by DEG degrees and M metres; "
                  "the true poses go to ground_truth/rig.json");
  cmd->add_option("--seed", o.seed, "Random seed (output is deterministic for a seed)")->capture_default_str();
  cmd->add_option("--noise", args->noise, "Sensor model: kinect (all effects) or none (ideal depth and colour)")
      ->check(CLI::IsMember({"kinect", "none"}))
      ->capture_default_str();
  cmd->add_flag("--no-shadows", args->no_shadows, "No IR projector shadows");
  cmd->add_flag("--no-edge-dropout", args->no_edge_dropout, "No missing depth at depth edges");
  cmd->add_flag("--no-holes", args->no_holes, "No small random holes");
  cmd->add_flag("--no-axial-noise", args->no_axial_noise, "No axial noise sigma(z)");
  cmd->add_flag("--no-quantization", args->no_quantization, "No 1/8-px disparity quantisation");
  cmd->add_option("--color-noise", o.color_noise_sigma, "Colour noise sigma, 8-bit levels (0 with --noise none unless given)")->capture_default_str();
  cmd->add_option("--color-format", args->color_format, "Colour files: jpg or png")
      ->check(CLI::IsMember({"jpg", "png"}))
      ->capture_default_str();
  cmd->add_option("--jpeg-quality", o.jpeg_quality, "JPEG quality 1..100")->capture_default_str();
  cmd->add_flag("--no-floor", args->no_floor, "Do not render the floor");
  add_threads_option(cmd, o.num_threads);
  cmd->callback([args, cmd] {
    // An option of another mode would be ignored: refused, naming the mode it belongs to.
    auto only_with = [&](std::initializer_list<const char*> options, bool mode_chosen, const std::string& mode) {
      std::string given;
      for (const char* option : options) {
        if (cmd->count(option) > 0) given += (given.empty() ? "" : ", ") + std::string(option);
      }
      if (!given.empty() && !mode_chosen) throw InvalidInput(given + ": only with " + mode);
    };
    // One mode first: its own options are then judged against it.
    if (args->wand + args->checkerboard + !args->fakenect.empty() > 1) throw InvalidInput("--wand, --checkerboard, --fakenect: choose one");
    only_with({"--views", "--board", "--square"}, args->checkerboard, "--checkerboard");
    only_with({"--led-distance", "--led-jitter"}, args->wand, "--wand");
    only_with({"--camera", "--truncate"}, !args->fakenect.empty(), "--fakenect");
    if (args->checkerboard) {
      // Checkerboard views are one camera's images: the capture's options have no meaning there.
      only_with({"--frames", "--fps", "--cameras", "--radius", "--height", "--target-height", "--subject", "--miscalibrate", "--noise",
                 "--no-shadows", "--no-edge-dropout", "--no-holes", "--no-axial-noise", "--no-quantization", "--color-format",
                 "--jpeg-quality", "--no-floor"},
                false, "a capture (not with --checkerboard)");
    }
    // A wand capture's colour is PNG, a fakenect dump's PPM: their format options mean nothing.
    only_with({"--jpeg-quality"}, !args->wand && args->fakenect.empty(), "a capture (not with --wand or --fakenect)");
    if ((args->wand || !args->fakenect.empty()) && cmd->count("--color-format") > 0) {
      throw InvalidInput(std::string("--color-format: ") + (args->wand ? "a wand capture's colour is always PNG" : "a fakenect dump's colour is PPM"));
    }
    args->wand_options.frames = cmd->count("--frames") > 0 ? args->options.frames : 300;
    args->color_noise_given = cmd->count("--color-noise") > 0;
    run_synth(*args);
  });
}

}  // namespace zipfusion::cli
