// End-to-end test of `zipfusion synth --wand/--checkerboard` and `zipfusion calibrate`: small
// captures (320x240, 120 wand frames, 8 board views) to stay fast; the full-size targets are in
// src/zipfusion/calib/*_test.cc.

#include <gtest/gtest.h>

#include <fstream>
#include <numbers>
#include <tuple>
#include <nlohmann/json.hpp>

#include "cli/cli_test_util.h"
#include "zipfusion/io/image_io.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/rig.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;
using testing::CommandResult;
using testing::line_count;

class CalibrateCli : public testing::CliTest {
 protected:
  // The factor in calibrate extrinsics' "the depth cameras' surfaces meet with the rig at F times
  // the size", or 0 when it printed none.
  static double depth_scale_in(const std::string& out) {
    const std::string before = "surfaces meet with the rig at ";
    const size_t at = out.find(before);
    return at == std::string::npos ? 0 : std::stod(out.substr(at + before.size()));
  }
  // The largest distance (metres) and rotation (degrees) of a camera from where the truth has it.
  static std::pair<double, double> worst_error(const Rig& calibrated, const Rig& truth) {
    double worst_m = 0, worst_deg = 0;
    for (size_t c = 0; c < truth.cameras.size(); ++c) {
      const Rigid3d& est = calibrated.cameras[c].world_from_depth;
      const Rigid3d& tru = truth.cameras[c].world_from_depth;
      worst_m = std::max(worst_m, (est.translation() - tru.translation()).norm());
      worst_deg = std::max(worst_deg, rotation_angle_deg(tru.inverse() * est));
    }
    return {worst_m, worst_deg};
  }
  // Moves the capture's rig (its truth) into camera 0's frame, levels it with `calibrate floor
  // CAPTURE OPTIONS`, and compares the result with the truth (expect_levelled_like_truth).
  void level_like_truth(const fs::path& capture, const Rig& truth, const std::string& options, bool origin_known, const std::string& what);
};

TEST_F(CalibrateCli, CalibratesAWandCaptureIntoARigTheReaderLoads) {
  const fs::path capture = dir_ / "wand";
  ASSERT_EQ(run("synth --wand --out " + capture.string() + " --frames 120 --cameras 4 --resolution 320x240 --miscalibrate 2,0.05").exit_code, 0);
  // One colour frame cut short, as a recorder killed mid-write leaves it: that camera's frame is
  // not used, with a warning, and the calibration goes on.
  const fs::path cut = capture / "cam2" / "color" / "000050.png";
  const fs::path cut_jpg = capture / "cam2" / "color" / "000050.jpg";
  const fs::path frame = fs::exists(cut) ? cut : cut_jpg;
  std::vector<std::uint8_t> bytes = read_file_bytes(frame);
  bytes.resize(bytes.size() / 3);
  write_file_atomic(frame, bytes);
  const fs::path out = dir_ / "rig.json";
  const CommandResult r = run("calibrate extrinsics " + capture.string() + " --led-distance 0.445 --out " + out.string() + " --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(line_count(r.err), 1) << r.err;
  EXPECT_EQ(r.err.rfind("calibrate: warning: " + frame.string() + ": cannot decode image (corrupt or truncated): ", 0), 0u) << r.err;
  EXPECT_NE(r.out.find("cam3"), std::string::npos);
  EXPECT_NE(r.out.find("after BA"), std::string::npos);
  // The depth cameras see the person waving the wand, and their surfaces agree with the LED distance.
  EXPECT_NEAR(depth_scale_in(r.out), 1.0, 0.01) << r.out;
  const Rig calibrated = read_rig(out);
  const Rig truth = read_rig(capture / "ground_truth" / "rig.json");
  ASSERT_EQ(calibrated.cameras.size(), 4u);
  for (size_t c = 0; c < 4; ++c) {
    const Rigid3d& est = calibrated.cameras[c].world_from_depth;
    const Rigid3d& tru = truth.cameras[c].world_from_depth;
    // Half the resolution and 120 frames: looser than the library test's 5 mm / 0.2°.
    EXPECT_LT((est.translation() - tru.translation()).norm(), 0.01) << c;
    EXPECT_LT(rotation_angle_deg(tru.inverse() * est), 0.4) << c;
  }
}

// Colour cameras fix the rig only up to scale, and --led-distance gives it; the depth cameras
// measure it too (depth_scale.h). A wand 10 % longer than --led-distance says (0.445 m against 0.4)
// is refused in one line that names the option and the length the depth fits, and nothing is
// written; --scale depth takes the depth's scale and finds the cameras; --scale led keeps the wrong
// one, every camera 10 % of its distance too close to camera 0. Without depth nothing is checked,
// and the output says so.
TEST_F(CalibrateCli, ChecksTheLedDistanceAgainstTheDepth) {
  const fs::path capture = dir_ / "wand";
  ASSERT_EQ(run("synth --wand --out " + capture.string() + " --frames 120 --cameras 4 --resolution 320x240").exit_code, 0);
  const Rig truth = read_rig(capture / "ground_truth" / "rig.json");
  const fs::path out = dir_ / "rig.json";
  const std::string calibrate = "calibrate extrinsics " + capture.string() + " --led-distance 0.4 --out " + out.string();
  CommandResult r = run(calibrate);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(line_count(r.err), 1) << r.err;
  EXPECT_EQ(r.err.rfind("zipfusion: error: --led-distance: 0.4000 m puts the cameras ", 0), 0u) << r.err;
  EXPECT_NE(r.err.find(" % nearer to camera 0 than their depth does (it fits the LEDs 0.44"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--scale depth"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));

  r = run(calibrate + " --scale depth");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NEAR(depth_scale_in(r.out), 0.445 / 0.4, 0.01) << r.out;
  EXPECT_LT(worst_error(read_rig(out), truth).first, 0.04);  // the depth's scale is good to about 0.5 % (camera 2 is 5 m away)

  r = run(calibrate + " --scale led");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NEAR(depth_scale_in(r.out), 0.445 / 0.4, 0.01) << r.out;
  EXPECT_GT(worst_error(read_rig(out), truth).first, 0.4);  // camera 2, 5 m from camera 0, lies 10 % of that short

  // Blank depth, as the wand captures of earlier versions have it.
  for (const CameraModel& camera : truth.cameras) {
    for (const auto& file : fs::directory_iterator(capture / camera.name / "depth")) {
      write_depth_png(file.path(), DepthImage(camera.depth_intrinsics.width, camera.depth_intrinsics.height, 0));
    }
  }
  r = run(calibrate + " --scale depth");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "zipfusion: error: --scale depth: " + capture.string() + ": no depth in the 8 frames from 7 to 112\n");
  r = run("calibrate extrinsics " + capture.string() + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("scale: from --led-distance 0.4450 m alone (the depth cannot check it: no depth in the 8 frames from 7 to 112)"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(r.err, "calibrate: warning: --led-distance is unchecked: the depth cannot measure the rig's scale (see above)\n");
  EXPECT_LT(worst_error(read_rig(out), truth).first, 0.01);
}

// Calibrated intrinsics given per camera (`--intrinsics NAME=FILE`, the files `calibrate
// intrinsics` writes) are used for the wand and written into the rig: with the capture's own
// (wrong) intrinsics the poses are far off, with the files' they are found, and the output rig
// carries the files' intrinsics exactly.
TEST_F(CalibrateCli, TakesEachCamerasCalibratedIntrinsicsIntoTheRig) {
  const fs::path capture = dir_ / "wand";
  ASSERT_EQ(run("synth --wand --out " + capture.string() + " --frames 120 --cameras 4 --resolution 320x240").exit_code, 0);
  const Rig truth = read_rig(capture / "ground_truth" / "rig.json");
  // The capture's rig.json: every colour camera's focal length 5 % long and its principal point
  // 6 pixels off, as a device's nominal intrinsics are; its depth intrinsics off too.
  Rig nominal = read_rig(capture / "rig.json");
  std::string color_files, depth_files;
  for (size_t c = 0; c < nominal.cameras.size(); ++c) {
    CameraModel& model = nominal.cameras[c];
    model.color_intrinsics->fx *= 1.05;
    model.color_intrinsics->fy *= 1.05;
    model.color_intrinsics->cx += 6;
    model.depth_intrinsics.cx -= 3;
    auto write_intrinsics = [&](const std::string& file, const Intrinsics& k) {
      const fs::path path = dir_ / file;
      write_file_atomic(path, "{\"format\": \"zipfusion.intrinsics/1\", \"rms_px\": 0.1, \"intrinsics\": " + format_intrinsics(k) + "}\n");
      return " " + model.name + "=" + path.string();
    };
    color_files += " --intrinsics" + write_intrinsics(model.name + "_color.json", *truth.cameras[c].color_intrinsics);
    depth_files += " --depth-intrinsics" + write_intrinsics(model.name + "_depth.json", truth.cameras[c].depth_intrinsics);
  }
  write_rig(capture / "rig.json", nominal);

  const fs::path nominal_out = dir_ / "nominal.json";
  CommandResult r = run("calibrate extrinsics " + capture.string() + " --out " + nominal_out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_GT(worst_error(read_rig(nominal_out), truth).first, 0.05);  // the wrong focal lengths misplace the cameras

  // The options before the capture: each takes one CAMERA=FILE, never the capture after it.
  const fs::path out = dir_ / "rig.json";
  r = run("calibrate extrinsics" + color_files + depth_files + " " + capture.string() + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Rig calibrated = read_rig(out);
  const auto [error_m, error_deg] = worst_error(calibrated, truth);
  EXPECT_LT(error_m, 0.01);  // as CalibratesAWandCaptureIntoARigTheReaderLoads
  EXPECT_LT(error_deg, 0.4);
  for (size_t c = 0; c < truth.cameras.size(); ++c) {
    EXPECT_EQ(*calibrated.cameras[c].color_intrinsics, *truth.cameras[c].color_intrinsics) << c;
    EXPECT_EQ(calibrated.cameras[c].depth_intrinsics, truth.cameras[c].depth_intrinsics) << c;
  }

  // What cannot be applied is one line naming the option or the file, and nothing is written.
  const std::string bad_file = (dir_ / "bad.json").string();
  write_file_atomic(bad_file, std::string("{\"format\": \"zipfusion.intrinsics/1\", \"intrinsics\": {\"width\": 320, \"height\": 240, "
                                          "\"fx\": -1, \"fy\": 262.5, \"cx\": 159.5, \"cy\": 119.5}}"));
  const std::string big_file = (dir_ / "big.json").string();
  Intrinsics big = *truth.cameras[0].color_intrinsics;
  big.width = 640;
  big.height = 480;
  write_file_atomic(big_file, "{\"format\": \"zipfusion.intrinsics/1\", \"intrinsics\": " + format_intrinsics(big) + "}");
  const std::string rig_json = (capture / "rig.json").string();
  const std::pair<std::string, std::string> cases[] = {
      {"--intrinsics cam9=" + bad_file, "--intrinsics: no camera \"cam9\" in " + rig_json + " (its cameras: cam0, cam1, cam2, cam3)"},
      {"--intrinsics cam0", "--intrinsics: expected CAMERA=FILE (e.g. cam0=cam0.json), got \"cam0\""},
      {"--intrinsics cam0=" + (dir_ / "cam0_color.json").string() + " --intrinsics cam0=" + big_file, "--intrinsics: camera cam0 is given twice"},
      {"--intrinsics cam1=" + bad_file, bad_file + ": intrinsics.fx: must be positive, got -1"},
      {"--intrinsics cam1=" + rig_json, rig_json + ": format: must be \"zipfusion.intrinsics/1\", got \"zipfusion.rig/1\""},
      {"--depth-intrinsics cam2=" + big_file, big_file + ": intrinsics: 640x480, but cam2's depth images are 320x240 (" + rig_json + ")"},
  };
  const fs::path unwritten = dir_ / "unwritten.json";
  for (const auto& [args, message] : cases) {
    r = run("calibrate extrinsics " + capture.string() + " " + args + " --out " + unwritten.string());
    EXPECT_EQ(r.exit_code, 2) << args;
    EXPECT_EQ(r.err, "zipfusion: error: " + message + "\n") << args;
    EXPECT_FALSE(fs::exists(unwritten)) << args;
  }
}

// A levelled rig is the true one (synth's and samba-4cam's world: z up, the floor at 0, the
// cameras looking at the origin) seen from a world turned about z, where calibrate floor puts
// camera 0 on −y: one rigid motion from the truth's world to the levelled one that keeps z
// (within 0.2°) and the floor (5 mm), and, where the cameras' axes meet (`origin_known`), the
// origin too; every camera within 1 mm and 0.05° of the truth moved by it.
void expect_levelled_like_truth(const Rig& levelled, const Rig& truth, bool origin_known, const std::string& what) {
  ASSERT_EQ(levelled.cameras.size(), truth.cameras.size()) << what;
  const Rigid3d levelled_from_truth = levelled.cameras[0].world_from_depth * truth.cameras[0].world_from_depth.inverse();
  EXPECT_LT(std::acos(std::min(1.0, (levelled_from_truth.linear() * Eigen::Vector3d::UnitZ()).z())) * 180 / std::numbers::pi, 0.2) << what;
  EXPECT_LT(std::abs(levelled_from_truth.translation().z()), 0.005) << what;
  if (origin_known) {
    EXPECT_LT(levelled_from_truth.translation().norm(), 0.005) << what;
  }
  const Eigen::Vector3d camera0 = levelled.cameras[0].world_from_depth.translation();
  EXPECT_NEAR(camera0.x(), 0, 1e-6) << what;  // on the −y axis
  EXPECT_LT(camera0.y(), 0) << what;
  for (size_t c = 0; c < truth.cameras.size(); ++c) {
    const Rigid3d expected = levelled_from_truth * truth.cameras[c].world_from_depth;
    const Rigid3d& got = levelled.cameras[c].world_from_depth;
    EXPECT_LT((got.translation() - expected.translation()).norm(), 0.001) << what << " camera " << c;
    EXPECT_LT(rotation_angle_deg(expected.inverse() * got), 0.05) << what << " camera " << c;
  }
}

// A rig moved as a whole by `moved_from_world` (its volume dropped), as a recorder without --rig
// or a calibration from another start leaves it.
Rig moved_rig(Rig rig, const Rigid3d& moved_from_world) {
  for (CameraModel& model : rig.cameras) model.world_from_depth = moved_from_world * model.world_from_depth;
  rig.volume.reset();
  return rig;
}

Rig in_camera0_frame(const Rig& rig) { return moved_rig(rig, rig.cameras[0].world_from_depth.inverse()); }

void CalibrateCli::level_like_truth(const fs::path& capture, const Rig& truth, const std::string& options, bool origin_known,
                                    const std::string& what) {
  write_rig(capture / "rig.json", in_camera0_frame(truth));
  const fs::path out = dir_ / "level.json";
  const CommandResult r = run("calibrate floor " + capture.string() + options + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << what << ": " << r.err;
  expect_levelled_like_truth(read_rig(out), truth, origin_known, what);
}

TEST_F(CalibrateCli, LevelsTheRigOnTheFloorSeenInTheDepth) {
  const fs::path capture = dir_ / "ring";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 2 --cameras 3 --resolution 320x240").exit_code, 0);
  const Rig truth = read_rig(capture / "ground_truth" / "rig.json");
  write_rig(capture / "rig.json", in_camera0_frame(truth));
  const fs::path out = dir_ / "level.json";
  CommandResult r = run("calibrate floor " + capture.string() + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("cam2"), std::string::npos) << r.out;  // the table: a row per camera
  const Rig levelled = read_rig(out);
  expect_levelled_like_truth(levelled, truth, true, "synth, camera 0's frame");
  // The ring's radius is 2.5 m: a volume of half that each way, from just above the floor.
  ASSERT_TRUE(levelled.volume.has_value());
  EXPECT_NEAR(levelled.volume->max.x(), 1.25, 0.01);
  EXPECT_NEAR(levelled.volume->min.y(), -1.25, 0.01);
  EXPECT_DOUBLE_EQ(levelled.volume->min.z(), 0.02);
  EXPECT_DOUBLE_EQ(levelled.volume->max.z(), 2.2);

  // Any start: the rig turned and moved as a whole, even upside down.
  for (const auto& [angle, axis] : {std::pair{2.0, Eigen::Vector3d(1, 2, 3)}, std::pair{std::numbers::pi, Eigen::Vector3d(1, 0, 0)}}) {
    Rigid3d moved = Rigid3d::Identity();
    moved.linear() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
    moved.translation() = Eigen::Vector3d(3, -7, 11);
    write_rig(dir_ / "moved.json", moved_rig(truth, moved));
    r = run("calibrate floor " + capture.string() + " --rig " + (dir_ / "moved.json").string() + " --out " + out.string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    expect_levelled_like_truth(read_rig(out), truth, true, "synth, moved");
  }

  // The volume as asked, or none.
  r = run("calibrate floor " + capture.string() + " --volume-half-width 0.7 --volume-height 2 --out " + (dir_ / "sized.json").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Rig sized = read_rig(dir_ / "sized.json");
  ASSERT_TRUE(sized.volume.has_value());
  EXPECT_DOUBLE_EQ(sized.volume->max.x(), 0.7);
  EXPECT_DOUBLE_EQ(sized.volume->max.z(), 2.0);
  ASSERT_EQ(run("calibrate floor " + capture.string() + " --no-volume --out " + (dir_ / "open.json").string()).exit_code, 0);
  EXPECT_FALSE(read_rig(dir_ / "open.json").volume.has_value());

  // Without a floor in view nothing is written, and the error says what to do.
  const fs::path floorless = dir_ / "floorless";
  ASSERT_EQ(run("synth --out " + floorless.string() + " --frames 1 --cameras 3 --resolution 320x240 --no-floor").exit_code, 0);
  const fs::path unwritten = dir_ / "unwritten.json";
  r = run("calibrate floor " + floorless.string() + " --out " + unwritten.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err.rfind("zipfusion: error: " + floorless.string() + ": no floor found in frames 0 to 0: ", 0), 0u) << r.err;
  EXPECT_NE(r.err.find("; frame the floor in some camera's view\n"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(unwritten));
  // Saturated depth (every pixel 65535 mm) is no floor: it was taken for one 35 m below the cameras.
  const fs::path saturated = dir_ / "saturated";
  fs::copy(floorless, saturated, fs::copy_options::recursive);
  for (const CameraModel& camera : read_rig(saturated / "rig.json").cameras) {
    for (const auto& file : fs::directory_iterator(saturated / camera.name / "depth")) {
      write_depth_png(file.path(), DepthImage(camera.depth_intrinsics.width, camera.depth_intrinsics.height, 65535));
    }
  }
  r = run("calibrate floor " + saturated.string() + " --out " + unwritten.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "zipfusion: error: " + saturated.string() + ": too little depth in frames 0 to 0 to find the floor (0 points; 14400 farther than 10 m left out)\n");
  EXPECT_FALSE(fs::exists(unwritten));
  // Poses that do not fit the depth (every camera turned 90° about its optical axis, its depth
  // not): each camera's floor lands elsewhere, and the error says why the largest plane is none.
  Rig sideways = truth;
  for (CameraModel& model : sideways.cameras) {
    model.world_from_depth.linear() = model.world_from_depth.linear() * Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  }
  write_rig(dir_ / "sideways.json", sideways);
  r = run("calibrate floor " + capture.string() + " --rig " + (dir_ / "sideways.json").string() + " --out " + unwritten.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find(": the largest plane ("), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(" is not the floor: "), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(unwritten));
  // A --rig of other cameras is named with the field.
  Rig other = truth;
  other.cameras[1].name = "side";
  write_rig(dir_ / "other.json", other);
  r = run("calibrate floor " + capture.string() + " --rig " + (dir_ / "other.json").string() + " --out " + unwritten.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "zipfusion: error: " + (dir_ / "other.json").string() + ": cameras[1].name: \"side\" is not the capture's \"cam1\"\n");
  EXPECT_FALSE(fs::exists(unwritten));
  // A corrupt depth frame is named and left out.
  const fs::path depth0 = capture / "cam1" / "depth" / "000000.png";
  std::vector<std::uint8_t> bytes = read_file_bytes(depth0);
  bytes.resize(bytes.size() / 2);
  write_file_atomic(depth0, bytes);
  r = run("calibrate floor " + capture.string() + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(line_count(r.err), 1) << r.err;
  EXPECT_EQ(r.err.rfind("calibrate: warning: " + depth0.string() + ": ", 0), 0u) << r.err;
  expect_levelled_like_truth(read_rig(out), truth, true, "synth, a corrupt frame");
}

// Rigs other than a ring: two neighbours of an eight-camera ring (an arc: the origin is still
// where they look), a camera mounted upside down, two cameras facing each other, and one camera
// looking steeply down (54°; its origin goes 2 m ahead of it, so only the floor and the tilt are
// checked).
TEST_F(CalibrateCli, LevelsArcsUpsideDownAndSingleCameras) {
  // Keeps only the cameras `kept` of a synth capture (rig.json, ground truth and folders).
  auto keep_cameras = [](const fs::path& capture, const std::vector<int>& kept) {
    for (const fs::path& file : {capture / "rig.json", capture / "ground_truth" / "rig.json"}) {
      Rig rig = read_rig(file);
      std::vector<CameraModel> cameras;
      for (int c : kept) cameras.push_back(rig.cameras[c]);
      for (size_t c = 0; c < rig.cameras.size(); ++c) {
        if (std::find(kept.begin(), kept.end(), static_cast<int>(c)) == kept.end()) fs::remove_all(capture / rig.cameras[c].name);
      }
      rig.cameras = cameras;
      write_rig(file, rig);
    }
  };
  const fs::path arc = dir_ / "arc";
  ASSERT_EQ(run("synth --out " + arc.string() + " --frames 1 --cameras 8 --resolution 320x240").exit_code, 0);
  keep_cameras(arc, {0, 1});
  level_like_truth(arc, read_rig(arc / "ground_truth" / "rig.json"), "", true, "arc");

  // Camera 0 of a ring upside down: its depth turned 180° in the image, its pose about its
  // optical axis (the principal point is the image's centre, so the pixels map exactly).
  const fs::path ring = dir_ / "ring";
  ASSERT_EQ(run("synth --out " + ring.string() + " --frames 1 --cameras 4 --resolution 320x240").exit_code, 0);
  Rig flipped_truth = read_rig(ring / "ground_truth" / "rig.json");
  const fs::path file = ring / flipped_truth.cameras[0].name / "depth" / "000000.png";
  const DepthImage depth = read_depth_png(file);
  DepthImage turned(depth.width, depth.height);
  for (int v = 0; v < depth.height; ++v) {
    for (int u = 0; u < depth.width; ++u) turned(depth.width - 1 - u, depth.height - 1 - v) = depth(u, v);
  }
  write_depth_png(file, turned);
  Rigid3d& pose = flipped_truth.cameras[0].world_from_depth;
  pose.linear() = pose.linear() * Eigen::Vector3d(-1, -1, 1).asDiagonal();
  write_rig(ring / "ground_truth" / "rig.json", flipped_truth);
  level_like_truth(ring, flipped_truth, "", true, "upside down");

  // Two cameras facing each other: their axes lie on one line, and the origin is between them.
  const fs::path pair = dir_ / "pair";
  ASSERT_EQ(run("synth --out " + pair.string() + " --frames 1 --cameras 2 --resolution 320x240").exit_code, 0);
  level_like_truth(pair, read_rig(pair / "ground_truth" / "rig.json"), "", true, "facing pair");

  const fs::path single = dir_ / "single";
  ASSERT_EQ(run("synth --out " + single.string() + " --frames 2 --cameras 1 --height 3 --radius 1.5 --resolution 320x240").exit_code, 0);
  level_like_truth(single, read_rig(single / "ground_truth" / "rig.json"), " --volume-half-width 1", false, "single camera");
}

// A PLY of the rectangle corner + a·side_a + b·side_b (a, b in [0, 1]) in tiles of about 0.25 m,
// both faces, for `synth --subject` (the renderer clips small triangles at the near plane better).
void write_rectangle_ply(const fs::path& path, const Eigen::Vector3d& corner, const Eigen::Vector3d& side_a, const Eigen::Vector3d& side_b) {
  const int na = std::max(1, static_cast<int>(std::lround(side_a.norm() / 0.25)));
  const int nb = std::max(1, static_cast<int>(std::lround(side_b.norm() / 0.25)));
  std::string vertices, faces;
  for (int i = 0; i <= na; ++i) {
    for (int j = 0; j <= nb; ++j) {
      const Eigen::Vector3d p = corner + side_a * i / na + side_b * j / nb;
      vertices += std::to_string(p.x()) + " " + std::to_string(p.y()) + " " + std::to_string(p.z()) + "\n";
    }
  }
  int count = 0;
  for (int i = 0; i < na; ++i) {
    for (int j = 0; j < nb; ++j) {
      const int a = i * (nb + 1) + j, b = a + nb + 1;
      for (const auto& [x, y, z] : {std::tuple{a, b, b + 1}, {a, b + 1, a + 1}, {a, b + 1, b}, {a, a + 1, b + 1}}) {
        faces += "3 " + std::to_string(x) + " " + std::to_string(y) + " " + std::to_string(z) + "\n";
        ++count;
      }
    }
  }
  write_file_atomic(path, "ply\nformat ascii 1.0\nelement vertex " + std::to_string((na + 1) * (nb + 1)) +
                              "\nproperty float x\nproperty float y\nproperty float z\nelement face " + std::to_string(count) +
                              "\nproperty list uchar int vertex_indices\nend_header\n" + vertices + faces);
}

// A table top 2.4 m wide at 0.75 m fills more of the cameras' views than the floor around it
// (8 536 of 10 562 points within 3 cm of it against 1 870), but the floor lies below it, level
// and wide enough: it is the floor.
TEST_F(CalibrateCli, TakesTheFloorUnderATableTop) {
  write_rectangle_ply(dir_ / "table000000.ply", {-1.2, -1.2, 0.75}, {2.4, 0, 0}, {0, 2.4, 0});
  const fs::path capture = dir_ / "room";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 1 --cameras 4 --resolution 320x240 --height 2.2 --subject " +
                (dir_ / "table%06d.ply").string()).exit_code, 0);
  const Rig truth = read_rig(capture / "ground_truth" / "rig.json");
  level_like_truth(capture, truth, "", true, "table");
  const CommandResult r = run("calibrate floor " + capture.string() + " --out " + (dir_ / "noted.json").string());
  EXPECT_NE(r.out.find("floor: taken under the largest plane, which lies 0.75 m above it (a table top; a stage the subject stands on: --floor largest)"),
            std::string::npos)
      << r.out;
  // A stage the subject stands on: with --floor largest the top is the floor, 0.75 m up.
  level_like_truth(capture, moved_rig(truth, Rigid3d(Eigen::Translation3d(0, 0, -0.75))), " --floor largest", true, "stage");
  const CommandResult bad = run("calibrate floor " + capture.string() + " --floor top --out " + (dir_ / "bad.json").string());
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--floor"), std::string::npos) << bad.err;
}

// Planes that face the cameras but are no floor: a ceiling over level cameras (which sees more of
// it than of the floor), and a wall 0.75 m ahead of a single camera looking 54° down.
TEST_F(CalibrateCli, TakesNeitherACeilingNorAWallForTheFloor) {
  write_rectangle_ply(dir_ / "ceiling000000.ply", {-5, -5, 2.5}, {10, 0, 0}, {0, 10, 0});
  const fs::path ceiling = dir_ / "ceiling";
  ASSERT_EQ(run("synth --out " + ceiling.string() + " --frames 1 --cameras 4 --resolution 320x240 --target-height 1.3 --subject " +
                (dir_ / "ceiling%06d.ply").string()).exit_code, 0);
  level_like_truth(ceiling, read_rig(ceiling / "ground_truth" / "rig.json"), "", true, "under a ceiling");

  // synth puts camera 0 at 45° on its circle (0.8 m here), looking at the circle's centre.
  const Eigen::Vector3d camera{0.8 * std::cos(std::numbers::pi / 4), 0.8 * std::sin(std::numbers::pi / 4), 0};
  const Eigen::Vector3d ahead = -camera.normalized(), across(-ahead.y(), ahead.x(), 0);
  write_rectangle_ply(dir_ / "wall000000.ply", camera + 0.75 * ahead - 3 * across, 6 * across, {0, 0, 3});
  const fs::path wall = dir_ / "wall";
  ASSERT_EQ(run("synth --out " + wall.string() + " --frames 1 --cameras 1 --radius 0.8 --target-height 0.2 --resolution 320x240 --subject " +
                (dir_ / "wall%06d.ply").string()).exit_code, 0);
  level_like_truth(wall, read_rig(wall / "ground_truth" / "rig.json"), " --volume-half-width 1", false, "before a wall");
}

// The same on the real dancer capture (Kinect noise and holes), from its true poses moved into
// camera 0's frame through --rig.
TEST_F(CalibrateCli, LevelsSamba4camOnItsFloor) {
  const fs::path samba = fs::path(ZF_SOURCE_DIR) / ".." / "shared" / "data" / "samba-4cam";
  const Rig truth = read_rig(samba / "ground_truth" / "rig.json");
  const fs::path start = dir_ / "start.json";
  write_rig(start, in_camera0_frame(truth));
  const fs::path out = dir_ / "level.json";
  const CommandResult r = run("calibrate floor " + samba.string() + " --rig " + start.string() + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Rig levelled = read_rig(out);
  expect_levelled_like_truth(levelled, truth, true, "samba-4cam");
  // Its own volume, ±1 m in a ring of 2 m.
  ASSERT_TRUE(levelled.volume.has_value());
  EXPECT_NEAR(levelled.volume->max.y(), 1.0, 0.01);
}

// A calibration replaces an earlier output of its kind and nothing else: a capture's rig.json
// named as calibrate intrinsics' --out, or an intrinsics file as extrinsics' or register's, is
// refused before any work and left as it was; an intrinsics file or an empty one is replaced.
TEST_F(CalibrateCli, ReplacesOnlyAFileOfItsOwnKind) {
  auto slurp = [](const fs::path& p) {
    const std::vector<std::uint8_t> bytes = read_file_bytes(p);
    return std::string(bytes.begin(), bytes.end());
  };
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 1 --cameras 2 --resolution 160x120").exit_code, 0);
  const fs::path rig_json = capture / "rig.json";
  const std::string rig_before = slurp(rig_json);
  const CommandResult intrinsics = run("calibrate intrinsics --images 'nothing/*.png' --board 9x6 --out " + rig_json.string());
  EXPECT_EQ(intrinsics.exit_code, 2);
  EXPECT_EQ(intrinsics.err, "zipfusion: error: --out: " + rig_json.string() +
                                " is a \"zipfusion.rig/1\" file, not a \"zipfusion.intrinsics/1\" file to replace; name a new file, or remove "
                                "that one first\n");
  EXPECT_EQ(slurp(rig_json), rig_before);

  const fs::path cam_json = dir_ / "cam.json";
  write_file_atomic(cam_json, "{\"format\": \"zipfusion.intrinsics/1\"}\n");
  const CommandResult registered = run("register " + capture.string() + " --out " + cam_json.string());
  EXPECT_EQ(registered.exit_code, 2);
  EXPECT_NE(registered.err.find(" is a \"zipfusion.intrinsics/1\" file, not a \"zipfusion.rig/1\" file to replace"), std::string::npos) << registered.err;
  const fs::path photo = dir_ / "photo.jpg";
  write_file_atomic(photo, "\xff\xd8\xff\xe0 not json");
  const CommandResult floor = run("calibrate floor " + capture.string() + " --out " + photo.string());
  EXPECT_EQ(floor.exit_code, 2);
  EXPECT_NE(floor.err.find(photo.string() + " is there and is not JSON"), std::string::npos) << floor.err;
  EXPECT_EQ(slurp(photo), "\xff\xd8\xff\xe0 not json");

  // info's report names the rig's format but is no rig.
  const fs::path report = dir_ / "info.json";
  const CommandResult info = run("info --json " + capture.string());
  ASSERT_EQ(info.exit_code, 0) << info.err;
  write_file_atomic(report, info.out);
  const CommandResult over_report = run("calibrate floor " + capture.string() + " --out " + report.string());
  EXPECT_EQ(over_report.exit_code, 2);
  EXPECT_NE(over_report.err.find(" has no cameras with world_from_depth"), std::string::npos) << over_report.err;
  EXPECT_EQ(slurp(report), info.out);

  // Its own kind, and an empty file (mktemp's), get as far as the images.
  for (const std::string& contents : {std::string("{\"format\": \"zipfusion.intrinsics/1\", \"intrinsics\": {}}"), std::string()}) {
    write_file_atomic(cam_json, contents);
    const CommandResult again = run("calibrate intrinsics --images '" + (dir_ / "none").string() + "/*.png' --board 9x6 --out " + cam_json.string());
    EXPECT_EQ(again.err.find("--out:"), std::string::npos) << again.err;
    EXPECT_NE(again.err.find("none"), std::string::npos) << again.err;
  }
}

TEST_F(CalibrateCli, CalibratesIntrinsicsFromRenderedBoards) {
  const fs::path boards = dir_ / "boards";
  ASSERT_EQ(run("synth --checkerboard --views 8 --out " + boards.string()).exit_code, 0);
  write_color_image(boards / "view_blank.png", ColorImage(640, 480, Rgb8{128, 128, 128}));  // no board in it
  const fs::path out = dir_ / "cam.json";
  const CommandResult r = run("calibrate intrinsics --images '" + boards.string() + "/*.png' --board 9x6 --square 0.025 --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("view_007.png"), std::string::npos);  // the error per image
  EXPECT_EQ(r.err, "calibrate: warning: only 8 views used; 10 or more, the board tilted differently in each, pin the principal point down\n");
  std::ifstream in(out);
  const nlohmann::json j = nlohmann::json::parse(in);
  std::ifstream truth_in(boards / "truth.json");
  const nlohmann::json truth = nlohmann::json::parse(truth_in);
  for (const char* key : {"fx", "fy", "cx", "cy"}) {
    EXPECT_NEAR(j["intrinsics"][key].get<double>(), truth["intrinsics"][key].get<double>(), 0.005 * truth["intrinsics"][key].get<double>()) << key;
  }
  // The file is what `calibrate extrinsics --intrinsics` reads: the same numbers, exactly.
  const Intrinsics read_back = read_intrinsics_file(out);
  EXPECT_EQ(read_back.fx, j["intrinsics"]["fx"].get<double>());
  EXPECT_EQ(read_back.cy, j["intrinsics"]["cy"].get<double>());
  EXPECT_EQ(read_back.distortion[1], j["intrinsics"]["distortion"][1].get<double>());
  EXPECT_EQ(read_back.width, 640);
  ASSERT_EQ(j["views"].size(), 9u);
  for (const auto& view : j["views"]) {
    const bool blank = view["file"].get<std::string>().ends_with("view_blank.png");
    EXPECT_EQ(view["board_found"], !blank);
    EXPECT_EQ(view["rms_px"].is_null(), blank) << view;  // no board, no error of its own (not 0)
  }
  // Squares counted instead of inner corners: one line saying what the images show, within
  // seconds (the older detector searched each image for 9 s), and nothing written.
  const fs::path wrong = dir_ / "wrong.json";
  const CommandResult miscounted = run("calibrate intrinsics --images '" + boards.string() + "/*.png' --board 10x7 --out " + wrong.string());
  EXPECT_EQ(miscounted.exit_code, 2);
  EXPECT_EQ(line_count(miscounted.err), 1) << miscounted.err;
  EXPECT_NE(miscounted.err.find("--board: 10x7 found in none of 9 images; the largest board seen, in "), std::string::npos) << miscounted.err;
  EXPECT_NE(miscounted.err.find(", has 9x6 inner corners"), std::string::npos) << miscounted.err;
  EXPECT_FALSE(fs::exists(wrong));
  // A --board smaller than the board would match a piece of it (and calibrate fx 8678 against 530):
  // no piece is taken for the board, and the error says what the images show.
  for (const std::string smaller : {"5x4", "8x5"}) {
    const CommandResult piece = run("calibrate intrinsics --images '" + boards.string() + "/*.png' --board " + smaller + " --out " + wrong.string());
    EXPECT_EQ(piece.exit_code, 2) << smaller << ": " << piece.out;
    EXPECT_NE(piece.err.find("--board: " + smaller + " found in none of 9 images; the largest board seen, in "), std::string::npos) << piece.err;
    EXPECT_NE(piece.err.find(", has 9x6 inner corners"), std::string::npos) << piece.err;
    EXPECT_FALSE(fs::exists(wrong));
  }
  // 3x3 pieces of a steeply tilted board, whose grid the detector cannot grow, still pass (1 of
  // these 9 views): too few to calibrate.
  const CommandResult tiny = run("calibrate intrinsics --images '" + boards.string() + "/*.png' --board 3x3 --out " + wrong.string());
  EXPECT_EQ(tiny.exit_code, 2) << tiny.out;
  EXPECT_FALSE(fs::exists(wrong));
}

TEST_F(CalibrateCli, BadInputIsOneLineNamingTheFieldAndExitCode2) {
  CommandResult r = run("calibrate intrinsics --images '" + (dir_ / "none").string() + "/*.png' --out " + (dir_ / "c.json").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--images"), std::string::npos) << r.err;
  r = run("calibrate intrinsics --images '" + (dir_ / "*.png").string() + "' --board 9by6 --out " + (dir_ / "c.json").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--board"), std::string::npos) << r.err;
  r = run("calibrate extrinsics " + dir_.string() + " --led-distance -1 --out " + (dir_ / "r.json").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("led-distance"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "r.json"));
  // A capture without a wand in it: the cameras are not connected, said of that capture.
  const fs::path capture = dir_ / "nowand";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 2 --cameras 2 --resolution 160x120").exit_code, 0);
  r = run("calibrate extrinsics " + capture.string() + " --out " + (dir_ / "r.json").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(line_count(r.err), 1) << r.err;
  EXPECT_EQ(r.err.rfind("zipfusion: error: " + capture.string() + ": the rig is not connected: cam1 share", 0), 0u) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "r.json"));
  // An output that cannot be written is found before the work (exit 3, nothing printed).
  const std::string unwritable = (dir_ / "no" / "r.json").string();
  for (const std::string& args : {"calibrate extrinsics " + capture.string() + " --out " + unwritable,
                                  "calibrate intrinsics --images '" + (dir_ / "*.png").string() + "' --out " + unwritable}) {
    r = run(args);
    EXPECT_EQ(r.exit_code, 3) << args;
    EXPECT_EQ(r.out, "") << args;
    EXPECT_EQ(r.err, "zipfusion: error: " + unwritable + ": cannot write: folder " + (dir_ / "no").string() + " does not exist\n") << args;
  }
  // A folder that looks writable but takes no file (/proc, even for root) is found before the
  // work too: a probe file is made there first.
  r = run("calibrate floor " + capture.string() + " --out /proc/zf_calibrate_cli_test.json");
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err, "zipfusion: error: /proc/zf_calibrate_cli_test.json: cannot write: folder /proc does not take new files\n");
}

}  // namespace
}  // namespace zipfusion
