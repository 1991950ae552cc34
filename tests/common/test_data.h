// Where tests find the shared real DEMs: $TERRAIN_DATA_DIR, else ../shared/data beside the
// checkout (fixed at configure time). Tests that need a file call TERRAIN_REQUIRE_DATA(path),
// which skips the test with a message naming the missing file.
#pragma once
#include <cstdlib>
#include <filesystem>
#include <string>

#include <unistd.h>

namespace terrain::test {

inline std::filesystem::path data_dir() {
  if (const char* env = std::getenv("TERRAIN_DATA_DIR"); env && *env) return env;
  return TERRAIN_DEFAULT_DATA_DIR;
}
inline std::filesystem::path data_file(const std::string& name) { return data_dir() / name; }
inline std::filesystem::path bin_dir() { return TERRAIN_BIN_DIR; }
inline std::filesystem::path source_dir() { return TERRAIN_SOURCE_DIR; }

// A fresh, empty scratch folder for one test, under the build tree (<build>/test-scratch), so a
// test run leaves nothing in /tmp and `rm -rf build` removes everything it wrote.
inline std::filesystem::path scratch_dir(const std::string& test_name) {
  auto dir = std::filesystem::path(TERRAIN_TEST_SCRATCH_DIR) /
             (test_name + "-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace terrain::test

#define TERRAIN_REQUIRE_DATA(path)                                                                   \
  do {                                                                                               \
    if (!std::filesystem::exists(path))                                                              \
      GTEST_SKIP() << "real data not found: " << (path)                                              \
                   << " (set TERRAIN_DATA_DIR to the folder of the shared DEMs)";                   \
  } while (0)
