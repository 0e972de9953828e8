// End-to-end test of `zipfusion eval`: a synthetic capture, reconstructions made from its ground
// truth, the table, the JSON and the errors.

#include <gtest/gtest.h>

#include "cli/cli_test_util.h"
#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "zipfusion/io/file_util.h"
#include "zipfusion/io/mesh_io.h"

namespace zipfusion {
namespace {

namespace fs = std::filesystem;

using testing::CommandResult;
using testing::line_count;

class EvalCli : public testing::CliTest {};

TEST_F(EvalCli, MeasuresReconstructionsAgainstTheTruth) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 3 --cameras 3 --noise none").exit_code, 0);
  // Frame 0: the true surface with colours 10 levels darker (the true colours are all >= 16);
  // frame 1: the truth 5 mm higher, as OBJ, with two of its triangles laid again turned over;
  // frame 2: none.
  const fs::path recon = dir_ / "recon";
  fs::create_directories(recon);
  TriangleMesh darker = read_mesh(capture / "ground_truth" / "mesh" / "000000.ply");
  for (Rgb8& c : darker.colors) c = {static_cast<unsigned char>(c.r - 10), static_cast<unsigned char>(c.g - 10), static_cast<unsigned char>(c.b - 10)};
  write_mesh(recon / "000000.ply", darker);
  TriangleMesh moved = read_mesh(capture / "ground_truth" / "mesh" / "000001.ply");
  for (Eigen::Vector3f& p : moved.positions) p.z() += 0.005f;
  for (int t : {0, 1}) moved.triangles.emplace_back(moved.triangles[t][0], moved.triangles[t][2], moved.triangles[t][1]);
  write_mesh(recon / "000001.obj", moved);

  const CommandResult json_run = run("eval " + capture.string() + " " + recon.string() + " --json --threads 2");
  ASSERT_EQ(json_run.exit_code, 0) << json_run.err;
  const nlohmann::json j = nlohmann::json::parse(json_run.out);
  ASSERT_EQ(j["frames"].size(), 3u);
  EXPECT_EQ(j["missing_frames"], nlohmann::json::array({2}));
  // The missing frame is scored as an empty mesh: leaving a frame out cannot raise the mean.
  const auto& missing = j["frames"][2];
  EXPECT_TRUE(missing["file"].is_null());
  EXPECT_EQ(missing["triangles"], 0);
  EXPECT_DOUBLE_EQ(missing["completeness"].get<double>(), 0.0);
  EXPECT_TRUE(missing["accuracy_mean_mm"].is_null());
  const auto& exact = j["frames"][0];
  EXPECT_EQ(exact["frame"], 0);
  EXPECT_LT(exact["accuracy_mean_mm"].get<double>(), 0.01);
  EXPECT_DOUBLE_EQ(exact["completeness"].get<double>(), 1.0);
  EXPECT_NEAR(exact["color_error"].get<double>(), 10.0, 0.01);
  EXPECT_EQ(exact["non_manifold_edges"], 0);
  EXPECT_EQ(exact["doubled_triangles"], 0);
  EXPECT_EQ(exact["components"], 18);  // the built-in human's closed parts
  EXPECT_GT(exact["area_ratio"].get<double>(), 1.0);  // some of the truth is hidden from all cameras
  const auto& shifted = j["frames"][1];
  EXPECT_EQ(shifted["file"], "000001.obj");
  EXPECT_EQ(shifted["doubled_triangles"], 2);
  EXPECT_DOUBLE_EQ(j["mean"]["doubled_triangles"].get<double>(), 1.0);  // counts over the frames there are
  EXPECT_GT(shifted["accuracy_mean_mm"].get<double>(), 1.0);  // 5 mm up: 0 on vertical surfaces, 5 on horizontal ones
  EXPECT_GT(shifted["accuracy_p95_mm"].get<double>(), 4.0);
  EXPECT_LT(shifted["accuracy_mean_mm"].get<double>(), 5.0);
  EXPECT_GT(shifted["completeness"].get<double>(), 0.99);
  EXPECT_NEAR(j["mean"]["accuracy_mean_mm"].get<double>(), shifted["accuracy_mean_mm"].get<double>() / 2, 0.01);
  EXPECT_NEAR(j["mean"]["color_error"].get<double>(), (10 + shifted["color_error"].get<double>()) / 2, 0.01);
  EXPECT_NEAR(j["mean"]["completeness"].get<double>(), (1 + shifted["completeness"].get<double>() + 0) / 3, 1e-9);

  const CommandResult table = run("eval " + capture.string() + " " + recon.string() + " --frames 1:3");
  ASSERT_EQ(table.exit_code, 0) << table.err;
  for (const char* expected : {"reconstructions  ", ": 1 of 2 frames (a missing one is scored as an empty mesh)", "     1 ", "     2   missing ",
                               "  mean ", "missing reconstructions: 1 frame (2)"}) {
    EXPECT_NE(table.out.find(expected), std::string::npos) << expected << "\n" << table.out;
  }
  EXPECT_EQ(table.out.find("\n     0 "), std::string::npos) << table.out;
}

// Meshes scored against another capture's truth are warned of, from their stats.json.
TEST_F(EvalCli, MeshesOfAnotherCaptureAreWarnedOf) {
  const fs::path first = dir_ / "first", second = dir_ / "second", meshes = dir_ / "meshes";
  ASSERT_EQ(run("synth --out " + first.string() + " --frames 1 --cameras 2 --resolution 160x120 --noise none").exit_code, 0);
  ASSERT_EQ(run("synth --out " + second.string() + " --frames 1 --cameras 2 --resolution 160x120 --noise none --seed 2").exit_code, 0);
  ASSERT_EQ(run("reconstruct " + first.string() + " --threads 1 --out " + meshes.string()).exit_code, 0);
  const CommandResult own = run("eval " + first.string() + " " + meshes.string());
  ASSERT_EQ(own.exit_code, 0) << own.err;
  EXPECT_EQ(own.err, "");
  const CommandResult other = run("eval " + second.string() + " " + meshes.string());
  ASSERT_EQ(other.exit_code, 0) << other.err;
  EXPECT_EQ(other.err, "eval: warning: " + (meshes / "stats.json").string() + " says these meshes were made of " + first.string() + ", not " +
                           second.string() + "\n");
  // Meshes numbered past the capture's frames cannot be scored; said so, and the score is the same.
  fs::copy_file(meshes / "000000.ply", meshes / "000003.ply");
  fs::copy_file(meshes / "000000.ply", meshes / "000001.ply");
  write_obj(meshes / "000003.obj", TriangleMesh{});  // the same frame again: one mesh
  const CommandResult beyond = run("eval " + first.string() + " " + meshes.string());
  ASSERT_EQ(beyond.exit_code, 0) << beyond.err;
  EXPECT_EQ(beyond.err, "eval: warning: " + meshes.string() + ": 2 meshes numbered past the capture's last frame (000000), from 000001 on; not scored\n");
  EXPECT_EQ(beyond.out, own.out);
}

TEST_F(EvalCli, BadInputGivesOneLineAndExitTwo) {
  const fs::path capture = dir_ / "cap";
  ASSERT_EQ(run("synth --out " + capture.string() + " --frames 1 --cameras 1 --noise none").exit_code, 0);
  const fs::path no_truth = dir_ / "no_truth";
  fs::copy(capture, no_truth, fs::copy_options::recursive);
  fs::remove_all(no_truth / "ground_truth");
  const fs::path empty = dir_ / "empty";
  fs::create_directories(empty);
  struct Case {
    std::string args, expected;
    int exit_code = 2;  // 3: a file or folder cannot be read
  };
  std::vector<Case> cases = {
      {"eval " + no_truth.string() + " " + empty.string(),
       (no_truth / "ground_truth" / "rig.json").string() + ": missing: eval needs a capture with ground truth (synth writes one)"},
      {"eval " + capture.string() + " " + empty.string(), empty.string() + ": no reconstruction"},
      {"eval " + capture.string() + " " + (dir_ / "nowhere").string(), "nowhere: not a folder of reconstructions (no such folder)", 3},
      {"eval " + capture.string() + " " + (capture / "rig.json").string(), "rig.json: not a folder of reconstructions (a file, not a folder)", 3},
      {"eval " + capture.string() + " " + empty.string() + " --min-range 3 --max-range 2", "--max-range: must be above --min-range"},
  };
  // What is not a mesh is an error naming the file, not an empty reconstruction; nor is a frame
  // with both formats read as either.
  const fs::path renamed = dir_ / "renamed", both = dir_ / "both";
  fs::create_directories(renamed);
  fs::create_directories(both);
  write_file_atomic(renamed / "000000.obj", "ply\nformat binary_little_endian 1.0\n");
  write_obj(both / "000000.obj", TriangleMesh{});
  write_ply(both / "000000.ply", TriangleMesh{});
  cases.push_back({"eval " + capture.string() + " " + renamed.string(), (renamed / "000000.obj").string() + ": line 1: not an OBJ statement"});
  cases.push_back({"eval " + capture.string() + " " + both.string(),
                   (both / "000000.ply").string() + ", 000000.obj: two reconstructions of one frame; keep one"});
  for (const Case& c : cases) {
    const CommandResult r = run(c.args);
    EXPECT_EQ(r.exit_code, c.exit_code) << c.args;
    EXPECT_EQ(line_count(r.err), 1) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << c.args << "\n" << r.err;
  }
  EXPECT_NE(run("eval --help").out.find("--completeness-mm"), std::string::npos);
}

}  // namespace
}  // namespace zipfusion
