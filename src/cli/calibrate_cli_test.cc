// End-to-end test of `zipfusion synth --wand/--checkerboard` and `zipfusion calibrate`: small
// captures (320x240, 120 wand frames, 8 board views) to stay fast; the full-size targets are in
// src/zipfusion/calib/*_test.cc.

#include <gtest/gtest.h>

#include <fstream>
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

class CalibrateCli : public testing::CliTest {};

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
  ASSERT_EQ(j["views"].size(), 9u);
  for (const auto& view : j["views"]) {
    const bool blank = view["file"].get<std::string>().ends_with("view_blank.png");
    EXPECT_EQ(view["board_found"], !blank);
    EXPECT_EQ(view["rms_px"].is_null(), blank) << view;  // no board, no error of its own (not 0)
  }
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
}

}  // namespace
}  // namespace zipfusion
