// Replays the committed fuzz seeds (and any regression inputs) through the fuzz target's body, so
// every ctest run (and the sanitizer run) exercises the fuzz property on them.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "fuzz_archive_reader_body.h"
#include "test_data.h"

namespace {

std::vector<uint8_t> slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

TEST(FuzzArchiveReader, SeedsOpenAndReplayCleanly) {
  const auto dir = terrain::test::source_dir() / "tests/format/fuzz_seeds";
  int seeds = 0, opened = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    const auto bytes = slurp(entry.path());
    opened += terrain::fuzz::archive_reader_one_input(bytes.data(), bytes.size());
    ++seeds;
    // Every prefix of a seed (fresh allocation each, so ASan sees over-reads) must fail cleanly.
    for (size_t n = 0; n < bytes.size(); n += 1 + n / 16) {
      std::vector<uint8_t> prefix(bytes.begin(), bytes.begin() + std::ptrdiff_t(n));
      EXPECT_EQ(terrain::fuzz::archive_reader_one_input(prefix.data(), prefix.size()), 0) << entry.path() << " prefix " << n;
    }
  }
  EXPECT_GE(seeds, 2);
  EXPECT_EQ(opened, seeds) << "every committed seed is a valid archive";
}

}  // namespace
