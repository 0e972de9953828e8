// End-to-end test of `zipfusion bench` on a small synthetic capture: the report's numbers must be
// consistent with each other and with what the configurations do.

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <regex>

#include "cli/cli_test_util.h"

namespace zipfusion {
namespace {

class BenchCli : public testing::CliTest {};

TEST_F(BenchCli, ReportsEveryStageOfEveryConfiguration) {
  const std::string capture = (dir_ / "cap").string();
  ASSERT_EQ(run("synth --out " + capture + " --frames 2 --cameras 3").exit_code, 0);
  const testing::CommandResult r = run("bench " + capture + " --frames 2 --repeat 2 --soak 3 --json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json report = nlohmann::json::parse(r.out);
  EXPECT_EQ(report["cameras"], 3);
  EXPECT_EQ(report["frames"], 2);
  EXPECT_GT(report["decode_ms"]["median"].get<double>(), 0);
  // When and where it ran, for a report written later (scripts/bench_report.py).
  EXPECT_TRUE(std::regex_match(report["date"].get<std::string>(), std::regex(R"(20\d\d-[01]\d-[0-3]\d)"))) << report["date"];
  EXPECT_EQ(report["machine"]["os"].get<std::string>().rfind("Linux ", 0), 0u) << report["machine"]["os"];
  std::map<std::string, nlohmann::json> configs;
  for (const auto& c : report["configs"]) configs[c["name"]] = c;
  ASSERT_EQ(configs.size(), 13u);
  for (const auto& [name, c] : configs) {
    SCOPED_TRACE(name);
    const double total = c["ms"]["total"]["median"];
    EXPECT_GT(total, 0);
    EXPECT_NEAR(c["fps"].get<double>(), 1000.0 / total, 1e-6);
    const double stolen = c["cpu_stolen_share"];  // a share of /proc/stat's CPU time
    EXPECT_GE(stolen, 0.0);
    EXPECT_LE(stolen, 1.0);
    for (const auto& [stage, t] : c["ms"].items()) {
      EXPECT_LE(t["median"].get<double>(), t["p95"].get<double>()) << stage;
      EXPECT_LE(t["median"].get<double>(), c["ms"]["total"]["p95"].get<double>()) << stage;
    }
    // The two stages added per frame set: each sum is at least either part and at most the frame
    // set's total, so their median is too.
    const double together = c["ms"]["redundancy+clipping"]["median"];
    EXPECT_GE(together, c["ms"]["redundancy"]["median"].get<double>());
    EXPECT_GE(together, c["ms"]["clipping"]["median"].get<double>());
    EXPECT_LE(together, total);
  }
  // Only the filtered configurations filter; only the zipper ones zipper, with fewer triangles.
  EXPECT_GT(configs["zipper+filter"]["ms"]["filter"]["median"].get<double>(), 0);
  EXPECT_EQ(configs["zipper"]["ms"]["filter"]["median"].get<double>(), 0);
  EXPECT_EQ(configs["separate"]["ms"]["clipping"]["median"].get<double>(), 0);
  EXPECT_EQ(configs["separate"]["ms"]["redundancy+clipping"]["median"].get<double>(), 0);
  EXPECT_GT(configs["zipper"]["ms"]["clipping"]["median"].get<double>(), 0);
  EXPECT_LT(configs["zipper"]["triangles"].get<double>(), configs["separate"]["triangles"].get<double>());
  EXPECT_EQ(configs["zipper 1 thread"]["triangles"], configs["zipper"]["triangles"]);
  // Overlapping pairs: none for separate meshes; of three cameras in a ring, one to three.
  EXPECT_EQ(configs["separate"]["pairs"].get<double>(), 0);
  EXPECT_GE(configs["zipper"]["pairs"].get<double>(), 1);
  EXPECT_LE(configs["zipper"]["pairs"].get<double>(), 3);
  EXPECT_EQ(configs["zipper 1 thread"]["pairs"], configs["zipper"]["pairs"]);
  EXPECT_EQ(configs["zipper border ownership"]["ms"]["filter"]["median"].get<double>(), 0);
  EXPECT_NE(configs["zipper border ownership"]["triangles"], configs["zipper"]["triangles"]);
  EXPECT_GT(configs["zipper+separable filter"]["ms"]["filter"]["median"].get<double>(), 0);
  // The 5×5 filter filters, otherwise than the paper's, and only the zipper one zippers.
  EXPECT_GT(configs["zipper+5x5 filter"]["ms"]["filter"]["median"].get<double>(), 0);
  EXPECT_NE(configs["zipper+5x5 filter"]["triangles"], configs["zipper+filter"]["triangles"]);
  EXPECT_GT(configs["zipper+5x5 filter"]["ms"]["clipping"]["median"].get<double>(), 0);
  EXPECT_GT(configs["separate+5x5 filter"]["ms"]["filter"]["median"].get<double>(), 0);
  EXPECT_EQ(configs["separate+5x5 filter"]["ms"]["clipping"]["median"].get<double>(), 0);
  EXPECT_LT(configs["zipper+5x5 filter"]["triangles"].get<double>(), configs["separate+5x5 filter"]["triangles"].get<double>());
  // Level of detail 1: a quarter of the triangles, give or take the seams.
  for (const char* lod : {"zipper lod 1", "zipper+filter lod 1"}) {
    const double share = configs[lod]["triangles"].get<double>() / configs["zipper"]["triangles"].get<double>();
    EXPECT_GT(share, 0.15) << lod;
    EXPECT_LT(share, 0.35) << lod;
  }
  EXPECT_GT(configs["zipper+filter lod 1"]["ms"]["filter"]["median"].get<double>(), 0);
  // Dropping small pieces removes triangles (the noisy synthetic rig has some: 455 of 96 251) and
  // adds no filtering.
  EXPECT_LT(configs["zipper min component 50"]["triangles"].get<double>(), configs["zipper"]["triangles"].get<double>());
  EXPECT_EQ(configs["zipper min component 50"]["ms"]["filter"]["median"].get<double>(), 0);
  EXPECT_GT(configs["zipper min component 50"]["ms"]["clipping"]["median"].get<double>(), 0);
  EXPECT_EQ(report["soak"]["frames"], 3);
  EXPECT_EQ(report["soak"]["early_frames"], 3);
  // Buffers are sized by the first frame set: three more must not grow the resident size.
  EXPECT_LE(report["soak"]["rss_mb_at_end"].get<double>(), report["soak"]["rss_mb_early"].get<double>() * 1.02 + 1);
}

TEST_F(BenchCli, BadArgumentsGiveOneLineAndExitTwo) {
  const std::string capture = (dir_ / "cap").string();
  ASSERT_EQ(run("synth --out " + capture + " --frames 1 --cameras 2").exit_code, 0);
  for (const std::string option : {"--repeat 0", "--soak -1", "--threads -2", "--frames 0"}) {
    const testing::CommandResult r = run("bench " + capture + " " + option);
    EXPECT_EQ(r.exit_code, 2) << option;
    EXPECT_EQ(testing::line_count(r.err), 1) << option;
    EXPECT_NE(r.err.find(option.substr(0, option.find(' '))), std::string::npos) << r.err;
  }
}

// Asking for more frame sets than the capture has is an error (it used to time the ones there were
// and say so only in its header); left to its default, bench takes as many of 30 as there are.
TEST_F(BenchCli, FramesPastTheCaptureAreAnError) {
  const std::string capture = (dir_ / "cap").string();
  ASSERT_EQ(run("synth --out " + capture + " --frames 2 --cameras 2").exit_code, 0);
  const testing::CommandResult past = run("bench " + capture + " --frames 3 --repeat 1 --json");
  EXPECT_EQ(past.exit_code, 2);
  EXPECT_EQ(testing::line_count(past.err), 1);
  EXPECT_NE(past.err.find("--frames: 3 reaches past the last frame of a capture with 2 frames"), std::string::npos) << past.err;
  const testing::CommandResult by_default = run("bench " + capture + " --repeat 1 --json");
  ASSERT_EQ(by_default.exit_code, 0) << by_default.err;
  EXPECT_EQ(nlohmann::json::parse(by_default.out)["frames"], 2);
}

}  // namespace
}  // namespace zipfusion
