// A gtest fixture with a scratch directory of its own (named after the test, removed afterwards)
// and the path of an archive in it, for the format tests that write archives.
#pragma once
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <utility>

#include "archive_fixture.h"
#include "terrain/archive_reader.h"
#include "test_data.h"

namespace terrain::test {

class ScratchArchiveTest : public ::testing::Test {
 protected:
  explicit ScratchArchiveTest(std::string file_name = "a.terrain") : file_name_(std::move(file_name)) {}
  void SetUp() override {
    dir_ = scratch_dir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    path_ = (dir_ / file_name_).string();
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  // Writes the seed chain (write_seed_archive kind 1: the plane with a hole, finest node 0/4/3)
  // to path_ and opens it in reader_.
  void open_seed_chain() {
    ASSERT_TRUE(write_seed_archive(path_, 1).ok());
    ASSERT_TRUE(reader_.open(path_).ok());
  }
  std::filesystem::path dir_;
  std::string path_;
  ArchiveReader reader_;

 private:
  std::string file_name_;
};

}  // namespace terrain::test
