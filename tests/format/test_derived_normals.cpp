// Normals codec 4 (SPEC 16.7): the texels rebuilt from the heights, the one BC3 encoder every
// reader uses, the payload round trip and the archive-level rule (only with the derived_normals record).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>

#include "archive_fixture.h"
#include "scratch_archive_test.h"
#include "terrain/archive_layout.h"
#include "terrain/derived_normals.h"
#include "terrain/surface_contract.h"

namespace terrain {
namespace {

NormalsDerivation sample_derivation(uint32_t seed, float rise) {
  std::mt19937 rng(seed);
  NormalsDerivation d;
  d.rise_per_unit = rise;
  for (auto& b : d.apron) b = uint8_t(1 + rng() % 255);
  for (auto& q : d.ao) q = uint8_t(rng() % 32);
  return d;
}

// Texel (t, u) of a 132 x 132 RGBA8 image decoded from 33 x 33 BC3 blocks.
std::vector<uint8_t> decode_texels(const uint8_t* bc3) {
  std::vector<uint8_t> rgba(size_t(kTexels) * kTexels * 4);
  decode_bc3_image(bc3, kTexelBlocks, kTexelBlocks, rgba.data());
  return rgba;
}

TEST(DerivedNormals, PlaneTexelsAreExactBeforeBlocksAndWithinOneStepAfter) {
  // A plane r = 3 i + 5 j (units) at rise 1/16 m per unit per spacing: gradient (3/16, 5/16).
  std::vector<uint16_t> h(static_cast<size_t>(kHeightCount));
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) h[size_t(j * kHeightSamples + i)] = uint16_t(1000 + 3 * i + 5 * j);
  const NormalsDerivation d = sample_derivation(1, 1.0f / 16.0f);
  std::vector<uint8_t> rgba(size_t(kTexels) * kTexels * 4);
  derive_normal_texels(h.data(), nullptr, d, rgba.data());
  const double gx = 3.0 / 16.0, gy = 5.0 / 16.0, len = std::sqrt(gx * gx + gy * gy + 1.0);
  const uint8_t x8 = normal_texel_of(float(-gx / len)), y8 = normal_texel_of(float(-gy / len));
  std::vector<uint8_t> bc3(kNormalsBytes);
  encode_derived_normals_bc3(rgba.data(), bc3.data());
  const std::vector<uint8_t> decoded = decode_texels(bc3.data());
  for (int u = kApron; u < kTexels - kApron; ++u)
    for (int t = kApron; t < kTexels - kApron; ++t) {
      const uint8_t* px = &rgba[4 * size_t(u * kTexels + t)];
      ASSERT_EQ(px[3], x8) << t << "," << u;
      ASSERT_EQ(px[1], y8) << t << "," << u;
      // A block of one value: alpha exact; G within one 6-bit step (4 of 255) of the value.
      const uint8_t* dx = &decoded[4 * size_t(u * kTexels + t)];
      if (t >= 4 && t < 128 && u >= 4 && u < 128) {  // blocks with no apron texel
        EXPECT_EQ(dx[3], x8);
        EXPECT_LE(std::abs(int(dx[1]) - int(y8)), 2) << t << "," << u;
      }
    }
}

TEST(DerivedNormals, ApronAndAoComeFromTheRecordAoExactAfterBlocks) {
  std::vector<uint16_t> h(static_cast<size_t>(kHeightCount), 7);
  const NormalsDerivation d = sample_derivation(2, 0.25f);
  std::vector<uint8_t> rgba(size_t(kTexels) * kTexels * 4);
  derive_normal_texels(h.data(), nullptr, d, rgba.data());
  std::vector<uint8_t> bc3(kNormalsBytes);
  encode_derived_normals_bc3(rgba.data(), bc3.data());
  const std::vector<uint8_t> decoded = decode_texels(bc3.data());
  size_t at = 0;
  for (int u = 0; u < kTexels; ++u)
    for (int t = 0; t < kTexels; ++t) {
      const size_t k = 4 * size_t(u * kTexels + t);
      const int q = d.ao[size_t((u / 4) * kTexelBlocks + t / 4)];
      EXPECT_EQ(rgba[k + 0], (q << 3) | (q >> 2));
      EXPECT_EQ(decoded[k + 0], (q << 3) | (q >> 2)) << "AO must survive BC3 exactly";
      EXPECT_EQ(decoded[k + 2], 0);
      const bool apron = t < 2 || t >= 130 || u < 2 || u >= 130;
      if (apron) {
        EXPECT_EQ(rgba[k + 3], d.apron[at++]);
        EXPECT_EQ(rgba[k + 1], d.apron[at++]);
      } else {  // flat: the up normal
        EXPECT_EQ(rgba[k + 3], 128);
        EXPECT_EQ(rgba[k + 1], 128);
      }
    }
  EXPECT_EQ(at, d.apron.size());
}

TEST(DerivedNormals, EncoderPicksTheNearestEntryOfItsPalette) {
  // Random texels: every decoded alpha and G value is the nearest entry of its block's palette.
  std::mt19937 rng(3);
  std::vector<uint8_t> rgba(size_t(kTexels) * kTexels * 4);
  for (size_t k = 0; k < rgba.size(); k += 4) {
    rgba[k + 0] = 0;
    rgba[k + 1] = uint8_t(60 + rng() % 120);
    rgba[k + 2] = 0;
    rgba[k + 3] = uint8_t(40 + rng() % 160);
  }
  std::vector<uint8_t> bc3(kNormalsBytes);
  encode_derived_normals_bc3(rgba.data(), bc3.data());
  for (int b = 0; b < kTexelBlocks * kTexelBlocks; ++b) {
    const uint8_t* blk = &bc3[16 * size_t(b)];
    uint8_t alpha_palette[8], block[16], probe[64];
    std::copy(blk, blk + 16, block);
    // Entries of the alpha palette: indices 0..7 on the first 8 texels.
    uint64_t bits = 0;
    for (int i = 0; i < 8; ++i) bits |= uint64_t(i) << (3 * i);
    for (int i = 0; i < 6; ++i) block[2 + i] = uint8_t(bits >> (8 * i));
    for (int i = 0; i < 4; ++i) block[12 + i] = uint8_t(i == 0 ? 0xE4 : 0);  // colour indices 0,1,2,3
    decode_bc3_block(block, probe);
    for (int i = 0; i < 8; ++i) alpha_palette[i] = probe[4 * i + 3];
    uint8_t decoded[64];
    decode_bc3_block(blk, decoded);
    const int bx = b % kTexelBlocks, by = b / kTexelBlocks;
    for (int p = 0; p < 16; ++p) {
      const uint8_t* src = &rgba[4 * size_t((by * 4 + p / 4) * kTexels + bx * 4 + p % 4)];
      for (int e = 0; e < 8; ++e) ASSERT_LE(std::abs(decoded[4 * p + 3] - src[3]), std::abs(alpha_palette[e] - src[3]));
      for (int e = 0; e < 4; ++e) ASSERT_LE(std::abs(decoded[4 * p + 1] - src[1]), std::abs(probe[4 * e + 1] - src[1]));
    }
  }
}

TEST(DerivedNormals, VectorEncoderWritesTheReferenceBytes) {
  // Images of every spread from flat to full range, AO constant per block as the layout has it.
  std::mt19937 rng(9);
  std::vector<uint8_t> rgba(size_t(kTexels) * kTexels * 4), fast(kNormalsBytes), reference(kNormalsBytes);
  for (int spread = 1; spread <= 256; spread += 5) {
    for (int u = 0; u < kTexels; ++u)
      for (int t = 0; t < kTexels; ++t) {
        uint8_t* px = &rgba[4 * size_t(u * kTexels + t)];
        const uint32_t q = (uint32_t(t / 4) * 7 + uint32_t(u / 4) * 3) % 32;
        px[0] = uint8_t((q << 3) | (q >> 2));
        px[1] = uint8_t(std::clamp(128 + int(rng() % uint32_t(spread)) - spread / 2, 1, 255));
        px[2] = 0;
        px[3] = uint8_t(std::clamp(100 + int(rng() % uint32_t(spread)) - spread / 3, 1, 255));
      }
    encode_derived_normals_bc3(rgba.data(), fast.data());
    encode_derived_normals_bc3_reference(rgba.data(), reference.data());
    ASSERT_EQ(fast, reference) << "spread " << spread;
  }
}

TEST(DerivedNormals, HoleCornersUseTheEdgesThatHaveBoth) {
  // r = 10 i (east slope) with vertex (5, 5) a hole: cell (5, 5) keeps the x gradient from its
  // north edge (both corners present) and its y gradient from its east edge.
  std::vector<uint16_t> h(static_cast<size_t>(kHeightCount));
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) h[size_t(j * kHeightSamples + i)] = uint16_t(100 + 10 * i);
  std::vector<uint8_t> holes(static_cast<size_t>(kHeightCount), 0);
  holes[size_t(5 * kHeightSamples + 5)] = 1;
  h[size_t(5 * kHeightSamples + 5)] = 60000;  // a hole's height is never read
  const NormalsDerivation d = sample_derivation(4, 0.1f);
  std::vector<uint8_t> with(size_t(kTexels) * kTexels * 4), plane(with.size());
  derive_normal_texels(h.data(), holes.data(), d, with.data());
  h[size_t(5 * kHeightSamples + 5)] = uint16_t(150);
  derive_normal_texels(h.data(), nullptr, d, plane.data());
  EXPECT_EQ(with, plane);
}

// The payload of a node whose normals are codec 4.
std::vector<uint8_t> derived_payload(const NodeData& data, const NormalsDerivation& d) {
  std::vector<uint8_t> out;
  EXPECT_TRUE(encode_node_payload(data, PayloadOptions{}, out, nullptr, &d).ok());
  return out;
}

TEST(DerivedNormals, PayloadRoundTripsToWhatTheReaderDerives) {
  const WorldInfo w = test::make_world(1, 1);
  test::BuiltNode n = test::make_synthetic_node(w, NodeKey{5, 0, 0}, 5);  // bumpy heights, a round hole
  const NormalsDerivation d = sample_derivation(5, 1.0f / 512.0f);
  const std::vector<uint8_t> payload = derived_payload(*n.data, d);
  EXPECT_EQ(payload[4 + 12 + 1], uint8_t(layout::Codec::normals_derived));
  // Expected: the texels from the node's heights and the hole mask of its albedo.
  std::vector<uint8_t> holes(static_cast<size_t>(kHeightCount));
  ASSERT_GT(decode_hole_mask(*n.data, holes.data()), 0);
  std::vector<uint8_t> rgba(size_t(kTexels) * kTexels * 4), expected(kNormalsBytes);
  derive_normal_texels(n.data->heights.data(), holes.data(), d, rgba.data());
  encode_derived_normals_bc3(rgba.data(), expected.data());
  for (unsigned sections : {unsigned(kSectionNormals), unsigned(kSectionAll), unsigned(kSectionNormals | kSectionAlbedo)}) {
    auto out = std::make_unique<NodeData>();
    ASSERT_TRUE(decode_node_payload(payload, sections, *out).ok());
    EXPECT_TRUE(std::equal(expected.begin(), expected.end(), out->normals_bc3.begin())) << sections;
    if (!(sections & kSectionHeights)) {
      EXPECT_EQ(out->heights[0], 0) << "only the asked sections change";
    }
  }
  // Heights decoded alone are untouched by the normals' rule.
  auto h = std::make_unique<NodeData>();
  ASSERT_TRUE(decode_node_payload(payload, kSectionHeights, *h).ok());
  EXPECT_EQ(h->heights, n.data->heights);
}

TEST(DerivedNormals, MalformedRecordsAndCodecsAreRejected) {
  const WorldInfo w = test::make_world(1, 1);
  test::BuiltNode n = test::make_synthetic_node(w, NodeKey{5, 0, 0}, 6);
  NormalsDerivation d = sample_derivation(6, 0.5f);
  std::vector<uint8_t> out;
  d.rise_per_unit = NAN;
  EXPECT_FALSE(encode_node_payload(*n.data, PayloadOptions{}, out, nullptr, &d).ok());
  d.rise_per_unit = 2048.0f;  // past kMaxRisePerUnit: gradients could overflow
  EXPECT_FALSE(encode_node_payload(*n.data, PayloadOptions{}, out, nullptr, &d).ok());
  d.rise_per_unit = 0.5f;
  d.ao[7] = 32;
  EXPECT_FALSE(encode_node_payload(*n.data, PayloadOptions{}, out, nullptr, &d).ok());
  d.ao[7] = 3;
  std::vector<uint8_t> payload = derived_payload(*n.data, d);
  auto data = std::make_unique<NodeData>();
  // Codec 4 on another section (albedo: byte 4 + 2*12 + 1) is malformed.
  std::vector<uint8_t> bad = payload;
  bad[4 + 2 * 12 + 1] = uint8_t(layout::Codec::normals_derived);
  EXPECT_EQ(decode_node_payload(bad, kSectionAll, *data).code, Error::payload_invalid);
  bad = payload;
  bad[4 + 12 + 1] = 5;  // unknown codec
  EXPECT_EQ(decode_node_payload(bad, kSectionAll, *data).code, Error::payload_invalid);
  EXPECT_TRUE(decode_node_payload(payload, kSectionAll, *data).ok());
}

class DerivedNormalsArchive : public test::ScratchArchiveTest {};

// Writes one root whose normals are codec 4; `declare` sets the derived_normals record.
Status write_one_root(const std::string& path, bool declare, std::vector<uint8_t>& expected_normals) {
  WorldInfo w = test::make_world(1, 1);
  w.derived_normals = declare;
  test::BuiltNode n = test::make_synthetic_node(w, NodeKey{5, 0, 0}, 7);
  const NormalsDerivation d = sample_derivation(7, 1.0f / 512.0f);
  std::vector<uint8_t> payload = derived_payload(*n.data, d);
  auto decoded = std::make_unique<NodeData>();
  TERRAIN_TRY(decode_node_payload(payload, kSectionNormals, *decoded));
  expected_normals.assign(decoded->normals_bc3.begin(), decoded->normals_bc3.end());
  ArchiveWriter writer;
  TERRAIN_TRY(writer.open(path));
  TERRAIN_TRY(writer.add_node(n.record, payload));
  return writer.finish(w);
}

TEST_F(DerivedNormalsArchive, OnlyArchivesWithTheRecordMayUseCodec4) {
  std::vector<uint8_t> expected;
  const std::string with = (dir_ / "with.terrain").string(), without = (dir_ / "without.terrain").string();
  ASSERT_TRUE(write_one_root(with, true, expected).ok());
  ArchiveReader r;
  ASSERT_TRUE(r.open(with).ok());
  EXPECT_TRUE(r.world().derived_normals);
  EXPECT_EQ(r.format_version(), 3u);
  auto data = std::make_unique<NodeData>();
  ASSERT_TRUE(r.decode_node(0, *data).ok());
  EXPECT_TRUE(std::equal(expected.begin(), expected.end(), data->normals_bc3.begin()));

  ASSERT_TRUE(write_one_root(without, false, expected).ok());
  ArchiveReader r2;
  ASSERT_TRUE(r2.open(without).ok());
  EXPECT_FALSE(r2.world().derived_normals);
  const Status s = r2.decode_node(0, *data);
  EXPECT_EQ(s.code, Error::payload_invalid);
  EXPECT_NE(s.message.find("derived_normals"), std::string::npos) << s.message;
}

}  // namespace
}  // namespace terrain
