// The build's absolute paths, compiled into this one file. As defines on every test they were in
// every test's compile command, so a clone at another path (CI's clean-clone stage, a second
// worktree) missed ccache on every test file (44 of 160 compiles here).
#include "test_data.h"

#include <unistd.h>

namespace terrain::test {

const char* configured_data_dir() { return TERRAIN_DEFAULT_DATA_DIR; }
std::filesystem::path bin_dir() { return TERRAIN_BIN_DIR; }
std::filesystem::path source_dir() { return TERRAIN_SOURCE_DIR; }
std::filesystem::path build_dir() { return TERRAIN_BUILD_DIR; }
std::filesystem::path test_archives_dir() {
  if (const char* env = std::getenv("TERRAIN_TEST_ARCHIVES"); env && *env) return env;
  return TERRAIN_TEST_ARCHIVES;
}

std::filesystem::path scratch_dir(const std::string& test_name) {
  auto dir = std::filesystem::path(TERRAIN_TEST_SCRATCH_DIR) / (test_name + "-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}
std::filesystem::path scratch_root() { return TERRAIN_TEST_SCRATCH_DIR; }

}  // namespace terrain::test
