// Replays the cooker input fuzzer's generated seeds through its body (cooker/fuzz), with every
// prefix and a deterministic set of byte flips, so ctest (and the sanitizer run) checks the
// fuzz property: no crash, a named error or a consistent raster.
#include <gtest/gtest.h>

#include <filesystem>

#include "fuzz_cooker_inputs_body.h"

namespace {

TEST(FuzzCookerInputs, SeedsLoadAndMutantsFailCleanly) {
  const auto dir = std::filesystem::path(TERRAIN_BUILD_DIR) / "cooker-robust-scratch" / "fuzz-replay";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const auto seeds = terrain::fuzz::cooker_inputs_seeds(dir.string());
  ASSERT_EQ(seeds.size(), 7u);
  int loaded = 0;
  for (size_t s = 0; s < seeds.size(); ++s) {
    const auto& seed = seeds[s];
    EXPECT_LT(seed.size(), 16000u) << "seeds stay small";
    loaded += terrain::fuzz::cooker_inputs_one_input(seed.data(), seed.size(), dir.string());
    for (size_t n = 0; n < seed.size(); n += 1 + n / 8) {
      std::vector<uint8_t> prefix(seed.begin(), seed.begin() + std::ptrdiff_t(n));
      terrain::fuzz::cooker_inputs_one_input(prefix.data(), prefix.size(), dir.string());
    }
    for (size_t i = 3; i < seed.size(); i += 1 + seed.size() / 64) {
      std::vector<uint8_t> flipped = seed;
      flipped[i] ^= uint8_t(0x5a + i);
      terrain::fuzz::cooker_inputs_one_input(flipped.data(), flipped.size(), dir.string());
    }
  }
  EXPECT_EQ(loaded, int(seeds.size())) << "every seed is a valid input";
  std::filesystem::remove_all(dir);
}

}  // namespace
