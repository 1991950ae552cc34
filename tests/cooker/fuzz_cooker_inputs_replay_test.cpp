// Replays the cooker input fuzzer's generated seeds through its body (cooker/fuzz), with every
// prefix and a deterministic set of byte flips, so ctest (and the sanitizer run) checks the
// fuzz property: no crash, a named error or a consistent raster.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "fuzz_cooker_inputs_body.h"
#include "inputs/inputs.h"
#include "test_data.h"

namespace {

TEST(FuzzCookerInputs, SeedsLoadAndMutantsFailCleanly) {
  const auto dir = terrain::test::build_dir() / "cooker-robust-scratch" / "fuzz-replay";
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

// Found by fuzz_cooker_inputs in CI: an .npz whose only entry is not elevation.npy and whose
// central directory claims 4278190224 uncompressed bytes for 73 compressed ones. The "is the zip
// readable" probe allocated the claimed size (libFuzzer: out-of-memory). Memory must follow the bytes
// that really decompress: the read fails, and the buffer never grows past one read chunk.
TEST(FuzzCookerInputs, ForgedZipEntrySizeIsNotAnAllocation) {
  static const uint8_t kInput[] = {
    0x03, 0x00, 0x00, 0x50, 0x4b, 0x03, 0x04, 0x14, 0x02, 0x00, 0x00, 0x08, 0x00, 0x46, 0x03, 0x82, 0x5d,
    0x31, 0x03, 0xfe, 0xe9, 0x49, 0x00, 0x00, 0x00, 0x90, 0x00, 0x00, 0x00, 0x0d, 0x00, 0x00, 0x00, 0x65,
    0x6c, 0x65, 0x76, 0x61, 0x74, 0x69, 0x6f, 0x6e, 0x2e, 0x6e, 0x70, 0x79, 0x9b, 0xec, 0x17, 0xea, 0x1b,
    0x10, 0xc9, 0xc8, 0x50, 0xc6, 0x50, 0xad, 0x9e, 0x92, 0x5a, 0x9c, 0x5c, 0xa4, 0x6e, 0xa5, 0xa0, 0x6e,
    0xc0, 0x7b, 0x05, 0x00, 0x60, 0x60, 0x00, 0x00, 0x5f, 0x54, 0x52, 0x94, 0x98, 0x17, 0x9f, 0x5f, 0x94,
    0x92, 0x0a, 0x12, 0x77, 0x4b, 0xcc, 0x29, 0x4e, 0x05, 0x8a, 0x17, 0x67, 0x24, 0x16, 0xa4, 0x02, 0xf9,
    0x1a, 0x46, 0x3a, 0x0a, 0x46, 0x9a, 0x3a, 0x0a, 0xb5, 0x0a, 0x64, 0x03, 0x2e, 0x27, 0x38, 0x00, 0x00,
    0x50, 0x4b, 0x01, 0x02, 0x3f, 0x03, 0x14, 0x00, 0x02, 0x00, 0x08, 0x00, 0x46, 0x03, 0x82, 0x5d, 0x31,
    0x03, 0xfe, 0xe9, 0x49, 0x00, 0x00, 0x00, 0x90, 0x00, 0x00, 0xff, 0x0d, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xb6, 0x81, 0x00, 0x00, 0x00, 0x00, 0x65, 0x6c, 0x65, 0x76, 0x61,
    0x74, 0x69, 0x6f, 0x7e, 0x2e, 0x6e, 0x70, 0x79, 0x50, 0x4b, 0x05, 0x06, 0x00, 0x00, 0x00, 0x00, 0x01,
    0x00, 0x01, 0x00, 0x3b, 0x00, 0x00, 0x00, 0x74, 0x00, 0x00, 0x00, 0x00, 0x00};
  const auto dir = terrain::test::build_dir() / "cooker-robust-scratch" / "fuzz-forged-zip";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  EXPECT_EQ(terrain::fuzz::cooker_inputs_one_input(kInput, sizeof kInput, dir.string()), 0) << "refused, not loaded";

  const std::string zip = (dir / "forged.npz").string();
  std::ofstream(zip, std::ios::binary).write(reinterpret_cast<const char*>(kInput + 3), sizeof kInput - 3);
  std::vector<uint8_t> bytes;
  std::string entry;
  const terrain::Status st = terrain::cook::read_zip_entry(zip, ".npy", bytes, entry, uint64_t(1) << 33);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message.find("corrupt or truncated"), std::string::npos) << st.message;
  EXPECT_LE(bytes.capacity(), size_t(2) << 20) << "the header's 4 GB claim became an allocation";
  std::filesystem::remove_all(dir);
}

}  // namespace
