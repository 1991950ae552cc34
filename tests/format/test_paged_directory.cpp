// The paged directory (format/SPEC.md section 20): a wide archive opens by page with the header and
// one read of page table and metadata, each lookup then costs at most the read of one page, a
// damaged page fails only its own nodes, and the ordered writer (the merge's) puts row-ordered
// levels into directory order with the same bytes as the default writer.
#include <gtest/gtest.h>

#include <random>

#include "archive_bytes.h"
#include "archive_fixture.h"
#include "counting_source.h"
#include "scratch_archive_test.h"
#include "terrain/archive_layout.h"
#include "terrain/archive_writer.h"
#include "terrain/surface_contract.h"

namespace terrain {
namespace {

using namespace test;  // archive_bytes.h, counting_source.h

// A world of `side` x `side` roots, every root with its four level-4 children and their sixteen
// level-3 children, and every overview node above: 21 nodes per root. Every node has the same
// small payload (only the directory is under test).
struct WideWorld {
  WorldInfo world;
  std::vector<NodeRecord> records;  // in payload order (SPEC 18): levels 5..3, then 6 upward; rows
  std::vector<uint8_t> payload;
};

WideWorld make_wide_world(uint32_t side) {
  WideWorld w;
  w.world = make_world(side, side);
  const int k = overview_levels_needed(side, side);
  w.world.overview_step_log2.assign(size_t(k), 5);
  BuiltNode n = make_seed_node(w.world, {5, 0, 0});
  EXPECT_TRUE(encode_node_payload(*n.data, PayloadOptions{}, w.payload).ok());
  auto add_level = [&](int level, uint8_t mask) {
    const uint64_t nx = level_grid_cells(side, level), ny = level_grid_cells(side, level);
    for (uint32_t y = 0; y < ny; ++y)
      for (uint32_t x = 0; x < nx; ++x) {
        NodeRecord r = n.record;
        r.key = {uint32_t(level), x, y};
        r.child_mask = mask;
        w.records.push_back(r);
      }
  };
  // Levels 4 and 3 are dense below every root: their grids are the full grids of those levels.
  add_level(5, 0xF);
  add_level(4, 0xF);
  add_level(3, 0);
  for (int level = 6; level <= 5 + k; ++level) add_level(level, 0xF);  // side is a power of two: all full
  return w;
}

Status write_wide(const std::string& path, const WideWorld& w, bool ordered) {
  ArchiveWriter writer;
  if (ordered) {
    ArchiveShape shape;
    for (const NodeRecord& r : w.records) ++shape.level_nodes[r.key.level];
    shape.payload_bytes = w.records.size() * w.payload.size();
    TERRAIN_TRY(writer.open_ordered(path, shape));
  } else {
    TERRAIN_TRY(writer.open(path));
  }
  for (const NodeRecord& r : w.records) TERRAIN_TRY(writer.add_node(r, w.payload));
  return writer.finish(w.world);
}

class PagedDirectory : public ScratchArchiveTest {
 protected:
  void SetUp() override {
    ScratchArchiveTest::SetUp();
    wide_ = make_wide_world(64);  // 4096 roots: 86016 nodes below them, 1360 above
    ASSERT_TRUE(write_wide(path_, wide_, false).ok());
    ASSERT_TRUE(whole_.open(path_).ok());
  }
  std::unique_ptr<CountingSource> counting(const std::string& path) {
    std::unique_ptr<ByteSource> file;
    EXPECT_TRUE(open_file_source(path, file).ok());
    return std::make_unique<CountingSource>(std::move(file));
  }
  WideWorld wide_;
  ArchiveReader whole_;
};

TEST_F(PagedDirectory, AWideArchiveOpensWithTwoReadsAndEachLookupReadsAtMostOnePage) {
  ASSERT_EQ(whole_.nodes().size(), 87376u);
  EXPECT_EQ(whole_.format_version(), 3u);
  EXPECT_EQ(whole_.directory_pages(), 86u);  // 1024 entries a page
  const uint64_t directory_bytes = whole_.nodes().size() * layout::kEntrySize;

  auto source = counting(path_);
  const CountingSource& io = *source;
  ArchiveReader paged;
  ASSERT_TRUE(paged.open(std::move(source), DirectoryLoad::by_page).ok());
  EXPECT_EQ(io.reads.load(), 2);  // the header; the page table with the metadata
  const uint64_t open_bytes = io.bytes.load();
  EXPECT_LT(open_bytes, 128 + 86 * 16 + 2048u);
  EXPECT_LT(open_bytes * 100, directory_bytes);  // under 1 % of the directory
  EXPECT_EQ(paged.node_count(), 87376u);
  EXPECT_TRUE(paged.nodes().empty());
  EXPECT_EQ(paged.verify().code, Error::invalid_argument);  // never a verify of nothing

  // Keys that exist and keys that do not (below level 3, outside the grid, between), at random.
  std::mt19937 rng(5);
  std::vector<NodeKey> keys;
  for (int i = 0; i < 300; ++i) {
    const uint32_t level = 2 + rng() % 8;
    const uint32_t cells = uint32_t(level_grid_cells(64, int(level)));
    keys.push_back({level, uint32_t(rng() % (cells + 1)), uint32_t(rng() % (cells + 1))});
  }
  keys.push_back({9, 3, 3});  // the top's last node: the last page
  keys.push_back({3, 0, 0});  // the first entry: the first page
  int found = 0;
  for (const NodeKey& k : keys) {
    const int before = io.reads.load();
    const uint64_t pages_before = paged.directory_pages_read();
    int64_t index = -2;
    ASSERT_TRUE(paged.lookup(k, index).ok()) << node_name(k);
    EXPECT_EQ(index, whole_.find(k)) << node_name(k);
    EXPECT_LE(io.reads.load() - before, 1) << node_name(k);
    EXPECT_EQ(uint64_t(io.reads.load() - before), paged.directory_pages_read() - pages_before);
    if (index < 0) continue;
    ++found;
    NodeRecord r;
    ASSERT_TRUE(paged.record(size_t(index), r).ok());
    EXPECT_EQ(r.key, k);
    EXPECT_EQ(r.payload_offset, whole_.nodes()[size_t(index)].payload_offset);
  }
  EXPECT_GT(found, 100);
  EXPECT_LT(paged.directory_pages_read(), whole_.directory_pages());
  // A page once read is not read again; a payload reads only its bytes.
  const int reads = io.reads.load();
  EXPECT_EQ(paged.find({9, 3, 3}), whole_.find({9, 3, 3}));
  EXPECT_EQ(io.reads.load(), reads);
  NodeData a, b;
  ASSERT_TRUE(paged.decode_node(size_t(whole_.find({9, 3, 3})), a).ok());
  ASSERT_TRUE(whole_.decode_node(size_t(whole_.find({9, 3, 3})), b).ok());
  EXPECT_EQ(a.heights, b.heights);
  EXPECT_EQ(io.reads.load(), reads + 1);

  // load_directory(): the rest in one read; then the reader is one opened whole.
  ASSERT_TRUE(paged.load_directory().ok());
  EXPECT_EQ(io.reads.load(), reads + 2);
  ASSERT_EQ(paged.nodes().size(), whole_.nodes().size());
  EXPECT_EQ(paged.nodes_per_level(), whole_.nodes_per_level());
  for (size_t i = 0; i < paged.nodes().size(); i += 97) EXPECT_EQ(paged.nodes()[i].key, whole_.nodes()[i].key);
}

// A descent from the top to a point: every level's page named by the page table and read at once;
// the lookups after it read nothing.
TEST_F(PagedDirectory, PrefetchReadsEveryLevelsPageAtOnceAndLookupsThenReadNothing) {
  auto source = counting(path_);
  const CountingSource& io = *source;
  ArchiveReader paged;
  ASSERT_TRUE(paged.open(std::move(source), DirectoryLoad::by_page).ok());
  std::vector<NodeKey> path;
  const double x = 100.5 * 2048, y = 37.25 * 2048;  // metres from the origin
  for (int level = paged.top_level(); level >= 0; --level)
    path.push_back({uint32_t(level), uint32_t(x / node_size_m(level)), uint32_t(y / node_size_m(level))});
  path.push_back(path.back());  // twice: one read
  const int before = io.reads.load();
  ASSERT_TRUE(paged.prefetch(path).ok());
  // Levels 9..7 share the last page (336 entries), level 6 is page 84 (1024 entries), 5, 4 and 3
  // have a page each under the point; levels 2..0 come before every page: no page holds them.
  EXPECT_EQ(io.reads.load() - before, 5);
  EXPECT_EQ(paged.directory_pages_read(), 5u);
  for (const NodeKey& k : path) {
    int64_t index = -2;
    ASSERT_TRUE(paged.lookup(k, index).ok());
    EXPECT_EQ(index, whole_.find(k)) << node_name(k);
  }
  EXPECT_EQ(io.reads.load() - before, 5);
  ASSERT_TRUE(paged.prefetch(path).ok());  // all read: nothing to do
  EXPECT_EQ(io.reads.load() - before, 5);
}

TEST_F(PagedDirectory, DirectoryOrderGoesByLevelThenTilesOf32x32) {
  const auto nodes = whole_.nodes();
  for (size_t i = 1; i < nodes.size(); ++i) ASSERT_TRUE(directory_less(nodes[i - 1].key, nodes[i].key)) << i;
  // Level 3 is 256 x 256 nodes: its first 1024 entries are the tile (0..31, 0..31), one page.
  const auto level3 = whole_.level_nodes(3);
  ASSERT_EQ(level3.size(), 65536u);
  for (size_t i = 0; i < 1024; ++i) {
    EXPECT_LT(level3[i].key.x, 32u);
    EXPECT_LT(level3[i].key.y, 32u);
  }
  EXPECT_EQ(level3[1024].key, (NodeKey{3, 32, 0}));
  EXPECT_EQ(level3[32].key, (NodeKey{3, 0, 1}));
}

TEST_F(PagedDirectory, TheOrderedWriterWritesTheSameBytesAsTheDefaultOne) {
  const std::string ordered = (dir_ / "ordered.terrain").string();
  const Status s = write_wide(ordered, wide_, true);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(slurp(ordered), slurp(path_));
}

TEST_F(PagedDirectory, ADamagedPageFailsItsOwnNodesOnly) {
  auto bytes = slurp(path_);
  const size_t dir = size_t(get_u64(bytes, layout::header::directory_offset));
  const uint64_t page = 40;  // level 3's middle
  bytes[dir + page * 1024 * layout::kEntrySize + 1000] ^= 0x10;
  ArchiveReader damaged_whole;
  EXPECT_EQ(damaged_whole.open_memory(bytes).code, Error::directory_checksum);

  ArchiveReader paged;
  ASSERT_TRUE(paged.open(make_memory_source(bytes), DirectoryLoad::by_page).ok());
  const NodeKey in_page = whole_.nodes()[page * 1024 + 5].key, elsewhere = whole_.nodes()[(page + 1) * 1024 + 5].key;
  int64_t index = 0;
  const Status s = paged.lookup(in_page, index);
  EXPECT_EQ(s.code, Error::directory_checksum) << s.to_string();
  EXPECT_NE(s.message.find("directory page 40"), std::string::npos) << s.message;
  EXPECT_EQ(paged.find(in_page), -1);
  NodeRecord r;
  EXPECT_EQ(paged.record(page * 1024, r).code, Error::directory_checksum);
  ASSERT_TRUE(paged.lookup(elsewhere, index).ok());
  EXPECT_EQ(index, whole_.find(elsewhere));
  EXPECT_EQ(paged.load_directory().code, Error::directory_checksum);

  // The page table's own damage is found at open.
  bytes = slurp(path_);
  const size_t table = dir + whole_.nodes().size() * layout::kEntrySize;
  bytes[table + 16 * 3 + 5] ^= 0x01;  // page 3's first x
  EXPECT_EQ(paged.open(make_memory_source(bytes), DirectoryLoad::by_page).code, Error::directory_checksum);
  reseal(bytes);  // re-seal recomputes the table from the pages: a first key that lies needs a hand edit
  put_u32(bytes, table + 16 * 3 + layout::page_record::x, 97);  // page 3 starts at 3/96/0: still ascending
  put_u32(bytes, layout::header::directory_crc32, crc(bytes.data() + table, 86 * 16));
  put_u32(bytes, layout::header::header_crc32, crc(bytes.data(), layout::header::header_crc32));
  ASSERT_TRUE(paged.open(make_memory_source(bytes), DirectoryLoad::by_page).ok());
  const Status t = paged.lookup(whole_.nodes()[3 * 1024 + 1].key, index);
  EXPECT_EQ(t.code, Error::directory_invalid) << t.to_string();
  EXPECT_NE(t.message.find("is not the page table's"), std::string::npos) << t.message;
}

TEST_F(PagedDirectory, HeaderFieldsOfVersionThreeAreChecked) {
  auto open_with = [&](uint32_t page_entries, uint32_t node_count_delta = 0) {
    auto b = slurp(path_);
    put_u32(b, layout::header::page_entries, page_entries);
    put_u32(b, layout::header::node_count, get_u32(b, layout::header::node_count) + node_count_delta);
    put_u32(b, layout::header::header_crc32, crc(b.data(), layout::header::header_crc32));
    ArchiveReader r;
    return r.open_memory(b).code;
  };
  EXPECT_EQ(open_with(1024), Error::ok);
  EXPECT_EQ(open_with(1000), Error::header_invalid);  // not a power of two
  EXPECT_EQ(open_with(512), Error::header_invalid);   // below 1024
  EXPECT_EQ(open_with(1u << 21), Error::header_invalid);
  EXPECT_EQ(open_with(2048), Error::section_out_of_bounds);  // directory_size no longer adds up
  EXPECT_EQ(open_with(1024, 1), Error::section_out_of_bounds);
}

TEST(PagedDirectoryLimits, APageTableForTenToTheEightNodesStaysUnderHalfAMegabyte) {
  EXPECT_EQ(layout::page_entries_for(0), 1024u);
  EXPECT_EQ(layout::page_entries_for(1000), 1024u);
  EXPECT_EQ(layout::page_entries_for(uint64_t(1024) << 15), 1024u);
  EXPECT_EQ(layout::page_entries_for((uint64_t(1024) << 15) + 1), 2048u);
  // 10^5 roots of real lidar: about 10^8 nodes (issue 52).
  const uint32_t e = layout::page_entries_for(100'000'000);
  EXPECT_EQ(e, 4096u);
  const uint64_t pages = (100'000'000 + e - 1) / e;
  EXPECT_LE(pages * layout::kPageRecordSize, 512u << 10);
  EXPECT_EQ(layout::page_entries_for(layout::kMaxNodeCountV3), 65536u);
}

}  // namespace
}  // namespace terrain
