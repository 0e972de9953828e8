#include "zipfusion/io/capture.h"

#include <gtest/gtest.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <jpeglib.h>
#include <zlib.h>

#include <cstdlib>
#include <functional>
#include <span>
#include <string_view>
#include <typeinfo>
#include <opencv2/imgcodecs.hpp>

#include "zipfusion/core/error.h"
#include "zipfusion/core/error_test_util.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/image_io.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

const fs::path kSharedData = fs::path(ZF_SOURCE_DIR) / ".." / "shared" / "data";

DepthImage ramp_depth(int width, int height, int frame) {
  DepthImage d(width, height);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) d(u, v) = static_cast<unsigned short>((u + v) % 7 == 0 ? 0 : 1000 + 10 * u + v + frame);
  }
  return d;
}

ColorImage pattern_color(int width, int height, int frame) {
  ColorImage c(width, height);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) c(u, v) = {static_cast<unsigned char>(u * 7), static_cast<unsigned char>(v * 9), static_cast<unsigned char>(frame * 40)};
  }
  return c;
}

// A small two-camera capture: "a" with colour (PNG, lossless), "b" depth only.
class SmallCapture : public ::testing::Test {
 protected:
  static constexpr int kWidth = 32, kHeight = 24, kFrames = 3;
  fs::path dir_ = fs::temp_directory_path() / ("zf_capture_test_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));

  void SetUp() override {
    fs::remove_all(dir_);
    rig_.frame_count = kFrames;
    CameraModel a;
    a.name = "a";
    a.depth_intrinsics = {.width = kWidth, .height = kHeight, .fx = 30, .fy = 30, .cx = 15.5, .cy = 11.5};
    a.color_intrinsics = a.depth_intrinsics;
    CameraModel b = a;
    b.name = "b";
    b.color_intrinsics.reset();
    rig_.cameras = {a, b};
    for (const CameraModel& cam : rig_.cameras) fs::create_directories(dir_ / cam.name / "depth");
    fs::create_directories(dir_ / "a" / "color");
    for (int f = 0; f < kFrames; ++f) {
      for (const CameraModel& cam : rig_.cameras) write_depth_png(dir_ / cam.name / "depth" / frame_file_name(f, ".png"), ramp_depth(kWidth, kHeight, f));
      write_color_image(dir_ / "a" / "color" / frame_file_name(f, ".png"), pattern_color(kWidth, kHeight, f));
    }
    write_rig(dir_ / "rig.json", rig_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Any exception's message, not only InvalidInput's (so not invalid_input_message): opening also
  // throws IoError. "no error" when it opens.
  std::string open_error(const CaptureOpenOptions& options = {}) {
    try {
      Capture::open(dir_, options);
    } catch (const std::exception& e) {
      return e.what();
    }
    return "no error";
  }
  // Why a camera's frame file cannot be used: opened strict, the error thrown. Otherwise a file
  // whose bytes do not decode (`corrupt`) is listed with the same text in `unreadable` and the
  // frame loads without that image; one that decodes to another size or bit depth than rig.json's
  // is the same error.
  std::string load_error(int frame, int camera, bool corrupt) {
    std::string error = "no error";
    try {
      Capture::open(dir_, {.strict = true}).load_camera_frame(frame, camera);
    } catch (const InvalidInput& e) {
      error = e.what();
    }
    std::string error_not_strict = "no error";
    try {
      const CameraFrame degraded = Capture::open(dir_).load_camera_frame(frame, camera);
      EXPECT_EQ(degraded.unreadable, std::vector<std::string>{error});
    } catch (const InvalidInput& e) {
      error_not_strict = e.what();
    }
    EXPECT_EQ(error_not_strict, corrupt ? "no error" : error);
    return error;
  }

  Rig rig_;
};

TEST_F(SmallCapture, LoadsWhatWasWritten) {
  const Capture capture = Capture::open(dir_);
  EXPECT_EQ(capture.frame_count(), kFrames);
  EXPECT_TRUE(capture.missing_frames().empty());
  for (int f = 0; f < kFrames; ++f) {
    const FrameSet set = capture.load_frame(f);
    ASSERT_EQ(set.cameras.size(), 2u);
    EXPECT_TRUE(set.cameras[0].has_depth);
    EXPECT_EQ(set.cameras[0].depth, ramp_depth(kWidth, kHeight, f));
    EXPECT_TRUE(set.cameras[0].has_color);
    EXPECT_EQ(set.cameras[0].color, pattern_color(kWidth, kHeight, f));
    EXPECT_TRUE(set.cameras[1].has_depth);
    EXPECT_FALSE(set.cameras[1].has_color);
  }
}

TEST_F(SmallCapture, MissingFrameDegradesOrFailsWhenStrict) {
  fs::remove(dir_ / "b" / "depth" / "000001.png");
  fs::remove(dir_ / "a" / "color" / "000002.png");
  const Capture capture = Capture::open(dir_);
  ASSERT_EQ(capture.missing_frames().size(), 2u);
  const FrameSet set1 = capture.load_frame(1);
  EXPECT_TRUE(set1.cameras[0].has_depth);
  EXPECT_FALSE(set1.cameras[1].has_depth);
  const FrameSet set2 = capture.load_frame(2);
  EXPECT_TRUE(set2.cameras[0].has_depth);
  EXPECT_FALSE(set2.cameras[0].has_color);

  const std::string error = open_error({.strict = true});
  EXPECT_NE(error.find((dir_ / "b" / "depth" / "000001.png").string()), std::string::npos) << error;
  EXPECT_NE(error.find("missing frame"), std::string::npos) << error;
}

// A file that is there but cannot be used (a recorder killed mid-write) costs its camera that
// frame set, as a missing one does, and is listed with its reason; the other cameras and frames
// load as they are.
TEST_F(SmallCapture, AnUnusableFrameFileDegradesLikeAMissingOne) {
  const fs::path depth = dir_ / "b" / "depth" / "000002.png", color = dir_ / "a" / "color" / "000001.png";
  std::vector<std::uint8_t> bytes = read_file_bytes(depth);
  bytes.resize(bytes.size() / 2);
  write_file_atomic(depth, bytes);
  write_file_atomic(color, std::string_view("not an image"));
  const Capture capture = Capture::open(dir_);
  EXPECT_TRUE(capture.missing_frames().empty());
  const FrameSet set2 = capture.load_frame(2);
  EXPECT_FALSE(set2.cameras[1].has_depth);
  EXPECT_TRUE(set2.cameras[1].depth.empty());
  EXPECT_EQ(set2.cameras[0].depth, ramp_depth(kWidth, kHeight, 2));
  ASSERT_EQ(unreadable_files(set2).size(), 1u);
  EXPECT_EQ(unreadable_files(set2)[0].rfind(depth.string() + ": cannot decode image (corrupt or truncated): ", 0), 0u) << unreadable_files(set2)[0];
  const FrameSet set1 = capture.load_frame(1);
  EXPECT_TRUE(set1.cameras[0].has_depth);
  EXPECT_FALSE(set1.cameras[0].has_color);
  EXPECT_TRUE(set1.cameras[0].color.empty());
  EXPECT_EQ(unreadable_files(set1), std::vector<std::string>{color.string() + ": not a JPEG or PNG file"});
  EXPECT_TRUE(unreadable_files(capture.load_frame(0)).empty());
  // Depth alone does not decode the colour, nor report it.
  const CameraFrame depth_only = capture.load_camera_depth(1, 0);
  EXPECT_EQ(depth_only.depth, ramp_depth(kWidth, kHeight, 1));
  EXPECT_FALSE(depth_only.has_color);
  EXPECT_TRUE(depth_only.unreadable.empty());
}

// A FrameSetReader fills one FrameSet frame after frame (the pipeline's recycled sets): what it
// holds is what a fresh load gives, whatever the set held before. A missing, undecodable or
// present file after the others leaves its camera's image empty or whole, never last frame's.
TEST_F(SmallCapture, AReusedFrameSetHoldsWhatAFreshLoadGives) {
  const fs::path depth = dir_ / "b" / "depth" / "000002.png";
  std::vector<std::uint8_t> bytes = read_file_bytes(depth);
  bytes.resize(bytes.size() / 2);
  write_file_atomic(depth, bytes);
  fs::remove(dir_ / "a" / "color" / "000001.png");
  fs::remove(dir_ / "a" / "depth" / "000000.png");
  const Capture capture = Capture::open(dir_);
  FrameSetReader reader(capture);
  FrameSet set;
  for (int f : {1, 0, 2, 1, 2, 0, 2, 1}) {
    reader.read(f, set);
    const FrameSet fresh = capture.load_frame(f);
    EXPECT_EQ(set.index, f);
    ASSERT_EQ(set.cameras.size(), fresh.cameras.size());
    for (size_t c = 0; c < set.cameras.size(); ++c) {
      const CameraFrame &got = set.cameras[c], &want = fresh.cameras[c];
      EXPECT_EQ(got.has_depth, want.has_depth) << "frame " << f << " camera " << c;
      EXPECT_EQ(got.depth, want.depth) << "frame " << f << " camera " << c;
      EXPECT_EQ(got.has_color, want.has_color) << "frame " << f << " camera " << c;
      EXPECT_EQ(got.color, want.color) << "frame " << f << " camera " << c;
      EXPECT_EQ(got.unreadable, want.unreadable) << "frame " << f << " camera " << c;
    }
  }
  EXPECT_FALSE(set.cameras[0].has_color);  // frame 1, read last
  EXPECT_TRUE(set.cameras[0].color.empty());
}

// A corrupt depth file whose header claims a far larger image than the camera's: the decoder makes
// room for it before the data runs out. Left out, that room goes, not kept in the reused set for
// the rest of the run.
TEST_F(SmallCapture, ACorruptFilesClaimedSizeIsNotKept) {
  const std::vector<std::uint8_t> large = encode_depth_png(ramp_depth(2000, 1500, 7));
  const fs::path depth = dir_ / "b" / "depth" / "000001.png";
  write_file_atomic(depth, std::span<const std::uint8_t>(large.data(), 200));  // the header and a little of the data
  const Capture capture = Capture::open(dir_);
  FrameSetReader reader(capture);
  FrameSet set;
  reader.read(0, set);
  reader.read(1, set);
  EXPECT_FALSE(set.cameras[1].has_depth);
  ASSERT_EQ(unreadable_files(set).size(), 1u);
  EXPECT_LE(set.cameras[1].depth.data.capacity(), static_cast<size_t>(kWidth) * kHeight);
  reader.read(2, set);
  EXPECT_EQ(set.cameras[1].depth, ramp_depth(kWidth, kHeight, 2));
}

// A frame "file" that cannot be read (here a folder) is left out like an undecodable one.
TEST_F(SmallCapture, AFrameThatCannotBeReadDegradesLikeAnUndecodableOne) {
  const fs::path file = dir_ / "b" / "depth" / "000001.png";
  fs::remove(file);
  fs::create_directories(file);
  const FrameSet set = Capture::open(dir_).load_frame(1);
  EXPECT_FALSE(set.cameras[1].has_depth);
  EXPECT_TRUE(set.cameras[0].has_depth);
  EXPECT_EQ(unreadable_files(set), std::vector<std::string>{file.string() + ": not a regular file (a folder, device or pipe)"});
  EXPECT_THROW(Capture::open(dir_, {.strict = true}).load_frame(1), IoError);
  // A pipe with no writer: opening it must not wait for one.
  fs::remove(file);
  ASSERT_EQ(::mkfifo(file.c_str(), 0600), 0);
  EXPECT_EQ(unreadable_files(Capture::open(dir_).load_frame(1)), std::vector<std::string>{file.string() + ": not a regular file (a folder, device or pipe)"});
}

TEST(FolderPath, TrailingSeparatorsAndDotsGo) {
  EXPECT_EQ(folder_path("out"), fs::path("out"));
  EXPECT_EQ(folder_path("out/"), fs::path("out"));
  EXPECT_EQ(folder_path("out/."), fs::path("out"));
  EXPECT_EQ(folder_path("out/./"), fs::path("out"));
  EXPECT_EQ(folder_path("a/out//"), fs::path("a/out"));
  EXPECT_EQ(folder_path("/tmp/out/"), fs::path("/tmp/out"));
  EXPECT_EQ(folder_path("link/../out"), fs::path("link/../out"));  // ".." is the OS's to resolve, through a link
  EXPECT_EQ(folder_path("."), fs::path("."));
  EXPECT_EQ(folder_path("/"), fs::path("/"));
}

// A staging folder that a killed run left (its process gone, its lock free) goes with the next
// run; one whose process lives, or whose lock is held (a run in another PID namespace), stays.
// A run that fails removes the parent folders it made.
TEST(WriteFolderAtomic, RemovesOnlyAbandonedStagingFolders) {
  const fs::path dir = fs::temp_directory_path() / ("zf_write_folder_staging_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const pid_t gone = ::fork();
  if (gone == 0) ::_exit(0);
  ASSERT_GT(gone, 0);
  ASSERT_EQ(::waitpid(gone, nullptr, 0), gone);
  const fs::path abandoned = dir / (".cap.partial-" + std::to_string(gone));
  const fs::path alive = dir / (".cap.partial-" + std::to_string(::getppid()));
  const fs::path held = dir / ".cap.partial-999999999";
  for (const fs::path& p : {abandoned, alive, held}) fs::create_directories(p / "cam0");
  const int lock = ::open(held.c_str(), O_RDONLY | O_DIRECTORY);
  ASSERT_EQ(::flock(lock, LOCK_EX), 0);
  write_folder_atomic(dir / "cap", [](const fs::path& staging) { write_file_atomic(staging / "rig.json", "{}"); });
  ::close(lock);
  EXPECT_TRUE(fs::exists(dir / "cap" / "rig.json"));
  EXPECT_FALSE(fs::exists(abandoned));
  EXPECT_TRUE(fs::exists(alive));
  EXPECT_TRUE(fs::exists(held));
  EXPECT_THROW(write_folder_atomic(dir / "a" / "b" / "cap", [](const fs::path&) { throw IoError("no subject"); }), IoError);
  EXPECT_FALSE(fs::exists(dir / "a"));
  fs::remove_all(dir);
}

std::string read_text(const fs::path& path) {
  const std::vector<std::uint8_t> bytes = read_file_bytes(path);
  return std::string(bytes.begin(), bytes.end());
}

// A StagedFolder's files appear together at commit(), the one named last after the others
// (not observed here), replacing files of the same names and leaving the rest; without commit() the folder is as it
// was (a new one, and the parents made for it, gone). One run at a time holds the folder, and a
// killed run's staging folder goes with the next run.
TEST(StagedFolder, FilesAppearTogetherOrNotAtAll) {
  const fs::path dir = fs::temp_directory_path() / ("zf_staged_folder_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  {
    StagedFolder failed(dir / "a" / "out", "--out");
    EXPECT_TRUE(failed.made_dir());
    write_file_atomic(failed.staging() / "000000.ply", "new");
  }
  EXPECT_FALSE(fs::exists(dir / "a")) << "an uncommitted run leaves no folder it made";
  const fs::path out = dir / "out";
  const pid_t gone = ::fork();
  if (gone == 0) ::_exit(0);
  ASSERT_GT(gone, 0);
  ASSERT_EQ(::waitpid(gone, nullptr, 0), gone);
  const fs::path killed = out / (".zipfusion-staging-" + host_name() + "-" + std::to_string(gone));
  const fs::path elsewhere = out / (".zipfusion-staging-another.host-" + std::to_string(gone));  // a run on another machine
  fs::create_directories(killed / "x");
  fs::create_directories(elsewhere / "x");
  write_file_atomic(out / "000000.ply", "old 0");
  write_file_atomic(out / "notes.txt", "kept");
  {
    StagedFolder run(out, "--out");
    EXPECT_FALSE(run.made_dir());
    EXPECT_FALSE(fs::exists(killed));
    EXPECT_TRUE(fs::exists(elsewhere));
    EXPECT_EQ(run.removed(), std::vector<fs::path>{killed});
    EXPECT_EQ(run.staging().parent_path(), out);
    // A second run, in this process or another, finds the folder held.
    const std::string message = invalid_input_message([&] { StagedFolder second(out, "--out"); });
    EXPECT_NE(message.find("another zipfusion run is writing into this folder (choose another --out"), std::string::npos) << message;
    write_file_atomic(run.staging() / "000000.ply", "new 0");
    write_file_atomic(run.staging() / "000001.ply", "new 1");
    EXPECT_EQ(read_text(out / "000000.ply"), "old 0") << "nothing appears before commit()";
  }
  EXPECT_EQ(read_text(out / "000000.ply"), "old 0") << "an uncommitted run replaces nothing";
  EXPECT_FALSE(fs::exists(out / "000001.ply"));
  StagedFolder run(out, "--out");
  write_file_atomic(run.staging() / "stats.json", "{}");
  write_file_atomic(run.staging() / "000000.ply", "new 0");
  write_file_atomic(run.staging() / "000001.ply", "new 1");
  run.commit("stats.json");
  EXPECT_EQ(read_text(out / "000000.ply"), "new 0");
  EXPECT_EQ(read_text(out / "000001.ply"), "new 1");
  EXPECT_EQ(read_text(out / "notes.txt"), "kept");
  EXPECT_EQ(read_text(out / "stats.json"), "{}");
  EXPECT_FALSE(fs::exists(run.staging()));
  fs::remove_all(dir);
}

// An output folder named through links is written where they end; the links stay links.
TEST(WriteFolderAtomic, WritesThroughLinksAndKeepsThem) {
  const fs::path dir = fs::temp_directory_path() / "zf_write_folder_through_links";
  fs::remove_all(dir);
  fs::create_directories(dir / "runs" / "empty");
  fs::create_symlink("runs/empty", dir / "to_empty");  // relative, as `ln -s` makes them
  fs::create_symlink(dir / "to_empty", dir / "to_link");
  fs::create_symlink("runs/new", dir / "to_nothing");
  const auto fill = [](const fs::path& staging) { write_file_atomic(staging / "a.txt", "a"); };
  for (const std::string name : {"to_link/", "to_nothing"}) {
    const fs::path asked_for = dir / name;
    check_new_folder(asked_for, "--out");
    write_folder_atomic(asked_for, fill);
  }
  EXPECT_TRUE(fs::is_symlink(dir / "to_empty"));
  EXPECT_TRUE(fs::is_symlink(dir / "to_link"));
  EXPECT_TRUE(fs::is_symlink(dir / "to_nothing"));
  EXPECT_TRUE(fs::is_regular_file(dir / "runs" / "empty" / "a.txt"));
  EXPECT_TRUE(fs::is_regular_file(dir / "runs" / "new" / "a.txt"));
  // The folder a link ends at is what must be new, and errors name it.
  EXPECT_EQ(invalid_input_message([&] { check_new_folder(dir / "to_link", "--out"); }),
            (dir / "to_link").string() + " (a link to " + (dir / "runs" / "empty").string() + "): already exists and is not empty (choose a new --out)");
  write_file_atomic(dir / "file", "x");
  fs::create_symlink("file", dir / "to_file");
  EXPECT_EQ(invalid_input_message([&] { check_new_folder(dir / "to_file", "--out"); }),
            (dir / "to_file").string() + " (a link to " + (dir / "file").string() + "): is a file, not a folder (choose a new --out)");
  fs::create_symlink("loop_b", dir / "loop_a");
  fs::create_symlink("loop_a", dir / "loop_b");
  EXPECT_THROW(check_new_folder(dir / "loop_a", "--out"), InvalidInput);
  EXPECT_THROW(write_folder_atomic(dir / "loop_a", fill), InvalidInput);
  fs::remove_all(dir);
}

// A link to nothing is a missing frame at open, as loading finds it (info listed it as present).
TEST_F(SmallCapture, ALinkToNothingIsAMissingFrame) {
  const fs::path file = dir_ / "b" / "depth" / "000001.png";
  fs::remove(file);
  fs::create_symlink(dir_ / "nothing.png", file);
  const Capture capture = Capture::open(dir_);
  ASSERT_EQ(capture.missing_frames().size(), 1u);
  EXPECT_EQ(capture.missing_frames()[0].camera, 1);
  EXPECT_EQ(capture.missing_frames()[0].frame, 1);
  EXPECT_FALSE(capture.missing_frames()[0].color);
  EXPECT_FALSE(capture.load_frame(1).cameras[1].has_depth);
  EXPECT_TRUE(unreadable_files(capture.load_frame(1)).empty());
}

// Which of two colour files of one frame was meant is not known: an error at open naming them.
TEST_F(SmallCapture, AJpgAndAPngOfOneFrameAreRefused) {
  write_color_image(dir_ / "a" / "color" / "000001.jpg", pattern_color(kWidth, kHeight, 1));
  const std::string error = open_error();
  EXPECT_EQ(error, (dir_ / "a" / "color" / "000001.jpg").string() + ", 000001.png: a .jpg and a .png of the same frame");
}

// A frame_count far beyond the files is named with the last frame there is (rig.json caps it at
// a million, so a billion no longer reaches the scan: it made `info` fail with std::bad_alloc).
TEST_F(SmallCapture, AFrameCountFarBeyondTheFilesIsNamed) {
  rig_.frame_count = kMostFrames;
  write_rig(dir_ / "rig.json", rig_);
  EXPECT_EQ(open_error(), (dir_ / "rig.json").string() + ": frame_count: is 1000000 but no camera has frame 999999.png (last depth frame is 000002.png)");
}

TEST_F(SmallCapture, DeadCameraMidSequenceStillOpens) {
  fs::remove(dir_ / "b" / "depth" / "000001.png");
  fs::remove(dir_ / "b" / "depth" / "000002.png");
  const Capture capture = Capture::open(dir_);
  EXPECT_FALSE(capture.load_frame(2).cameras[1].has_depth);
  EXPECT_TRUE(capture.load_frame(2).cameras[0].has_depth);
}

TEST_F(SmallCapture, FrameCountMismatchIsAnError) {
  write_depth_png(dir_ / "a" / "depth" / "000003.png", ramp_depth(kWidth, kHeight, 3));
  std::string error = open_error();
  EXPECT_NE(error.find("rig.json: frame_count: is 3 but a/depth/000003.png exists"), std::string::npos) << error;

  fs::remove(dir_ / "a" / "depth" / "000003.png");
  rig_.frame_count = 5;
  write_rig(dir_ / "rig.json", rig_);
  error = open_error();
  EXPECT_NE(error.find("frame_count: is 5 but no camera has frame 000004.png"), std::string::npos) << error;
}

TEST_F(SmallCapture, WrongSizeIsNamed) {
  write_depth_png(dir_ / "b" / "depth" / "000001.png", ramp_depth(kWidth + 1, kHeight, 1));
  const std::string error = load_error(1, 1, false);
  EXPECT_NE(error.find((dir_ / "b" / "depth" / "000001.png").string()), std::string::npos) << error;
  EXPECT_NE(error.find("size 33x24 does not match rig.json depth_intrinsics 32x24"), std::string::npos) << error;

  write_color_image(dir_ / "a" / "color" / "000000.png", pattern_color(kWidth, kHeight + 2, 0));
  const std::string color_error = load_error(0, 0, false);
  EXPECT_NE(color_error.find("color_intrinsics"), std::string::npos) << color_error;
}

TEST_F(SmallCapture, WrongBitDepthIsNamed) {
  // An 8-bit grey PNG where a 16-bit depth map belongs.
  write_color_image(dir_ / "a" / "depth" / "000000.png", pattern_color(kWidth, kHeight, 0));
  const std::string error = load_error(0, 0, false);
  EXPECT_NE(error.find((dir_ / "a" / "depth" / "000000.png").string()), std::string::npos) << error;
  EXPECT_NE(error.find("bit depth: depth PNG must be 16-bit single-channel, got 8-bit with 3 channel(s)"), std::string::npos) << error;
}

TEST_F(SmallCapture, CorruptAndTruncatedFilesAreNamed) {
  std::vector<std::uint8_t> bytes = read_file_bytes(dir_ / "a" / "depth" / "000002.png");
  bytes.resize(bytes.size() / 2);
  write_file_atomic(dir_ / "a" / "depth" / "000002.png", bytes);
  std::string error = load_error(2, 0, true);
  EXPECT_NE(error.find("a/depth/000002.png"), std::string::npos) << error;

  write_file_atomic(dir_ / "b" / "depth" / "000002.png", std::string_view("not a png at all"));
  error = load_error(2, 1, true);
  EXPECT_NE(error.find("b/depth/000002.png: not a PNG file"), std::string::npos) << error;

  write_file_atomic(dir_ / "a" / "color" / "000001.png", std::string_view("\x89PNG\r\n\x1a\ngarbage"));
  error = load_error(1, 0, true);
  EXPECT_NE(error.find("a/color/000001.png: cannot decode image"), std::string::npos) << error;
}

// A frame file that is a loop of links is an error naming it, not a missing frame.
TEST_F(SmallCapture, FrameFileThatIsALinkLoopIsNamed) {
  const fs::path file = dir_ / "b" / "depth" / "000001.png";
  fs::remove(file);
  fs::create_symlink(file.filename(), file);
  try {
    Capture::open(dir_).load_frame(1);
    FAIL() << "a link loop must not read as a missing frame";
  } catch (const IoError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(file.string() + ": ", 0), 0u) << e.what();
  }
}

TEST_F(SmallCapture, LayoutErrorsAreNamed) {
  fs::remove_all(dir_ / "b");
  std::string error = open_error();
  EXPECT_NE(error.find("b/depth: missing folder for rig.json cameras[1]"), std::string::npos) << error;

  fs::remove(dir_ / "rig.json");
  error = open_error();
  EXPECT_NE(error.find("rig.json: missing"), std::string::npos) << error;
}

// A ground truth of other cameras is not used: the capture opens without it and says why (only
// eval needs it), and opened strict it is an error.
TEST_F(SmallCapture, GroundTruthRigMustMatchCameras) {
  fs::create_directories(dir_ / "ground_truth");
  Rig truth = rig_;
  truth.cameras[1].name = "c";
  write_rig(dir_ / "ground_truth" / "rig.json", truth);
  const Capture capture = Capture::open(dir_);
  EXPECT_FALSE(capture.ground_truth_rig().has_value());
  EXPECT_NE(capture.ground_truth_rig_problem().find("ground_truth/rig.json: cameras[1].name"), std::string::npos) << capture.ground_truth_rig_problem();
  const std::string error = open_error({.strict = true});
  EXPECT_NE(error.find("ground_truth/rig.json: cameras[1].name"), std::string::npos) << error;
  write_rig(dir_ / "ground_truth" / "rig.json", rig_);
  EXPECT_TRUE(Capture::open(dir_).ground_truth_rig().has_value());
  EXPECT_EQ(Capture::open(dir_).ground_truth_rig_problem(), "");
}

// Depth with lens distortion comes back undistorted: a tilted plane recorded through a barrel
// lens, back-projected through the pinhole model, lies on the plane again (as recorded, the
// image's corners were tens of millimetres off).
TEST_F(SmallCapture, DistortedDepthIsUndistorted) {
  constexpr int kW = 160, kH = 120;
  Rig rig = rig_;
  for (CameraModel& cam : rig.cameras) {
    cam.depth_intrinsics = {.width = kW, .height = kH, .fx = 150, .fy = 150, .cx = 79.5, .cy = 59.5};
    cam.color_intrinsics.reset();
  }
  Intrinsics& k = rig.cameras[1].depth_intrinsics;
  k.distortion = {-0.3, 0.1, 0.001, -0.001, 0};
  k.has_distortion = true;
  // The plane z = 1 + 0.5·x in the camera frame, recorded at each distorted pixel: the ray of a
  // recorded pixel is found by inverting the distortion (fixed-point iteration, as OpenCV's
  // undistortPoints does).
  auto plane_depth_along = [](const Eigen::Vector2d& xy) { return 1.0 / (1.0 - 0.5 * xy.x()); };
  DepthImage recorded(kW, kH);
  for (int v = 0; v < kH; ++v) {
    for (int u = 0; u < kW; ++u) {
      const Eigen::Vector2d distorted((u - k.cx) / k.fx, (v - k.cy) / k.fy);
      Eigen::Vector2d xy = distorted;
      for (int i = 0; i < 50; ++i) xy += distorted - distort(k, xy);
      recorded(u, v) = static_cast<std::uint16_t>(std::lround(1000 * plane_depth_along(xy)));
    }
  }
  for (int f = 0; f < kFrames; ++f) {
    for (const CameraModel& cam : rig.cameras) write_depth_png(dir_ / cam.name / "depth" / frame_file_name(f, ".png"), recorded);
  }
  fs::remove_all(dir_ / "a" / "color");
  write_rig(dir_ / "rig.json", rig);
  const FrameSet set = Capture::open(dir_).load_frame(0);
  // Worst distance from the plane over the pixels with depth, through the pinhole model.
  auto worst_plane_error_mm = [&](const DepthImage& depth, int& pixels) {
    double worst = 0;
    pixels = 0;
    for (int v = 0; v < kH; ++v) {
      for (int u = 0; u < kW; ++u) {
        if (depth(u, v) == 0) continue;
        ++pixels;
        const double z = depth(u, v) / 1000.0, x = (u - k.cx) / k.fx * z;
        worst = std::max(worst, std::abs(z - (1 + 0.5 * x)) * 1000);
      }
    }
    return worst;
  };
  int undistorted_pixels = 0, recorded_pixels = 0;
  const double undistorted_error = worst_plane_error_mm(set.cameras[1].depth, undistorted_pixels);
  const double recorded_error = worst_plane_error_mm(set.cameras[0].depth, recorded_pixels);  // camera a: no distortion declared
  EXPECT_EQ(set.cameras[0].depth.data, recorded.data);
  EXPECT_GT(recorded_error, 20.0);
  // Nearest pixel: off by at most about one pixel's step of the plane's depth (0.5 · z/f ≈ 5 mm a pixel at the edge).
  EXPECT_LT(undistorted_error, 6.0);
  // Barrel distortion: the recording sees wider than the pinhole camera, so every pinhole pixel
  // has a recorded one. Pincushion: the pinhole image's corners lie outside the recording.
  EXPECT_EQ(undistorted_pixels, recorded_pixels);
  Intrinsics pincushion = k;
  pincushion.distortion = {0.3, 0, 0, 0, 0};
  const std::vector<int> map = depth_undistortion_map(pincushion);
  EXPECT_EQ(map.front(), -1);
  EXPECT_EQ(map.back(), -1);
  EXPECT_EQ(map[static_cast<size_t>(kH / 2) * kW + kW / 2], (kH / 2) * kW + kW / 2);
}

// An output path that is a link is written through, and a pipe or folder is never replaced.
TEST(WriteFileAtomic, WritesThroughLinksAndNeverOverSpecialFiles) {
  const fs::path dir = fs::temp_directory_path() / "zf_write_file_atomic_test";
  fs::remove_all(dir);
  fs::create_directories(dir / "folder");
  write_file_atomic(dir / "target.json", std::string_view("old"));
  fs::create_symlink("target.json", dir / "link.json");
  write_file_atomic(dir / "link.json", std::string_view("new"));
  EXPECT_TRUE(fs::is_symlink(dir / "link.json"));
  const std::vector<std::uint8_t> written = read_file_bytes(dir / "target.json");
  EXPECT_EQ(std::string(written.begin(), written.end()), "new");
  // A link whose target does not exist yet creates the target.
  fs::create_symlink("later.json", dir / "dangling.json");
  write_file_atomic(dir / "dangling.json", std::string_view("made"));
  EXPECT_TRUE(fs::is_symlink(dir / "dangling.json"));
  EXPECT_TRUE(fs::is_regular_file(dir / "later.json"));
  ASSERT_EQ(::mkfifo((dir / "pipe.json").c_str(), 0600), 0);
  for (const char* special : {"pipe.json", "folder"}) {
    try {
      write_file_atomic(dir / special, std::string_view("x"));
      ADD_FAILURE() << special << " was written";
    } catch (const IoError& e) {
      EXPECT_NE(std::string(e.what()).find(": not a regular file (a folder, device or pipe), not replaced"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(fs::is_fifo(dir / "pipe.json"));
  EXPECT_TRUE(fs::is_directory(dir / "folder"));
  fs::remove_all(dir);
}

// Grey and BGRA colour images come out as RGB with their pixels (converted into the image's own
// buffer, which a conversion that reallocated would leave black).
TEST(ColorImage, GreyAndAlphaPngsDecodeToTheirPixels) {
  cv::Mat grey(3, 4, CV_8UC1), bgra(3, 4, CV_8UC4);
  for (int v = 0; v < 3; ++v) {
    for (int u = 0; u < 4; ++u) {
      grey.at<std::uint8_t>(v, u) = static_cast<std::uint8_t>(20 * u + 60 * v + 5);
      bgra.at<cv::Vec4b>(v, u) = {static_cast<std::uint8_t>(10 + u), static_cast<std::uint8_t>(100 + v), static_cast<std::uint8_t>(200 + u + v), 77};
    }
  }
  std::vector<std::uint8_t> grey_png, bgra_png;
  ASSERT_TRUE(cv::imencode(".png", grey, grey_png));
  ASSERT_TRUE(cv::imencode(".png", bgra, bgra_png));
  const ColorImage from_grey = decode_color_image(grey_png, "grey.png"), from_bgra = decode_color_image(bgra_png, "bgra.png");
  ASSERT_EQ(from_grey.width, 4);
  ASSERT_EQ(from_bgra.height, 3);
  for (int v = 0; v < 3; ++v) {
    for (int u = 0; u < 4; ++u) {
      const auto g = static_cast<unsigned char>(20 * u + 60 * v + 5);
      EXPECT_EQ(from_grey(u, v), (Rgb8{g, g, g}));
      EXPECT_EQ(from_bgra(u, v), (Rgb8{static_cast<unsigned char>(200 + u + v), static_cast<unsigned char>(100 + v), static_cast<unsigned char>(10 + u)}));
    }
  }
}

// A JPEG cut short or with corrupt data is an error naming the file, not an image with made-up
// rows (libjpeg only warns about both), and the decoders print nothing of their own.
TEST(ColorImage, CorruptJpegsAndPngsAreErrorsAndPrintNothing) {
  cv::Mat bgr(48, 64, CV_8UC3);
  cv::randu(bgr, 0, 255);
  std::vector<std::uint8_t> jpeg, png;
  ASSERT_TRUE(cv::imencode(".jpg", bgr, jpeg, {cv::IMWRITE_JPEG_QUALITY, 90}));
  ASSERT_TRUE(cv::imencode(".png", bgr, png));
  const ColorImage whole = decode_color_image(jpeg, "whole.jpg");
  ASSERT_EQ(whole.width, 64);
  ASSERT_EQ(whole.height, 48);

  std::vector<std::uint8_t> cut = jpeg, scrambled = jpeg, cut_png = png;
  cut.resize(jpeg.size() / 3);
  // Bytes in the middle of the entropy-coded data replaced by a marker-like run.
  for (size_t k = jpeg.size() / 2; k < jpeg.size() / 2 + 40; ++k) scrambled[k] = k % 2 ? 0xFF : 0xD3;
  cut_png.resize(png.size() / 2);
  const std::pair<const std::vector<std::uint8_t>*, const char*> cases[] = {{&cut, "cut.jpg"}, {&scrambled, "scrambled.jpg"}, {&cut_png, "cut.png"}};
  for (const auto& [bytes, name] : cases) {
    ::testing::internal::CaptureStderr();
    const std::string error = invalid_input_message([&] { decode_color_image(*bytes, name); });
    EXPECT_EQ(::testing::internal::GetCapturedStderr(), "") << name;
    EXPECT_EQ(error.rfind(std::string(name) + ": cannot decode image (corrupt or truncated): ", 0), 0u) << name << ": " << error;
    EXPECT_EQ(error.find('\n'), std::string::npos) << name << ": " << error;
  }
}

// A 4×4 CMYK JPEG, written by libjpeg itself (OpenCV writes no CMYK).
std::vector<std::uint8_t> cmyk_jpeg() {
  jpeg_compress_struct jpeg{};
  jpeg_error_mgr errors{};
  jpeg.err = jpeg_std_error(&errors);
  jpeg_create_compress(&jpeg);
  unsigned char* buffer = nullptr;
  unsigned long size = 0;
  jpeg_mem_dest(&jpeg, &buffer, &size);
  jpeg.image_width = 4;
  jpeg.image_height = 4;
  jpeg.input_components = 4;
  jpeg.in_color_space = JCS_CMYK;
  jpeg_set_defaults(&jpeg);
  jpeg_start_compress(&jpeg, TRUE);
  std::vector<JSAMPLE> row(16, 100);
  while (jpeg.next_scanline < jpeg.image_height) {
    JSAMPROW rows[] = {row.data()};
    jpeg_write_scanlines(&jpeg, rows, 1);
  }
  jpeg_finish_compress(&jpeg);
  jpeg_destroy_compress(&jpeg);
  std::vector<std::uint8_t> bytes(buffer, buffer + size);
  std::free(buffer);
  return bytes;
}

// Sizes no camera has (checked before any pixel is allocated), and a CMYK JPEG, are named as such
// rather than as corrupt files.
TEST(ColorImage, ImplausibleSizesAndCmykAreNamed) {
  cv::Mat bgr(2, 2, CV_8UC3, cv::Scalar(10, 20, 30));
  std::vector<std::uint8_t> png, jpeg;
  ASSERT_TRUE(cv::imencode(".png", bgr, png));
  ASSERT_TRUE(cv::imencode(".jpg", bgr, jpeg));
  // PNG: IHDR's width (bytes 16–19, big-endian) set to 40000, its CRC (over bytes 12–28) redone.
  png[16] = 0, png[17] = 0, png[18] = 40000 >> 8, png[19] = 40000 & 0xff;
  const std::uint32_t crc = static_cast<std::uint32_t>(::crc32(::crc32(0, nullptr, 0), png.data() + 12, 17));
  for (int i = 0; i < 4; ++i) png[29 + i] = static_cast<std::uint8_t>(crc >> (24 - 8 * i));
  // JPEG: the baseline frame header's (FF C0) width, 5 bytes after its length, set to 40000.
  size_t sof = 2;
  while (sof + 1 < jpeg.size() && !(jpeg[sof] == 0xFF && jpeg[sof + 1] == 0xC0)) ++sof;
  ASSERT_LT(sof + 8, jpeg.size());
  jpeg[sof + 7] = 40000 >> 8, jpeg[sof + 8] = 40000 & 0xff;
  const std::pair<std::vector<std::uint8_t>, std::string> cases[] = {
      {png, "wide.png: image size: 40000x2 is not a plausible camera image"},
      {jpeg, "wide.jpg: image size: 40000x2 is not a plausible camera image"},
      {cmyk_jpeg(), "cmyk.jpg: colour space: a CMYK JPEG is not a camera image"}};
  for (const auto& [bytes, expected] : cases) {
    const std::string source = expected.substr(0, expected.find(':'));
    const std::string message = invalid_input_message([&] { decode_color_image(bytes, source); });
    EXPECT_EQ(message.rfind(expected, 0), 0u) << "expected: " << expected << "\n  actual: " << message;
  }
  const std::string message = invalid_input_message([&] { decode_depth_png(png, "wide.png"); });
  EXPECT_EQ(message.rfind("wide.png: image size: 40000x2", 0), 0u) << message;
}

// Warnings about a JPEG's headers leave its pixels intact and pass: a JFIF revision libjpeg does
// not know (2.01), and stray bytes before a marker, as some MJPEG cameras write.
TEST(ColorImage, JpegHeaderWarningsPass) {
  cv::Mat bgr(24, 32, CV_8UC3);
  cv::randu(bgr, 0, 255);
  std::vector<std::uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", bgr, jpeg));
  ASSERT_TRUE(jpeg[2] == 0xFF && jpeg[3] == 0xE0 && jpeg[6] == 'J');  // SOI, then the JFIF APP0 segment
  const ColorImage reference = decode_color_image(jpeg, "reference.jpg");
  std::vector<std::uint8_t> revision = jpeg, stray = jpeg;
  revision[11] = 2;  // JFIF major version: 2.01
  const size_t after_app0 = 4 + (static_cast<size_t>(jpeg[4]) << 8 | jpeg[5]);
  stray.insert(stray.begin() + static_cast<std::ptrdiff_t>(after_app0), {0x00, 0x00});
  for (const auto* bytes : {&revision, &stray}) {
    ::testing::internal::CaptureStderr();
    const ColorImage decoded = decode_color_image(*bytes, "warned.jpg");
    EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
    EXPECT_EQ(decoded.data, reference.data);
  }
}

// The decoders' pixels are those OpenCV decodes from the same files (the same libraries).
TEST(ColorImage, JpegAndDepthPngPixelsMatchOpenCv) {
  cv::Mat bgr(30, 40, CV_8UC3);
  cv::randu(bgr, 0, 255);
  std::vector<std::uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", bgr, jpeg, {cv::IMWRITE_JPEG_QUALITY, 75}));
  const cv::Mat reference = cv::imdecode(jpeg, cv::IMREAD_COLOR);
  const ColorImage color = decode_color_image(jpeg, "x.jpg");
  for (int v = 0; v < 30; ++v) {
    for (int u = 0; u < 40; ++u) {
      const cv::Vec3b c = reference.at<cv::Vec3b>(v, u);
      ASSERT_EQ(color(u, v), (Rgb8{c[2], c[1], c[0]})) << u << "," << v;
    }
  }
  const DepthImage depth = ramp_depth(33, 17, 4);
  const DepthImage decoded = decode_depth_png(encode_depth_png(depth), "d.png");
  ASSERT_EQ(decoded.width, 33);
  EXPECT_EQ(decoded.data, depth.data);
}

// A JPEG without its Huffman tables (the DHT segments cut out), as MJPEG cameras send frames that
// use the standard tables.
std::vector<std::uint8_t> without_huffman_tables(const std::vector<std::uint8_t>& jpeg) {
  std::vector<std::uint8_t> out(jpeg.begin(), jpeg.begin() + 2);  // SOI
  size_t at = 2;
  while (at + 4 <= jpeg.size() && jpeg[at] == 0xFF && jpeg[at + 1] != 0xDA) {  // up to the scan
    const size_t length = 2 + (static_cast<size_t>(jpeg[at + 2]) << 8 | jpeg[at + 3]);
    if (jpeg[at + 1] != 0xC4) out.insert(out.end(), jpeg.begin() + static_cast<std::ptrdiff_t>(at), jpeg.begin() + static_cast<std::ptrdiff_t>(at + length));
    at += length;
  }
  out.insert(out.end(), jpeg.begin() + static_cast<std::ptrdiff_t>(at), jpeg.end());
  return out;
}

// One ImageDecoder through a run of images, good ones and bad ones of both kinds, of several
// sizes, decoding into the same two images: each outcome (pixels, or the error's type and text)
// is what a fresh decoder gives, so nothing an image leaves behind (libjpeg's tables or its state
// after an error, libpng's blocks, a larger image's buffer) changes the next. A JPEG with
// optimised Huffman tables before one without tables: a kept libjpeg decompressor decoded the
// second through the first's tables (the fuzz target found it).
TEST(ImageDecoder, OneDecoderGivesWhatFreshOnesGive) {
  cv::Mat bgr(30, 40, CV_8UC3), larger(48, 64, CV_8UC3);
  cv::randu(bgr, 0, 255);
  cv::randu(larger, 0, 255);
  std::vector<std::uint8_t> jpeg, larger_jpeg, color_png, grey_png;
  ASSERT_TRUE(cv::imencode(".jpg", bgr, jpeg));
  ASSERT_TRUE(cv::imencode(".jpg", larger, larger_jpeg));
  ASSERT_TRUE(cv::imencode(".png", bgr, color_png));
  cv::Mat grey(17, 33, CV_8UC1);
  cv::randu(grey, 0, 255);
  ASSERT_TRUE(cv::imencode(".png", grey, grey_png));
  const std::vector<std::uint8_t> depth = encode_depth_png(ramp_depth(33, 17, 4)), larger_depth = encode_depth_png(ramp_depth(70, 50, 9));
  const std::vector<std::uint8_t> truncated_jpeg(jpeg.begin(), jpeg.begin() + static_cast<std::ptrdiff_t>(jpeg.size() / 2));
  std::vector<std::uint8_t> optimized_jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", larger, optimized_jpeg, {cv::IMWRITE_JPEG_OPTIMIZE, 1}));
  const std::vector<std::uint8_t> no_tables_jpeg = without_huffman_tables(jpeg);
  ASSERT_LT(no_tables_jpeg.size(), jpeg.size());
  EXPECT_EQ(decode_color_image(no_tables_jpeg, "in.jpg"), decode_color_image(jpeg, "in.jpg"));  // the standard tables
  const std::vector<std::uint8_t> truncated_depth(larger_depth.begin(), larger_depth.begin() + static_cast<std::ptrdiff_t>(larger_depth.size() / 2));
  struct Input {
    const std::vector<std::uint8_t>* bytes;
    bool depth;
  };
  const std::vector<Input> run = {{&depth, true},         {&jpeg, false},          {&truncated_jpeg, false}, {&jpeg, false},
                                  {&larger_depth, true},  {&truncated_depth, true}, {&depth, true},          {&color_png, false},
                                  {&grey_png, true},      {&larger_jpeg, false},   {&grey_png, false},       {&truncated_jpeg, false},
                                  {&larger_jpeg, false},  {&optimized_jpeg, false}, {&no_tables_jpeg, false}, {&depth, true}};
  auto outcome = [](auto&& decode, const auto& image) -> std::string {
    try {
      decode();
    } catch (const std::exception& e) {
      return typeid(e).name() + std::string(": ") + e.what();
    }
    return std::to_string(image.width) + "x" + std::to_string(image.height) + " " +
           std::to_string(std::hash<std::string_view>{}(std::string_view(reinterpret_cast<const char*>(image.data.data()), image.data.size() * sizeof(image.data[0]))));
  };
  ImageDecoder decoder;
  DepthImage depth_image;
  ColorImage color_image;
  int errors = 0;
  for (int pass = 0; pass < 2; ++pass) {
    for (size_t i = 0; i < run.size(); ++i) {
      const Input& in = run[i];
      std::string reused, fresh;
      if (in.depth) {
        DepthImage alone;
        reused = outcome([&] { decoder.decode_depth_png(*in.bytes, "in.png", depth_image); }, depth_image);
        fresh = outcome([&] { alone = decode_depth_png(*in.bytes, "in.png"); }, alone);
      } else {
        ColorImage alone;
        reused = outcome([&] { decoder.decode_color_image(*in.bytes, "in.img", color_image); }, color_image);
        fresh = outcome([&] { alone = decode_color_image(*in.bytes, "in.img"); }, alone);
      }
      EXPECT_EQ(reused, fresh) << "pass " << pass << ", image " << i;
      errors += reused.find(": ") != std::string::npos && reused.find("in.") != std::string::npos;
    }
  }
  EXPECT_EQ(errors, 2 * 4);  // two truncated JPEGs, a truncated depth PNG, an 8-bit PNG as depth
}

// A camera's frames, a depth PNG and a colour PNG each time: libpng's blocks are made for the first
// frame and found again at every later one. Images of changing sizes do not pile blocks up: what
// is kept is what the last image used, as many blocks as a fresh decoder keeps for it alone.
TEST(ImageDecoder, LibpngsBlocksAreFoundAgainAndDoNotPileUp) {
  cv::Mat bgr(30, 40, CV_8UC3);
  cv::randu(bgr, 0, 255);
  std::vector<std::uint8_t> color_png;
  ASSERT_TRUE(cv::imencode(".png", bgr, color_png));
  const std::vector<std::uint8_t> depth_png = encode_depth_png(ramp_depth(40, 30, 4));
  ImageDecoder decoder;
  DepthImage depth;
  ColorImage color;
  long made_after_first_frame = 0;
  for (int frame = 0; frame < 3; ++frame) {
    decoder.decode_depth_png(depth_png, "d.png", depth);
    decoder.decode_color_image(color_png, "c.png", color);
    if (frame == 0) made_after_first_frame = decoder.png_blocks_made();
  }
  EXPECT_GT(made_after_first_frame, 0);
  EXPECT_EQ(decoder.png_blocks_made(), made_after_first_frame);

  ImageDecoder growing;
  std::vector<std::uint8_t> last;
  for (int width = 200; width <= 4000; width += 200) {
    last = encode_depth_png(ramp_depth(width, 8, width));
    growing.decode_depth_png(last, "d.png", depth);
  }
  ImageDecoder fresh;
  fresh.decode_depth_png(last, "d.png", depth);
  EXPECT_GT(growing.png_blocks_made(), fresh.png_blocks_made());  // the rows grew
  EXPECT_EQ(growing.png_memory_blocks(), fresh.png_memory_blocks());
}

// Every capture in ../shared/data follows the format and loads.
TEST(SharedData, EveryCaptureLoads) {
  ASSERT_TRUE(fs::is_directory(kSharedData)) << kSharedData;
  int captures = 0;
  for (const fs::directory_entry& entry : fs::directory_iterator(kSharedData)) {
    if (!fs::exists(entry.path() / "rig.json")) continue;
    ++captures;
    const Capture capture = Capture::open(entry.path(), {.strict = true});
    ASSERT_GT(capture.frame_count(), 0) << entry.path();
    for (int frame : {0, capture.frame_count() - 1}) {
      const FrameSet set = capture.load_frame(frame);
      for (int c = 0; c < capture.camera_count(); ++c) {
        const CameraModel& cam = capture.rig().cameras[c];
        const CameraFrame& f = set.cameras[c];
        ASSERT_TRUE(f.has_depth);
        EXPECT_EQ(f.depth.width, cam.depth_intrinsics.width);
        size_t valid = 0;
        for (unsigned short d : f.depth.data) valid += d != 0;
        EXPECT_GT(valid, f.depth.size() / 20) << entry.path() << " frame " << frame << " has almost no depth";
        EXPECT_EQ(f.has_color, cam.has_color());
      }
    }
  }
  EXPECT_EQ(captures, 3);
  const Capture samba = Capture::open(kSharedData / "samba-4cam");
  ASSERT_TRUE(samba.ground_truth_rig().has_value());
  EXPECT_TRUE(samba.has_ground_truth_meshes());
  EXPECT_EQ(samba.camera_count(), 4);
  EXPECT_EQ(samba.frame_count(), 40);
}

}  // namespace
}  // namespace zipfusion
