// zipfusion calibrate: intrinsics from checkerboard images, the rig's poses from a two-LED wand
// capture (paper Section IV-A; docs/design.md "Calibration").

#include <glob.h>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string_view>
#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "cli/frame_input.h"
#include "cli/frame_range.h"
#include "cli/rig_poses.h"
#include "zipfusion/calib/depth_scale.h"
#include "zipfusion/calib/extrinsics.h"
#include "zipfusion/calib/floor.h"
#include "zipfusion/calib/intrinsics.h"
#include "zipfusion/core/error.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/image_io.h"

namespace zipfusion::cli {
namespace {

struct IntrinsicsArgs {
  std::string images, board = "9x6", out;
  double square_m = 0.025;
  bool no_distortion = false;
};

struct ExtrinsicsArgs {
  std::string capture, out;
  ExtrinsicOptions options;
  int threads = 0;
  std::vector<std::string> color_intrinsics, depth_intrinsics;  // NAME=FILE each
  std::string scale = "check";    // --scale: check (the LED distance's, refused where the depth disagrees), led, depth
  double scale_tolerance = 0.02;  // --scale-tolerance: how far the cameras may lie from where the depth puts them, a share of their distance from camera 0
};

struct FloorArgs {
  std::string capture, rig, frames, out;  // frames empty: FloorOptions' first frames
  FloorOptions options;
  bool no_volume = false;
  std::string floor_plane = "lowest";  // --floor
};

std::vector<std::string> glob_files(const std::string& pattern) {
  glob_t found{};
  const int rc = ::glob(pattern.c_str(), 0, nullptr, &found);
  std::vector<std::string> files;
  if (rc == 0) {
    for (size_t i = 0; i < found.gl_pathc; ++i) files.emplace_back(found.gl_pathv[i]);
  }
  ::globfree(&found);
  if (files.empty()) throw InvalidInput("--images: no file matches '" + pattern + "'");
  return files;  // glob sorts them
}

BoardOptions parse_board(const std::string& text, double square_m) {
  int columns = 0, rows = 0;
  const char* end = text.data() + text.size();
  const auto [after_columns, columns_error] = std::from_chars(text.data(), end, columns);
  const bool has_x = columns_error == std::errc() && after_columns != end && *after_columns == 'x';
  const auto [after_rows, rows_error] = has_x ? std::from_chars(after_columns + 1, end, rows) : std::from_chars_result{end, std::errc::invalid_argument};
  if (!has_x || rows_error != std::errc() || after_rows != end) {
    throw InvalidInput("--board: expected COLUMNSxROWS of inner corners (e.g. 9x6), got \"" + text + "\"");
  }
  BoardOptions board{.inner_columns = columns, .inner_rows = rows, .square_m = square_m};
  board.validate();  // its messages name --board and --square
  return board;
}

// Fewer views used than this get a warning (Zhang's method needs 3; the principal point needs more).
constexpr int kFewestViewsAdvised = 10;

// No board found at all: when the images show a board of another size, --board is likely wrong
// (squares counted instead of inner corners, or another board), and the error says what they
// show. With some boards found, --board is right and the usual too-few error stands.
void explain_missing_boards(const std::vector<std::string>& files, const std::vector<std::optional<std::vector<Eigen::Vector2d>>>& corners,
                            const BoardOptions& board) {
  if (std::any_of(corners.begin(), corners.end(), [](const auto& c) { return c.has_value(); })) return;
  constexpr int kImagesProbed = 3;  // a board partly hidden in one of them looks smaller: the largest counts
  std::optional<std::pair<int, int>> largest;
  std::string shown_in;
  for (size_t i = 0; i < files.size() && static_cast<int>(i) < kImagesProbed; ++i) {
    const std::optional<std::pair<int, int>> size = largest_board_in(read_color_image(files[i]), board);
    if (size && (!largest || size->first * size->second > largest->first * largest->second)) {
      largest = size;
      shown_in = files[i];
    }
  }
  if (!largest || *largest == std::pair{board.inner_columns, board.inner_rows}) return;
  throw InvalidInput("--board: " + std::to_string(board.inner_columns) + "x" + std::to_string(board.inner_rows) + " found in none of " +
                     std::to_string(files.size()) + " images; the largest board seen, in " + shown_in + ", has " + std::to_string(largest->first) +
                     "x" + std::to_string(largest->second) +
                     " inner corners (a board partly hidden looks smaller; --board counts inner corners: squares - 1 each way)");
}

void run_intrinsics(const IntrinsicsArgs& args) {
  const BoardOptions board = parse_board(args.board, args.square_m);
  check_output_file(args.out);
  check_replaces_only_format(args.out, kIntrinsicsFormat, "--out");
  const std::vector<std::string> files = glob_files(args.images);
  std::vector<std::optional<std::vector<Eigen::Vector2d>>> corners(files.size());
  int width = 0, height = 0;
  for (size_t i = 0; i < files.size(); ++i) {
    const ColorImage image = read_color_image(files[i]);
    if (i == 0) {
      width = image.width;
      height = image.height;
    } else if (image.width != width || image.height != height) {
      throw InvalidInput(files[i] + ": size: " + std::to_string(image.width) + "x" + std::to_string(image.height) + ", but " + files[0] +
                         " is " + std::to_string(width) + "x" + std::to_string(height) + " (one camera per run)");
    }
    corners[i] = detect_board_corners(image, board);
    show_progress("corners", static_cast<int>(i) + 1, static_cast<int>(files.size()));
  }
  const IntrinsicOptions options{.estimate_distortion = !args.no_distortion};
  explain_missing_boards(files, corners, board);
  const IntrinsicResult result = calibrate_intrinsics(corners, files, width, height, board, options);

  nlohmann::json views = nlohmann::json::array();
  std::cout << "view                                   board  used  RMS px\n";
  for (const ViewReport& v : result.views) {
    const bool duplicate = std::find(result.duplicates.begin(), result.duplicates.end(), v.name) != result.duplicates.end();
    // No board (or a copy of an earlier view, not calibrated): no error of its own.
    const bool measured = v.board_found && !duplicate;
    views.push_back({{"file", v.name}, {"board_found", v.board_found}, {"used", v.used}, {"duplicate", duplicate},
                     {"rms_px", measured ? nlohmann::json(v.rms_px) : nlohmann::json(nullptr)}});
    char line[512];
    // A copy of an earlier view was not calibrated: it has no error of its own.
    std::snprintf(line, sizeof line, "%-38s %-6s %-5s %s\n", v.name.c_str(), v.board_found ? "yes" : "no",
                  v.used ? "yes" : "no", v.board_found && !duplicate ? std::to_string(v.rms_px).substr(0, 5).c_str() : "-");
    std::cout << line;
  }
  for (const std::string& name : result.rejected) std::cout << "rejected (error far above the other views): " << name << "\n";
  for (const std::string& name : result.duplicates) std::cout << "left out (the same board pose as an earlier view): " << name << "\n";
  const Intrinsics& k = result.intrinsics;
  const auto used = std::count_if(result.views.begin(), result.views.end(), [](const ViewReport& v) { return v.used; });
  std::printf("fx %.3f  fy %.3f  cx %.3f  cy %.3f  k1 %.5f  k2 %.5f; overall RMS %.3f px over %zu views\n", k.fx, k.fy, k.cx, k.cy,
              k.distortion[0], k.distortion[1], result.rms_px, static_cast<size_t>(used));
  // A low RMS over few views says little: with three, the principal point can be pixels off.
  if (used < kFewestViewsAdvised) {
    print_diagnostic("calibrate: warning: only " + std::to_string(used) + " views used; " + std::to_string(kFewestViewsAdvised) +
                     " or more, the board tilted differently in each, pin the principal point down");
  }
  const nlohmann::json out = {{"format", kIntrinsicsFormat},
                              {"intrinsics", nlohmann::json::parse(format_intrinsics(k))},
                              {"rms_px", result.rms_px},
                              {"board", {{"inner_columns", board.inner_columns}, {"inner_rows", board.inner_rows}, {"square_m", board.square_m}}},
                              {"views", views},
                              {"rejected", result.rejected},
                              {"duplicates", result.duplicates}};
  write_file_atomic(args.out, json_text(out, 2) + "\n");
  std::cout << "wrote " << args.out << "\n";
}

// Puts each NAME=FILE's intrinsics (a `calibrate intrinsics` file) into that camera of the rig,
// as its colour (`color`) or depth intrinsics. The image size must be the camera's: intrinsics
// are calibrated at one resolution, and the frames are checked against rig.json's size.
void apply_intrinsics_files(const std::vector<std::string>& assignments, bool color, const std::string& rig_source, Rig& rig) {
  const std::string option = color ? "--intrinsics" : "--depth-intrinsics";
  std::vector<std::string> named;
  for (const std::string& assignment : assignments) {
    const size_t equals = assignment.find('=');
    if (equals == std::string::npos || equals == 0 || equals + 1 == assignment.size()) {
      throw InvalidInput(option + ": expected CAMERA=FILE (e.g. cam0=cam0.json), got \"" + assignment + "\"");
    }
    const std::string name = assignment.substr(0, equals), file = assignment.substr(equals + 1);
    const int camera = rig.camera_index(name);
    if (camera < 0) {
      std::string cameras;
      for (const CameraModel& c : rig.cameras) cameras += (cameras.empty() ? "" : ", ") + c.name;
      throw InvalidInput(option + ": no camera \"" + name + "\" in " + rig_source + " (its cameras: " + cameras + ")");
    }
    if (std::find(named.begin(), named.end(), name) != named.end()) throw InvalidInput(option + ": camera " + name + " is given twice");
    named.push_back(name);
    CameraModel& model = rig.cameras[camera];
    if (color && !model.has_color()) throw InvalidInput(option + ": camera " + name + " has no colour in " + rig_source);
    const Intrinsics k = read_intrinsics_file(file);
    const Intrinsics& current = color ? *model.color_intrinsics : model.depth_intrinsics;
    if (k.width != current.width || k.height != current.height) {
      throw InvalidInput(file + ": intrinsics: " + std::to_string(k.width) + "x" + std::to_string(k.height) + ", but " + name + "'s " +
                         (color ? "colour" : "depth") + " images are " + std::to_string(current.width) + "x" +
                         std::to_string(current.height) + " (" + rig_source + ")");
    }
    (color ? *model.color_intrinsics : model.depth_intrinsics) = k;
  }
}

// The wand's rig at the scale --scale asks for. Colour cameras see the rig only up to scale, and
// the LED distance gives it; the depth cameras measure lengths themselves (depth_scale.h), so a
// wrong --led-distance shows as a rig whose depth surfaces meet only once it is scaled. `check`
// keeps the LED distance's scale where the depth agrees within the tolerance or cannot tell, and
// refuses it otherwise (every camera would stand that much too far from camera 0, beyond what
// registration pulls back); `depth` takes the depth's; `led` keeps the LED distance's regardless.
Rig rig_at_checked_scale(const ExtrinsicsArgs& args, const Capture& capture, const ExtrinsicResult& result) {
  const double led_m = args.options.led_distance_m;
  const DepthScaleResult depth = measure_depth_scale(capture, result.rig, 0, {.num_threads = args.threads});
  for (const std::string& file : depth.unreadable) print_diagnostic("calibrate: warning: " + file + "; that camera's depth is not used for the scale");
  char line[400];
  if (!depth.measured) {
    if (args.scale == "depth") throw InvalidInput("--scale depth: " + capture.dir().string() + ": " + depth.not_measured);
    std::printf("scale: from --led-distance %.4f m alone (the depth cannot check it: %s)\n", led_m, depth.not_measured.c_str());
    // Asked to check, and it could not: said where warnings go, not only in the report.
    if (args.scale == "check") print_diagnostic("calibrate: warning: --led-distance is unchecked: the depth cannot measure the rig's scale (see above)");
    return result.rig;
  }
  // How far the cameras lie from where the depth puts them, as a share of their distance from camera 0.
  const double cameras_off = 1 - 1 / depth.scale;
  std::snprintf(line, sizeof line, "the cameras' depth surfaces meet with the rig at %.3f times that size (the LEDs %.4f m apart)", depth.scale,
                led_m * depth.scale);
  if (args.scale == "depth") {
    std::printf("scale: from the depth, the rig scaled by %.3f: with --led-distance %.4f m %s\n", depth.scale, led_m, line);
    return scale_rig(result.rig, 0, depth.scale);
  }
  if (std::abs(cameras_off) > args.scale_tolerance && args.scale == "check") {
    std::snprintf(line, sizeof line,
                  "--led-distance: %.4f m puts the cameras %.1f %% %s camera 0 than their depth does (it fits the LEDs %.4f m apart); measure the "
                  "wand again, or take the depth's scale with --scale depth (--scale led keeps this one)",
                  led_m, 100 * std::abs(cameras_off), cameras_off > 0 ? "nearer to" : "farther from", led_m * depth.scale);
    throw InvalidInput(line);
  }
  std::printf("scale: from --led-distance %.4f m%s; %s\n", led_m, args.scale == "led" ? " (--scale led)" : ", which the depth confirms", line);
  return result.rig;
}

void run_extrinsics(ExtrinsicsArgs& args) {
  args.options.num_threads = args.threads;
  args.options.validate();
  check_output_file(args.out);
  const Capture capture = open_capture(args.capture, "calibrate");
  capture.check_output_outside(args.out, "--out");
  check_replaces_only_format(args.out, kRigFormat, "--out");
  // The rig the wand is calibrated in: the capture's, with the intrinsics given on the command line.
  Rig rig = capture.rig();
  const std::string rig_source = (capture.dir() / "rig.json").string();
  apply_intrinsics_files(args.color_intrinsics, true, rig_source, rig);
  apply_intrinsics_files(args.depth_intrinsics, false, rig_source, rig);
  const WandObservations observations =
      detect_wand(capture, {}, args.threads, [](int done, int total) { show_progress("detect", done, total); });
  for (const std::string& file : observations.unreadable) print_diagnostic("calibrate: warning: " + file + "; that camera's frame is not used");
  // What calibration finds wrong is about this capture's wand frames (a capture without a wand
  // leaves the cameras unconnected): named by the capture.
  const ExtrinsicResult result = [&] {
    try {
      return calibrate_extrinsics(rig, observations, args.options);
    } catch (const InvalidInput& e) {
      const std::string prefix = capture.dir().string() + ": ";
      if (std::string_view(e.what()).starts_with(prefix)) throw;  // already names the capture (its rig.json)
      throw InvalidInput(prefix + e.what());
    }
  }();

  std::cout << "camera      detections  observations  error before BA  after BA (px)\n";
  for (const CameraCalibrationReport& c : result.cameras) {
    std::printf("%-11s %10d  %12d  %15.3f  %8.3f\n", c.name.c_str(), c.detections, c.observations_used, c.error_before_px, c.error_after_px);
  }
  std::printf("all         %10s  %12s  %15.3f  %8.3f\n", "", "", result.error_before_px, result.error_after_px);
  std::cout << "initial rig from pairs:";
  for (const PairReport& p : result.pairs) {
    if (p.in_tree) std::cout << " " << capture.rig().cameras[p.camera_a].name << "-" << capture.rig().cameras[p.camera_b].name << " (" << p.inliers << " inliers)";
  }
  std::printf("\n%d LED points, %d observations dropped as outliers%s\n", result.points, result.dropped_observations,
              result.converged ? "" : "; bundle adjustment stopped before converging");
  const Rig rig_out = rig_at_checked_scale(args, capture, result);
  if (capture.ground_truth_rig()) {
    const Rig& truth = *capture.ground_truth_rig();
    double worst_mm = 0, worst_deg = 0;
    for (size_t c = 0; c < truth.cameras.size(); ++c) {
      const Rigid3d& est = rig_out.cameras[c].world_from_depth;
      const Rigid3d& tru = truth.cameras[c].world_from_depth;
      worst_mm = std::max(worst_mm, 1000 * (est.translation() - tru.translation()).norm());
      worst_deg = std::max(worst_deg, rotation_angle_deg(tru.inverse() * est));
    }
    std::printf("against ground_truth/rig.json: worst camera %.2f mm, %.3f deg\n", worst_mm, worst_deg);
  }
  write_rig(args.out, rig_out);
  std::cout << "wrote " << args.out << "\n";
}

void run_floor(FloorArgs& args) {
  args.options.set_volume = !args.no_volume;
  args.options.prefer_lower_plane = args.floor_plane == "lowest";
  args.options.validate();  // its own bounds first; the frames are checked against the capture below
  check_output_file(args.out);
  Capture capture = open_capture(args.capture, "calibrate");
  capture.check_output_outside(args.out, "--out");
  check_replaces_only_format(args.out, kRigFormat, "--out");
  // The floor does not move, and a few frames see it around a subject who does.
  if (capture.frame_count() == 0) throw InvalidInput(kNoFrames);
  const FrameRange range = args.frames.empty() ? FrameRange{0, std::min(FloorOptions{}.end_frame, capture.frame_count())}
                                               : parse_frame_range(args.frames, capture.frame_count());
  args.options.first_frame = range.begin;
  args.options.end_frame = range.end;
  // A calibrated rig (calibrate extrinsics') seen with this capture's recording: its depth unit, sizes.
  if (!args.rig.empty()) use_calibration_from(capture, args.rig);
  const FloorResult result = level_rig_to_floor(capture, args.options);
  for (const std::string& file : result.unreadable) print_diagnostic("calibrate: warning: " + file + "; that frame's depth is not used");

  std::printf("floor: %d of %d depth points within %.0f mm of it, RMS %.1f mm\n", result.floor_points, result.points,
              1000 * args.options.inlier_distance_m, 1000 * result.floor_rms_m);
  if (result.largest_plane_above_m > 0) {
    std::printf("floor: taken under the largest plane, which lies %.2f m above it (a table top; a stage the subject stands on: --floor largest)\n",
                result.largest_plane_above_m);
  }
  std::cout << "camera      floor points  height m  tilt down deg  from the origin m\n";
  for (const FloorCameraReport& c : result.cameras) {
    std::printf("%-11s %12d  %8.3f  %13.2f  %17.3f\n", c.name.c_str(), c.floor_points, c.height_m, c.tilt_down_deg, c.distance_m);
  }
  if (result.rig.volume) {
    const Box3d& v = *result.rig.volume;
    std::printf("volume: x %.2f to %.2f, y %.2f to %.2f, z %.2f to %.2f m\n", v.min.x(), v.max.x(), v.min.y(), v.max.y(), v.min.z(), v.max.z());
  }
  write_rig(args.out, result.rig);
  std::cout << "wrote " << args.out << "\n";
}

}  // namespace

void add_calibrate_command(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("calibrate", "Calibrate cameras: intrinsics from a checkerboard, the rig's poses from a two-LED wand");
  cmd->require_subcommand(1);

  auto in = std::make_shared<IntrinsicsArgs>();
  CLI::App* intr = cmd->add_subcommand("intrinsics", "A colour camera's intrinsics from checkerboard images (Zhang's method)");
  intr->add_option("--images", in->images, "Glob of the board images, quoted (e.g. 'DIR/*.png')")->required();
  intr->add_option("--board", in->board, "Inner corners COLUMNSxROWS")->capture_default_str();
  intr->add_option("--square", in->square_m, "Square side, metres")->capture_default_str();
  intr->add_option("--out", in->out, "Output JSON (intrinsics, per-view errors)")->required();
  intr->add_flag("--no-distortion", in->no_distortion, "Do not estimate radial distortion (k1, k2)");
  intr->callback([in] { run_intrinsics(*in); });

  auto ex = std::make_shared<ExtrinsicsArgs>();
  CLI::App* extr = cmd->add_subcommand("extrinsics", "All camera poses from a capture of a red and a green LED waved through the volume");
  extr->add_option("capture", ex->capture, "Wand capture folder (rig.json with the intrinsics, colour frames)")->required();
  extr->add_option("--led-distance", ex->options.led_distance_m, "Distance between the LEDs, metres")->capture_default_str();
  extr->add_option("--out", ex->out, "Output rig.json (the capture's rig with calibrated poses)")->required();
  extr->add_option("--min-common-frames", ex->options.min_common_frames, "Frames two cameras must share to be paired")->capture_default_str();
  extr->add_option("--intrinsics", ex->color_intrinsics,
                   "CAMERA=FILE: that camera's colour intrinsics from `calibrate intrinsics` (repeat per camera); used for the wand and written to --out")
      ->allow_extra_args(false)
      ->type_name("CAMERA=FILE");
  extr->add_option("--depth-intrinsics", ex->depth_intrinsics, "CAMERA=FILE: that camera's depth intrinsics, written to --out (repeat per camera)")
      ->allow_extra_args(false)
      ->type_name("CAMERA=FILE");
  extr->add_option("--scale", ex->scale,
                   "check: the scale from --led-distance, refused where it puts the cameras more than --scale-tolerance of their distance "
                   "from camera 0 nearer or farther than the depth cameras measure; depth: the scale the depth measures; led: "
                   "--led-distance's, unchecked")
      ->check(CLI::IsMember({"check", "depth", "led"}))
      ->capture_default_str();
  extr->add_option("--scale-tolerance", ex->scale_tolerance,
                   "--scale check: how far the cameras may lie from where the depth puts them, a fraction of their distance from camera 0")
      ->check(CLI::Range(0.001, 0.5))
      ->capture_default_str();
  add_threads_option(extr, ex->threads);
  extr->callback([ex] { run_extrinsics(*ex); });

  auto fl = std::make_shared<FloorArgs>();
  CLI::App* floor = cmd->add_subcommand("floor", "The world frame from the floor in the depth: z up, the floor at z = 0, a capture volume over it");
  floor->add_option("capture", fl->capture, "Capture whose depth shows the floor (any recording of the rig)")->required();
  floor->add_option("--rig", fl->rig, "The rig to level (e.g. calibrate extrinsics' output) instead of the capture's");
  floor->add_option("--frames", fl->frames, "Frames whose depth is searched, A:B (default: the first 5)");
  floor->add_option("--out", fl->out, "Output rig.json (the rig in the floor's world frame, with the volume)")->required();
  CLI::Option* half_width =
      floor->add_option("--volume-half-width", fl->options.volume_half_width_m, "Volume's x and y half-size, metres (0: 0.5 x the nearest camera's distance)")
          ->capture_default_str();
  CLI::Option* height = floor->add_option("--volume-height", fl->options.volume_height_m, "Volume's top above the floor, metres")->capture_default_str();
  floor->add_flag("--no-volume", fl->no_volume, "Write no capture volume")->excludes(half_width)->excludes(height);
  floor->add_option("--floor", fl->floor_plane,
                    "lowest: a level plane under the largest one with a fifth of its points is the floor (under a table top); "
                    "largest: the largest plane is (a stage the subject stands on)")
      ->check(CLI::IsMember({"lowest", "largest"}))
      ->capture_default_str();
  floor->add_option("--inlier-distance", fl->options.inlier_distance_m, "Depth this close to a plane lies on it, metres")->capture_default_str();
  floor->callback([fl] { run_floor(*fl); });
}

}  // namespace zipfusion::cli
