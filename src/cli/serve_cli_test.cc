// zipfusion serve from the command line: it streams a capture at its frame rate for the time
// asked, and bad options give one line naming the option and a non-zero exit.

#include <regex>

#include "cli/cli_test_util.h"

namespace zipfusion {
namespace {

using testing::CliTest;
using testing::CommandResult;
using testing::line_count;

class ServeCli : public CliTest {};

TEST_F(ServeCli, StreamsAtTheCaptureFrameRateForTheTimeAsked) {
  const std::string capture = (dir_ / "cap").string();
  ASSERT_EQ(run("synth --out " + capture + " --frames 6 --cameras 2").exit_code, 0);
  const CommandResult r = run("serve " + capture + " --loop --seconds 2 --port 0");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("serving http://127.0.0.1:"), std::string::npos) << r.out;
  std::smatch served;
  const std::regex served_line("served (\\d+) frame sets \\((\\d+) dropped by the pipeline to keep up, (\\d+) not made");
  ASSERT_TRUE(std::regex_search(r.out, served, served_line)) << r.out;
  // 2 s at 30 fps, looping over 6 frames: 60 frame sets handed over, and with no viewer none is
  // made (the pipeline may also drop one, as live, on a busy machine).
  EXPECT_EQ(std::stoi(served[1]) + std::stoi(served[2]) + std::stoi(served[3]), 60) << r.out;
  EXPECT_EQ(std::stoi(served[1]), 0) << r.out;
  EXPECT_GE(std::stoi(served[3]), 30) << r.out;
  // Without --loop the stream ends with the capture.
  const CommandResult once = run("serve " + capture + " --port 0");
  ASSERT_EQ(once.exit_code, 0) << once.err;
  ASSERT_TRUE(std::regex_search(once.out, served, served_line)) << once.out;
  EXPECT_EQ(std::stoi(served[1]) + std::stoi(served[2]) + std::stoi(served[3]), 6) << once.out;
}

// serve --live streams live cameras: here a fakenect dump replayed as a camera (as fast as it
// reads, so the pipeline drops what it cannot keep up with, as it would for a live device).
TEST_F(ServeCli, StreamsLiveCameras) {
  const std::string dump = (dir_ / "dump").string();
  ASSERT_EQ(run("synth --fakenect " + dump + " --frames 8").exit_code, 0);
  const CommandResult r = run("serve --live --replay " + dump + " --port 0");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::smatch served;
  ASSERT_TRUE(std::regex_search(r.out, served, std::regex("served (\\d+) frame sets \\((\\d+) dropped by the pipeline to keep up, (\\d+) not made"))) << r.out;
  EXPECT_EQ(std::stoi(served[1]) + std::stoi(served[2]) + std::stoi(served[3]), 8) << r.out;
  EXPECT_NE(run("serve --live --replay " + dump + " --loop --port 0").exit_code, 0);
}

TEST_F(ServeCli, BadOptionsGiveOneLineAndNonZeroExit) {
  const std::string capture = (dir_ / "cap").string();
  ASSERT_EQ(run("synth --out " + capture + " --frames 2 --cameras 2").exit_code, 0);
  struct Case {
    std::string args, expected;
  };
  const std::vector<Case> cases = {
      {"serve " + capture + " --port 70000", "--port"},
      {"serve " + capture + " --bind not-an-address --port 0", "--bind"},
      {"serve " + capture + " --token 'a b' --port 0", "--token"},
      {"serve " + capture + " --web " + (dir_ / "nowhere").string() + " --port 0", "index.html"},
      {"serve " + capture + " --lod 9 --port 0", "lod"},
      {"serve " + capture + " --position-bits 0 --port 0", "position-bits"},
      {"serve " + (dir_ / "missing").string() + " --port 0", "missing"},
  };
  for (const Case& c : cases) {
    const CommandResult r = run(c.args);
    EXPECT_NE(r.exit_code, 0) << c.args;
    EXPECT_EQ(line_count(r.err), 1) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.expected), std::string::npos) << c.args << "\n" << r.err;
  }
}

}  // namespace
}  // namespace zipfusion
