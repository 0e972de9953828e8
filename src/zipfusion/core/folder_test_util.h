#pragma once
//! \file
//! A test fixture with a folder of its own (header only, for tests).

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

namespace zipfusion {

//! `dir_`: <temp>/<prefix><test name>, empty when the test starts and removed after it.
class FolderTest : public ::testing::Test {
 protected:
  explicit FolderTest(const std::string& prefix)
      : dir_(std::filesystem::temp_directory_path() / (prefix + ::testing::UnitTest::GetInstance()->current_test_info()->name())) {}

  void SetUp() override {
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::filesystem::path dir_;
};

}  // namespace zipfusion
