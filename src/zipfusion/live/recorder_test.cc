#include "zipfusion/live/recorder.h"

#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <functional>

#include "zipfusion/core/error.h"
#include "zipfusion/core/error_test_util.h"
#include "zipfusion/io/capture.h"
#include "zipfusion/io/image_io.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 64, kHeight = 48;

DepthImage depth_of(int camera, int frame) {
  DepthImage d(kWidth, kHeight);
  for (size_t i = 0; i < d.data.size(); ++i) d.data[i] = i % 13 == 0 ? 0 : static_cast<unsigned short>(1000 + 100 * camera + frame + i % 50);
  return d;
}

ColorImage color_of(int camera, int frame) {
  ColorImage c(kWidth, kHeight);
  for (size_t i = 0; i < c.data.size(); ++i) c.data[i] = {static_cast<unsigned char>(i), static_cast<unsigned char>(camera * 50), static_cast<unsigned char>(frame)};
  return c;
}

// A camera that plays a fixed list of frame times, then ends.
class ScriptedCamera final : public LiveCamera {
 public:
  ScriptedCamera(int index, std::vector<double> times) : index_(index), times_(std::move(times)) {
    model_.name = "cam" + std::to_string(index);
    model_.depth_intrinsics = {.width = kWidth, .height = kHeight, .fx = 58, .fy = 58, .cx = 31.5, .cy = 23.5};
    model_.color_intrinsics = model_.depth_intrinsics;
  }
  const CameraModel& model() const override { return model_; }
  std::string description() const override { return "scripted " + std::to_string(index_); }
  double fps() const override { return 30; }
  ReadStatus read(LiveFrame& frame, double) override {
    if (stopped_) reason_ = "stopped";
    if (stopped_ || next_ >= times_.size()) {
      if (reason_.empty()) reason_ = "end of the script";
      return ReadStatus::kEnded;
    }
    const int i = static_cast<int>(next_++);
    frame.time_s = times_[i];
    frame.device_timestamp = static_cast<std::uint32_t>(1000 * index_ + i);
    frame.depth = depth_of(index_, i);
    frame.has_color = true;
    frame.color = color_of(index_, i);
    return ReadStatus::kFrame;
  }
  void stop() override { stopped_ = true; }
  std::string end_reason() const override { return reason_; }
  long dropped_frames() const override { return 0; }

 private:
  int index_;
  std::vector<double> times_;
  size_t next_ = 0;
  std::atomic<bool> stopped_{false};
  std::string reason_;
  CameraModel model_;
};

std::vector<double> regular(int frames, double offset_s) {
  std::vector<double> t;
  for (int i = 0; i < frames; ++i) t.push_back(100 + offset_s + i / 30.0);
  return t;
}

std::unique_ptr<LiveRig> scripted_rig(const std::vector<std::vector<double>>& times, const std::atomic<bool>* cancel = nullptr) {
  std::vector<std::unique_ptr<LiveCamera>> cameras;
  for (size_t c = 0; c < times.size(); ++c) cameras.push_back(std::make_unique<ScriptedCamera>(static_cast<int>(c), times[c]));
  return std::make_unique<LiveRig>(std::move(cameras), LiveRigOptions{.cancel = cancel});
}

class Recorder : public ::testing::Test {
 protected:
  fs::path dir_ = fs::temp_directory_path() / ("zf_recorder_test_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
  void SetUp() override { fs::remove_all(dir_); }
  void TearDown() override { fs::remove_all(dir_); }
};

TEST_F(Recorder, ACameraThatStopsLeavesTheOthersRecordingAndTheCaptureValidThroughout) {
  auto live = scripted_rig({regular(10, 0), regular(5, 0.004), regular(10, 0.002)});
  const Rig rig = make_live_rig(*live);
  int checked = 0;
  RecordOptions options{.color_extension = ".png"};
  options.progress = [&](const LiveFrameSet& set) {
    // After every frame set the folder is a valid capture of exactly the sets so far.
    const Capture now = Capture::open(dir_);
    EXPECT_EQ(now.frame_count(), set.index + 1);
    EXPECT_EQ(now.missing_frames().size(), set.index >= 5 ? 2u * (set.index - 4) : 0u);
    ++checked;
  };
  const RecordResult result = record_capture(*live, rig, dir_, options);
  EXPECT_EQ(checked, 10);
  EXPECT_EQ(result.frame_sets, 10);
  EXPECT_EQ(result.frames_written, (std::vector<int>{10, 5, 10}));
  EXPECT_NEAR(result.max_skew_s, 0.004, 1e-9);
  EXPECT_NEAR(result.mean_skew_s, (5 * 0.004 + 5 * 0.002) / 10, 1e-9);
  EXPECT_NEAR(result.duration_s, 9 / 30.0, 1e-9);
  EXPECT_FALSE(result.limit_reached);
  EXPECT_EQ(result.cameras[1].end_reason, "end of the script");
  EXPECT_EQ(result.cameras[1].frames, 5);

  const Capture capture = Capture::open(dir_);
  EXPECT_EQ(capture.frame_count(), 10);
  ASSERT_EQ(capture.missing_frames().size(), 10u);  // cam1's depth and colour of frames 5..9
  for (const MissingFrame& m : capture.missing_frames()) EXPECT_EQ(m.camera, 1);
  EXPECT_THROW(Capture::open(dir_, {.strict = true}), InvalidInput);
  for (int f = 0; f < 10; ++f) {
    const FrameSet set = capture.load_frame(f);
    for (int c = 0; c < 3; ++c) {
      if (c == 1 && f >= 5) {
        EXPECT_FALSE(set.cameras[c].has_depth);
        continue;
      }
      EXPECT_EQ(set.cameras[c].depth, depth_of(c, f)) << c << " " << f;
      EXPECT_EQ(set.cameras[c].color, color_of(c, f)) << c << " " << f;
    }
  }
  for (const auto& entry : fs::recursive_directory_iterator(dir_)) {
    EXPECT_NE(entry.path().extension(), ".part") << entry.path();
  }

  const std::vector<RecordedTimestamp> stamps = read_recorded_timestamps(dir_, capture.frame_count());
  ASSERT_EQ(stamps.size(), 25u);
  EXPECT_EQ(stamps[0].camera, "cam0");
  EXPECT_NEAR(stamps[0].time_s, 0, 1e-9);
  EXPECT_EQ(stamps[1].camera, "cam1");
  EXPECT_NEAR(stamps[1].time_s, 0.004, 1e-6);
  EXPECT_EQ(stamps[1].device_timestamp, 1000u);
  EXPECT_EQ(stamps.back().frame, 9);
  EXPECT_EQ(stamps.back().camera, "cam2");
  EXPECT_NEAR(stamps.back().time_s, 0.002 + 9 / 30.0, 1e-6);
  EXPECT_EQ(stamps.back().device_timestamp, 2009u);
}

TEST_F(Recorder, LimitsStopTheRecording) {
  {
    auto live = scripted_rig({regular(30, 0), regular(30, 0.001)});
    const RecordResult result = record_capture(*live, make_live_rig(*live), dir_, {.max_frames = 7});
    EXPECT_EQ(result.frame_sets, 7);
    EXPECT_TRUE(result.limit_reached);
    EXPECT_EQ(Capture::open(dir_, {.strict = true}).frame_count(), 7);
  }
  fs::remove_all(dir_);
  {
    auto live = scripted_rig({regular(30, 0), regular(30, 0.001)});
    const RecordResult result = record_capture(*live, make_live_rig(*live), dir_, {.max_seconds = 0.5});
    EXPECT_EQ(result.frame_sets, 15);  // anchors at 0, 1/30, ..., 14/30 < 0.5 s
    EXPECT_EQ(Capture::open(dir_, {.strict = true}).frame_count(), 15);
  }
}

TEST_F(Recorder, CancelStopsCleanlyWithAValidCapture) {
  std::atomic<bool> cancel{false};
  auto live = scripted_rig({regular(30, 0), regular(30, 0.001)}, &cancel);
  RecordOptions options;
  options.progress = [&](const LiveFrameSet& set) {
    if (set.index == 3) cancel = true;
  };
  const RecordResult result = record_capture(*live, make_live_rig(*live), dir_, options);
  EXPECT_FALSE(result.limit_reached);
  EXPECT_GE(result.frame_sets, 4);
  EXPECT_LE(result.frame_sets, 6);
  const Capture capture = Capture::open(dir_);
  EXPECT_EQ(capture.frame_count(), result.frame_sets);
  EXPECT_EQ(result.cameras[0].end_reason, "stopped");
  EXPECT_EQ(read_recorded_timestamps(dir_, capture.frame_count()).size(), static_cast<size_t>(result.frames_written[0] + result.frames_written[1]));
}

TEST_F(Recorder, CalibrationGivesNamesIntrinsicsPosesAndVolume) {
  auto live = scripted_rig({regular(3, 0), regular(3, 0)});
  Rig calibration = make_live_rig(*live);
  calibration.cameras[0].name = "left";
  calibration.cameras[1].name = "right";
  calibration.cameras[1].world_from_depth.translation() = Eigen::Vector3d(1, 2, 3);
  calibration.cameras[1].depth_intrinsics.fx = 999;  // calibrated intrinsics replace the devices' nominal ones
  calibration.cameras[1].color_intrinsics->cy = 24.25;
  calibration.cameras[1].color_from_depth.translation() = Eigen::Vector3d(0.025, 0, 0);
  calibration.volume = Box3d{{-1, -1, 0}, {1, 1, 2}};
  calibration.poses_trusted = true;
  const Rig rig = make_live_rig(*live, &calibration, "cal.json");
  EXPECT_EQ(rig.cameras[1].name, "right");
  EXPECT_EQ(rig.cameras[1].world_from_depth.translation(), Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(rig.cameras[1].depth_intrinsics.fx, 999);
  EXPECT_EQ(rig.cameras[1].color_intrinsics->cy, 24.25);
  EXPECT_EQ(rig.cameras[1].color_from_depth.translation(), Eigen::Vector3d(0.025, 0, 0));
  EXPECT_EQ(rig.cameras[0].depth_intrinsics.fx, 58);
  EXPECT_TRUE(rig.poses_trusted);
  record_capture(*live, rig, dir_, {});
  const Capture capture = Capture::open(dir_, {.strict = true});
  EXPECT_EQ(capture.rig().cameras[0].name, "left");
  EXPECT_EQ(capture.rig().cameras[1].depth_intrinsics.fx, 999);  // the recording reads through the calibration
  EXPECT_TRUE(capture.rig().poses_trusted);
  ASSERT_TRUE(capture.rig().volume.has_value());
  EXPECT_EQ(capture.frame_count(), 3);
  EXPECT_TRUE(fs::is_directory(dir_ / "right" / "depth"));

  calibration.cameras.pop_back();
  EXPECT_EQ(invalid_input_message([&] { make_live_rig(*live, &calibration, "cal.json"); }), "cal.json: cameras: has 1 cameras, but 2 devices are selected");
}

TEST_F(Recorder, ACalibrationOfOtherImagesIsOneLineNamingTheField) {
  auto live = scripted_rig({regular(3, 0), regular(3, 0)});
  const Rig devices = make_live_rig(*live);
  auto message = [&](const std::function<void(Rig&)>& change) {
    Rig calibration = devices;
    change(calibration);
    return invalid_input_message([&] { make_live_rig(*live, &calibration, "cal.json"); });
  };
  EXPECT_EQ(message([](Rig& r) { r.cameras[1].depth_intrinsics.width = 320; }),
            "cal.json: cameras[1].depth_intrinsics: 320x48, but the device's images are 64x48");
  EXPECT_EQ(message([](Rig& r) { r.cameras[0].color_intrinsics->height = 96; }),
            "cal.json: cameras[0].color_intrinsics: 64x96, but the device's images are 64x48");
  EXPECT_EQ(message([](Rig& r) { r.cameras[0].color_intrinsics.reset(); }),
            "cal.json: cameras[0].color_intrinsics: missing, but the device's camera has colour");
}

// Live frames through a calibration whose depth has lens distortion are undistorted exactly as
// the capture recorded through the same calibration reads them: the live view and a later
// reconstruction of the recording see the same depth.
TEST_F(Recorder, LiveDepthIsUndistortedAsTheRecordingReadsIt) {
  auto recording = scripted_rig({regular(3, 0), regular(3, 0)});
  Rig calibration = make_live_rig(*recording);
  Intrinsics& k = calibration.cameras[1].depth_intrinsics;
  k.distortion = {-0.25, 0.08, 0.002, -0.001, 0};
  k.has_distortion = true;
  const Rig rig = make_live_rig(*recording, &calibration, "cal.json");
  record_capture(*recording, rig, dir_, {});
  const Capture capture = Capture::open(dir_, {.strict = true});

  // One frame set filled again and again, as the pipeline hands its sets back; camera 1 ends after
  // frame 2, so its depth must then be gone, not frame 2's left in the set.
  auto live = scripted_rig({regular(5, 0), regular(3, 0)});
  LiveFrameSource source = live_frame_source(*live, {.depth_undistortion = depth_undistortion_maps(make_live_rig(*live, &calibration, "cal.json"))});
  FrameSet set;
  for (int f = 0; f < 5; ++f) {
    double decode_ms = 0;
    ASSERT_TRUE(source(set, decode_ms));
    EXPECT_EQ(set.index, f);
    EXPECT_EQ(set.cameras[0].depth.data, depth_of(0, f).data);  // no distortion: as delivered
    EXPECT_EQ(set.cameras[0].color, color_of(0, f));
    if (f >= 3) {
      EXPECT_FALSE(set.cameras[1].has_depth || set.cameras[1].has_color) << "frame " << f;
      EXPECT_TRUE(set.cameras[1].depth.empty() && set.cameras[1].color.empty()) << "frame " << f;
      continue;
    }
    const FrameSet recorded = capture.load_frame(f);
    EXPECT_EQ(set.cameras[1].depth.data, recorded.cameras[1].depth.data);
    int moved = 0;
    for (size_t p = 0; p < depth_of(1, f).data.size(); ++p) moved += set.cameras[1].depth.data[p] != depth_of(1, f).data[p];
    EXPECT_GT(moved, 300) << "frame " << f;  // the distortion moved pixels: the test sees the map
  }
}

TEST_F(Recorder, BadOptionsAndANonEmptyFolderAreRejected) {
  auto live = scripted_rig({regular(3, 0)});
  const Rig rig = make_live_rig(*live);
  EXPECT_THROW(record_capture(*live, rig, dir_, {.max_frames = -1}), InvalidInput);
  EXPECT_THROW(record_capture(*live, rig, dir_, {.color_extension = ".bmp"}), InvalidInput);
  fs::create_directories(dir_);
  { std::ofstream(dir_ / "something") << "x"; }
  const std::string message = invalid_input_message([&] { record_capture(*live, rig, dir_, {}); });
  EXPECT_NE(message.find("choose a new --out"), std::string::npos) << message;
}

}  // namespace
}  // namespace zipfusion
