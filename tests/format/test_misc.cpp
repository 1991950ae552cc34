// BC1/BC3 block decoders, the progress callback, error names and TERRAIN_TRY, and verify() naming the
// first bad node.
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>

#include "archive_fixture.h"
#include "scratch_archive_test.h"
#include "terrain/bc_decode.h"
#include "terrain/progress.h"
#include "test_data.h"

namespace terrain {
namespace {

TEST(BcDecode, Bc1FourColourModeInterpolatesAndIsOpaque) {
  // colour0 = pure red (0xF800) > colour1 = pure blue (0x001F); indices 0,1,2,3 in row 0.
  const uint8_t block[8] = {0x00, 0xF8, 0x1F, 0x00, 0b11100100, 0, 0, 0};
  uint8_t px[64];
  decode_bc1_block(block, px);
  EXPECT_EQ(px[0], 255);  // index 0: red
  EXPECT_EQ(px[2], 0);
  EXPECT_EQ(px[4 + 2], 255);  // index 1: blue
  EXPECT_EQ(px[8 + 0], 170);  // index 2: (2*255 + 0 + 1) / 3
  EXPECT_EQ(px[8 + 2], 85);
  EXPECT_EQ(px[12 + 0], 85);  // index 3: (255 + 2*0 + 1) / 3
  for (int p = 0; p < 16; ++p) EXPECT_EQ(px[4 * p + 3], 255);
}

TEST(BcDecode, Bc1ThreeColourModeMakesIndex3TransparentBlack) {
  // colour0 (blue 0x001F) <= colour1 (red 0xF800): punch-through mode.
  const uint8_t block[8] = {0x1F, 0x00, 0x00, 0xF8, 0b11100100, 0xFF, 0, 0};
  uint8_t px[64];
  decode_bc1_block(block, px);
  EXPECT_EQ(px[8 + 0], 128);  // index 2: (0 + 255 + 1) / 2
  EXPECT_EQ(px[8 + 2], 128);
  EXPECT_EQ(px[8 + 3], 255);
  for (int c = 0; c < 4; ++c) EXPECT_EQ(px[12 + c], 0);  // index 3: transparent black
  for (int p = 4; p < 8; ++p) EXPECT_EQ(px[4 * p + 3], 0);  // row 1: all index 3
  EXPECT_EQ(bc1_texel_alpha(block, 1, 3, 0), 0);
  EXPECT_EQ(bc1_texel_alpha(block, 1, 2, 0), 255);
  EXPECT_EQ(bc1_texel_alpha(block, 1, 0, 1), 0);
  // Equal endpoints are also the 3-colour mode.
  const uint8_t equal[8] = {0x34, 0x12, 0x34, 0x12, 0xFF, 0xFF, 0xFF, 0xFF};
  decode_bc1_block(equal, px);
  EXPECT_EQ(px[3], 0);
}

TEST(BcDecode, Bc3AlphaUsesEightAndSixValueModes) {
  uint8_t block[16] = {};
  block[0] = 255;  // a0 > a1: 8 values
  block[1] = 0;
  // texel 0 index 0 (255), texel 1 index 1 (0), texel 2 index 2 ((6*255 + 0 + 3)/7 = 219)
  const uint64_t bits = (0u << 0) | (1u << 3) | (2u << 6) | (7u << 9);
  for (int i = 0; i < 6; ++i) block[2 + i] = uint8_t(bits >> (8 * i));
  block[8] = 0x00;  // colour block: c0 = 0 <= c1 = 0, but BC3 colour is always 4-colour
  uint8_t px[64];
  decode_bc3_block(block, px);
  EXPECT_EQ(px[3], 255);
  EXPECT_EQ(px[7], 0);
  EXPECT_EQ(px[11], 219);
  EXPECT_EQ(px[15], (1 * 255 + 6 * 0 + 3) / 7);
  for (int p = 0; p < 16; ++p) EXPECT_EQ(px[4 * p + 0], 0);  // colour opaque black, never "transparent"
  block[0] = 10;  // a0 <= a1: 6 values, then 0 and 255
  block[1] = 60;
  const uint64_t bits6 = (6u << 0) | (7u << 3) | (2u << 6);
  for (int i = 0; i < 6; ++i) block[2 + i] = uint8_t(bits6 >> (8 * i));
  decode_bc3_block(block, px);
  EXPECT_EQ(px[3], 0);
  EXPECT_EQ(px[7], 255);
  EXPECT_EQ(px[11], (4 * 10 + 1 * 60 + 2) / 5);
}

TEST(BcDecode, ImageLayoutFollowsBlockRows) {
  // Two blocks side by side, second block row: image row 4..7.
  std::vector<uint8_t> blocks(2 * 2 * 8, 0);
  blocks[3 * 8 + 1] = 0xF8;  // block (1, 1): colour0 red, opaque, index 0 everywhere
  std::vector<uint8_t> rgba(8 * 8 * 4);
  decode_bc1_image(blocks.data(), 2, 2, rgba.data());
  EXPECT_EQ(rgba[(5 * 8 + 6) * 4 + 0], 255);  // pixel (6, 5) is in block (1, 1)
  EXPECT_EQ(rgba[(1 * 8 + 6) * 4 + 0], 0);    // pixel (6, 1) is in block (1, 0)
}

TEST(Progress, ScaledProgressMapsAndCancels) {
  std::vector<double> seen;
  ProgressFn parent = [&](double f, std::string_view) {
    seen.push_back(f);
    return f < 0.7;
  };
  ProgressFn sub = scaled_progress(parent, 0.5, 0.75);
  EXPECT_TRUE(sub(0.0, "a"));
  EXPECT_TRUE(sub(0.5, "a"));
  EXPECT_FALSE(sub(1.0, "a"));  // 0.75 >= 0.7: the parent cancels
  EXPECT_TRUE(sub(2.0, "a") == false);  // clamped to 1
  ASSERT_EQ(seen.size(), 4u);
  EXPECT_DOUBLE_EQ(seen[1], 0.625);
  EXPECT_TRUE(scaled_progress(nullptr, 0, 1)(0.5, "x"));
}

TEST(Status, NamesAreStableAndMessagesCarryThem) {
  EXPECT_STREQ(error_name(Error::payload_checksum), "payload_checksum");
  EXPECT_STREQ(error_name(Error::unsupported_version), "unsupported_version");
  EXPECT_EQ(int(Error::directory_invalid), 304);
  EXPECT_EQ(Status::failure(Error::truncated, "x.terrain: short").to_string(), "truncated: x.terrain: short");
  EXPECT_EQ(Status::success().to_string(), "ok");
}

// TERRAIN_TRY evaluates its expression once, returns a failure unchanged and goes on after success.
TEST(Status, TryReturnsTheFirstFailureAndGoesOnWhenOk) {
  int calls = 0;
  const auto step = [&](Status s) {
    ++calls;
    return s;
  };
  bool finished = false;
  const auto run = [&](Status first, Status second) -> Status {
    finished = false;
    TERRAIN_TRY(step(first));
    TERRAIN_TRY(step(second));
    finished = true;
    return Status::success();
  };
  EXPECT_TRUE(run({}, {}).ok());
  EXPECT_EQ(calls, 2);
  EXPECT_TRUE(finished);

  calls = 0;
  Status st = run(Status::failure(Error::io_read, "a.terrain: short read"), {});
  EXPECT_EQ(st.code, Error::io_read);
  EXPECT_EQ(st.message, "a.terrain: short read");
  EXPECT_EQ(calls, 1) << "the second step is not run";
  EXPECT_FALSE(finished);

  calls = 0;
  st = run({}, Status::failure(Error::payload_checksum, "node 3/1/2"));
  EXPECT_EQ(st.to_string(), "payload_checksum: node 3/1/2");
  EXPECT_EQ(calls, 2);
  EXPECT_FALSE(finished);

  // One statement: an if without braces and its else keep their meaning.
  const auto branch = [&](bool check, Status s) -> Status {
    if (check)
      TERRAIN_TRY(step(s));
    else
      return Status::failure(Error::internal, "else");
    return Status::success();
  };
  calls = 0;
  EXPECT_EQ(branch(true, Status::failure(Error::no_data, "x")).code, Error::no_data);
  EXPECT_TRUE(branch(true, {}).ok());
  EXPECT_EQ(branch(false, {}).message, "else");
  EXPECT_EQ(calls, 2);
}

// verify() reads everything and names the first node that breaks a promise of the directory.
class Verify : public test::ScratchArchiveTest {
 protected:
  // Writes the seed chain with `mutate` applied to node `victim` before encoding.
  Status write_with(const NodeKey& victim, const std::function<void(test::BuiltNode&)>& mutate) {
    WorldInfo w = test::make_world(1, 1);
    const auto keys = test::close_tree({{0, 4, 3}});
    ArchiveWriter writer;
    TERRAIN_TRY(writer.open(path_));
    std::vector<uint8_t> payload;
    for (const NodeKey& k : keys) {
      test::BuiltNode n = test::make_seed_node(w, k);
      n.record.child_mask = test::child_mask_of(keys, k);
      if (k == victim) mutate(n);
      TERRAIN_TRY(encode_node_payload(*n.data, {}, payload));
      TERRAIN_TRY(writer.add_node(n.record, payload));
    }
    return writer.finish(w);
  }
  Status verify_result() {
    ArchiveReader reader;
    TERRAIN_TRY(reader.open(path_));
    return reader.verify();
  }
};

TEST_F(Verify, HeightOutsideMinMax) {
  ASSERT_TRUE(write_with({2, 1, 0}, [](test::BuiltNode& n) { n.record.max_height -= 64; }).ok());
  const Status s = verify_result();
  EXPECT_EQ(s.code, Error::payload_invalid);
  EXPECT_NE(s.message.find("node 2/1/0"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("max_height"), std::string::npos) << s.message;
}

TEST_F(Verify, HasHolesFlagDisagreesWithAlbedoAlpha) {
  ASSERT_TRUE(write_with({0, 4, 3}, [](test::BuiltNode& n) { n.record.flags = 0; }).ok());
  const Status s = verify_result();
  EXPECT_EQ(s.code, Error::payload_invalid);
  EXPECT_NE(s.message.find("node 0/4/3"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("has_holes"), std::string::npos) << s.message;
}

TEST_F(Verify, SharedVertexDiffersFromTheParent) {
  // Raise one even vertex (coincides with a parent vertex) by one step.
  ASSERT_TRUE(write_with({1, 2, 1}, [](test::BuiltNode& n) {
                n.data->heights[size_t(100 * kHeightSamples + 100)] += 1;
                n.record.max_height += 64;
              }).ok());
  const Status s = verify_result();
  EXPECT_EQ(s.code, Error::payload_invalid);
  EXPECT_NE(s.message.find("node 1/2/1"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("parent 2/1/0"), std::string::npos) << s.message;
}

TEST_F(Verify, SplatIdOutsideThePalette) {
  ASSERT_TRUE(write_with({3, 0, 0}, [](test::BuiltNode& n) { n.data->splat[17] = 3; }).ok());
  const Status s = verify_result();
  EXPECT_EQ(s.code, Error::payload_invalid);
  EXPECT_NE(s.message.find("node 3/0/0"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("material 3"), std::string::npos) << s.message;
}

}  // namespace
}  // namespace terrain
