// Height codec: exact round trip on adversarial grids, random grids and real DEM windows; the
// residual layout and the height_shift rule; decoding rejects wrong sizes.
#include <gtest/gtest.h>

#include <random>

#include "real_dem.h"
#include "terrain/archive_writer.h"
#include "terrain/height_codec.h"
#include "test_data.h"

namespace terrain {
namespace {

using Grid = std::vector<uint16_t>;

void expect_round_trip(const Grid& g, const char* what) {
  std::vector<uint8_t> res;
  heights_to_residuals(g, res);
  ASSERT_EQ(res.size(), 2u * kHeightCount) << what;
  Grid back(static_cast<size_t>(kHeightCount), 0x5555);
  ASSERT_TRUE(residuals_to_heights(res, back).ok()) << what;
  ASSERT_EQ(back, g) << what;
  // With the common shift the payload path must be exact too.
  const int shift = heights_common_shift(g);
  heights_to_residuals(g, shift, res);
  Grid back2(static_cast<size_t>(kHeightCount), 0x5555);
  ASSERT_TRUE(residuals_to_heights(res, shift, back2).ok()) << what;
  ASSERT_EQ(back2, g) << what << " (shift " << shift << ")";
  // And through a whole payload at two zstd levels.
  auto node = std::make_unique<NodeData>();
  std::copy(g.begin(), g.end(), node->heights.begin());
  for (int level : {1, 9}) {
    std::vector<uint8_t> payload;
    ASSERT_TRUE(encode_node_payload(*node, PayloadOptions{level, true}, payload).ok());
    auto out = std::make_unique<NodeData>();
    ASSERT_TRUE(decode_node_payload(payload, kSectionHeights, *out).ok());
    ASSERT_TRUE(std::equal(g.begin(), g.end(), out->heights.begin())) << what << " level " << level;
  }
}

Grid filled(uint16_t v) { return Grid(static_cast<size_t>(kHeightCount), v); }

TEST(HeightCodec, ExactOnConstantGrids) {
  expect_round_trip(filled(0), "all 0");
  expect_round_trip(filled(65535), "all 65535");
  expect_round_trip(filled(32768), "all 32768");
}

TEST(HeightCodec, ExactOnCheckerboardOfExtremes) {
  Grid g = filled(0);
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) g[size_t(j * kHeightSamples + i)] = ((i + j) & 1) ? 65535 : 0;
  expect_round_trip(g, "checkerboard 0/65535");
  for (auto& v : g) v = uint16_t(65535 - v);
  expect_round_trip(g, "inverted checkerboard");
}

TEST(HeightCodec, ExactOnStripesRampsAndSpikes) {
  Grid g = filled(0);
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) g[size_t(j * kHeightSamples + i)] = (i % 3 == 0) ? 65535 : 1;
  expect_round_trip(g, "stripes");
  for (int k = 0; k < kHeightCount; ++k) g[size_t(k)] = uint16_t(k * 4);
  expect_round_trip(g, "wrapping ramp");
  g = filled(65535);
  g[size_t(64 * kHeightSamples + 64)] = 0;
  g[0] = 0;
  expect_round_trip(g, "spikes");
}

TEST(HeightCodec, ExactOnRandomGrids) {
  std::mt19937 rng(12345);
  for (int t = 0; t < 20; ++t) {
    Grid g = filled(0);
    const unsigned mask = t < 10 ? 0xFFFFu : (0xFFFFu << (t - 10));  // later grids: idle low bits
    for (auto& v : g) v = uint16_t(rng() & mask);
    expect_round_trip(g, "random");
  }
}

TEST(HeightCodec, CommonShiftCountsSharedTrailingZeros) {
  Grid g = filled(0);
  EXPECT_EQ(heights_common_shift(g), 15);
  g[7] = 96;  // 0b1100000
  EXPECT_EQ(heights_common_shift(g), 5);
  g[8] = 65535;
  EXPECT_EQ(heights_common_shift(g), 0);
}

TEST(HeightCodec, ConstantGridGivesAllZeroResidualsAfterTheFirst) {
  std::vector<uint8_t> res;
  heights_to_residuals(filled(1234), res);
  // residual 0 is zigzag(1234) = 2468 = 0x09A4: low plane byte 0 = 0xA4, high plane byte 0 = 0x09.
  EXPECT_EQ(res[0], 0xA4);
  EXPECT_EQ(res[size_t(kHeightCount)], 0x09);
  EXPECT_EQ(std::count(res.begin(), res.end(), uint8_t(0)), std::ptrdiff_t(res.size() - 2));
}

TEST(HeightCodec, LinearRampIsPredictedExactlyInside) {
  // A plane is reproduced by the linear and cubic line predictions: only the first 4 codes
  // (corners) are non-zero.
  Grid g = filled(0);
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) g[size_t(j * kHeightSamples + i)] = uint16_t(100 + 3 * i + 5 * j);
  std::vector<uint8_t> res;
  heights_to_residuals(g, res);
  int nonzero = 0;
  for (int k = 0; k < kHeightCount; ++k) nonzero += (res[size_t(k)] | res[size_t(kHeightCount + k)]) ? 1 : 0;
  EXPECT_EQ(nonzero, 4);
}

TEST(HeightCodec, RejectsWrongResidualSize) {
  Grid g = filled(0);
  std::vector<uint8_t> res(2 * size_t(kHeightCount) - 1);
  EXPECT_EQ(residuals_to_heights(res, g).code, Error::payload_invalid);
  res.resize(2 * size_t(kHeightCount));
  EXPECT_EQ(residuals_to_heights(res, 16, g).code, Error::payload_invalid);
}

TEST(HeightCodec, ExactOnRealKilaueaWindows) {
  const auto path = test::data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(path);
  test::Dem dem;
  ASSERT_TRUE(test::read_dem(path.string(), -32768.0f, dem));
  int windows = 0;
  for (int y0 = 0; y0 + kHeightSamples <= dem.height; y0 += 96)
    for (int x0 = 0; x0 + kHeightSamples <= dem.width; x0 += 96) {
      // Quantize as the archive does at step 0 and step 5 (1 mm / 3 cm), nodata as 0.
      for (int step : {0, 5}) {
        Grid g = filled(0);
        for (int j = 0; j < kHeightSamples; ++j)
          for (int i = 0; i < kHeightSamples; ++i) {
            const float v = dem.values[size_t(y0 + j) * size_t(dem.width) + size_t(x0 + i)];
            const double units = std::isfinite(v) ? double(v) * 1024.0 / double(1 << step) : 0.0;
            g[size_t(j * kHeightSamples + i)] = uint16_t(std::clamp(std::lround(units), 0L, 65535L));
          }
        expect_round_trip(g, "kilauea window");
        ++windows;
      }
    }
  EXPECT_GE(windows, 40);
}

}  // namespace
}  // namespace terrain
