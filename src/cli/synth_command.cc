// zipfusion synth: write a synthetic multi-Kinect capture with ground truth.

#include <cstdio>
#include <iostream>
#include <memory>

#include "cli/commands.h"
#include "zipfusion/core/error.h"
#include "zipfusion/synth/synth.h"

namespace zipfusion::cli {
namespace {

struct SynthArgs {
  std::string out;
  std::string miscalibrate;
  std::string resolution = "640x480";
  std::string color_format = "jpg";
  std::string noise = "kinect";
  SynthOptions options;
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
    options.color_noise_sigma = 0;
  }
  if (args.no_shadows) options.noise.projector_shadows = false;
  if (args.no_edge_dropout) options.noise.edge_dropout = false;
  if (args.no_holes) options.noise.random_holes = false;
  if (args.no_axial_noise) options.noise.axial_noise = false;
  if (args.no_quantization) options.noise.disparity_quantization = false;
  if (args.no_floor) options.floor = false;

  const SynthResult result = write_synthetic_capture(args.out, options, [](int done, int total) { show_progress("synth", done, total); });
  std::cout << "wrote " << args.out << ": " << result.rig.cameras.size() << " cameras x " << options.frames
            << " frames, ground truth in " << args.out << "/ground_truth\n";
}

}  // namespace

void add_synth_command(CLI::App& app) {
  auto args = std::make_shared<SynthArgs>();
  SynthOptions& o = args->options;
  CLI::App* cmd = app.add_subcommand("synth", "Write a synthetic multi-Kinect capture of a moving person, with ground truth");
  cmd->add_option("--out", args->out, "Output capture folder (must not exist)")->required();
  cmd->add_option("--frames", o.frames, "Frames to render")->capture_default_str();
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
  cmd->add_option("--color-noise", o.color_noise_sigma, "Colour noise sigma, 8-bit levels")->capture_default_str();
  cmd->add_option("--color-format", args->color_format, "Colour files: jpg or png")
      ->check(CLI::IsMember({"jpg", "png"}))
      ->capture_default_str();
  cmd->add_option("--jpeg-quality", o.jpeg_quality, "JPEG quality 1..100")->capture_default_str();
  cmd->add_flag("--no-floor", args->no_floor, "Do not render the floor");
  cmd->add_option("--threads", o.num_threads, "Worker threads (0 = all cores)")->capture_default_str();
  cmd->callback([args] { run_synth(*args); });
}

}  // namespace zipfusion::cli
