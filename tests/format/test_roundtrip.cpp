// Round trip of every section and metadata field, sparse lookups, determinism, atomic writes.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include "archive_fixture.h"
#include "counting_source.h"
#include "heap_in_use.h"
#include "scratch_archive_test.h"
#include "terrain/archive_layout.h"
#include "terrain/bc_decode.h"
#include "terrain/byte_source.h"
#include "terrain/height_codec.h"
#include "terrain/output_paths.h"
#include "terrain/surface_contract.h"
#include "test_data.h"

namespace terrain {
namespace {

using test::make_world;

std::vector<uint8_t> read_file(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

void expect_world_equal(const WorldInfo& a, const WorldInfo& b) {
  EXPECT_EQ(a.crs.kind, b.crs.kind);
  EXPECT_EQ(a.crs.epsg, b.crs.epsg);
  EXPECT_EQ(a.crs.semi_major_m, b.crs.semi_major_m);
  EXPECT_EQ(a.crs.inverse_flattening, b.crs.inverse_flattening);
  EXPECT_EQ(a.crs.lat0_deg, b.crs.lat0_deg);
  EXPECT_EQ(a.crs.lon0_deg, b.crs.lon0_deg);
  EXPECT_EQ(a.crs.scale_k0, b.crs.scale_k0);
  EXPECT_EQ(a.crs.false_easting_m, b.crs.false_easting_m);
  EXPECT_EQ(a.crs.false_northing_m, b.crs.false_northing_m);
  EXPECT_EQ(a.crs.name, b.crs.name);
  EXPECT_EQ(a.origin_x_m, b.origin_x_m);
  EXPECT_EQ(a.origin_y_m, b.origin_y_m);
  EXPECT_EQ(a.roots_x, b.roots_x);
  EXPECT_EQ(a.roots_y, b.roots_y);
  EXPECT_EQ(a.extent_min_x_m, b.extent_min_x_m);
  EXPECT_EQ(a.extent_min_y_m, b.extent_min_y_m);
  EXPECT_EQ(a.extent_max_x_m, b.extent_max_x_m);
  EXPECT_EQ(a.extent_max_y_m, b.extent_max_y_m);
  EXPECT_EQ(a.step_log2, b.step_log2);
  ASSERT_EQ(a.palette.size(), b.palette.size());
  for (size_t i = 0; i < a.palette.size(); ++i) {
    EXPECT_EQ(a.palette[i].name, b.palette[i].name);
    EXPECT_EQ(a.palette[i].albedo_srgb, b.palette[i].albedo_srgb);
    EXPECT_EQ(a.palette[i].flags, b.palette[i].flags);
    EXPECT_EQ(a.palette[i].roughness, b.palette[i].roughness);
    EXPECT_EQ(a.palette[i].detail_scale_m, b.palette[i].detail_scale_m);
    EXPECT_EQ(a.palette[i].detail_strength, b.palette[i].detail_strength);
    EXPECT_EQ(a.palette[i].height_blend, b.palette[i].height_blend);
  }
  EXPECT_EQ(a.cook_info_json, b.cook_info_json);
}

class ArchiveRoundTrip : public test::ScratchArchiveTest {
 protected:
  ArchiveRoundTrip() : ScratchArchiveTest("world.terrain") {}
  // Writes the synthetic world over the sparse tree (make_world(), sparse_keys()) to path_ and
  // opens it in `reader`.
  void open_sparse_world(ArchiveReader& reader) {
    ASSERT_TRUE(test::write_synthetic_archive(path_, world_, test::sparse_keys()).ok());
    ASSERT_TRUE(reader.open(path_).ok());
  }
  const WorldInfo world_ = make_world();
};

TEST_F(ArchiveRoundTrip, EverySectionAndRecordFieldSurvives) {
  const WorldInfo w = make_world();
  const auto keys = test::sparse_keys();
  ASSERT_TRUE(test::write_synthetic_archive(path_, w, keys).ok());
  ArchiveReader reader;
  const Status s = reader.open(path_);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_EQ(reader.format_version(), 3u);
  EXPECT_EQ(reader.file_size(), std::filesystem::file_size(path_));
  expect_world_equal(w, reader.world());
  ASSERT_EQ(reader.nodes().size(), keys.size());
  NodeData got;
  for (const NodeKey& k : keys) {
    const int64_t index = reader.find(k);
    ASSERT_GE(index, 0) << k.level << "/" << k.x << "/" << k.y;
    const test::BuiltNode want = test::make_synthetic_node(w, k, 1);
    const NodeRecord& r = reader.nodes()[size_t(index)];
    EXPECT_EQ(r.key, k);
    EXPECT_EQ(r.child_mask, test::child_mask_of(keys, k));
    EXPECT_EQ(r.flags, want.record.flags);
    EXPECT_EQ(r.height_offset, want.record.height_offset);
    EXPECT_EQ(r.min_height, want.record.min_height);
    EXPECT_EQ(r.max_height, want.record.max_height);
    EXPECT_EQ(r.geometric_error_m, want.record.geometric_error_m);
    ASSERT_TRUE(reader.decode_node(size_t(index), got).ok());
    EXPECT_EQ(got.heights, want.data->heights);
    EXPECT_EQ(got.normals_bc3, want.data->normals_bc3);
    EXPECT_EQ(got.albedo_bc1, want.data->albedo_bc1);
    EXPECT_EQ(got.splat, want.data->splat);
    EXPECT_EQ(got.cones_bc3, want.data->cones_bc3);
  }
  const Status v = reader.verify();
  EXPECT_TRUE(v.ok()) << v.to_string();
}

TEST_F(ArchiveRoundTrip, DecodeOnlyRequestedSections) {
  ArchiveReader reader;
  ASSERT_NO_FATAL_FAILURE(open_sparse_world(reader));
  auto got = std::make_unique<NodeData>();
  got->normals_bc3.fill(0xAB);
  got->cones_bc3.fill(0xCD);
  ASSERT_TRUE(reader.decode_node(0, *got, kSectionHeights | kSectionSplat).ok());
  const auto want = test::make_synthetic_node(world_, reader.nodes()[0].key, 1);
  EXPECT_EQ(got->heights, want.data->heights);
  EXPECT_EQ(got->splat, want.data->splat);
  EXPECT_TRUE(std::all_of(got->normals_bc3.begin(), got->normals_bc3.end(), [](uint8_t b) { return b == 0xAB; }));
  EXPECT_TRUE(std::all_of(got->cones_bc3.begin(), got->cones_bc3.end(), [](uint8_t b) { return b == 0xCD; }));
}

// surface_zstd_level changes only the four surface sections: the height section's bytes stay
// those of zstd_level, every section decodes back exactly, and an out-of-range level is an error
// that names the option.
TEST(PayloadOptionsTest, SurfaceLevelAppliesToTheSurfaceSectionsOnly) {
  const WorldInfo w = make_world();
  const auto node = test::make_synthetic_node(w, NodeKey{0, 3, 2}, 7);
  PayloadOptions heights_only_level{9, true};
  PayloadOptions split = heights_only_level;
  split.surface_zstd_level = 1;
  std::vector<uint8_t> a, b;
  ASSERT_TRUE(encode_node_payload(*node.data, heights_only_level, a).ok());
  ASSERT_TRUE(encode_node_payload(*node.data, split, b).ok());
  // Section table entries: [id, codec, shift, pad, stored u32, raw u32]; heights come first.
  auto stored = [](const std::vector<uint8_t>& p, int s) {
    const uint8_t* e = p.data() + 4 + s * layout::kPayloadTableEntrySize;
    return uint32_t(e[4]) | uint32_t(e[5]) << 8 | uint32_t(e[6]) << 16 | uint32_t(e[7]) << 24;
  };
  const uint32_t heights = stored(a, 0);
  EXPECT_EQ(heights, stored(b, 0));
  EXPECT_TRUE(std::equal(a.begin() + layout::kPayloadHeaderSize, a.begin() + layout::kPayloadHeaderSize + heights,
                         b.begin() + layout::kPayloadHeaderSize));
  EXPECT_NE(a, b);  // the surface sections were compressed differently
  for (const auto* p : {&a, &b}) {
    auto got = std::make_unique<NodeData>();
    ASSERT_TRUE(decode_node_payload(*p, kSectionAll, *got).ok());
    EXPECT_EQ(got->heights, node.data->heights);
    EXPECT_EQ(got->normals_bc3, node.data->normals_bc3);
    EXPECT_EQ(got->albedo_bc1, node.data->albedo_bc1);
    EXPECT_EQ(got->splat, node.data->splat);
    EXPECT_EQ(got->cones_bc3, node.data->cones_bc3);
  }
  split.surface_zstd_level = 23;
  const Status bad = encode_node_payload(*node.data, split, b);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.to_string().find("surface_zstd_level 23"), std::string::npos) << bad.to_string();
}

TEST_F(ArchiveRoundTrip, LookupsAcrossASparseTreeTellPresentFromAbsent) {
  const WorldInfo w = make_world(2, 1);
  const auto keys = test::sparse_keys();
  ASSERT_TRUE(test::write_synthetic_archive(path_, w, keys).ok());
  ArchiveReader reader;
  ASSERT_TRUE(reader.open(path_).ok());
  std::vector<uint32_t> expected(kLevelCount);
  for (const NodeKey& k : keys) ++expected[k.level];
  EXPECT_EQ(reader.nodes_per_level(), expected);
  // Every key of every level's full grid (level 0: 64 x 32 nodes) is either found at its own
  // entry or reported absent, matching the key list.
  int present = 0, absent = 0;
  for (uint32_t level = 0; level < uint32_t(kLevelCount); ++level) {
    const uint32_t nx = w.roots_x << (kRootLevel - int(level)), ny = w.roots_y << (kRootLevel - int(level));
    for (uint32_t y = 0; y < ny; ++y)
      for (uint32_t x = 0; x < nx; ++x) {
        const NodeKey k{level, x, y};
        const bool want = std::find(keys.begin(), keys.end(), k) != keys.end();
        const int64_t i = reader.find(k);
        ASSERT_EQ(i >= 0, want) << level << "/" << x << "/" << y;
        if (i >= 0) {
          EXPECT_EQ(reader.nodes()[size_t(i)].key, k);
          ++present;
        } else {
          ++absent;
        }
      }
  }
  EXPECT_EQ(present, int(keys.size()));
  EXPECT_GT(absent, 2000);
  // Keys beyond the grid or level range are absent, not errors.
  EXPECT_EQ(reader.find({0, 64, 0}), -1);
  EXPECT_EQ(reader.find({6, 0, 0}), -1);
  EXPECT_EQ(reader.find({0, 0xFFFFFFFFu, 0xFFFFFFFFu}), -1);
  NodeData d;
  EXPECT_EQ(reader.decode_node(reader.nodes().size(), d).code, Error::node_not_found);
}

TEST_F(ArchiveRoundTrip, SameInputsGiveIdenticalBytesAtAnyThreadCount) {
  const WorldInfo w = make_world();
  const auto keys = test::sparse_keys();
  ASSERT_TRUE(test::write_synthetic_archive(path_, w, keys).ok());
  const auto first = read_file(path_);
  ASSERT_TRUE(test::write_synthetic_archive(path_ + "2", w, keys).ok());
  EXPECT_EQ(read_file(path_ + "2"), first);
  // Payloads encoded on 4 threads (thread-local zstd contexts) equal the serial ones.
  std::vector<std::vector<uint8_t>> serial(keys.size()), parallel(keys.size());
  for (size_t i = 0; i < keys.size(); ++i)
    ASSERT_TRUE(encode_node_payload(*test::make_synthetic_node(w, keys[i], 1).data, {}, serial[i]).ok());
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      for (size_t i = size_t(t); i < keys.size(); i += 4)
        (void)encode_node_payload(*test::make_synthetic_node(w, keys[i], 1).data, {}, parallel[i]);
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(serial, parallel);
  // The directory is sorted whatever the add order; payload order follows the calls.
  ArchiveWriter writer;
  ASSERT_TRUE(writer.open(path_ + "3").ok());
  for (size_t i = keys.size(); i-- > 0;) {
    test::BuiltNode n = test::make_synthetic_node(w, keys[i], 1);
    n.record.child_mask = test::child_mask_of(keys, keys[i]);
    ASSERT_TRUE(writer.add_node(n.record, serial[i]).ok());
  }
  ASSERT_TRUE(writer.finish(w).ok());
  ArchiveReader a, b;
  ASSERT_TRUE(a.open(path_).ok());
  ASSERT_TRUE(b.open(path_ + "3").ok());
  ASSERT_EQ(a.nodes().size(), b.nodes().size());
  std::vector<uint8_t> pa, pb;
  for (size_t i = 0; i < a.nodes().size(); ++i) {
    EXPECT_EQ(a.nodes()[i].key, b.nodes()[i].key);
    ASSERT_TRUE(a.read_payload(i, pa).ok());
    ASSERT_TRUE(b.read_payload(i, pb).ok());
    EXPECT_EQ(pa, pb);
  }
}

using test::CountingSource;

TEST_F(ArchiveRoundTrip, APayloadRunIsOneReadAndDecodesLikeEachNode) {
  ASSERT_TRUE(test::write_synthetic_archive(path_, make_world(), test::sparse_keys()).ok());
  std::unique_ptr<ByteSource> file;
  ASSERT_TRUE(open_file_source(path_, file).ok());
  auto counting = std::make_unique<CountingSource>(std::move(file));
  const CountingSource& source = *counting;
  ArchiveReader reader;
  ASSERT_TRUE(reader.open(std::move(counting)).ok());
  const size_t n = reader.nodes().size();

  // The longest run of nodes whose payloads follow each other in the file, found by offsets alone.
  std::vector<uint32_t> order(n);
  for (uint32_t i = 0; i < n; ++i) order[i] = i;
  std::sort(order.begin(), order.end(),
            [&](uint32_t a, uint32_t b) { return reader.nodes()[a].payload_offset < reader.nodes()[b].payload_offset; });
  std::vector<uint32_t> run{order[0]};
  for (size_t i = 1; i < n && run.size() < 6; ++i) {
    const NodeRecord& prev = reader.nodes()[order[i - 1]];
    if (reader.nodes()[order[i]].payload_offset != prev.payload_offset + prev.payload_size) break;
    EXPECT_TRUE(reader.payloads_adjacent(order[i - 1], order[i]));
    run.push_back(order[i]);
  }
  ASSERT_GE(run.size(), 3u);

  std::vector<uint8_t> bytes, one;
  const int before = source.reads.load();
  ASSERT_TRUE(reader.read_payload_run(run, bytes).ok());
  EXPECT_EQ(source.reads.load() - before, 1) << "a run is one read";
  size_t at = 0;
  auto got = std::make_unique<NodeData>(), want = std::make_unique<NodeData>();
  for (uint32_t node : run) {
    ASSERT_TRUE(reader.read_payload(node, one).ok());
    const std::span<const uint8_t> stored = std::span<const uint8_t>(bytes).subspan(at, one.size());
    EXPECT_TRUE(std::equal(one.begin(), one.end(), stored.begin()));
    ASSERT_TRUE(reader.decode_payload(node, stored, *got).ok());
    ASSERT_TRUE(reader.decode_node(node, *want).ok());
    EXPECT_EQ(std::memcmp(got.get(), want.get(), sizeof(NodeData)), 0) << node_name(reader.nodes()[node].key);
    at += one.size();
  }
  EXPECT_EQ(at, bytes.size());

  // Nodes out of file order are refused by name before anything is read.
  const std::vector<uint32_t> backwards{run[1], run[0]};
  const Status refused = reader.read_payload_run(backwards, bytes);
  EXPECT_EQ(refused.code, Error::invalid_argument);
  EXPECT_NE(refused.message.find("node " + node_name(reader.nodes()[run[0]].key) + " does not follow node " +
                                 node_name(reader.nodes()[run[1]].key)),
            std::string::npos)
      << refused.to_string();
  // decode_payload checks what it is given: the size the directory states, then the CRC-32.
  ASSERT_TRUE(reader.read_payload(run[0], one).ok());
  const Status short_bytes = reader.decode_payload(run[0], std::span<const uint8_t>(one).first(one.size() - 1), *got);
  EXPECT_EQ(short_bytes.code, Error::invalid_argument);
  EXPECT_NE(short_bytes.message.find(node_name(reader.nodes()[run[0]].key)), std::string::npos);
  one[one.size() / 2] ^= 0x10;
  const Status flipped = reader.decode_payload(run[0], one, *got);
  EXPECT_EQ(flipped.code, Error::payload_checksum);
  EXPECT_NE(flipped.message.find("node " + node_name(reader.nodes()[run[0]].key)), std::string::npos);
}

TEST_F(ArchiveRoundTrip, FailedOrAbortedWriteLeavesTheEarlierArchiveIntact) {
  const WorldInfo w = make_world();
  const auto keys = test::sparse_keys();
  ASSERT_TRUE(test::write_synthetic_archive(path_, w, keys).ok());
  const auto before = read_file(path_);
  auto temp_files = [&] {
    int n = 0;
    for (const auto& e : std::filesystem::directory_iterator(dir_)) n += e.path().filename().string().find(".tmp-") != std::string::npos;
    return n;
  };
  std::vector<uint8_t> payload;
  ASSERT_TRUE(encode_node_payload(*test::make_synthetic_node(w, keys[0], 1).data, {}, payload).ok());
  {  // explicit abort
    ArchiveWriter writer;
    ASSERT_TRUE(writer.open(path_).ok());
    EXPECT_EQ(temp_files(), 1);
    ASSERT_TRUE(writer.add_node(test::make_synthetic_node(w, keys[0], 1).record, payload).ok());
    writer.abort();
    EXPECT_EQ(temp_files(), 0);
  }
  {  // destroyed without finish (a crash in the cooker's loop)
    ArchiveWriter writer;
    ASSERT_TRUE(writer.open(path_).ok());
    ASSERT_TRUE(writer.add_node(test::make_synthetic_node(w, keys[0], 1).record, payload).ok());
  }
  EXPECT_EQ(temp_files(), 0);
  {  // finish() refuses an inconsistent tree (a level-0 node without its parents)
    ArchiveWriter writer;
    ASSERT_TRUE(writer.open(path_).ok());
    ASSERT_TRUE(writer.add_node(test::make_synthetic_node(w, {0, 1, 1}, 1).record, payload).ok());
    const Status s = writer.finish(w);
    EXPECT_EQ(s.code, Error::directory_invalid) << s.to_string();
    EXPECT_NE(s.message.find("parent"), std::string::npos) << s.message;
    EXPECT_EQ(temp_files(), 0);
  }
  {  // finish() refuses invalid metadata
    ArchiveWriter writer;
    ASSERT_TRUE(writer.open(path_).ok());
    WorldInfo bad = w;
    bad.cook_info_json = "{not json";
    EXPECT_EQ(writer.finish(bad).code, Error::metadata_invalid);
    EXPECT_EQ(temp_files(), 0);
  }
  EXPECT_EQ(read_file(path_), before);
  ArchiveReader reader;
  EXPECT_TRUE(reader.open(path_).ok());
}

// What a SIGKILLed writer leaves (its staged file under its host and pid) is removed by the next
// writer of the same target; staged files of other hosts, of live processes and of other targets stay.
TEST_F(ArchiveRoundTrip, NextWriterRemovesWhatAKilledWriterLeft) {
  const pid_t dead = ::fork();
  if (dead == 0) ::_exit(0);
  ASSERT_GT(dead, 0);
  ASSERT_EQ(::waitpid(dead, nullptr, 0), dead);  // reaped: kill(dead, 0) now fails with ESRCH
  const std::string mine = staging_path(path_);  // "<path>.tmp-<host>-<our pid>"
  const std::string host_part = mine.substr(path_.size() + 5, mine.rfind('-') - path_.size() - 5);
  auto touch = [](const std::string& p) { std::ofstream(p) << "x"; };
  const std::string stale_tmp = path_ + ".tmp-" + host_part + "-" + std::to_string(dead);
  const std::string stale_spool = path_ + ".spool-" + host_part + "-" + std::to_string(dead);
  const std::string stale_ext = stale_tmp + ".payloads";
  const std::string live = path_ + ".tmp-" + host_part + "-" + std::to_string(::getppid());
  const std::string other_host = path_ + ".tmp-" + host_part + "x-" + std::to_string(dead);
  const std::string prefixed_host = path_ + ".tmp-" + host_part + "-5-" + std::to_string(dead);
  const std::string other_target = path_ + "2.tmp-" + host_part + "-" + std::to_string(dead);
  for (const std::string* p : {&stale_tmp, &stale_spool, &stale_ext, &live, &other_host, &prefixed_host, &other_target})
    touch(*p);
  const WorldInfo w = make_world();
  ASSERT_TRUE(test::write_synthetic_archive(path_, w, test::sparse_keys()).ok());
  for (const std::string* p : {&stale_tmp, &stale_spool, &stale_ext})
    EXPECT_FALSE(std::filesystem::exists(*p)) << *p << " (a dead writer's) survived";
  for (const std::string* p : {&live, &other_host, &prefixed_host, &other_target})
    EXPECT_TRUE(std::filesystem::exists(*p)) << *p << " was removed";
  EXPECT_EQ(remove_stale_staging(path_), 0u);  // nothing stale left
}

// The work dir's sweep (terrain-cook plan and merge): every target's stale staged files in one
// listing, the same keep rules as above.
TEST_F(ArchiveRoundTrip, DirectorySweepRemovesEveryDeadWritersFilesOnly) {
  const pid_t dead = ::fork();
  if (dead == 0) ::_exit(0);
  ASSERT_GT(dead, 0);
  ASSERT_EQ(::waitpid(dead, nullptr, 0), dead);
  const std::filesystem::path dir = path_ + ".units";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string mine = staging_path((dir / "u").string());
  const std::string host_part = mine.substr(mine.find(".tmp-") + 5, mine.rfind('-') - mine.find(".tmp-") - 5);
  const std::string d = std::to_string(dead), live = std::to_string(::getppid());
  const std::vector<std::string> stale = {"unit-3.tcu.tmp-" + host_part + "-" + d,
                                          "unit-3.tcu.tmp-" + host_part + "-" + d + ".payloads",
                                          "unit-17.tcu.spool-" + host_part + "-" + d,
                                          "a.terrain.tmp-" + host_part + "-" + d + ".tmp-" + host_part + "-" + d};
  const std::vector<std::string> kept = {"unit-3.tcu",
                                         "unit-4.tcu.tmp-" + host_part + "-" + live,
                                         "unit-5.tcu.tmp-" + host_part + "x-" + d,
                                         "unit-6.tcu.tmp-" + host_part + "-5-" + d,
                                         "unit-7.tcu.tmpx-" + host_part + "-" + d,
                                         "unit-8.tcu.tmp-" + host_part + "-" + d + "x"};
  for (const auto& n : stale) std::ofstream(dir / n) << "x";
  for (const auto& n : kept) std::ofstream(dir / n) << "x";
  EXPECT_EQ(remove_stale_staging_in(dir.string()), stale.size());
  for (const auto& n : stale) EXPECT_FALSE(std::filesystem::exists(dir / n)) << n << " (a dead writer's) survived";
  for (const auto& n : kept) EXPECT_TRUE(std::filesystem::exists(dir / n)) << n << " was removed";
  EXPECT_EQ(remove_stale_staging_in(dir.string()), 0u);
  EXPECT_EQ(remove_stale_staging_in((dir / "missing").string()), 0u);  // no such directory: nothing, no throw
  std::filesystem::remove_all(dir);
}

TEST_F(ArchiveRoundTrip, ChildMasksMustMatchTheDirectoryExactly) {
  const WorldInfo w = make_world(1, 1);
  const auto keys = test::close_tree({{0, 4, 3}});
  for (int variant = 0; variant < 3; ++variant) {
    ArchiveWriter writer;
    ASSERT_TRUE(writer.open(path_).ok());
    std::vector<uint8_t> payload;
    for (const NodeKey& k : keys) {
      test::BuiltNode n = test::make_seed_node(w, k);
      n.record.child_mask = test::child_mask_of(keys, k);
      if (k == NodeKey{2, 1, 0}) {
        if (variant == 0) n.record.child_mask = 0;                  // child 1/2/1 exists, bit clear
        if (variant == 1) n.record.child_mask |= 1;                 // bit set, child 1/2/0 absent
        if (variant == 2) n.record.child_mask = uint8_t(0x4 | 0x10);  // reserved bit 4
      }
      ASSERT_TRUE(encode_node_payload(*n.data, {}, payload).ok());
      ASSERT_TRUE(writer.add_node(n.record, payload).ok() || variant == 2);
    }
    const Status s = writer.finish(w);
    if (variant == 2) {  // rejected at add_node already; finish then sees the missing node
      EXPECT_FALSE(s.ok());
      continue;
    }
    EXPECT_EQ(s.code, Error::directory_invalid) << variant << ": " << s.to_string();
    EXPECT_NE(s.message.find("node 2/1/0: child_mask bit"), std::string::npos) << s.message;
  }
}

TEST_F(ArchiveRoundTrip, WriterRejectsCallerMistakesWithoutLosingTheArchive) {
  const WorldInfo w = make_world();
  std::vector<uint8_t> payload;
  test::BuiltNode root = test::make_synthetic_node(w, {5, 0, 0}, 1);
  ASSERT_TRUE(encode_node_payload(*root.data, {}, payload).ok());
  ArchiveWriter writer;
  EXPECT_EQ(writer.add_node(root.record, payload).code, Error::invalid_argument);  // not open
  ASSERT_TRUE(writer.open(path_).ok());
  ASSERT_TRUE(writer.add_node(root.record, payload).ok());
  EXPECT_EQ(writer.add_node(root.record, payload).code, Error::invalid_argument);  // duplicate
  NodeRecord bad = root.record;
  bad.key = {uint32_t(kMaxLevels), 0, 0};  // levels 6.. may be overview levels (SPEC 19): finish() checks them
  EXPECT_EQ(writer.add_node(bad, payload).code, Error::invalid_argument);  // level
  bad = root.record;
  bad.key = {5, 1, 0};
  bad.min_height = bad.max_height + 1;
  EXPECT_EQ(writer.add_node(bad, payload).code, Error::invalid_argument);  // min > max
  bad = root.record;
  bad.key = {5, 1, 0};
  std::vector<uint8_t> garbage(payload.size(), 0x7F);
  EXPECT_EQ(writer.add_node(bad, garbage).code, Error::invalid_argument);  // not a payload
  EXPECT_EQ(encode_node_payload(*root.data, {99, true}, payload).code, Error::invalid_argument);
  ASSERT_TRUE(writer.finish(w).ok());  // the good node still makes a valid archive
  ArchiveReader reader;
  ASSERT_TRUE(reader.open(path_).ok());
  EXPECT_EQ(reader.nodes().size(), 1u);
  EXPECT_TRUE(reader.verify().ok());
}

// Issue 48: the reader used to map the file, so a file cut short after open() raised SIGBUS on the
// first decode that touched a lost page. Now every node whose payload lies past the new end fails
// with `truncated`, naming the node and the sizes; the nodes before it still decode; nothing dies.
TEST_F(ArchiveRoundTrip, FileTruncatedAfterOpenFailsTheLostNodesByName) {
  ArchiveReader reader;
  ASSERT_NO_FATAL_FAILURE(open_sparse_world(reader));
  const uint64_t size = reader.file_size();
  const uint64_t half = size / 2;
  std::filesystem::resize_file(path_, half);
  auto data = std::make_unique<NodeData>();
  std::vector<uint8_t> bytes;
  size_t lost = 0, kept = 0;
  for (size_t i = 0; i < reader.nodes().size(); ++i) {
    const NodeRecord& r = reader.nodes()[i];
    const std::string name = node_name(r.key);
    const Status d = reader.decode_node(i, *data);
    const Status p = reader.read_payload(i, bytes);
    if (r.payload_offset + r.payload_size <= half) {
      ++kept;
      EXPECT_TRUE(d.ok()) << name << ": " << d.to_string();
      EXPECT_TRUE(p.ok()) << name << ": " << p.to_string();
      continue;
    }
    ++lost;
    for (const Status& s : {d, p}) {
      EXPECT_EQ(s.code, Error::truncated) << s.to_string();
      EXPECT_NE(s.message.find("node " + name + " at offset " + std::to_string(r.payload_offset)), std::string::npos) << s.message;
      EXPECT_NE(s.message.find("short read"), std::string::npos) << s.message;
      EXPECT_NE(s.message.find("the file ends at " + std::to_string(half) + " bytes, it had " + std::to_string(size)),
                std::string::npos)
          << s.message;
    }
  }
  EXPECT_GT(lost, 0u);
  EXPECT_GT(kept, 0u);
  EXPECT_EQ(reader.verify().code, Error::truncated);
  SectionBytes sections;
  EXPECT_EQ(reader.section_bytes(sections).code, Error::truncated);
  // The directory was copied at open(): lookups still answer.
  EXPECT_EQ(reader.find(reader.nodes().back().key), int64_t(reader.nodes().size() - 1));
  // Reopening sees the cut file as the truncated archive it now is.
  ArchiveReader again;
  const Status reopened = again.open(path_);
  EXPECT_EQ(reopened.code, Error::truncated) << reopened.to_string();
}

// The same through a caller's own ByteSource (what a remote source implements): its errors reach
// the caller of decode_node() with the node named in front.
TEST_F(ArchiveRoundTrip, ByteSourceErrorsReachTheCallerNamingTheNode) {
  ASSERT_TRUE(test::write_synthetic_archive(path_, world_, test::sparse_keys()).ok());
  struct FailingSource final : ByteSource {
    std::unique_ptr<ByteSource> inner;
    uint64_t fail_from = UINT64_MAX;  // set after open()
    std::string label = "flaky";
    uint64_t size() const override { return inner->size(); }
    const std::string& name() const override { return label; }
    Status read(uint64_t offset, std::span<uint8_t> dst) const override {
      if (offset >= fail_from) return Status::failure(Error::io_read, label + ": connection reset");
      return inner->read(offset, dst);
    }
  };
  auto source = std::make_unique<FailingSource>();
  ASSERT_TRUE(open_file_source(path_, source->inner).ok());
  FailingSource& raw = *source;
  ArchiveReader reader;
  ASSERT_TRUE(reader.open(std::move(source)).ok());
  EXPECT_EQ(reader.source(), &raw);
  raw.fail_from = reader.nodes()[0].payload_offset;  // every payload from here on
  auto data = std::make_unique<NodeData>();
  const Status s = reader.decode_node(0, *data);
  EXPECT_EQ(s.code, Error::io_read);
  EXPECT_EQ(s.message, "node " + node_name(reader.nodes()[0].key) + " at offset " +
                           std::to_string(reader.nodes()[0].payload_offset) + ": flaky: connection reset");
}

TEST_F(ArchiveRoundTrip, OpenFromMemoryMatchesOpenFromFile) {
  const WorldInfo w = make_world();
  ASSERT_TRUE(test::write_synthetic_archive(path_, w, test::sparse_keys()).ok());
  ArchiveReader a, b;
  ASSERT_TRUE(a.open(path_).ok());
  ASSERT_TRUE(b.open_memory(read_file(path_)).ok());
  ASSERT_EQ(a.nodes().size(), b.nodes().size());
  std::vector<uint8_t> pa, pb;
  for (size_t i = 0; i < a.nodes().size(); ++i) {
    ASSERT_TRUE(a.read_payload(i, pa).ok());
    ASSERT_TRUE(b.read_payload(i, pb).ok());
    EXPECT_EQ(pa, pb);
    EXPECT_EQ(pa.size(), a.nodes()[i].payload_size);
  }
  ArchiveReader closed;
  EXPECT_FALSE(closed.is_open());
  EXPECT_EQ(closed.find({5, 0, 0}), -1);
  EXPECT_TRUE(closed.nodes().empty());
  EXPECT_EQ(closed.open("/nonexistent/x.terrain").code, Error::io_open);
  EXPECT_EQ(closed.open(dir_.string()).code, Error::io_open);  // a directory
}

TEST_F(ArchiveRoundTrip, ConcurrentDecodesFromManyThreadsAgree) {
  ArchiveReader reader;
  ASSERT_NO_FATAL_FAILURE(open_sparse_world(reader));
  std::vector<std::unique_ptr<NodeData>> want;
  for (size_t i = 0; i < reader.nodes().size(); ++i) {
    want.push_back(std::make_unique<NodeData>());
    ASSERT_TRUE(reader.decode_node(i, *want.back()).ok());
  }
  std::atomic<int> mismatches{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      auto d = std::make_unique<NodeData>();
      for (int round = 0; round < 3; ++round)
        for (size_t i = size_t(t); i < reader.nodes().size(); i += 2) {
          if (!reader.decode_node(i, *d).ok() || d->heights != want[i]->heights || d->albedo_bc1 != want[i]->albedo_bc1)
            ++mismatches;
          if (reader.find(reader.nodes()[i].key) != int64_t(i)) ++mismatches;
        }
    });
  for (auto& th : threads) th.join();
  EXPECT_EQ(mismatches.load(), 0);
}

// ---- ordered mode (open_ordered, the merge of work units) ----
bool payload_order(const NodeKey& a, const NodeKey& b) {
  if (a.level != b.level) return a.level > b.level;
  return key_less(a, b);
}
ArchiveShape shape_of(const std::vector<NodeKey>& keys, const std::vector<std::vector<uint8_t>>& payloads) {
  ArchiveShape s;
  for (size_t i = 0; i < keys.size(); ++i) {
    ++s.level_nodes[keys[i].level];
    s.payload_bytes += payloads[i].size();
  }
  return s;
}

TEST_F(ArchiveRoundTrip, OrderedWriterGivesTheSameBytesAsTheDefaultOne) {
  const WorldInfo w = make_world();
  auto keys = test::sparse_keys();
  std::sort(keys.begin(), keys.end(), payload_order);
  std::vector<std::vector<uint8_t>> payloads(keys.size());
  std::vector<NodeRecord> records;
  for (size_t i = 0; i < keys.size(); ++i) {
    test::BuiltNode n = test::make_synthetic_node(w, keys[i], 1);
    n.record.child_mask = test::child_mask_of(keys, keys[i]);
    records.push_back(n.record);
    ASSERT_TRUE(encode_node_payload(*n.data, {}, payloads[i]).ok());
  }
  ArchiveWriter a, b;
  ASSERT_TRUE(a.open(path_).ok());
  ASSERT_TRUE(b.open_ordered(path_ + "2", shape_of(keys, payloads)).ok());
  for (size_t i = 0; i < keys.size(); ++i) {
    ASSERT_TRUE(a.add_node(records[i], payloads[i]).ok());
    uint32_t crc = 0;
    const Status s = b.add_node(records[i], payloads[i], &crc);
    ASSERT_TRUE(s.ok()) << s.to_string();
    EXPECT_EQ(crc, uint32_t(::crc32(0, payloads[i].data(), uInt(payloads[i].size()))));
  }
  ASSERT_TRUE(a.finish(w).ok());
  const Status s = b.finish(w);
  ASSERT_TRUE(s.ok()) << s.to_string();
  EXPECT_GT(keys.size(), 20u);
  EXPECT_EQ(read_file(path_ + "2"), read_file(path_));
  EXPECT_EQ(a.section_bytes().stored[0], b.section_bytes().stored[0]);
  ArchiveReader reader;
  ASSERT_TRUE(reader.open(path_ + "2").ok());
  SectionBytes sb;
  ASSERT_TRUE(reader.section_bytes(sb).ok());
  for (int k = 0; k < 5; ++k) {
    EXPECT_EQ(b.section_bytes().stored[k], sb.stored[k]);
    EXPECT_EQ(b.section_bytes().raw[k], sb.raw[k]);
  }
  EXPECT_GT(sb.stored[0], 0u);
  // The split by level (terrain-inspect's and the cook report's bytes per km2): the writer's and the
  // reader's agree, each level's bytes are its nodes' payload tables, and the levels add up.
  std::vector<uint64_t> level_bytes(kMaxLevels, 0), level_nodes(kMaxLevels, 0);
  for (size_t i = 0; i < keys.size(); ++i) {
    ++level_nodes[keys[i].level];
    // SPEC "Payload": the sections' stored bytes fill the payload behind its table.
    level_bytes[keys[i].level] += payloads[i].size() - (4 + layout::kSectionCount * layout::kPayloadTableEntrySize);
  }
  int levels_seen = 0;
  for (int l = 0; l < kMaxLevels; ++l) {
    uint64_t reader_sum = 0;
    for (int k = 0; k < 5; ++k) {
      EXPECT_EQ(b.section_bytes().stored_by_level[l][k], sb.stored_by_level[l][k]) << "level " << l << " section " << k;
      reader_sum += sb.stored_by_level[l][k];
    }
    EXPECT_EQ(reader_sum, level_bytes[size_t(l)]) << "level " << l;
    EXPECT_EQ(sb.nodes_by_level[l], level_nodes[size_t(l)]) << "level " << l;
    levels_seen += level_nodes[size_t(l)] > 0;
  }
  EXPECT_GE(levels_seen, 3);  // the split is tested across levels, not on one
  for (int k = 0; k < 5; ++k) {
    uint64_t by_level = 0;
    for (int l = 0; l < kMaxLevels; ++l) by_level += sb.stored_by_level[l][k];
    EXPECT_EQ(by_level, sb.stored[k]) << "section " << k;
  }
}

// The merge of a national cook hands its writer 10^7 nodes and more: in ordered mode nothing may
// grow with them. Measured as the heap in use (mallinfo2) after the first node and after the
// last; the default writer, which holds every record until finish() (48 bytes each plus its
// duplicate-key set), is the control that shows the measure sees per-node memory.
TEST_F(ArchiveRoundTrip, TheOrderedWriterHoldsNothingPerNode) {
  const WorldInfo w = make_world(8, 4);  // 32 roots, every node of every level: 43 680 nodes
  std::vector<NodeKey> keys;              // payload order: level 5 first, then by y, x
  for (int level = kRootLevel; level >= 0; --level)
    for (uint32_t y = 0; y < uint32_t(level_grid_cells(w.roots_y, level)); ++y)
      for (uint32_t x = 0; x < uint32_t(level_grid_cells(w.roots_x, level)); ++x) keys.push_back({uint32_t(level), x, y});
  const auto flat = std::make_unique<NodeData>();  // one small payload for every node
  std::vector<uint8_t> payload;
  ASSERT_TRUE(encode_node_payload(*flat, {}, payload).ok());
  ArchiveShape shape;
  for (const NodeKey& k : keys) ++shape.level_nodes[k.level];
  shape.payload_bytes = uint64_t(payload.size()) * keys.size();
  auto growth = [&](bool ordered, const std::string& path) -> int64_t {
    ArchiveWriter writer;
    EXPECT_TRUE((ordered ? writer.open_ordered(path, shape) : writer.open(path)).ok());
    int64_t first = 0;
    for (size_t i = 0; i < keys.size(); ++i) {
      NodeRecord r;
      r.key = keys[i];
      r.child_mask = keys[i].level > 0 ? 0xF : 0;
      const Status s = writer.add_node(r, payload);
      if (!s.ok()) {
        ADD_FAILURE() << s.to_string();
        return -1;
      }
      if (i == 0) first = test::heap_in_use();
    }
    const int64_t last = test::heap_in_use();
    const Status s = writer.finish(w);
    EXPECT_TRUE(s.ok()) << s.to_string();
    return last - first;
  };
  const int64_t ordered = growth(true, path_), held = growth(false, path_ + "2");
  std::printf("heap growth over %zu nodes: ordered writer %lld bytes, default writer %lld bytes\n", keys.size(),
              static_cast<long long>(ordered), static_cast<long long>(held));
  EXPECT_EQ(read_file(path_), read_file(path_ + "2"));
  EXPECT_GT(keys.size(), 40000u);
  if (test::kSanitizedHeap) return;  // mallinfo2 does not see a sanitizer's heap; the bytes are checked
  EXPECT_GT(held, int64_t(48 * keys.size())) << "the control: the default writer holds every record";
  EXPECT_LT(ordered, int64_t(256) << 10) << "ordered writer: " << ordered << " bytes more after " << keys.size() << " nodes";
}

TEST_F(ArchiveRoundTrip, OrderedWriterRefusesWhatTheDefaultOneRefuses) {
  const WorldInfo w = make_world(1, 1);
  auto keys = test::close_tree({{0, 4, 3}, {0, 30, 17}});
  std::sort(keys.begin(), keys.end(), payload_order);
  std::vector<std::vector<uint8_t>> payloads(keys.size());
  std::vector<NodeRecord> records;
  for (size_t i = 0; i < keys.size(); ++i) {
    test::BuiltNode n = test::make_seed_node(w, keys[i]);
    n.record.child_mask = test::child_mask_of(keys, keys[i]);
    records.push_back(n.record);
    ASSERT_TRUE(encode_node_payload(*n.data, {}, payloads[i]).ok());
  }
  // variant: 0 bit clear but child exists, 1 bit set but child absent, 2 two nodes swapped,
  // (refused by the tree check: the first level-3 node is not 3/0/0), 3 a node missing from the
  // shape's count, 4 a level-0 node dropped (its parent's bit dangles)
  for (int variant = 0; variant < 5; ++variant) {
    std::vector<NodeRecord> r = records;
    std::vector<std::vector<uint8_t>> p = payloads;
    std::vector<NodeKey> k = keys;
    ArchiveShape shape = shape_of(keys, payloads);
    for (NodeRecord& n : r)
      if (n.key == NodeKey{2, 1, 0}) n.child_mask = variant == 0 ? 0 : variant == 1 ? uint8_t(n.child_mask | 1) : n.child_mask;
    if (variant == 2) std::swap(r[3], r[4]), std::swap(p[3], p[4]);
    if (variant == 3) ++shape.level_nodes[0];
    if (variant == 4) {
      shape.level_nodes[0] -= 1;
      shape.payload_bytes -= p.back().size();
      r.pop_back();
      p.pop_back();
    }
    ArchiveWriter writer;
    ASSERT_TRUE(writer.open_ordered(path_, shape).ok());
    Status s = Status::success();
    for (size_t i = 0; i < r.size() && s.ok(); ++i) s = writer.add_node(r[i], p[i]);
    if (s.ok()) s = writer.finish(w);
    EXPECT_FALSE(s.ok()) << variant;
    if (variant <= 1 || variant == 4) {
      EXPECT_EQ(s.code, Error::directory_invalid) << variant << ": " << s.to_string();
      EXPECT_NE(s.message.find("child_mask bit"), std::string::npos) << s.message;
    }
    if (variant == 0) {
      EXPECT_NE(s.message.find("parent 2/1/0"), std::string::npos) << s.message;
    }
    if (variant == 1) {
      EXPECT_NE(s.message.find("node 2/1/0: child_mask bit 0 is set"), std::string::npos) << s.message;
    }
    if (variant == 3) {
      EXPECT_EQ(s.code, Error::invalid_argument) << variant << ": " << s.to_string();
    }
    EXPECT_FALSE(std::filesystem::exists(path_)) << variant;
  }
}

}  // namespace
}  // namespace terrain
