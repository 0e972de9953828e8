#pragma once
// Test helper: runs the zipfusion binary (ZF_BINARY) in a fresh temporary folder per test and
// captures its exit code, standard output and standard error.

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "zipfusion/core/geometry.h"

namespace zipfusion::testing {

struct CommandResult {
  int exit_code = -1;
  std::string out, err;
};

class CliTest : public ::testing::Test {
 protected:
  std::filesystem::path dir_ = std::filesystem::temp_directory_path() /
                               ("zf_cli_" + std::string(::testing::UnitTest::GetInstance()->current_test_suite()->name()) + "_" +
                                ::testing::UnitTest::GetInstance()->current_test_info()->name());
  void SetUp() override {
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  //! Runs `zipfusion ARGS` with no standard input.
  CommandResult run(const std::string& args) {
    const std::string command = std::string(ZF_BINARY) + " " + args + " > " + (dir_ / "stdout").string() + " 2> " +
                                (dir_ / "stderr").string() + " < /dev/null";
    const int status = std::system(command.c_str());
    CommandResult r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    auto slurp = [](const std::filesystem::path& p) {
      std::ifstream in(p);
      std::stringstream s;
      s << in.rdbuf();
      return s.str();
    };
    r.out = slurp(dir_ / "stdout");
    r.err = slurp(dir_ / "stderr");
    return r;
  }
};

inline int line_count(const std::string& text) { return static_cast<int>(std::count(text.begin(), text.end(), '\n')); }

//! Every camera's pose in one of stats.json's pose_updates (`world_from_depth`, row-major 4×4 each).
inline std::vector<Rigid3d> poses_of_update(const nlohmann::json& update) {
  std::vector<Rigid3d> poses;
  for (const nlohmann::json& rows : update.at("world_from_depth")) {
    Eigen::Matrix4d m;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) m(i, j) = rows.at(i).at(j).get<double>();
    poses.emplace_back(m);
  }
  return poses;
}

}  // namespace zipfusion::testing
