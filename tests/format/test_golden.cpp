// Frozen bytes: the seed archives in tests/format/fuzz_seeds are regenerated and must match
// byte for byte (format drift shows at once). TERRAIN_UPDATE_GOLDEN=1 rewrites them. The legacy_*
// seeds are frozen files of older format versions (1 and 2, written before SPEC 20): every reader
// opens and verifies them, with the same nodes as today's file of the same archive.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "archive_fixture.h"
#include "test_data.h"

namespace terrain {
namespace {

std::vector<uint8_t> slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

void check_golden(const std::string& name, int kind) {
  const auto dir = test::scratch_dir("golden-" + name);
  const auto fresh = dir / name;
  ASSERT_TRUE(test::write_seed_archive(fresh.string(), kind).ok());
  const auto golden = test::source_dir() / "tests/format/fuzz_seeds" / name;
  const char* update = std::getenv("TERRAIN_UPDATE_GOLDEN");
  if (update && std::string(update) == "1") {
    std::filesystem::copy_file(fresh, golden, std::filesystem::copy_options::overwrite_existing);
  }
  ASSERT_TRUE(std::filesystem::exists(golden)) << golden << " is missing (run with TERRAIN_UPDATE_GOLDEN=1)";
  const auto a = slurp(fresh), b = slurp(golden);
  EXPECT_EQ(a.size(), b.size());
  const auto mismatch = std::mismatch(a.begin(), a.end(), b.begin(), b.end());
  EXPECT_TRUE(mismatch.first == a.end() && mismatch.second == b.end())
      << name << " differs from the golden file at byte " << (mismatch.first - a.begin());
  ArchiveReader reader;
  const Status s = reader.open(golden.string());
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_TRUE(reader.verify().ok());
  std::filesystem::remove_all(dir);
}

TEST(GoldenArchive, OneRootMatchesFrozenBytes) { check_golden("one_root.terrain", 0); }
TEST(GoldenArchive, SixLevelChainMatchesFrozenBytes) { check_golden("chain6.terrain", 1); }
TEST(GoldenArchive, PlainAndStoredCodecsMatchFrozenBytes) { check_golden("plain_codecs.terrain", 2); }
TEST(GoldenArchive, ConstantHeightsCodecMatchesFrozenBytes) { check_golden("constant_heights.terrain", 3); }
TEST(GoldenArchive, DerivedNormalsCodecMatchesFrozenBytes) { check_golden("derived_normals.terrain", 4); }

void check_legacy(const std::string& name, uint32_t version) {
  const auto seeds = test::source_dir() / "tests/format/fuzz_seeds";
  ArchiveReader old_file, new_file;
  const Status s = old_file.open((seeds / ("legacy_" + name)).string());
  ASSERT_TRUE(s.ok()) << s.to_string();
  ASSERT_TRUE(new_file.open((seeds / name).string()).ok());
  EXPECT_EQ(old_file.format_version(), version);
  EXPECT_EQ(new_file.format_version(), 3u);
  EXPECT_TRUE(old_file.verify().ok());
  ASSERT_EQ(old_file.nodes().size(), new_file.nodes().size());
  for (size_t i = 0; i < new_file.nodes().size(); ++i) {
    const NodeRecord &a = old_file.nodes()[i], &b = new_file.nodes()[i];
    EXPECT_EQ(a.key, b.key) << name << " node " << i;
    EXPECT_EQ(a.payload_offset, b.payload_offset) << name << " node " << i;
    EXPECT_EQ(a.payload_crc32, b.payload_crc32) << name << " node " << i;
  }
}
TEST(GoldenArchive, VersionOneAndTwoFilesReadLikeTodaysOnes) {
  check_legacy("one_root.terrain", 1);
  check_legacy("chain6.terrain", 1);
  check_legacy("derived_normals.terrain", 2);
}

}  // namespace
}  // namespace terrain
