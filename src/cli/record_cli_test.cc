// End-to-end tests of live capture: synthetic fakenect dumps (synth --fakenect) replayed through
// libfreenect's fakenect into `zipfusion record` and `reconstruct --live`, and through --replay;
// the recorded captures are checked against the dumps' truth.

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>
#include <thread>

#include "cli/cli_test_util.h"
#include "zipfusion/core/error.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/live/fakenect_dump.h"
#include "zipfusion/live/kinect_disparity.h"
#include "zipfusion/live/recorder.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

struct CommandResult {
  int exit_code = -1;
  std::string out, err;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

int line_count(const std::string& text) { return static_cast<int>(std::count(text.begin(), text.end(), '\n')); }

// Per process, so two test runs on one machine do not share folders.
const fs::path kShared = fs::temp_directory_path() / ("zf_record_cli_dumps_" + std::to_string(::getpid()));
const std::string kBinary = ZF_BINARY;
constexpr int kFrames = 20, kCutAt = 8, kLongFrames = 45;

// Runs a shell command line with no standard input.
CommandResult sh(const std::string& command, const fs::path& dir) {
  const int status = std::system((command + " > " + (dir / "stdout").string() + " 2> " + (dir / "stderr").string() + " < /dev/null").c_str());
  CommandResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(dir / "stdout");
  r.err = slurp(dir / "stderr");
  return r;
}

// How far recorded depth is from the truth, against the disparity model's quantisation: half a
// raw step at the pixel's depth plus the millimetre rounding.
struct DepthCheck {
  long valid = 0;             // pixels with depth in both
  long validity_differs = 0;  // depth in one but not the other
  double max_error_mm = 0;
  double max_ratio = 0;       // max of error / (half a step + 0.5 mm)
};

void compare_depth(const DepthImage& recorded, const DepthImage& truth, DepthCheck& check) {
  ASSERT_EQ(recorded.width, truth.width);
  ASSERT_EQ(recorded.height, truth.height);
  for (size_t i = 0; i < truth.data.size(); ++i) {
    const int t = truth.data[i], r = recorded.data[i];
    if ((t == 0) != (r == 0)) ++check.validity_differs;
    if (t == 0 || r == 0) continue;
    ++check.valid;
    const double z = t / 1000.0;
    const double bound_mm = 1000 * kinect_raw_step_m(z + kinect_raw_step_m(z)) / 2 + 0.5;
    const double error_mm = std::abs(r - t);
    check.max_error_mm = std::max(check.max_error_mm, error_mm);
    check.max_ratio = std::max(check.max_ratio, error_mm / bound_mm);
  }
}

class RecordCli : public ::testing::Test {
 protected:
  // The dumps are written once for all tests: camera 0 complete, camera 1 cut off at frame 8
  // (its device "unplugged"), and a longer one to interrupt.
  static void SetUpTestSuite() {
    fs::remove_all(kShared);
    fs::create_directories(kShared);
    for (const std::string& args : {"--fakenect " + (kShared / "full").string() + " --frames " + std::to_string(kFrames),
                                    "--fakenect " + (kShared / "cut").string() + " --frames " + std::to_string(kFrames) + " --camera 1 --truncate " +
                                        std::to_string(kCutAt),
                                    "--fakenect " + (kShared / "long").string() + " --frames " + std::to_string(kLongFrames) + " --noise none"}) {
      const CommandResult r = sh(kBinary + " synth " + args, kShared);
      ASSERT_EQ(r.exit_code, 0) << args << "\n" << r.err;
    }
    // A dump whose frame 10 depth file is gone (fakenect-record killed while writing, a copy cut
    // short): fakenect itself would exit the process on reaching it.
    fs::create_directories(kShared / "gap");
    const std::vector<FakenectIndexEntry> index = read_fakenect_index(kShared / "full");
    for (const FakenectIndexEntry& e : index) {
      if (e.file != index[21].file) fs::create_symlink(kShared / "full" / e.file, kShared / "gap" / e.file);
    }
    fs::copy_file(kShared / "full" / "INDEX.txt", kShared / "gap" / "INDEX.txt");
  }
  static void TearDownTestSuite() { fs::remove_all(kShared); }

  fs::path dir_ = fs::temp_directory_path() /
                  ("zf_record_cli_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" + std::to_string(::getpid()));
  void SetUp() override {
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  CommandResult run(const std::string& args) { return sh(kBinary + " " + args, dir_); }
  CommandResult under_fakenect(const fs::path& dump, const std::string& args) { return sh("fakenect " + dump.string() + " " + kBinary + " " + args, dir_); }

  // Checks camera `camera` of a recorded capture against a dump's truth over `frames` frames.
  void expect_matches_truth(const Capture& recorded, int camera, const fs::path& dump, int frames, bool replay_times) {
    const Capture truth = Capture::open(dump / "truth", {.strict = true});
    DepthCheck check;
    for (int f = 0; f < frames; ++f) {
      const CameraFrame r = recorded.load_camera_frame(f, camera);
      const CameraFrame t = truth.load_camera_frame(f, 0);
      ASSERT_TRUE(r.has_depth) << f;
      compare_depth(r.depth, t.depth, check);
      ASSERT_TRUE(r.has_color) << f;
      EXPECT_EQ(r.color, t.color) << "colour of frame " << f;
    }
    EXPECT_EQ(check.validity_differs, 0);
    EXPECT_GT(check.valid, 0.2 * 640 * 480 * frames);
    EXPECT_LE(check.max_ratio, 1.0);
    EXPECT_GT(check.max_error_mm, 3.0);  // the raw encoding did quantise (steps of 5-60 mm at 1.3-4.5 m)
    std::printf("[ measured ] %s: %d frames, %ld valid depth pixels, max depth error %.1f mm = %.3f of half a raw step + 0.5 mm\n",
                dump.filename().c_str(), frames, check.valid, check.max_error_mm, check.max_ratio);

    const std::string name = recorded.rig().cameras[camera].name;
    const std::vector<RecordedTimestamp> truth_times = read_recorded_timestamps(dump / "truth", frames);
    std::vector<RecordedTimestamp> times;
    for (const RecordedTimestamp& t : read_recorded_timestamps(recorded.dir(), recorded.frame_count())) {
      if (t.camera == name) times.push_back(t);
    }
    ASSERT_EQ(static_cast<int>(times.size()), frames);
    for (int f = 0; f < frames; ++f) {
      EXPECT_EQ(times[f].frame, f);
      EXPECT_EQ(times[f].device_timestamp, truth_times[f].device_timestamp) << f;
      if (f > 0) {
        EXPECT_GT(times[f].time_s, times[f - 1].time_s) << f;
      }
      if (replay_times) {
        EXPECT_NEAR(times[f].time_s - times[0].time_s, truth_times[f].time_s, 2e-6) << f;
      }
    }
    // Replays keep the dump's times; under fakenect they are the host's arrival times, paced by
    // fakenect's sleeps: never closer than the dump's 1/30 s (less a tenth for the clock's
    // granularity). They may be farther apart (the sleeps do not count the time spent in the
    // callbacks, and a machine busy with other tests slows them), so there is no upper bound: a
    // stall shows as the test's timeout.
    const double mean_interval = (times.back().time_s - times.front().time_s) / (frames - 1);
    std::printf("[ measured ] %s: mean frame interval %.2f ms (the dump's: 33.33 ms)\n", dump.filename().c_str(), mean_interval * 1000);
    EXPECT_GT(mean_interval, 0.9 / 30);
  }
};

TEST_F(RecordCli, FakenectReplayIsRecordedAsTheScene) {
  const fs::path capture = dir_ / "cap";
  const CommandResult r = under_fakenect(kShared / "full", "record --devices all --out " + capture.string() + " --color-format png");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("recording cam0 = Kinect v1 #0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("record: cam0 (Kinect v1 #0): stream ended after 20 frames: end of the fakenect recording"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("recorded 20 frame sets"), std::string::npos) << r.out;
  const Capture recorded = Capture::open(capture, {.strict = true});
  EXPECT_EQ(recorded.frame_count(), kFrames);
  EXPECT_EQ(recorded.rig().fps, 30);
  EXPECT_FALSE(recorded.rig().poses_trusted);
  const CameraModel& camera = recorded.rig().cameras.at(0);
  EXPECT_EQ(camera.name, "cam0");
  EXPECT_EQ(camera.depth_intrinsics.fx, 580);  // fakenect has no registration data: the Kinect v1 defaults
  EXPECT_EQ(camera.color_intrinsics->fx, 525);
  expect_matches_truth(recorded, 0, kShared / "full", kFrames, false);
}

TEST_F(RecordCli, ATruncatedRecordingEndsTheStreamCleanly) {
  const fs::path capture = dir_ / "cap";
  const CommandResult r = under_fakenect(kShared / "cut", "record --devices 0 --out " + capture.string() + " --color-format png");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("stream ended after 8 frames: end of the fakenect recording"), std::string::npos) << r.out;
  const Capture recorded = Capture::open(capture, {.strict = true});
  EXPECT_EQ(recorded.frame_count(), kCutAt);  // frame 8's colour came, its depth did not: no frame 8
  expect_matches_truth(recorded, 0, kShared / "cut", kCutAt, false);
}

TEST_F(RecordCli, AFileMissingFromTheRecordingEndsTheStreamBeforeIt) {
  const fs::path capture = dir_ / "cap";
  const CommandResult r = under_fakenect(kShared / "gap", "record --devices all --out " + capture.string() + " --color-format png");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("stream ended after 10 frames: the fakenect recording ends at INDEX.txt line 22 ("), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("Error: Cannot open file"), std::string::npos) << r.out;  // fakenect never reached it
  const Capture recorded = Capture::open(capture, {.strict = true});
  EXPECT_EQ(recorded.frame_count(), 10);
  expect_matches_truth(recorded, 0, kShared / "full", 10, false);
}

TEST_F(RecordCli, ReplayedDumpsRecordTwoCamerasOneOfWhichStops) {
  // A calibration naming the cameras and giving their true poses.
  Rig calibration = read_rig(kShared / "full" / "truth" / "rig.json");
  const Rig second = read_rig(kShared / "cut" / "truth" / "rig.json");
  calibration.cameras.push_back(second.cameras[0]);
  calibration.cameras[0].name = "front";
  calibration.cameras[1].name = "side";
  write_rig(dir_ / "cal.json", calibration);
  const fs::path capture = dir_ / "cap";
  const CommandResult r = run("record --replay " + (kShared / "full").string() + "," + (kShared / "cut").string() + " --rig " +
                              (dir_ / "cal.json").string() + " --out " + capture.string() + " --color-format png");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("record: side (fakenect dump " + (kShared / "cut").string() + "): stream ended after 8 frames: "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("recorded 20 frame sets in 0.63 s to " + capture.string() + ": front 20 side 8 frames; skew max 0.0 ms, mean 0.0 ms"),
            std::string::npos)
      << r.out;
  const Capture recorded = Capture::open(capture);
  EXPECT_EQ(recorded.frame_count(), kFrames);
  EXPECT_TRUE(recorded.rig().poses_trusted);
  EXPECT_TRUE(recorded.rig().cameras[1].world_from_depth.isApprox(second.cameras[0].world_from_depth, 1e-12));
  ASSERT_EQ(recorded.missing_frames().size(), 2u * (kFrames - kCutAt));
  for (const MissingFrame& m : recorded.missing_frames()) {
    EXPECT_EQ(m.camera, 1);
    EXPECT_GE(m.frame, kCutAt);
  }
  expect_matches_truth(recorded, 0, kShared / "full", kFrames, true);
  expect_matches_truth(recorded, 1, kShared / "cut", kCutAt, true);
}

TEST_F(RecordCli, LiveReconstructionOfReplayedDumps) {
  Rig calibration = read_rig(kShared / "full" / "truth" / "rig.json");
  calibration.cameras.push_back(read_rig(kShared / "cut" / "truth" / "rig.json").cameras[0]);
  calibration.cameras[1].name = "cam1";
  write_rig(dir_ / "cal.json", calibration);
  const fs::path out = dir_ / "meshes";
  const CommandResult r = run("reconstruct --live --replay " + (kShared / "full").string() + "," + (kShared / "cut").string() + " --rig " +
                              (dir_ / "cal.json").string() + " --frames 3 --filter none --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const nlohmann::json stats = nlohmann::json::parse(slurp(out / "stats.json"));
  EXPECT_EQ(stats["capture"], "live");
  EXPECT_EQ(stats["register"], "off");  // the calibration's poses are trusted
  ASSERT_EQ(stats["devices"].size(), 2u);
  EXPECT_EQ(stats["devices"][1]["name"], "cam1");
  ASSERT_EQ(stats["frames"].size(), 3u);  // three sets fit the queues: none dropped
  EXPECT_EQ(stats["dropped_frame_sets"], 0);
  for (const auto& frame : stats["frames"]) {
    EXPECT_EQ(frame["cameras_used"], 2);
    EXPECT_GT(frame["triangles"].get<int>(), 20000);
    EXPECT_DOUBLE_EQ(frame["skew_ms"].get<double>(), 0.0);
    EXPECT_TRUE(fs::exists(out / frame_file_name(frame["frame"].get<int>(), ".ply")));
  }
}

// Live cameras whose calibration is not trusted are refined on their first 16 frame sets before
// the first mesh (a capture's on frames spread over it): the meshes are not made at poses 2° / 5 cm
// off until the worker's first refinement lands. Those sets are not reconstructed (seconds old by
// then) nor counted by --frames.
TEST_F(RecordCli, LiveCamerasAreRefinedBeforeTheFirstMesh) {
  for (int c : {0, 1}) {
    const std::string args = "synth --fakenect " + (dir_ / ("cam" + std::to_string(c))).string() + " --frames 22 --camera " + std::to_string(c);
    ASSERT_EQ(run(args).exit_code, 0) << args;
  }
  Rig truth = read_rig(dir_ / "cam0" / "truth" / "rig.json");
  truth.cameras.push_back(read_rig(dir_ / "cam1" / "truth" / "rig.json").cameras[0]);
  truth.cameras[1].name = "cam1";
  Rig off = truth;
  off.poses_trusted = false;
  Rigid3d& moved = off.cameras[1].world_from_depth;
  moved = moved * Rigid3d(Eigen::AngleAxisd(2 * std::numbers::pi / 180, Eigen::Vector3d(0.3, 1, 0.2).normalized()));
  moved.translation() += Eigen::Vector3d(0.03, -0.02, 0.035);
  write_rig(dir_ / "off.json", off);
  const fs::path out = dir_ / "meshes";
  const CommandResult r = run("reconstruct --live --replay " + (dir_ / "cam0").string() + "," + (dir_ / "cam1").string() + " --rig " +
                              (dir_ / "off.json").string() + " --frames 6 --filter none --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_EQ(r.out.rfind("reconstruct: refining the poses on the first live frame sets before the first mesh (--register once)\n", 0), 0u) << r.out;
  EXPECT_NE(r.out.find("reconstruct: poses refined before the first frame in "), std::string::npos) << r.out;
  const nlohmann::json stats = nlohmann::json::parse(slurp(out / "stats.json"));
  EXPECT_EQ(stats["register"], "once+background");
  EXPECT_GT(stats["refinement_before_first_frame_s"].get<double>(), 0);
  ASSERT_GE(stats["pose_updates"].size(), 1u);
  const nlohmann::json& first = stats["pose_updates"][0];
  EXPECT_EQ(first["frame"], 0);
  EXPECT_EQ(first["version"], 1);
  // The poses the meshes were made with, read back: cam1 relative to cam0 as the truth has it.
  const std::vector<Rigid3d> used = testing::poses_of_update(first);
  const Rigid3d refined = used[0].inverse() * used[1];
  const Rigid3d wanted = truth.cameras[0].world_from_depth.inverse() * truth.cameras[1].world_from_depth;
  const Rigid3d error = wanted.inverse() * refined;
  EXPECT_LT(Eigen::AngleAxisd(error.linear()).angle() * 180 / std::numbers::pi, 0.5);
  EXPECT_LT(error.translation().norm(), 0.01);
  // --frames 6 counts the sets after the 16 taken: six go to the pipeline (which may drop late ones),
  // numbered from 0.
  EXPECT_EQ(static_cast<int>(stats["frames"].size()) + stats["dropped_frame_sets"].get<int>(), 6);
  for (const auto& frame : stats["frames"]) EXPECT_LT(frame["frame"].get<int>(), 6);
}

TEST_F(RecordCli, LiveReconstructionUnderFakenect) {
  const fs::path out = dir_ / "meshes";
  const CommandResult r = under_fakenect(kShared / "full", "reconstruct --live --devices all --frames 4 --filter none --register off --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const nlohmann::json stats = nlohmann::json::parse(slurp(out / "stats.json"));
  EXPECT_EQ(stats["devices"][0]["device"], "Kinect v1 #0");
  const int meshes = static_cast<int>(stats["frames"].size());
  EXPECT_GE(meshes, 1);
  EXPECT_EQ(meshes + stats["dropped_frame_sets"].get<int>(), 4);  // the live queue drops what falls behind
  // Each mesh made live is the one the same frames make offline: the dump recorded (lossless
  // colour), then reconstructed from the capture with the same options, byte for byte.
  const fs::path capture = dir_ / "cap", offline = dir_ / "offline";
  const CommandResult recorded = under_fakenect(kShared / "full", "record --devices all --out " + capture.string() + " --color-format png");
  ASSERT_EQ(recorded.exit_code, 0) << recorded.out << recorded.err;
  const CommandResult made = run("reconstruct " + capture.string() + " --frames 0:4 --filter none --register off --out " + offline.string());
  ASSERT_EQ(made.exit_code, 0) << made.out << made.err;
  for (const auto& frame : stats["frames"]) {
    const std::string name = frame_file_name(frame["frame"].get<int>(), ".ply");
    EXPECT_GT(frame["triangles"].get<int>(), 10000) << name;
    EXPECT_TRUE(slurp(out / name) == slurp(offline / name)) << name << " differs from the offline reconstruction's";
  }
}

TEST_F(RecordCli, CtrlCStopsCleanlyWithAValidCapture) {
  const fs::path capture = dir_ / "cap";
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    setpgid(0, 0);  // a process group of its own, like a shell job: Ctrl-C reaches all of it
    std::freopen((dir_ / "stdout").c_str(), "w", stdout);
    std::freopen((dir_ / "stderr").c_str(), "w", stderr);
    const std::string dump = (kShared / "long").string(), out = capture.string();
    execlp("fakenect", "fakenect", dump.c_str(), kBinary.c_str(), "record", "--devices", "all", "--out", out.c_str(), nullptr);
    _exit(127);
  }
  setpgid(pid, pid);
  // Wait until a few frame sets are on disk, then press Ctrl-C.
  int frames_before = 0;
  for (int i = 0; i < 200 && frames_before < 3; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
    try {
      frames_before = read_rig(capture / "rig.json").frame_count;
    } catch (const std::exception&) {
    }
  }
  ASSERT_GE(frames_before, 3) << slurp(dir_ / "stdout") << slurp(dir_ / "stderr");
  kill(-pid, SIGINT);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  const std::string out = slurp(dir_ / "stdout");
  ASSERT_TRUE(WIFEXITED(status)) << out;
  EXPECT_EQ(WEXITSTATUS(status), 0) << out << slurp(dir_ / "stderr");
  EXPECT_NE(out.find("(stopped by Ctrl-C)"), std::string::npos) << out;
  const Capture recorded = Capture::open(capture, {.strict = true});
  EXPECT_GE(recorded.frame_count(), frames_before);
  EXPECT_LT(recorded.frame_count(), kLongFrames);
  EXPECT_EQ(static_cast<int>(read_recorded_timestamps(capture, recorded.frame_count()).size()), recorded.frame_count());
  std::printf("[ measured ] Ctrl-C after %d frame sets on disk: %d recorded\n", frames_before, recorded.frame_count());
}

TEST_F(RecordCli, BadOptionsGiveOneLineNamingTheOption) {
  struct Case {
    bool fakenect;
    std::string args, expected;
    int exit_code;
  };
  const std::string out = (dir_ / "cap").string(), full = (kShared / "full").string();
  fs::create_directories(dir_ / "busy");
  { std::ofstream(dir_ / "busy" / "x") << "x"; }
  Rig small = read_rig(kShared / "full" / "truth" / "rig.json");  // a calibration of 320x240 depth
  small.cameras[0].depth_intrinsics = {.width = 320, .height = 240, .fx = 290, .fy = 290, .cx = 159.5, .cy = 119.5};
  write_rig(dir_ / "small.json", small);
  const std::string small_calibration = (dir_ / "small.json").string();
  const std::vector<Case> cases = {
      {false, "record --out " + out, "--devices, --replay: give exactly one", 2},
      {false, "record --devices all --replay " + full + " --out " + out, "--devices, --replay: give exactly one", 2},
      {false, "record --replay " + full, "--out: required", 2},
      {false, "record --replay " + full + " --out " + out + " --frames -1", "--frames: must be in [0, 1000000] (0 = no limit), got -1", 2},
      {false, "record --replay " + full + " --out " + out + " --jpeg-quality 0", "--jpeg-quality: must be in [1, 100]", 2},
      {false, "record --replay " + full + " --out " + (dir_ / "busy").string(), "choose a new --out", 2},
      {false, "record --replay " + (dir_ / "nothing").string() + " --out " + out, "INDEX.txt", 3},
      {false, "record --replay " + full + " --rig " + (kShared / "cut" / "truth" / "rig.json").string() + "," + " --out " + out, "rig.json", 3},
      {true, "record --devices 1 --out " + out, "--devices: index 1: only 1 Kinect v1 found", 2},
      {true, "record --devices 0,0 --out " + out, "--devices: device 0 is selected twice", 2},
      {true, "record --devices 0, --out " + out, "--devices: \"0,\": an empty entry", 2},
      {true, "record --devices A00364A11700045A --out " + out, "--devices: serial A00364A11700045A: this libfreenect cannot list serials", 2},
      {true, "record --devices all --depth-format mm --out " + out, "--depth-format: this libfreenect delivers only raw 11-bit depth (fakenect)", 2},
      {false, "record --replay " + full + " --rig " + small_calibration + " --out " + out,
       small_calibration + ": cameras[0].depth_intrinsics: 320x240, but the device's images are 640x480", 2},
      {false, "reconstruct --live --replay " + full + " --rig " + small_calibration + " --out " + out,
       small_calibration + ": cameras[0].depth_intrinsics: 320x240, but the device's images are 640x480", 2},
      {false, "reconstruct --live --out " + out, "--devices, --replay: give exactly one", 2},
      // Two cameras without a calibration would both stand at the identity pose.
      {false, "reconstruct --live --replay " + full + "," + (kShared / "cut").string() + " --out " + out, "--rig: required with 2 live cameras", 2},
      {false, "serve --live --replay " + full + "," + (kShared / "cut").string() + " --port 0", "--rig: required with 2 live cameras", 2},
      {false, "reconstruct --live --replay " + full + " --frames 0:3 --out " + out, "--frames: with --live, the number of frame sets", 2},
      {false, "reconstruct " + full + " --live --replay " + full + " --out " + out, "--live: takes no CAPTURE", 2},
      {false, "reconstruct --out " + out, "capture: required (or --live)", 2},
      {false, "synth --fakenect " + (dir_ / "d").string() + " --frames 3 --truncate 3", "--truncate: must be in [0, 2]", 2},
      {false, "synth --fakenect " + (dir_ / "d").string() + " --camera 4", "--camera: must be in [0, 3]", 2},
      {false, "synth --fakenect " + (dir_ / "d").string() + " --resolution 320x240", "--resolution: fakenect replays 640x480 only", 2},
      {false, "synth --fakenect " + (dir_ / "d").string() + " --out " + out, "--out, --fakenect: choose one", 2},
  };
  for (const Case& c : cases) {
    const CommandResult r = c.fakenect ? under_fakenect(kShared / "full", c.args) : run(c.args);
    EXPECT_EQ(r.exit_code, c.exit_code) << c.args << "\n" << r.out << r.err;
    EXPECT_EQ(line_count(r.err), 1) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_EQ(r.out.find("recording"), std::string::npos) << c.args << ": refused before it starts\n" << r.out;
  }
  EXPECT_FALSE(fs::exists(dir_ / "cap" / "rig.json"));
}

}  // namespace
}  // namespace zipfusion
