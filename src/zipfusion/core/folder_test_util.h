#pragma once
//! \file
//! A test fixture with a folder of its own (header only, for tests).

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include <unistd.h>

namespace zipfusion {

//! `dir_`: <temp>/<prefix><test name>_<process id>, empty when the test starts and removed after
//! it; the process id keeps two runs of the same test at once (two builds' ctest) apart.
class FolderTest : public ::testing::Test {
 protected:
  explicit FolderTest(const std::string& prefix)
      : dir_(std::filesystem::temp_directory_path() /
             (prefix + ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_" + std::to_string(::getpid()))) {}

  void SetUp() override {
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::filesystem::path dir_;
};

}  // namespace zipfusion
