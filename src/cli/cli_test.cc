// End-to-end tests of the zipfusion binary: exit codes, one-line errors, outputs.

#include <gtest/gtest.h>

#include "cli/cli_test_util.h"
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "zipfusion/io/capture.h"
#include "zipfusion/io/file_util.h"
#include "zipfusion/io/image_io.h"
#include "zipfusion/io/mesh_io.h"
#include "zipfusion/io/rig.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

using testing::CommandResult;
using testing::line_count;

class Cli : public testing::CliTest {};

TEST_F(Cli, SynthThenInfoDescribesTheCapture) {
  const std::string capture = (dir_ / "cap").string();
  const CommandResult synth = run("synth --out " + capture + " --frames 2 --cameras 6 --miscalibrate 0.5,0.01");
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const CommandResult info = run("info " + capture);
  ASSERT_EQ(info.exit_code, 0) << info.err;
  for (const char* expected : {"zipfusion.rig/1, 2 frames at 30 fps", "cam0", "cam5", "up to 0.500 deg / 10.0 mm", "frames examined: 2 of 2"}) {
    EXPECT_NE(info.out.find(expected), std::string::npos) << expected << "\n" << info.out;
  }
  const CommandResult json_info = run("info --json " + capture);
  ASSERT_EQ(json_info.exit_code, 0) << json_info.err;
  const nlohmann::json j = nlohmann::json::parse(json_info.out);
  ASSERT_EQ(j["cameras"].size(), 6u);
  for (const auto& cam : j["cameras"]) {
    EXPECT_EQ(cam["frames_with_depth"], 2);
    EXPECT_GT(cam["valid_depth_fraction"].get<double>(), 0.2);
    EXPECT_GT(cam["depth_m"]["median"].get<double>(), 1.5);
    EXPECT_LT(cam["depth_m"]["median"].get<double>(), 4.5);
    // The subject is in the volume; the floor and the far floor are not.
    EXPECT_GT(cam["in_volume_fraction"].get<double>(), 0.1);
    EXPECT_LT(cam["in_volume_fraction"].get<double>(), 0.9);
  }
}

TEST_F(Cli, BadInputGivesOneLineAndNonZeroExit) {
  struct Case {
    std::string args, expected;
    int exit_code = 2;  // invalid input; 3: a file or folder cannot be read
  };
  const std::string capture = (dir_ / "cap").string();
  ASSERT_EQ(run("synth --out " + capture + " --frames 1 --cameras 2 --noise none").exit_code, 0);
  // Break the rig: a focal length of zero.
  const std::string original_rig = [&] { std::ifstream in(fs::path(capture) / "rig.json"); std::stringstream s; s << in.rdbuf(); return s.str(); }();
  std::string rig = original_rig;
  const std::string broken = (dir_ / "broken").string();
  fs::copy(capture, broken, fs::copy_options::recursive);
  rig.replace(rig.find("\"fx\":580.0"), 10, "\"fx\":0");
  write_file_atomic(fs::path(broken) / "rig.json", rig);
  // A capture of no frames: its rig.json says so and its folders hold no files.
  const std::string no_frames = (dir_ / "no_frames").string();
  fs::copy(capture, no_frames, fs::copy_options::recursive);
  for (const char* camera : {"cam0", "cam1"}) {
    for (const char* kind : {"depth", "color"}) {
      fs::remove_all(fs::path(no_frames) / camera / kind);
      fs::create_directories(fs::path(no_frames) / camera / kind);
    }
  }
  std::string no_frames_rig = original_rig;
  no_frames_rig.replace(no_frames_rig.find("\"frame_count\": 1"), 16, "\"frame_count\": 0");
  write_file_atomic(fs::path(no_frames) / "rig.json", no_frames_rig);
  const std::string a_file = (dir_ / "a_file").string();
  write_file_atomic(a_file, "not a folder");

  const std::vector<Case> cases = {
      {"info " + (dir_ / "nowhere").string(), "nowhere: not a capture folder", 3},
      {"info " + broken, "rig.json: cameras[0].depth_intrinsics.fx: must be positive"},
      {"synth --out " + capture, "already exists and is not empty"},
      // A whole number is asked for by name, not as a range "abc" is out of.
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --threads abc", "zipfusion: error: --threads: must be a whole number, got abc"},
      {"info " + capture + " --sample 1.5", "zipfusion: error: --sample: must be a whole number, got 1.5"},
      {"synth --out " + (dir_ / "x").string() + " --miscalibrate half", "--miscalibrate: expected DEG,M"},
      {"synth --out " + (dir_ / "x").string() + " --cameras 0", "zipfusion: error: --cameras: must be in [1, 64]"},
      {"synth --out " + (dir_ / "x").string() + " --fps 0.0001", "zipfusion: error: --fps: must be in [0.001, 1000]"},  // rig.json's range
      {"synth --out " + (dir_ / "x").string() + " --checkerboard --views 0", "zipfusion: error: --views: must be in [1, 10000]"},
      {"synth --out " + (dir_ / "x").string() + " --checkerboard --board 2x2", "zipfusion: error: --board: needs 3 to 100 inner corners each way, got 2x2"},
      // synth writes only the wands calibrate takes.
      {"synth --out " + (dir_ / "x").string() + " --wand --led-distance 0.04", "zipfusion: error: --led-distance: must be in (0.05, 5) metres"},
      {"calibrate extrinsics " + capture + " --led-distance 5 --out " + (dir_ / "x.json").string(), "zipfusion: error: --led-distance: must be in (0.05, 5) metres"},
      // A folder that cannot be made is named as asked for, not as the hidden one it is built in.
      {"synth --out /proc/zf_cli_test_capture", "zipfusion: error: /proc/zf_cli_test_capture: cannot write (", 3},
      {"synth --out " + (dir_ / "x").string() + " --subject " + (dir_ / "none%06d.ply").string(), "none000000.ply", 3},
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --seam-smoothing 5", "zipfusion: error: --seam-smoothing: must be in [0, 4] pixels"},
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --seam-fairing 9", "zipfusion: error: --seam-fairing: must be in [0, 8] rounds"},
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --floor-noise -1",
       "zipfusion: error: --floor-noise: must be in [0, 10] standard deviations"},
      // The largest int: one frame past it would overflow.
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --frames 2147483647",
       "--frames: \"2147483647\" reaches past the last frame of a capture with 1 frames"},
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --frames +0", "--frames: expected A:B with whole numbers, got \"+0\""},
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --frames -0", "--frames: expected A:B with whole numbers, got \"-0\""},
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --frames 0:99999999999",
       "--frames: \"0:99999999999\" reaches past the last frame of a capture with 1 frames"},
      {"synth --out " + (dir_ / "x").string() + " --checkerboard --views 1 --resolution 100000x100000",
       "zipfusion: error: --resolution: must be within 32x24 .. 4096x4096"},
      {"synth --out " + (dir_ / "x").string() + " --checkerboard --resolution 32x24", "zipfusion: error: --resolution: checkerboard views need at least 64x48"},
      // Another mode's options would be ignored.
      {"synth --out " + (dir_ / "x").string() + " --views 3 --square 0.03", "zipfusion: error: --views, --square: only with --checkerboard"},
      {"synth --out " + (dir_ / "x").string() + " --checkerboard --frames 5", "zipfusion: error: --frames: only with a capture (not with --checkerboard)"},
      {"synth --out " + (dir_ / "x").string() + " --wand --color-format jpg", "zipfusion: error: --color-format: a wand capture's colour is always PNG"},
      // An infinite depth or σ would pass as "positive" and reach stats.json as null.
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --max-depth inf", "zipfusion: error: --max-depth: must be a finite number, got inf"},
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --bilateral-sigma-px inf",
       "zipfusion: error: --bilateral-sigma-px: must be a finite number, got inf"},
      // Every floating-point option refuses NaN, which CLI11's ranges let through: it turned the
      // scale check of calibrate extrinsics off, and made --max-wait its default without a word.
      {"calibrate extrinsics " + capture + " --scale-tolerance nan --out " + (dir_ / "x.json").string(),
       "zipfusion: error: --scale-tolerance: must be a finite number, got nan"},
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --max-wait nan", "zipfusion: error: --max-wait: must be a finite number, got nan"},
      // An empty number is not 0, an empty --out not an error found after all the work.
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --coarse-levels ''", "zipfusion: error: --coarse-levels: must be a number, got nothing"},
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --min-depth ''", "zipfusion: error: --min-depth: must be a number, got nothing"},
      {"register " + capture + " --out ''", "zipfusion: error: --out: must not be empty"},
      {"calibrate floor " + capture + " --out ''", "zipfusion: error: --out: must not be empty"},
      // An --out that is the wrong kind of thing is the user's choice: invalid input, as synth says.
      {"reconstruct " + capture + " --out " + a_file, "a_file: is a file, not a folder (choose another --out)"},
      {"register " + capture + " --out " + dir_.string(), ": is a folder, not a file to write"},
      {"calibrate intrinsics --images '" + capture + "/cam0/color/*.jpg' --board 0x0 --out " + (dir_ / "x.json").string(),
       "zipfusion: error: --board: needs 3 to 100 inner corners each way, got 0x0"},
      // No frames at all is said so, not that a --frames never given selects none.
      {"reconstruct " + no_frames + " --out " + (dir_ / "x").string(), "zipfusion: error: rig.json: frame_count: is 0 (the capture has no frames)"},
      {"calibrate floor " + no_frames + " --out " + (dir_ / "x.json").string(), "zipfusion: error: rig.json: frame_count: is 0 (the capture has no frames)"},
      {"info " + a_file, "a_file: not a capture folder (a file, not a folder)", 3},
      // Live cameras' options on a capture would be ignored.
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --max-wait 1 --stall-timeout 5",
       "zipfusion: error: --stall-timeout, --max-wait: only with --live"},
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --stall-timeout 2 --depth-format auto",  // the defaults, given
       "zipfusion: error: --depth-format, --stall-timeout: only with --live"},
      // Usage errors that CLI11 finds: one line too, with the same prefix, exit 2.
      {"frobnicate", "zipfusion: error: unknown command \"frobnicate\" (commands: synth, info,"},
      {"", "zipfusion: error: A subcommand is required"},
      {"calibrate bogus", "zipfusion: error: unknown calibrate command \"bogus\" (commands: intrinsics, extrinsics, floor)"},
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --threads -1", "zipfusion: error: --threads: Value -1 not in range 0 to 1024"},
      {"synth --out " + (dir_ / "x").string() + " --threads 100000", "--threads: Value 100000 not in range 0 to 1024"},
      {"eval " + capture + " " + (dir_ / "x").string() + " --spacing-mm nan", "zipfusion: error: --spacing-mm: must be a finite number, got nan"},
      {"eval " + capture + " " + (dir_ / "x").string() + " --min-range 2 --max-range 1", "zipfusion: error: --max-range: must be above --min-range"},
      {"reconstruct " + capture + " --out " + (dir_ / "x").string() + " --no-such-flag", "zipfusion: error: The following argument was not expected: --no-such-flag"},
  };
  for (const Case& c : cases) {
    const CommandResult r = run(c.args);
    EXPECT_EQ(r.exit_code, c.exit_code) << c.args;
    EXPECT_EQ(line_count(r.err), 1) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << c.args << "\n" << r.err;
  }
  EXPECT_FALSE(fs::exists(dir_ / "x"));
}

TEST_F(Cli, ReconstructWritesMeshesAndStats) {
  const std::string capture = (dir_ / "cap").string();
  ASSERT_EQ(run("synth --out " + capture + " --frames 3 --cameras 4").exit_code, 0);
  const std::string zipper = (dir_ / "zip").string(), separate = (dir_ / "sep").string();
  const CommandResult z = run("reconstruct " + capture + " --out " + zipper + " --frames 1:3");
  ASSERT_EQ(z.exit_code, 0) << z.err;
  ASSERT_EQ(run("reconstruct " + capture + " --out " + separate + " --mode separate --format obj --frames 1:3").exit_code, 0);
  EXPECT_FALSE(fs::exists(fs::path(zipper) / "000000.ply"));
  for (int frame : {1, 2}) {
    const TriangleMesh zipped = read_mesh(fs::path(zipper) / frame_file_name(frame, ".ply"));
    const TriangleMesh side_by_side = read_mesh(fs::path(separate) / frame_file_name(frame, ".obj"));
    EXPECT_EQ(zipped.colors.size(), zipped.positions.size());
    // The zipper removes the doubled overlaps of the separate meshes.
    EXPECT_LT(zipped.triangle_count(), side_by_side.triangle_count() * 0.9);
    EXPECT_GT(zipped.triangle_count(), side_by_side.triangle_count() * 0.4);
  }
  std::ifstream in(fs::path(zipper) / "stats.json");
  const nlohmann::json stats = nlohmann::json::parse(in);
  ASSERT_EQ(stats["frames"].size(), 2u);
  // --ownership and --seam-smoothing auto are resolved by the filter and recorded as used: border
  // and 1 with the bilateral filter (the default), smoothness and 2 without a filter.
  EXPECT_EQ(stats["options"]["ownership"], "border");
  EXPECT_EQ(stats["options"]["seam_smoothing_px"], 1);
  const std::string unfiltered = (dir_ / "unfiltered").string();
  ASSERT_EQ(run("reconstruct " + capture + " --out " + unfiltered + " --frames 1:2 --filter none").exit_code, 0);
  std::ifstream unfiltered_stats_file(fs::path(unfiltered) / "stats.json");
  const nlohmann::json unfiltered_stats = nlohmann::json::parse(unfiltered_stats_file);
  EXPECT_EQ(unfiltered_stats["options"]["ownership"], "smoothness");
  EXPECT_EQ(unfiltered_stats["options"]["seam_smoothing_px"], 2);
  // At a level of detail the options in pixels shrink: what ran is recorded beside what was given.
  EXPECT_FALSE(stats.contains("options_applied"));
  const std::string lod = (dir_ / "lod").string();
  ASSERT_EQ(run("reconstruct " + capture + " --out " + lod + " --frames 1:2 --lod 1").exit_code, 0);
  const nlohmann::json lod_stats = nlohmann::json::parse(read_file_bytes(fs::path(lod) / "stats.json"));
  EXPECT_EQ(lod_stats["options"]["bilateral_radius_px"], 6);
  EXPECT_EQ(lod_stats["options_applied"]["bilateral_radius_px"], 3);
  EXPECT_EQ(lod_stats["options_applied"]["coarse_levels"], lod_stats["options"]["coarse_levels"].get<int>() - 1);
  for (const auto& f : stats["frames"]) {
    EXPECT_EQ(f["cameras_used"], 4);
    EXPECT_GT(f["ms"]["total"].get<double>(), 0.0);
    EXPECT_GE(f["zipper"]["pairs"].get<int>(), 4);
    // Seam faces left out at creases (one-triangle gaps) are a small share of the seams' faces.
    EXPECT_LE(f["zipper"]["seam_crease_gaps"].get<int>(), f["zipper"]["seam_added"].get<int>() / 100);
    TriangleMesh mesh = read_mesh(fs::path(zipper) / frame_file_name(f["frame"].get<int>(), ".ply"));
    EXPECT_EQ(f["triangles"].get<size_t>(), mesh.triangle_count());
    EXPECT_EQ(f["vertices"].get<size_t>(), mesh.vertex_count());
    std::vector<int> remap;
    EXPECT_EQ(remove_unreferenced_vertices(mesh, remap), 0) << "every vertex written is a triangle's";
  }
  // A frame set without any camera is an empty mesh, with the colour properties of the others.
  for (const auto& file : fs::directory_iterator(fs::path(capture))) {
    if (fs::is_directory(file.path() / "depth")) fs::remove(file.path() / "depth" / "000001.png");
  }
  const std::string holes = (dir_ / "holes").string();
  ASSERT_EQ(run("reconstruct " + capture + " --out " + holes).exit_code, 0);
  const std::vector<std::uint8_t> empty_file = read_file_bytes(fs::path(holes) / "000001.ply");
  EXPECT_NE(std::string(empty_file.begin(), empty_file.end()).find("element vertex 0\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red"),
            std::string::npos);
  const CommandResult bad = run("reconstruct " + capture + " --out " + zipper + " --frames 2:9");
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.err.find("--frames: \"2:9\" reaches past the last frame of a capture with 3 frames"), std::string::npos) << bad.err;
  const CommandResult empty = run("reconstruct " + capture + " --out " + zipper + " --frames 2:2");
  EXPECT_NE(empty.err.find("--frames: \"2:2\" selects no frames of a capture with 3 frames"), std::string::npos) << empty.err;
}

// A corrupt frame file costs its camera that frame set, not the run: one warning line naming the
// file, the frame set made from the other cameras, the file listed in stats.json.
TEST_F(Cli, CorruptFrameDegradesItsFrameSetNotTheRun) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 3 --cameras 2 --resolution 160x120").exit_code, 0);
  const fs::path depth = capture / "cam1" / "depth" / "000001.png";
  std::vector<std::uint8_t> bytes = read_file_bytes(depth);
  bytes.resize(bytes.size() / 2);
  write_file_atomic(depth, bytes);
  const fs::path color = capture / "cam0" / "color" / "000002.jpg";
  write_file_atomic(color, std::string_view(""));
  const fs::path out = dir_ / "out";
  const CommandResult r = run("reconstruct " + capture.string() + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "reconstruct: warning: " + depth.string() + ": cannot decode image (corrupt or truncated): the file ends early; cam1 left "
                   "out of frame set 1\nreconstruct: warning: " + color.string() + ": not a JPEG or PNG file; cam0 has no colour in frame set 2\n");
  const nlohmann::json stats = nlohmann::json::parse(read_file_bytes(out / "stats.json"));
  EXPECT_EQ(stats["unreadable_file_count"], 2);
  ASSERT_EQ(stats["frames"].size(), 3u);
  for (int f = 0; f < 3; ++f) {
    EXPECT_TRUE(fs::exists(out / frame_file_name(f, ".ply"))) << f;
    EXPECT_EQ(stats["frames"][f]["cameras_used"], f == 1 ? 1 : 2) << f;
    EXPECT_EQ(stats["frames"][f].contains("unreadable_files"), f > 0) << f;
  }
  EXPECT_EQ(stats["frames"][1]["unreadable_files"][0].get<std::string>().rfind(depth.string() + ": ", 0), 0u);
  // info lists them; --strict makes the first an error.
  const CommandResult info = run("info " + capture.string() + " --json");
  ASSERT_EQ(info.exit_code, 0) << info.err;
  const nlohmann::json described = nlohmann::json::parse(info.out);
  EXPECT_EQ(described["cameras"][0]["unreadable_frame_files"], nlohmann::json::array({color.string() + ": not a JPEG or PNG file"}));
  EXPECT_EQ(described["cameras"][1]["unreadable_frame_files"].size(), 1u);
  const CommandResult strict = run("info " + capture.string() + " --strict");
  EXPECT_EQ(strict.exit_code, 2);
  EXPECT_EQ(line_count(strict.err), 1) << strict.err;
}

// What a terminal shows of text written to it: "\r" returns to the line's start, "\033[K" erases
// to its end, other characters overwrite.
std::vector<std::string> terminal_lines(const std::string& written) {
  std::vector<std::string> lines;
  std::istringstream in(written);
  for (std::string text; std::getline(in, text);) {
    std::string line;
    size_t cursor = 0;
    for (size_t i = 0; i < text.size(); ++i) {
      if (text[i] == '\r') {
        cursor = 0;
      } else if (text.compare(i, 3, "\033[K") == 0) {
        line.resize(cursor);
        i += 2;
      } else {
        if (cursor < line.size()) line[cursor] = text[i];
        else line += text[i];
        ++cursor;
      }
    }
    lines.push_back(line);
  }
  return lines;
}

// On a terminal the progress is drawn in place; a warning takes its line and the progress is
// drawn again below, so that no warning starts in the middle of a progress line.
TEST_F(Cli, AWarningDoesNotRunIntoTheProgressLine) {
  if (std::system("script -qec true /dev/null > /dev/null 2>&1 < /dev/null") != 0) GTEST_SKIP() << "no util-linux script(1) or no pseudo-terminal";
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 40 --cameras 2 --resolution 160x120").exit_code, 0);
  const fs::path depth = capture / "cam1" / "depth" / "000030.png";  // decoded after the progress has begun
  std::vector<std::uint8_t> bytes = read_file_bytes(depth);
  bytes.resize(bytes.size() / 2);
  write_file_atomic(depth, bytes);
  // script(1) runs the command on a pseudo-terminal and copies what the terminal receives.
  const fs::path shown = dir_ / "terminal";
  const std::string command = "script -qec \"" + std::string(ZF_BINARY) + " reconstruct " + capture.string() + " --out " +
                              (dir_ / "out").string() + " > /dev/null\" /dev/null > " + shown.string() + " < /dev/null";
  const int status = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << command;
  const std::string written = std::string(reinterpret_cast<const char*>(read_file_bytes(shown).data()), fs::file_size(shown));
  EXPECT_EQ(terminal_lines(written),
            (std::vector<std::string>{"reconstruct: warning: " + depth.string() +
                                          ": cannot decode image (corrupt or truncated): the file ends early; cam1 left out of frame set 30",
                                      "reconstruct: 40/40"}))
      << written;
}

// When no depth of the capture decodes (every file a Git LFS pointer, say), going on would write
// empty meshes and a warning per file: the first frame set stops the run instead, before anything
// is written.
TEST_F(Cli, ACaptureWhoseDepthDoesNotDecodeIsAnError) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 2 --cameras 2 --resolution 160x120").exit_code, 0);
  for (const char* camera : {"cam0", "cam1"}) {
    for (const char* frame : {"000000.png", "000001.png"}) {
      write_file_atomic(capture / camera / "depth" / frame, std::string_view("version https://git-lfs.github.com/spec/v1\n"));
    }
  }
  const fs::path out = dir_ / "out";
  const CommandResult r = run("reconstruct " + capture.string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(line_count(r.err), 1) << r.err;
  EXPECT_NE(r.err.find(": not a PNG file (depth must be 16-bit PNG); no depth of the capture has decoded up to this frame set"), std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(out));
}

// A run that fails before writing a mesh (here a frame file that is a loop of links, which cannot
// even be looked at) does not leave the output folder it created behind empty.
TEST_F(Cli, ARunThatFailsBeforeWritingLeavesNoOutputFolder) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 2 --cameras 2 --resolution 160x120").exit_code, 0);
  const fs::path depth = capture / "cam1" / "depth" / "000000.png";
  fs::remove(depth);
  fs::create_symlink(depth.filename(), depth);
  const fs::path out = dir_ / "out";
  const CommandResult r = run("reconstruct " + capture.string() + " --out " + out.string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_EQ(line_count(r.err), 1) << r.err;
  EXPECT_NE(r.err.find(depth.string()), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
}

// A run into a folder holding meshes of an earlier run that it would not replace stops before
// writing: eval reads every mesh of a folder and would measure both runs together.
TEST_F(Cli, EarlierMeshesThatWouldStayAreRefused) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 3 --cameras 2 --resolution 160x120").exit_code, 0);
  const fs::path out = dir_ / "out";
  ASSERT_EQ(run("reconstruct " + capture.string() + " --out " + out.string() + " --frames 0:3").exit_code, 0);
  // The same frames again replace every mesh: allowed.
  EXPECT_EQ(run("reconstruct " + capture.string() + " --out " + out.string() + " --frames 0:3").exit_code, 0);
  const auto written_at = fs::last_write_time(out / "000000.ply");
  // Fewer frames, or the other format, would leave meshes behind.
  for (const std::string options : {"--frames 0:2", "--frames 0:3 --format obj"}) {
    const CommandResult r = run("reconstruct " + capture.string() + " --out " + out.string() + " " + options);
    EXPECT_EQ(r.exit_code, 2) << options;
    EXPECT_EQ(line_count(r.err), 1) << r.err;
    EXPECT_NE(r.err.find(": a mesh of an earlier run that this one would not replace"), std::string::npos) << r.err;
  }
  EXPECT_FALSE(fs::exists(out / "000000.obj"));
  EXPECT_EQ(fs::last_write_time(out / "000000.ply"), written_at);  // the refused runs wrote nothing
}

// A run that fails part-way leaves the output folder as it was: none (a new one) or an earlier
// run's meshes and stats.json, untouched. Here frame 2 of camera 1 is of another size than
// rig.json's, an error found only when that frame is decoded, after frames 0 and 1 are made.
TEST_F(Cli, ARunThatFailsPartWayLeavesTheOutputAsItWas) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 3 --cameras 2 --resolution 160x120").exit_code, 0);
  const fs::path out = dir_ / "out", earlier = dir_ / "earlier";
  ASSERT_EQ(run("reconstruct " + capture.string() + " --threads 1 --out " + earlier.string()).exit_code, 0);
  const auto stats_written_at = fs::last_write_time(earlier / "stats.json");
  const auto mesh_written_at = fs::last_write_time(earlier / "000000.ply");
  write_depth_png(capture / "cam1" / "depth" / "000002.png", DepthImage(80, 60, 1500));
  for (const fs::path& folder : {out, earlier}) {
    const CommandResult r = run("reconstruct " + capture.string() + " --threads 1 --out " + folder.string());
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(line_count(r.err), 1) << r.err;
    EXPECT_NE(r.err.find("cam1/depth/000002.png: size 80x60 does not match"), std::string::npos) << r.err;
  }
  EXPECT_FALSE(fs::exists(out));
  EXPECT_EQ(fs::last_write_time(earlier / "stats.json"), stats_written_at);
  EXPECT_EQ(fs::last_write_time(earlier / "000000.ply"), mesh_written_at);
  int entries = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(earlier)) ++entries;
  EXPECT_EQ(entries, 4) << "three meshes and stats.json, no staging folder left";
  // What stands where a mesh would go and cannot be replaced by it is found before the work.
  fs::create_directories(out / "000001.ply");
  const CommandResult r = run("reconstruct " + capture.string() + " --frames 0:2 --out " + out.string());
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_EQ(r.err, "zipfusion: error: " + (out / "000001.ply").string() +
                       ": is not a file (a folder, link or device), so this run's file of that name would replace it, not write into it; remove it "
                       "or choose another --out\n");
}

// Two runs cannot write into one folder at once (their meshes and stats.json would mix): the
// second is refused while the first holds it.
TEST_F(Cli, ASecondRunIntoAFolderInUseIsRefused) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 1 --cameras 2 --resolution 160x120").exit_code, 0);
  const fs::path out = dir_ / "out";
  const StagedFolder first(out, "--out");  // a run in progress
  const CommandResult r = run("reconstruct " + capture.string() + " --out " + out.string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "zipfusion: error: " + out.string() + ": another zipfusion run is writing into this folder (choose another --out or wait for it)\n");
  EXPECT_FALSE(fs::exists(out / "000000.ply"));
}

// Runs `reconstruct ARGS --out OUT` on samba-4cam as a background job of bash (which ignores
// SIGINT for it) after `prelude`, sends `signal` once `first_mesh` is in the staging folder (the
// handler is in place by then) and waits: the exit status, and stderr. An exit status of -2: the
// run had ended before the signal went.
struct SignalledRun {
  int status = -1;
  std::string err;
};
SignalledRun reconstruct_and_signal(const fs::path& dir, const std::string& args, const fs::path& out, const std::string& first_mesh,
                                    const std::string& signal, const std::string& prelude = "") {
  const fs::path samba = fs::path(ZF_SOURCE_DIR) / ".." / "shared" / "data" / "samba-4cam";
  const std::string script = prelude + std::string(ZF_BINARY) + " reconstruct " + samba.string() + " " + args + " --out " + out.string() +
                             " > " + (dir / "stdout").string() + " 2> " + (dir / "stderr").string() +
                             " & p=$!; for i in $(seq 1000); do ls " + out.string() + "/.zipfusion-staging-*/" + first_mesh +
                             " > /dev/null 2>&1 && break; sleep 0.01; done; if kill -" + signal + " $p; then wait $p; echo $?; else echo -2; fi > " +
                             (dir / "status").string();
  EXPECT_EQ(std::system(("bash -c '" + script + "'").c_str()), 0);
  SignalledRun run;
  std::ifstream status_file(dir / "status");
  status_file >> run.status;
  std::ifstream err_file(dir / "stderr");
  run.err.assign(std::istreambuf_iterator<char>(err_file), std::istreambuf_iterator<char>());
  return run;
}

// Ctrl-C (SIGINT) during a capture's reconstruction keeps the meshes made, each whole, with a
// stats.json that lists them and says the run was interrupted; the exit status is 130. Meshes of
// an earlier run for frames it did not reach go (eval would measure them with this run's). The
// run is a script's background job, for which bash ignores SIGINT: it catches it all the same.
TEST_F(Cli, AnInterruptedRunKeepsWholeMeshesAndSaysSo) {
  const fs::path samba = fs::path(ZF_SOURCE_DIR) / ".." / "shared" / "data" / "samba-4cam";
  const fs::path out = dir_ / "out";
  ASSERT_EQ(run("reconstruct " + samba.string() + " --frames 36:40 --register off --out " + out.string()).exit_code, 0);
  ASSERT_TRUE(fs::exists(out / "000039.ply"));
  const auto [status, err] = reconstruct_and_signal(dir_, "--register off", out, "000000.ply", "INT");
  ASSERT_EQ(status, 130) << err;
  EXPECT_EQ(err.rfind("reconstruct: stopped by a signal after ", 0), 0u) << err;
  std::ifstream stats_file(out / "stats.json");
  const nlohmann::json stats = nlohmann::json::parse(stats_file);
  EXPECT_TRUE(stats["interrupted"].get<bool>());
  const size_t made = stats["frames"].size();
  EXPECT_GE(made, 1u);
  EXPECT_LT(made, 40u);
  size_t meshes = 0;
  for (const auto& entry : fs::directory_iterator(out)) {
    if (entry.path().extension() != ".ply") continue;
    ++meshes;
    EXPECT_GT(read_mesh(entry.path()).triangle_count(), 10000u) << entry.path();  // whole: it reads
  }
  EXPECT_EQ(meshes, made);
  EXPECT_NE(err.find(" of 40 frame sets; wrote those to "), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(out / "000039.ply")) << "the earlier run's mesh of a frame not reached";
}

// A SIGHUP the run started with ignored stays ignored: nohup's (the run outlives its terminal).
// The run goes on to the end, where SIGHUP used to stop it.
TEST_F(Cli, NohupsSighupStaysIgnored) {
  const fs::path out = dir_ / "out";
  const auto [status, err] = reconstruct_and_signal(dir_, "--frames 30:40 --register off", out, "000030.ply", "HUP", "trap \"\" HUP; ");
  ASSERT_NE(status, -2) << "the run ended before the signal was sent";
  ASSERT_EQ(status, 0) << err;
  std::ifstream stats_file(out / "stats.json");
  const nlohmann::json stats = nlohmann::json::parse(stats_file);
  EXPECT_FALSE(stats.contains("interrupted") && stats["interrupted"].get<bool>()) << stats.dump();
  EXPECT_EQ(stats["frames"].size(), 10u);
  EXPECT_TRUE(fs::exists(out / "000039.ply"));
}

// A capture or output folder whose name is not UTF-8 (Linux allows any bytes) is written, its
// stray bytes as U+FFFD in stats.json.
TEST_F(Cli, PathsThatAreNotUtf8AreWritten) {
  const fs::path capture = dir_ / "cap\xe9";
  ASSERT_EQ(run("synth --out '" + capture.string() + "' --frames 1 --cameras 2 --resolution 160x120").exit_code, 0);
  const fs::path out = dir_ / "out\xff";
  const CommandResult r = run("reconstruct '" + capture.string() + "' --threads 1 --out '" + out.string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ifstream stats_file(out / "stats.json");
  const nlohmann::json stats = nlohmann::json::parse(stats_file);
  EXPECT_EQ(stats["capture"].get<std::string>(), (dir_ / "cap\xef\xbf\xbd").string());
  const CommandResult info = run("info --json '" + capture.string() + "'");
  EXPECT_EQ(info.exit_code, 0) << info.err;
  EXPECT_EQ(nlohmann::json::parse(info.out)["capture"].get<std::string>(), (dir_ / "cap\xef\xbf\xbd").string());
}

// Outputs never land among the capture's own files: meshes written into its ground truth would
// replace the true ones (and every later eval of the capture would score 0 mm, 100 %), a rig
// written there the true poses. A link does not hide where the output goes. Nothing is written.
TEST_F(Cli, OutputsStayOutOfTheCapturesFolders) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 1 --cameras 2 --resolution 160x120 --noise none").exit_code, 0);
  const fs::path truth_mesh = capture / "ground_truth" / "mesh" / "000000.ply";
  const auto truth_written_at = fs::last_write_time(truth_mesh);
  fs::create_directory_symlink(capture / "ground_truth", dir_ / "truth_link");
  struct Case {
    std::string args, expected;
  };
  const std::string reconstruct = "reconstruct " + capture.string() + " --threads 1 --out ";
  const std::vector<Case> cases = {
      {reconstruct + capture.string(), "--out: " + capture.string() + " is the folder of the capture " + capture.string()},
      {reconstruct + (capture / "ground_truth" / "mesh").string(), " lies in the ground truth of the capture "},
      {reconstruct + (dir_ / "truth_link" / "new").string(), " lies in the ground truth of the capture "},
      {reconstruct + (capture / "cam1" / "depth").string(), " lies among the frames of camera cam1 of the capture "},
      {"register " + capture.string() + " --out " + (capture / "ground_truth" / "rig.json").string(), " lies in the ground truth of the capture "},
      {"register " + capture.string() + " --out " + (capture / "notes.txt").string(), "notes.txt is a file of the capture "},
  };
  write_file_atomic(capture / "notes.txt", "the capture's own\n");
  for (const Case& c : cases) {
    const CommandResult r = run(c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args;
    EXPECT_EQ(line_count(r.err), 1) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << c.args << "\n" << r.err;
  }
  EXPECT_EQ(fs::last_write_time(truth_mesh), truth_written_at);
  EXPECT_EQ(read_file_bytes(capture / "notes.txt").size(), 18u);
  EXPECT_FALSE(fs::exists(capture / "000000.ply"));
  EXPECT_FALSE(fs::exists(capture / "ground_truth" / "new"));
  // A folder of its own inside the capture is not among its files.
  EXPECT_EQ(run(reconstruct + (capture / "meshes").string()).exit_code, 0);
}

// The ground truth is optional: a ground_truth/rig.json that cannot be used is a warning for
// reconstruct (its meshes as without it), "not used" in info, and an error only where it is needed
// (eval) or asked for (info --strict).
TEST_F(Cli, AnUnusableGroundTruthRigStopsOnlyWhatNeedsIt) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 1 --cameras 2 --resolution 160x120 --noise none").exit_code, 0);
  write_file_atomic(capture / "ground_truth" / "rig.json", "garbage\n");
  const std::string problem = (capture / "ground_truth" / "rig.json").string() + ": not valid JSON";
  const CommandResult reconstructed = run("reconstruct " + capture.string() + " --threads 1 --out " + (dir_ / "out").string());
  EXPECT_EQ(reconstructed.exit_code, 0) << reconstructed.err;
  EXPECT_EQ(reconstructed.err.rfind("reconstruct: warning: " + problem, 0), 0u) << reconstructed.err;
  EXPECT_NE(reconstructed.err.find("; the ground truth is not used"), std::string::npos) << reconstructed.err;
  EXPECT_GT(read_mesh(dir_ / "out" / "000000.ply").triangle_count(), 1000u);
  const CommandResult info = run("info " + capture.string());
  EXPECT_EQ(info.exit_code, 0) << info.err;
  EXPECT_NE(info.out.find("ground truth not used: " + problem), std::string::npos) << info.out;
  for (const std::string& args : {"info --strict " + capture.string(), "eval " + capture.string() + " " + (dir_ / "out").string()}) {
    const CommandResult r = run(args);
    EXPECT_EQ(r.exit_code, 2) << args;
    EXPECT_EQ(r.err.rfind("zipfusion: error: " + problem, 0), 0u) << args << "\n" << r.err;
    EXPECT_EQ(line_count(r.err), 1) << r.err;
  }
}

// Cameras at one pose (a capture recorded without --rig has identity poses) would lay their
// meshes over each other: reconstruct, bench and register refuse such a rig, naming the file and
// the camera, and write nothing; info shows it (also with --strict: a wand recording for
// calibrate is such a capture). The same rig from --rig is refused likewise, and a calibration
// given with --rig makes the capture usable.
TEST_F(Cli, CamerasAtOnePoseAreAnUncalibratedRig) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 1 --cameras 3 --resolution 160x120 --noise none").exit_code, 0);
  Rig rig = read_rig(capture / "rig.json");
  const fs::path calibrated = dir_ / "calibrated.json";
  write_rig(calibrated, rig);
  // Camera 2 a few millimetres and a fraction of a degree from camera 0: still one place.
  rig.cameras[2].world_from_depth = rig.cameras[0].world_from_depth * Rigid3d(Eigen::AngleAxisd(0.005, Eigen::Vector3d::UnitY()));
  rig.cameras[2].world_from_depth.translation() += Eigen::Vector3d(0.004, -0.003, 0.002);
  write_rig(capture / "rig.json", rig);
  const std::string problem = "rig.json: cameras[2].world_from_depth: the pose of cameras[0] (\"cam0\" and \"cam2\" within 1 cm and 1 degree)";
  const fs::path out = dir_ / "out";
  for (const std::string& args : {"reconstruct " + capture.string() + " --out " + out.string(), "bench " + capture.string() + " --repeat 1",
                                  "register " + capture.string() + " --out " + (dir_ / "registered.json").string(),
                                  "reconstruct " + (dir_ / "cap2").string() + " --out " + out.string()}) {
    if (args.find("cap2") != std::string::npos) {  // the same rig through --rig
      ASSERT_EQ(run("synth --out " + (dir_ / "cap2").string() + " --frames 1 --cameras 3 --resolution 160x120 --noise none").exit_code, 0);
      const CommandResult r = run(args + " --rig " + (capture / "rig.json").string());
      EXPECT_EQ(r.exit_code, 2) << r.err;
      EXPECT_EQ(r.err.rfind("zipfusion: error: " + (capture / problem).string(), 0), 0u) << r.err;
      continue;
    }
    const CommandResult r = run(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.err;
    EXPECT_EQ(r.err.rfind("zipfusion: error: " + (capture / problem).string(), 0), 0u) << args << "\n" << r.err;
    EXPECT_NE(r.err.find("the rig is not calibrated"), std::string::npos) << r.err;
    EXPECT_EQ(line_count(r.err), 1) << r.err;
  }
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(dir_ / "registered.json"));
  for (const std::string strict : {"", "--strict "}) {
    const CommandResult info = run("info " + strict + capture.string());
    EXPECT_EQ(info.exit_code, 0) << info.err;
    EXPECT_NE(info.out.find("poses        cameras[2].world_from_depth: the pose of cameras[0]"), std::string::npos) << info.out;
  }
  const CommandResult with_calibration = run("reconstruct " + capture.string() + " --threads 1 --rig " + calibrated.string() + " --out " + out.string());
  EXPECT_EQ(with_calibration.exit_code, 0) << with_calibration.err;
  EXPECT_GT(read_mesh(out / "000000.ply").triangle_count(), 1000u);
}

// A camera whose frames hold no depth has no depth range: "-" in info's table and null in its
// JSON, not 0.00 m (a depth no camera measures).
TEST_F(Cli, InfoGivesNoDepthRangeForACameraWithoutDepth) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 1 --cameras 2 --resolution 160x120 --noise none").exit_code, 0);
  write_depth_png(capture / "cam1" / "depth" / "000000.png", DepthImage(160, 120, 0));
  const CommandResult json_info = run("info --json " + capture.string());
  ASSERT_EQ(json_info.exit_code, 0) << json_info.err;
  const nlohmann::json j = nlohmann::json::parse(json_info.out);
  EXPECT_TRUE(j["cameras"][1]["depth_m"].is_null()) << j["cameras"][1];
  EXPECT_GT(j["cameras"][0]["depth_m"]["median"].get<double>(), 1.5);
  const CommandResult table = run("info " + capture.string());
  const size_t row = table.out.find("\ncam1 ", table.out.find("frames examined"));
  ASSERT_NE(row, std::string::npos) << table.out;
  const std::string line = table.out.substr(row + 1, table.out.find('\n', row + 1) - row - 1);
  EXPECT_EQ(line.back(), '-') << line;
}

// A synth that fails leaves nothing: not the parent folders it would have written into, nor a
// capture volume no viewer can quantise (a subject reaching 1e38 m); and --color-noise given
// with --noise none is used, not silently zeroed.
TEST_F(Cli, SynthLeavesNothingWhenItFailsAndTakesTheColourNoiseGiven) {
  const fs::path subjects = dir_ / "subjects";
  fs::create_directories(subjects);
  write_file_atomic(subjects / "far0.obj", "v 0 0 1\nv 0.5 0 1\nv 0 0 1.5\nv 3e38 0 0\nf 1 2 3\nf 1 2 4\n");
  struct Case {
    std::string args, expected;
    int exit_code;
  };
  for (const Case& c : std::vector<Case>{
           {"synth --out " + (dir_ / "a" / "b" / "cap").string() + " --frames 1 --resolution 64x48 --subject " + (subjects / "none%d.obj").string(),
            "none0.obj: no such file", 3},
           {"synth --out " + (dir_ / "a" / "b" / "cap").string() + " --frames 1 --resolution 64x48 --subject " + (subjects / "far%d.obj").string(),
            "far0.obj: a vertex lies 3e+38 m from the origin; a subject must lie within 999 m of it on each axis", 2}}) {
    const CommandResult r = run(c.args);
    EXPECT_EQ(r.exit_code, c.exit_code) << c.args;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir_ / "a")) << c.args;
  }
  const std::string plain = "synth --frames 1 --cameras 1 --resolution 64x48 --noise none --color-format png --out ";
  ASSERT_EQ(run(plain + (dir_ / "quiet").string()).exit_code, 0);
  ASSERT_EQ(run(plain + (dir_ / "noisy").string() + " --color-noise 20").exit_code, 0);
  EXPECT_NE(read_file_bytes(dir_ / "quiet" / "cam0" / "color" / "000000.png"), read_file_bytes(dir_ / "noisy" / "cam0" / "color" / "000000.png"));
  // Checkerboard views too take the --color-noise given (their own default otherwise).
  const std::string board = "synth --checkerboard --views 1 --resolution 160x120 --out ";
  ASSERT_EQ(run(board + (dir_ / "board_default").string()).exit_code, 0);
  ASSERT_EQ(run(board + (dir_ / "board_clean").string() + " --color-noise 0").exit_code, 0);
  EXPECT_NE(read_file_bytes(dir_ / "board_default" / "view_000.png"), read_file_bytes(dir_ / "board_clean" / "view_000.png"));
}

// Frame files the capture lacks are one warning line saying what becomes of their cameras: left
// out without depth, grey without colour (cameras_used counts the camera that is only grey).
TEST_F(Cli, MissingFrameFilesAreAWarning) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 2 --cameras 2 --resolution 160x120 --noise none").exit_code, 0);
  fs::remove(capture / "cam1" / "color" / "000000.jpg");
  fs::remove(capture / "cam0" / "depth" / "000001.png");
  const CommandResult r = run("reconstruct " + capture.string() + " --threads 1 --out " + (dir_ / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "reconstruct: warning: 2 frame files missing (cam0 depth 1 colour 0, cam1 depth 0 colour 1): a camera without its depth "
                   "file is left out of that frame set, one without its colour file is grey there\n");
  const nlohmann::json stats = nlohmann::json::parse(read_file_bytes(dir_ / "out" / "stats.json"));
  EXPECT_EQ(stats["frames"][0]["cameras_used"], 2);
  EXPECT_EQ(stats["frames"][1]["cameras_used"], 1);
  // Only the frames asked for count.
  const CommandResult second = run("reconstruct " + capture.string() + " --threads 1 --frames 1 --out " + (dir_ / "out1").string());
  EXPECT_NE(second.err.find("1 frame files missing (cam0 depth 1 colour 0)"), std::string::npos) << second.err;
  // --frames N is frame N alone, which a newcomer took for the first N: said in a line.
  EXPECT_NE(second.out.find("wrote 1 mesh (zipper)"), std::string::npos) << second.out;
  EXPECT_NE(second.out.find("reconstruct: --frames 1 is frame 1 alone; --frames 0:1 gives the first 1\n"), std::string::npos) << second.out;
}

// Depth in tenths of a millimetre read as millimetres (a unit typed wrong) puts every point
// within half a metre of its camera, outside the volume: reconstruct made empty meshes and info
// showed 0 % in the volume, both without a word.
TEST_F(Cli, DepthThatNeverReachesTheVolumeIsWarnedOf) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 2 --cameras 2 --resolution 160x120 --noise none").exit_code, 0);
  const CommandResult good = run("reconstruct " + capture.string() + " --threads 1 --out " + (dir_ / "good").string());
  ASSERT_EQ(good.exit_code, 0) << good.err;
  EXPECT_EQ(good.err, "");
  EXPECT_EQ(run("info " + capture.string()).out.find("no depth in the volume"), std::string::npos);

  nlohmann::json rig = nlohmann::json::parse(read_file_bytes(capture / "rig.json"));
  rig["depth_unit_m"] = 0.0001;
  write_file_atomic(capture / "rig.json", rig.dump(2));
  const CommandResult empty = run("reconstruct " + capture.string() + " --threads 1 --out " + (dir_ / "empty").string());
  ASSERT_EQ(empty.exit_code, 0) << empty.err;
  EXPECT_EQ(empty.err,
            "reconstruct: warning: every mesh is empty; is there depth between --min-depth 0.4 and --max-depth 4.5 m inside the capture "
            "volume (rig.json's depth_unit_m: 0.0001 m; `zipfusion info` shows where the depth lies)?\n");
  const nlohmann::json stats = nlohmann::json::parse(read_file_bytes(dir_ / "empty" / "stats.json"));
  EXPECT_EQ(stats["frames"][0]["triangles"], 0);
  // A refinement with no depth to match moves no camera, and no pose update is recorded.
  ASSERT_EQ(run("reconstruct " + capture.string() + " --threads 1 --register once --out " + (dir_ / "once").string()).exit_code, 0);
  EXPECT_EQ(nlohmann::json::parse(read_file_bytes(dir_ / "once" / "stats.json"))["pose_updates"], nlohmann::json::array());
  const CommandResult info = run("info " + capture.string());
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_NE(info.out.find("no depth in the volume: cam0, cam1; reconstruct keeps only depth inside it (check rig.json's depth_unit_m, "
                          "0.0001 m, and volume, or reconstruct with --no-volume-crop)"),
            std::string::npos)
      << info.out;
}

// "DIR/" and "DIR/." (as a shell completes a folder) name DIR: the capture is written there, with
// nothing left beside or inside it (the staging folder was made inside DIR, so renaming failed
// after the whole capture was rendered, and an empty DIR stayed).
TEST_F(Cli, AnOutputFolderWithATrailingSlashIsThatFolder) {
  for (const std::string suffix : {"/", "/."}) {
    const fs::path capture = dir_ / "slash";
    fs::remove_all(capture);
    const CommandResult r = run("synth --out " + capture.string() + suffix + " --frames 1 --cameras 2 --resolution 160x120");
    ASSERT_EQ(r.exit_code, 0) << suffix << ": " << r.err;
    EXPECT_EQ(Capture::open(capture).camera_count(), 2) << suffix;
    for (const fs::directory_entry& e : fs::directory_iterator(dir_)) EXPECT_NE(e.path().filename().string()[0], '.') << e.path();
    for (const fs::directory_entry& e : fs::directory_iterator(capture)) EXPECT_NE(e.path().filename().string()[0], '.') << e.path();
    const fs::path board = dir_ / "board";
    ASSERT_EQ(run("synth --out " + board.string() + suffix + " --checkerboard --views 1").exit_code, 0) << suffix;
    EXPECT_TRUE(fs::exists(board / "truth.json")) << suffix;
    EXPECT_TRUE(fs::exists(board / "view_000.png")) << suffix;
    fs::remove_all(board);
  }
}

// reconstruct's --out through a link to a folder not made yet makes the folder where it points.
TEST_F(Cli, ReconstructWritesThroughALinkToANewFolder) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 1 --cameras 2 --resolution 160x120").exit_code, 0);
  fs::create_symlink("runs/new", dir_ / "outlink");
  const CommandResult r = run("reconstruct " + capture.string() + " --out " + (dir_ / "outlink").string() + "/");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::is_symlink(dir_ / "outlink"));
  EXPECT_TRUE(fs::is_regular_file(dir_ / "runs" / "new" / "000000.ply"));
  EXPECT_TRUE(fs::is_regular_file(dir_ / "runs" / "new" / "stats.json"));
}

// --rig brings a whole calibration (as calibrate writes it): intrinsics, poses and the volume. A
// capture whose own rig.json has nominal depth intrinsics and no volume, reconstructed with
// --rig of the true rig, gives the very mesh the true rig.json gives.
TEST_F(Cli, ReconstructTakesTheWholeCalibrationFromRig) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 1 --cameras 2 --resolution 160x120").exit_code, 0);
  ASSERT_EQ(run("reconstruct " + capture.string() + " --out " + (dir_ / "true").string()).exit_code, 0);
  const fs::path truth = dir_ / "truth.json";
  fs::copy_file(capture / "rig.json", truth);
  Rig nominal = read_rig(truth);
  nominal.volume.reset();
  for (CameraModel& model : nominal.cameras) model.depth_intrinsics.fx *= 1.1;
  write_rig(capture / "rig.json", nominal);
  CommandResult r = run("reconstruct " + capture.string() + " --rig " + truth.string() + " --out " + (dir_ / "calibrated").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(read_file_bytes(dir_ / "calibrated" / "000000.ply"), read_file_bytes(dir_ / "true" / "000000.ply"));
  ASSERT_EQ(run("reconstruct " + capture.string() + " --out " + (dir_ / "nominal").string()).exit_code, 0);
  EXPECT_NE(read_file_bytes(dir_ / "nominal" / "000000.ply"), read_file_bytes(dir_ / "true" / "000000.ply"));
  // Depth distortion in --rig undistorts the depth as it would from the capture's own rig.json.
  Rig distorted = read_rig(truth);
  for (CameraModel& model : distorted.cameras) {
    model.depth_intrinsics.distortion = {0.04, -0.02, 0, 0, 0};
    model.depth_intrinsics.has_distortion = true;
  }
  write_rig(dir_ / "distorted.json", distorted);
  r = run("reconstruct " + capture.string() + " --rig " + (dir_ / "distorted.json").string() + " --out " + (dir_ / "through_rig").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  write_rig(capture / "rig.json", distorted);
  ASSERT_EQ(run("reconstruct " + capture.string() + " --out " + (dir_ / "own").string()).exit_code, 0);
  EXPECT_EQ(read_file_bytes(dir_ / "through_rig" / "000000.ply"), read_file_bytes(dir_ / "own" / "000000.ply"));
  EXPECT_NE(read_file_bytes(dir_ / "own" / "000000.ply"), read_file_bytes(dir_ / "true" / "000000.ply"));
  write_rig(capture / "rig.json", nominal);
  // A calibration of other images is refused, naming the field.
  Rig other = read_rig(truth);
  other.cameras[1].color_intrinsics->width = 320;
  write_rig(dir_ / "other.json", other);
  r = run("reconstruct " + capture.string() + " --rig " + (dir_ / "other.json").string() + " --out " + (dir_ / "x").string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.err, "zipfusion: error: " + (dir_ / "other.json").string() +
                       ": cameras[1].color_intrinsics: 320x120, but the capture's images are 160x120\n");
  EXPECT_FALSE(fs::exists(dir_ / "x"));
}

// The floor lift (--floor-noise) raises the volume's lowest-z face: in a rig whose world is not
// z-up that face is no floor, and reconstruct says so once (not for a z-up rig, nor with the lift
// off).
TEST_F(Cli, AWorldThatIsNotZUpIsWarnedOfTheFloorLift) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 1 --cameras 2 --resolution 160x120").exit_code, 0);
  const std::string warning = "reconstruct: warning: the rig's world does not look z-up";
  CommandResult r = run("reconstruct " + capture.string() + " --register off --out " + (dir_ / "z_up").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err.find(warning), std::string::npos) << r.err;
  // The same rig and volume with y up: (x, y, z) → (x, z, −y).
  Rig y_up = read_rig(capture / "rig.json");
  const Rigid3d to_y_up(Eigen::AngleAxisd(-std::numbers::pi / 2, Eigen::Vector3d::UnitX()));
  for (CameraModel& camera : y_up.cameras) camera.world_from_depth = to_y_up * camera.world_from_depth;
  ASSERT_TRUE(y_up.volume.has_value());
  const Box3d box = *y_up.volume;
  y_up.volume = Box3d{.min = {box.min.x(), box.min.z(), -box.max.y()}, .max = {box.max.x(), box.max.z(), -box.min.y()}};
  write_rig(dir_ / "y_up.json", y_up);
  r = run("reconstruct " + capture.string() + " --rig " + (dir_ / "y_up.json").string() + " --register off --out " + (dir_ / "y_up").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err.rfind(warning, 0), 0u) << r.err;
  EXPECT_EQ(r.err.find(warning, 1), std::string::npos) << r.err;  // once
  r = run("reconstruct " + capture.string() + " --rig " + (dir_ / "y_up.json").string() + " --register off --floor-noise 0 --out " +
          (dir_ / "lift_off").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err.find(warning), std::string::npos) << r.err;
}

// The subcommands a --help lists under "Subcommands:", each with its one-line description.
std::vector<std::pair<std::string, std::string>> listed_subcommands(const std::string& help) {
  std::vector<std::pair<std::string, std::string>> listed;
  std::istringstream lines(help.substr(std::min(help.size(), help.find("Subcommands:"))));
  std::string line;
  std::getline(lines, line);  // the heading
  while (std::getline(lines, line) && line.rfind("  ", 0) == 0) {
    std::istringstream words(line);
    std::string name, description;
    words >> name;
    std::getline(words >> std::ws, description);
    listed.emplace_back(name, description);
  }
  return listed;
}

// Every subcommand the top-level --help lists (and calibrate's own) answers --help with its
// description and usage, and exits 0.
TEST_F(Cli, EverySubcommandHasHelp) {
  const CommandResult top = run("--help");
  ASSERT_EQ(top.exit_code, 0);
  auto subcommands = listed_subcommands(top.out);
  ASSERT_GE(subcommands.size(), 9u) << top.out;  // synth … record, as README lists them
  const CommandResult calibrate = run("calibrate --help");
  const auto calibrate_subcommands = listed_subcommands(calibrate.out);
  ASSERT_EQ(calibrate_subcommands.size(), 3u) << calibrate.out;  // intrinsics, extrinsics, floor
  for (const auto& [name, description] : calibrate_subcommands) subcommands.emplace_back("calibrate " + name, description);
  for (const auto& [name, description] : subcommands) {
    const CommandResult r = run(name + " --help");
    EXPECT_EQ(r.exit_code, 0) << name;
    EXPECT_EQ(r.out.rfind(description + "\n", 0), 0u) << name << ": " << r.out;
    EXPECT_NE(r.out.find("Usage: "), std::string::npos) << name << ": " << r.out;
  }
  EXPECT_NE(run("synth --help").out.find("--miscalibrate"), std::string::npos);
  EXPECT_NE(run("").exit_code, 0);
}

}  // namespace
}  // namespace zipfusion
