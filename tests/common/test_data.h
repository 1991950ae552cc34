// Where tests find the shared real DEMs: $TERRAIN_DATA_DIR, else ../shared/data beside the
// checkout (fixed at configure time). Tests that need a file call TERRAIN_REQUIRE_DATA(path),
// which skips the test with a message naming the missing file.
#pragma once
#include <cstdlib>
#include <filesystem>
#include <string>

#include <unistd.h>


namespace terrain::test {

// The paths this build was configured with (tests/common/test_paths.cpp).
const char* configured_data_dir();                // ../shared/data beside the checkout, or -DTERRAIN_DATA_DIR
std::filesystem::path bin_dir();                  // <build>/bin
std::filesystem::path source_dir();               // the checkout
std::filesystem::path build_dir();                // <build>
std::filesystem::path test_archives_dir();        // $TERRAIN_TEST_ARCHIVES, else the cook_test_archives fixture's
std::filesystem::path scratch_root();             // <build>/test-scratch

inline std::filesystem::path data_dir() {
  if (const char* env = std::getenv("TERRAIN_DATA_DIR"); env && *env) return env;
  return configured_data_dir();
}
inline std::filesystem::path data_file(const std::string& name) { return data_dir() / name; }

// A fresh, empty scratch folder for one test, under the build tree (<build>/test-scratch), so a
// test run leaves nothing in /tmp and `rm -rf build` removes everything it wrote.
std::filesystem::path scratch_dir(const std::string& test_name);

}  // namespace terrain::test

#define TERRAIN_REQUIRE_DATA(path)                                                                   \
  do {                                                                                               \
    if (!std::filesystem::exists(path))                                                              \
      GTEST_SKIP() << "real data not found: " << (path)                                              \
                   << " (set TERRAIN_DATA_DIR to the folder of the shared DEMs)";                   \
  } while (0)
