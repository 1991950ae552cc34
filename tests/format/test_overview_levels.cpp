// Overview levels above the roots (format/SPEC.md section 19, extension tag 2): written and read
// back, crack-free against the roots (verify), and every rule of the section rejected with its code.
#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>

#include "scratch_archive_test.h"
#include "synthetic_archive.h"
#include "archive_bytes.h"
#include "terrain/archive_layout.h"
#include "terrain/archive_reader.h"
#include "terrain/archive_writer.h"
#include "terrain/surface_contract.h"
#include "test_data.h"

namespace terrain {
namespace {

using namespace test;  // archive_bytes.h: slurp, get/put_u32/u64, crc, reseal

// 20 x 20 roots, roots only (min_level 5): the synthetic roots are crack-free among themselves,
// so verify() checks the overview levels' shared vertices against them. 20 -> 10 -> 5 -> 3: K = 3.
synthetic::Spec overview_spec() {
  synthetic::Spec s;
  s.roots_x = s.roots_y = 20;
  s.root_fill = 0.6;
  s.min_level = 5;
  s.overview_levels = -1;
  return s;
}

// Writes `nodes` (any order) with `world`; returns the writer's status. `ordered`: in the payload
// order of SPEC 18 and 19 (5 first, towards 0, then 6 upward), by the ordered (streaming) writer.
Status write_nodes(const std::string& path, const WorldInfo& world, std::vector<synthetic::Node> nodes, bool ordered = false) {
  ArchiveWriter writer;
  std::vector<uint8_t> payload;
  PayloadOptions options;
  options.zstd_level = synthetic::Spec{}.zstd_level;  // as synthetic::write_archive() writes
  if (ordered) {
    std::sort(nodes.begin(), nodes.end(), [&](const synthetic::Node& a, const synthetic::Node& b) {
      const NodeKey &x = a.record.key, &y = b.record.key;
      return x.level != y.level ? payload_order_rank(x.level) < payload_order_rank(y.level) : key_less(x, y);
    });
    ArchiveShape shape;
    for (const synthetic::Node& n : nodes) {
      TERRAIN_TRY(encode_node_payload(n.data, options, payload));
      ++shape.level_nodes[n.record.key.level];
      shape.payload_bytes += payload.size();
    }
    TERRAIN_TRY(writer.open_ordered(path, shape));
  } else {
    TERRAIN_TRY(writer.open(path));
  }
  for (const synthetic::Node& n : nodes) {
    TERRAIN_TRY(encode_node_payload(n.data, options, payload));
    TERRAIN_TRY(writer.add_node(n.record, payload));
  }
  return writer.finish(world);
}

class OverviewLevels : public test::ScratchArchiveTest {
 protected:
  void SetUp() override {
    ScratchArchiveTest::SetUp();
    world_ = synthetic::make_world(overview_spec());
    // The synthetic key marker puts ids up to 255 into the splat: a full palette keeps verify()
    // on the heights.
    world_.world.palette.resize(256);
    path_ = (dir_ / "overview.terrain").string();  // the fixture's own path_, reused
    ASSERT_TRUE(write_nodes(path_, world_.world, world_.nodes).ok());
    good_ = slurp(path_);
    meta_ = size_t(get_u64(good_, layout::header::metadata_offset));
    ext_ = good_.size() - get_u32(good_, meta_ + layout::metadata::extension_size);
  }
  // Opens good_ (or its version-`legacy` bytes, legacy_bytes()) changed by `mutate`, re-sealed.
  Error open_with(const std::function<void(std::vector<uint8_t>&)>& mutate, std::string* message = nullptr,
                  uint32_t legacy = 0) {
    std::vector<uint8_t> b = legacy ? legacy_bytes(good_, legacy) : good_;
    mutate(b);
    reseal(b);
    ArchiveReader r;
    const Status s = r.open_memory(b);
    if (message) *message = s.message;
    return s.code;
  }
  // The writer's verdict on the world's nodes after `edit` (ordered_: the ordered writer's).
  Status write_edited(const std::function<void(WorldInfo&, std::vector<synthetic::Node>&)>& edit) {
    synthetic::World w = world_;
    edit(w.world, w.nodes);
    return write_nodes((dir_ / "edited.terrain").string(), w.world, w.nodes, ordered_);
  }
  bool ordered_ = false;
  void check_directory_rules();
  size_t first_of_level(uint32_t level) const {
    const auto& n = world_.nodes;
    return size_t(std::find_if(n.begin(), n.end(), [&](const synthetic::Node& x) { return x.record.key.level == level; }) - n.begin());
  }
  synthetic::World world_;
  std::vector<uint8_t> good_;
  size_t meta_ = 0, ext_ = 0;
};

TEST_F(OverviewLevels, NeededLevelsKeepTheTopSmall) {
  EXPECT_EQ(overview_levels_needed(4, 4), 0);
  EXPECT_EQ(overview_levels_needed(5, 4), 1);  // 20 roots > 16: one level of 3 x 2
  EXPECT_EQ(overview_levels_needed(20, 20), 3);
  EXPECT_EQ(overview_levels_needed(100, 100), 5);  // 100 -> 50 -> 25 -> 13 -> 7 -> 4
  EXPECT_EQ(overview_levels_needed(317, 317), 7);
  EXPECT_EQ(overview_levels_needed(65536, 65536), 14);
  EXPECT_EQ(level_grid_cells(20, 6), 10u);
  EXPECT_EQ(level_grid_cells(21, 6), 11u);  // ceil: an overview node may reach past the root grid
  EXPECT_EQ(level_grid_cells(20, 8), 3u);
  EXPECT_EQ(level_grid_cells(20, 4), 40u);
}

TEST_F(OverviewLevels, RoundTripAndVerify) {
  ArchiveReader r;
  ASSERT_TRUE(r.open(path_).ok());
  EXPECT_EQ(r.format_version(), 3u);
  EXPECT_EQ(r.level_count(), 9);
  EXPECT_EQ(r.top_level(), 8);
  EXPECT_EQ(r.world().overview_step_log2, (std::vector<uint8_t>{7, 7, 7}));
  EXPECT_EQ(level_step_log2(r.world(), 8), 7);
  // The record on disk: tag 2, size 1 + K, K, the steps, zero padding.
  EXPECT_EQ(get_u32(good_, ext_), layout::kExtensionOverviewLevels);
  EXPECT_EQ(get_u32(good_, ext_ + 4), 4u);
  EXPECT_EQ(good_[ext_ + 8], 3);
  const auto per_level = r.nodes_per_level();
  ASSERT_EQ(per_level.size(), 9u);
  std::vector<uint32_t> expected(9);
  for (const synthetic::Node& n : world_.nodes) ++expected[n.record.key.level];
  EXPECT_EQ(per_level, expected);
  EXPECT_EQ(per_level[6], 97u);  // 3 of the 100 2 x 2 blocks of 60 % filled roots are empty (seed 1)
  EXPECT_EQ(per_level[7], 25u);
  EXPECT_EQ(per_level[8], 9u);
  EXPECT_EQ(r.level_nodes(8).size(), 9u);
  EXPECT_EQ(r.level_nodes(8).front().key, (NodeKey{8, 0, 0}));
  EXPECT_TRUE(r.level_nodes(9).empty());
  EXPECT_GE(r.find({8, 2, 2}), 0);
  EXPECT_EQ(r.find({9, 0, 0}), -1);
  // Every node round-trips, and every root has its level-6 parent.
  for (const synthetic::Node& n : world_.nodes) {
    const int64_t i = r.find(n.record.key);
    ASSERT_GE(i, 0) << node_name(n.record.key);
    EXPECT_EQ(r.nodes()[size_t(i)].child_mask, n.record.child_mask);
    EXPECT_EQ(r.nodes()[size_t(i)].min_height, n.record.min_height);
    if (n.record.key.level == uint32_t(kRootLevel)) {
      EXPECT_GE(r.find(parent_of(n.record.key)), 0);
    }
  }
  // verify(): shared vertices of roots and level 6, 6 and 7, 7 and 8 and within each level agree;
  // holes where no root holds a point are flagged.
  const Status v = r.verify();
  EXPECT_TRUE(v.ok()) << v.to_string();
  size_t with_holes = 0;
  for (const NodeRecord& n : r.level_nodes(6)) with_holes += (n.flags & kNodeFlagHasHoles) != 0;
  EXPECT_GT(with_holes, 0u);
}

TEST_F(OverviewLevels, VerifyFindsACrackBetweenARootAndItsOverviewParent) {
  synthetic::World w = world_;
  const size_t i = first_of_level(6);
  ASSERT_NE(w.nodes[i].record.child_mask, 0);
  // Raise one even vertex that a root also holds (vertex (0,0) of 6/0/0 is root 5/0/0's corner).
  w.nodes[i].data.heights[0] = uint16_t(w.nodes[i].data.heights[0] + 1);
  w.nodes[i].record.max_height = std::max(w.nodes[i].record.max_height,
                                          w.nodes[i].record.height_offset + (int32_t(w.nodes[i].data.heights[0]) << 7));
  const auto path = (dir_ / "crack.terrain").string();
  ASSERT_TRUE(write_nodes(path, w.world, w.nodes).ok());
  ArchiveReader r;
  ASSERT_TRUE(r.open(path).ok());
  const Status v = r.verify();
  EXPECT_EQ(v.code, Error::payload_invalid) << v.to_string();
  EXPECT_NE(v.message.find("parent 6/0/0"), std::string::npos) << v.message;
}

TEST_F(OverviewLevels, WithoutTheRecordReadsAsBefore) {
  synthetic::Spec s = overview_spec();
  s.overview_levels = 0;
  const auto path = (dir_ / "plain.terrain").string();
  ASSERT_TRUE(synthetic::write_archive(path, s).ok());
  const auto b = slurp(path);
  EXPECT_EQ(get_u32(b, layout::header::format_version), 3u);  // every writer writes version 3 (SPEC 20)
  ArchiveReader r;
  ASSERT_TRUE(r.open(path).ok());
  EXPECT_EQ(r.level_count(), 6);
  EXPECT_EQ(r.top_level(), kRootLevel);
  EXPECT_TRUE(r.world().overview_step_log2.empty());
  EXPECT_EQ(r.nodes_per_level().size(), 6u);
  EXPECT_EQ(r.nodes_per_level()[5], r.nodes().size());
  EXPECT_EQ(r.find({6, 0, 0}), -1);
  // The same roots, byte for byte, as in the file with overview levels (the synthetic overview
  // step equals the roots' step, so no root vertex is re-rounded).
  ArchiveReader o;
  ASSERT_TRUE(o.open(path_).ok());
  for (const NodeRecord& n : r.nodes()) {
    const int64_t j = o.find(n.key);
    ASSERT_GE(j, 0);
    EXPECT_EQ(o.nodes()[size_t(j)].payload_crc32, n.payload_crc32);
  }
}

TEST_F(OverviewLevels, DamagedRecordsAreNamed) {
  std::string msg;
  // K = 0 (size 1).
  EXPECT_EQ(open_with([&](auto& b) { put_u32(b, ext_ + 4, 1); std::fill(b.begin() + long(ext_ + 8), b.begin() + long(ext_ + 12), 0); }, &msg),
            Error::metadata_invalid);
  EXPECT_NE(msg.find("overview_levels"), std::string::npos) << msg;
  // size disagrees with K.
  EXPECT_EQ(open_with([&](auto& b) { b[ext_ + 8] = 2; }, &msg), Error::metadata_invalid);
  EXPECT_NE(msg.find("1 + K"), std::string::npos) << msg;
  // A step above 14.
  EXPECT_EQ(open_with([&](auto& b) { b[ext_ + 11] = 15; }, &msg), Error::metadata_invalid);
  EXPECT_NE(msg.find("exceeds 14"), std::string::npos) << msg;
  // A step below the level under it (level 7 below level 6; level 6 below the roots' 7).
  EXPECT_EQ(open_with([&](auto& b) { b[ext_ + 10] = 6; }, &msg), Error::metadata_invalid);
  EXPECT_NE(msg.find("never decrease"), std::string::npos) << msg;
  EXPECT_EQ(open_with([&](auto& b) { b[ext_ + 9] = 6; b[ext_ + 10] = 6; b[ext_ + 11] = 6; }, &msg), Error::metadata_invalid);
  EXPECT_NE(msg.find("below level 5"), std::string::npos) << msg;
  // An unknown required tag 3 in place of 2 (a newer writer's record).
  EXPECT_EQ(open_with([&](auto& b) { put_u32(b, ext_, 3); }, &msg), Error::metadata_invalid);
  // In a version-1 file the extension_size field is reserved: the file is invalid, never misread.
  EXPECT_EQ(open_with([](auto& b) { put_u32(b, layout::header::format_version, 1); }, &msg, 2), Error::metadata_invalid);
  EXPECT_NE(msg.find("reserved"), std::string::npos) << msg;
  // Too many levels: the writer refuses a WorldInfo the reader would reject.
  WorldInfo w = world_.world;
  w.overview_step_log2.assign(15, 7);
  EXPECT_EQ(validate_world(w).code, Error::metadata_invalid);
}

// The merge of work units streams with the ordered writer, overview levels included: the same
// bytes as the default writer given the same calls, and the same directory rules refused.
TEST_F(OverviewLevels, TheOrderedWriterTakesOverviewLevels) {
  const std::string a = (dir_ / "default.terrain").string(), b = (dir_ / "ordered.terrain").string();
  ASSERT_TRUE(write_nodes(a, world_.world, world_.nodes, false).ok());  // in the order given
  std::vector<synthetic::Node> sorted = world_.nodes;
  std::sort(sorted.begin(), sorted.end(), [&](const synthetic::Node& x, const synthetic::Node& y) {
    return x.record.key.level != y.record.key.level ? payload_order_rank(x.record.key.level) < payload_order_rank(y.record.key.level)
                                                      : key_less(x.record.key, y.record.key);
  });
  ASSERT_TRUE(write_nodes(a, world_.world, sorted, false).ok());
  const Status s = write_nodes(b, world_.world, world_.nodes, true);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(slurp(a), slurp(b));
  ArchiveReader r;
  ASSERT_TRUE(r.open(b).ok());
  EXPECT_EQ(r.world().overview_step_log2.size(), 3u);
  size_t overview = 0;
  for (const synthetic::Node& n : world_.nodes) overview += n.record.key.level > uint32_t(kRootLevel);
  EXPECT_GE(overview, 10u);  // the levels above the roots are in the test, not only the roots
  // Out of order: an overview node before a level-0..5 node.
  std::vector<synthetic::Node> swapped = sorted;
  std::rotate(swapped.begin(), swapped.end() - 1, swapped.end());  // the top node first
  ArchiveShape shape;
  std::vector<std::vector<uint8_t>> payloads(swapped.size());
  PayloadOptions options;
  options.zstd_level = synthetic::Spec{}.zstd_level;
  for (size_t i = 0; i < swapped.size(); ++i) {
    ASSERT_TRUE(encode_node_payload(swapped[i].data, options, payloads[i]).ok());
    ++shape.level_nodes[swapped[i].record.key.level];
    shape.payload_bytes += payloads[i].size();
  }
  ArchiveWriter w;
  ASSERT_TRUE(w.open_ordered(b, shape).ok());
  const Status u = w.add_node(swapped[0].record, payloads[0]);  // the top node before the roots: refused
  EXPECT_EQ(u.code, Error::invalid_argument) << u.to_string();
  EXPECT_NE(u.message.find("level 5 got no nodes, the shape says"), std::string::npos) << u.message;
}

TEST_F(OverviewLevels, DirectoryRulesAreChecked) {
  for (bool ordered : {false, true}) {
    ordered_ = ordered;
    SCOPED_TRACE(ordered ? "ordered writer" : "default writer");
    check_directory_rules();
  }
}

void OverviewLevels::check_directory_rules() {
  std::string msg;
  // A level above the top (level byte 9 with K = 3): directory_invalid at the reader.
  const size_t dir = size_t(get_u64(good_, layout::header::directory_offset));
  const size_t last = dir + (get_u32(good_, layout::header::node_count) - 1) * layout::kEntrySize;
  EXPECT_EQ(open_with([&](auto& b) { b[last + layout::entry::level] = 9; }, &msg), Error::directory_invalid);
  EXPECT_NE(msg.find("level must be 0..8"), std::string::npos) << msg;
  // A root without its level-6 parent (closed upward).
  Status s = write_edited([&](WorldInfo&, std::vector<synthetic::Node>& nodes) {
    const NodeKey parent = parent_of(nodes[0].record.key);
    for (auto& n : nodes)
      if (n.record.key == parent_of(parent)) n.record.child_mask = uint8_t(n.record.child_mask & ~(1u << ((parent.x & 1) | ((parent.y & 1) << 1))));
    std::erase_if(nodes, [&](const synthetic::Node& n) { return n.record.key == parent; });
  });
  EXPECT_EQ(s.code, Error::directory_invalid) << s.to_string();
  EXPECT_NE(s.message.find("is absent"), std::string::npos) << s.message;
  // A level-6 child mask that does not name its roots.
  s = write_edited([&](WorldInfo&, std::vector<synthetic::Node>& nodes) { nodes[first_of_level(6)].record.child_mask ^= 0x8; });
  EXPECT_EQ(s.code, Error::directory_invalid) << s.to_string();
  EXPECT_NE(s.message.find("child_mask"), std::string::npos) << s.message;
  // A level-6 node outside its grid (10 x 10 at 20 x 20 roots).
  s = write_edited([&](WorldInfo&, std::vector<synthetic::Node>& nodes) {
    synthetic::Node extra = nodes[first_of_level(6)];
    extra.record.key = {6, 10, 0};
    extra.record.child_mask = 0;
    nodes.push_back(extra);
  });
  EXPECT_EQ(s.code, Error::directory_invalid) << s.to_string();
  // The ordered writer checks the tree (6/10/0 has no parent at level 7) before the grid.
  EXPECT_NE(s.message.find(ordered_ ? "parent 7/5/0 is absent" : "node grid"), std::string::npos) << s.message;
  // Overview nodes in a world that declares none.
  s = write_edited([&](WorldInfo& w, std::vector<synthetic::Node>&) { w.overview_step_log2.clear(); });
  if (ordered_) {  // the ordered writer was told the levels by its shape: the world contradicts it
    EXPECT_EQ(s.code, Error::invalid_argument) << s.to_string();
    EXPECT_NE(s.message.find("above the world's top level 5"), std::string::npos) << s.message;
  } else {
    EXPECT_EQ(s.code, Error::directory_invalid) << s.to_string();
    EXPECT_NE(s.message.find("declares no overview levels"), std::string::npos) << s.message;
  }
  // A top level of more than 16 nodes: K = 2 leaves the 5 x 5 level 7 on top.
  s = write_edited([&](WorldInfo& w, std::vector<synthetic::Node>& nodes) {
    w.overview_step_log2.resize(2);
    std::erase_if(nodes, [](const synthetic::Node& n) { return n.record.key.level == 8; });
  });
  EXPECT_EQ(s.code, Error::directory_invalid) << s.to_string();
  EXPECT_NE(s.message.find("more than 16"), std::string::npos) << s.message;
}

}  // namespace
}  // namespace terrain
