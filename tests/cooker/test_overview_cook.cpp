// Overview levels written by the cooker (format/SPEC.md section 19, issue 15): the archive
// verifies, the streamer opens it with its default budget, every overview vertex is its children's
// even vertex (rule 7), overview errors bound their children's (rule 8), the bytes do not depend
// on threads, blocks or work units, and `auto` leaves small worlds' bytes as they were.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>

#include "cooker_test_util.h"
#include "heap_in_use.h"
#include "pyramid/overview_levels.h"
#include "terrain/bc_decode.h"
#include "terrain/streamer.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;

namespace {

std::string file_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

// A node's 129 x 129 units and hole flags as a renderer sees them.
struct Vertices {
  std::vector<int32_t> units = std::vector<int32_t>(kHeightCount);
  std::vector<uint8_t> hole = std::vector<uint8_t>(kHeightCount);
};

Status node_vertices(const ArchiveReader& r, size_t index, Vertices& out) {
  auto data = std::make_unique<NodeData>();
  TERRAIN_TRY(r.decode_node(index, *data, kSectionHeights | kSectionAlbedo));
  const NodeRecord& rec = r.nodes()[index];
  const int step = level_step_log2(r.world(), int(rec.key.level));
  std::vector<uint8_t> rgba(size_t(kTexels) * kTexels * 4);
  decode_bc1_image(data->albedo_bc1.data(), kTexelBlocks, kTexelBlocks, rgba.data());
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) {
      const size_t k = size_t(j * kHeightSamples + i);
      out.units[k] = rec.height_offset + int32_t(uint32_t(data->heights[k]) << step);
      out.hole[k] = rgba[(size_t(j + kApron) * kTexels + size_t(i + kApron)) * 4 + 3] == 0;
    }
  return Status::success();
}

// One scratch folder for the whole run (scratch_dir() empties it on every call).
const std::filesystem::path& scratch() {
  static const std::filesystem::path dir = scratch_dir("overview-cook");
  return dir;
}

cook::CookOptions kilauea_options(const std::string& name) {
  cook::CookOptions o;
  o.inputs = {data_file("kilauea_utm5n.tif").string()};
  o.output = (scratch() / (name + ".terrain")).string();
  o.threads = 2;
  o.finest_level = 4;  // roots and one level below them: fast, and level 4 shares the roots' vertices
  o.overview_levels = cook::OverviewMode::on;
  return o;
}

TEST(OverviewCook, KilaueaOverviewNodesAreTheirChildrensEvenVertices) {
  const auto dem = data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(dem);
  const cook::CookOptions o = kilauea_options("kilauea-on");
  cook::CookReport report;
  const Status st = cook::cook(o, nullptr, report);
  ASSERT_TRUE(st.ok()) << st.message;
  ArchiveReader r;
  ASSERT_TRUE(r.open(o.output).ok());
  ASSERT_TRUE(r.verify().ok()) << r.verify().message;
  const WorldInfo& w = r.world();
  // 13 x 13 roots: 7 x 7 level-6 nodes, 4 x 4 at level 7 (at most 16): K = 2.
  ASSERT_EQ(w.roots_x, 13u);
  ASSERT_EQ(w.roots_y, 13u);
  ASSERT_EQ(w.overview_step_log2.size(), 2u);
  ASSERT_EQ(overview_levels_needed(w.roots_x, w.roots_y), 2);
  EXPECT_EQ(report.overview_levels, 2);
  EXPECT_GE(w.overview_step_log2[0], w.step_log2[kRootLevel]);
  EXPECT_EQ(report.overview_nodes, r.level_nodes(6).size() + r.level_nodes(7).size());
  EXPECT_LE(r.level_nodes(7).size(), size_t(kMaxTopNodes));
  EXPECT_GE(r.level_nodes(7).size(), 9u);
  std::printf("kilauea: %zu roots, %zu + %zu overview nodes, steps 2^%d (roots 2^%d), overview error max %.3f m, "
              "overview cpu %.2f s of %.2f s\n",
              r.level_nodes(kRootLevel).size(), r.level_nodes(6).size(), r.level_nodes(7).size(),
              int(w.overview_step_log2[0]), int(w.step_log2[kRootLevel]), report.overview_error_max_m,
              report.cpu_overview, report.cpu_total);

  // Every root has a parent (closed upward).
  for (const NodeRecord& root : r.level_nodes(kRootLevel)) EXPECT_GE(r.find(parent_of(root.key)), 0);
  uint64_t compared = 0, parent_only = 0;
  for (int level = 6; level <= top_level(w); ++level)
    for (const NodeRecord& rec : r.level_nodes(level)) {
      const int64_t pi = r.find(rec.key);
      ASSERT_GE(pi, 0);
      Vertices parent;
      ASSERT_TRUE(node_vertices(r, size_t(pi), parent).ok());
      std::vector<uint8_t> held(kHeightCount, 0);  // parent vertices some child holds as non-hole
      float child_error = 0;
      for (int c = 0; c < 4; ++c) {
        const int64_t ci = r.find(child_of(rec.key, c));
        EXPECT_EQ((rec.child_mask >> c) & 1, ci >= 0 ? 1 : 0) << level << "/" << rec.key.x << "/" << rec.key.y;
        if (ci < 0) continue;
        child_error = std::max(child_error, r.nodes()[size_t(ci)].geometric_error_m);
        Vertices child;
        ASSERT_TRUE(node_vertices(r, size_t(ci), child).ok());
        for (int j = 0; j < kHeightSamples; j += 2)
          for (int i = 0; i < kHeightSamples; i += 2) {
            const size_t k = size_t(j * kHeightSamples + i);
            const size_t pk = size_t((64 * (c >> 1) + j / 2) * kHeightSamples + 64 * (c & 1) + i / 2);
            if (child.hole[k]) continue;
            held[pk] = 1;
            ASSERT_FALSE(parent.hole[pk]) << "a child's vertex is a hole in the parent";
            ASSERT_EQ(parent.units[pk], child.units[k]) << "level " << level << " node " << rec.key.x << "/" << rec.key.y;
            ++compared;
          }
      }
      for (size_t k = 0; k < size_t(kHeightCount); ++k) parent_only += !parent.hole[k] && !held[k];
      EXPECT_GE(rec.geometric_error_m, child_error) << level << "/" << rec.key.x << "/" << rec.key.y;
    }
  EXPECT_GT(compared, 100000u);
  // Coarser levels deviate more from the source: the top's largest error exceeds the roots'.
  float root_max = 0, top_max = 0;
  for (const NodeRecord& n : r.level_nodes(kRootLevel)) root_max = std::max(root_max, n.geometric_error_m);
  for (const NodeRecord& n : r.level_nodes(top_level(w))) top_max = std::max(top_max, n.geometric_error_m);
  EXPECT_GT(top_max, root_max);
  EXPECT_EQ(parent_only, 0u) << "an overview vertex no child holds must be a hole";

  // Against the same cook without overview levels: with a coarser overview step the roots' even
  // vertices move by at most half of it (rule 7) and their odd vertices not at all.
  cook::CookOptions off = o;
  off.output = (scratch() / "kilauea-off.terrain").string();
  off.overview_levels = cook::OverviewMode::off;
  cook::CookReport report_off;
  ASSERT_TRUE(cook::cook(off, nullptr, report_off).ok());
  ArchiveReader ro;
  ASSERT_TRUE(ro.open(off.output).ok());
  ASSERT_EQ(ro.level_nodes(kRootLevel).size(), r.level_nodes(kRootLevel).size());
  int32_t even_moved_max = 0;
  uint64_t even_moved = 0, odd_moved = 0, even_total = 0;
  double error_change_max = 0;
  for (const NodeRecord& root : r.level_nodes(kRootLevel)) {
    const int64_t a = r.find(root.key), b = ro.find(root.key);
    ASSERT_GE(b, 0);
    Vertices va, vb;
    ASSERT_TRUE(node_vertices(r, size_t(a), va).ok());
    ASSERT_TRUE(node_vertices(ro, size_t(b), vb).ok());
    for (int j = 0; j < kHeightSamples; ++j)
      for (int i = 0; i < kHeightSamples; ++i) {
        const size_t k = size_t(j * kHeightSamples + i);
        ASSERT_EQ(va.hole[k], vb.hole[k]);
        if (va.hole[k]) continue;
        const int32_t d = std::abs(va.units[k] - vb.units[k]);
        if ((i | j) & 1) {
          odd_moved += d != 0;
        } else {
          ++even_total;
          even_moved += d != 0;
          even_moved_max = std::max(even_moved_max, d);
        }
      }
    error_change_max = std::max(error_change_max, std::fabs(double(root.geometric_error_m) -
                                                            double(ro.nodes()[size_t(b)].geometric_error_m)));
  }
  EXPECT_EQ(odd_moved, 0u);
  if (w.overview_step_log2[0] == w.step_log2[kRootLevel]) {
    EXPECT_EQ(even_moved, 0u);
  } else {
    EXPECT_GT(even_moved, 0u);
    EXPECT_LE(even_moved_max, 1 << (w.overview_step_log2[0] - 1));
  }
  std::printf("kilauea roots against the cook without overview levels: %llu of %llu even vertices moved, by at most %d "
              "units (%.1f mm); odd vertices moved: %llu; root error changed by at most %.4f m\n",
              static_cast<unsigned long long>(even_moved), static_cast<unsigned long long>(even_total), even_moved_max,
              even_moved_max * kHeightUnitM * 1000.0, static_cast<unsigned long long>(odd_moved), error_change_max);

  // The streamer opens it with its default budget (512) and keeps the top level resident.
  Streamer s;
  ASSERT_TRUE(s.open(o.output).ok());
  EXPECT_EQ(s.world().overview_step_log2.size(), 2u);
}

// The same bytes at 1 and 2 threads, in blocks and in one, and through plan/unit/merge.
TEST(OverviewCook, SameBytesForThreadsBlocksAndWorkUnits) {
  const auto dem = data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(dem);
  cook::CookOptions base = kilauea_options("det-base");
  base.block_roots = 4096;  // one block: spooled anyway (the overview levels read the roots back)
  cook::CookReport whole;
  ASSERT_TRUE(cook::cook(base, nullptr, whole).ok());
  ASSERT_EQ(whole.blocks, 1u);
  ASSERT_GT(whole.overview_nodes, 0u);
  const std::string expected = file_bytes(base.output);
  ASSERT_GT(expected.size(), 100000u);
  struct Run {
    const char* name;
    int threads;
    uint32_t block_roots;
    bool units;
  };
  for (const Run& run : {Run{"det-t1", 1, 4096, false}, Run{"det-blocks", 2, 4, false}, Run{"det-units", 2, 0, true}}) {
    cook::CookOptions o = base;
    o.output = (scratch() / (std::string(run.name) + ".terrain")).string();
    o.threads = run.threads;
    o.block_roots = run.block_roots;
    if (run.units) {
      o.block_roots = 0;
      o.work_dir = (scratch() / "work").string();
      std::filesystem::remove_all(o.work_dir);
      o.unit_roots = 5;
    }
    cook::CookReport r;
    const Status st = cook::cook(o, nullptr, r);
    ASSERT_TRUE(st.ok()) << run.name << ": " << st.message;
    EXPECT_EQ(r.overview_nodes, whole.overview_nodes) << run.name;
    EXPECT_TRUE(file_bytes(o.output) == expected) << run.name << ": " << o.output << " differs from " << base.output;
  }
}

// `auto` on a world of at most kOverviewAutoRoots root cells is `off`, byte for byte (version 1).
// 100 x 100 roots (10^4; a country has 10^5): the overview levels keep a band of the level-6
// lattice's rows in memory, never the lattice (6401 x 6401 vertices, 164 MB at 4 bytes). Every
// root is the same flat payload, so the work is the overview levels' own. Peak heap growth is
// sampled at every node handed out.
TEST(OverviewCook, TenThousandRootsNeedABandOfTheLatticeNotTheLattice) {
  const uint32_t side = 100;
  cook::OverviewSettings s;
  s.world.roots_x = s.world.roots_y = side;
  s.world.step_log2 = {0, 0, 0, 0, 0, 0};
  s.world.overview_step_log2.assign(size_t(overview_levels_needed(side, side)), 0);
  s.heights_only = true;
  s.threads = 2;
  const auto dir = std::filesystem::temp_directory_path() / ("overview-band-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  s.scratch_path = (dir / "lattice").string();
  std::vector<uint8_t> payload;
  {
    auto flat = std::make_unique<NodeData>();
    ASSERT_TRUE(encode_node_payload(*flat, {}, payload).ok());
  }
  cook::RootSource roots;
  for (uint32_t y = 0; y < side; ++y)
    for (uint32_t x = 0; x < side; ++x) {
      NodeRecord r;
      r.key = {uint32_t(kRootLevel), x, y};
      r.height_offset = r.min_height = r.max_height = 4096;
      roots.roots.push_back(r);
    }
  roots.read = [&](size_t, std::vector<uint8_t>& out) {
    out = payload;
    return Status::success();
  };
  const int64_t base = test::heap_in_use();
  int64_t peak = 0;
  size_t nodes = 0, top = 0;
  cook::OverviewStats stats;
  const Status st = cook::write_overview_levels(
      s, roots,
      [&](const NodeRecord& r, std::span<const uint8_t>) {
        peak = std::max(peak, test::heap_in_use() - base);
        ++nodes;
        top += r.key.level == uint32_t(kRootLevel + s.world.overview_step_log2.size());
        EXPECT_EQ(r.min_height, 4096);  // flat: every overview vertex is the roots' height
        EXPECT_EQ(r.max_height, 4096);
        return Status::success();
      },
      stats);
  std::filesystem::remove_all(dir);
  ASSERT_TRUE(st.ok()) << st.to_string();
  // 50 x 50 + 25 x 25 + 13 x 13 + 7 x 7 + 4 x 4 nodes, every one over some root.
  EXPECT_EQ(nodes, 2500u + 625u + 169u + 49u + 16u);
  EXPECT_EQ(top, 16u);
  const double lattice_mb = 6401.0 * 6401.0 * 4.0 / 1e6;
  std::printf("10^4 roots: peak heap growth %.1f MB while building %zu overview nodes (the whole lattice: %.0f MB)\n",
              double(peak) / 1e6, nodes, lattice_mb);
  // A band: 329 rows of 6401 vertices (8.4 MB) plus a row buffer, the root grid and the batch.
  // (Not under a sanitizer: mallinfo2 does not see its heap. The nodes are checked there too.)
  if (!test::kSanitizedHeap) {
    EXPECT_LT(double(peak) / 1e6, 24.0);
  }
}

TEST(OverviewCook, AutoOnASmallWorldIsOff) {
  const auto dem = data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(dem);
  cook::CookOptions a = kilauea_options("auto");
  a.finest_level = 5;
  a.heights_only = true;
  a.overview_levels = cook::OverviewMode::automatic;
  cook::CookOptions off = a;
  off.output = (scratch() / "off.terrain").string();
  off.overview_levels = cook::OverviewMode::off;
  cook::CookReport ra, ro;
  ASSERT_TRUE(cook::cook(a, nullptr, ra).ok());
  ASSERT_TRUE(cook::cook(off, nullptr, ro).ok());
  EXPECT_LE(uint64_t(ra.roots_x) * ra.roots_y, cook::kOverviewAutoRoots);
  EXPECT_EQ(ra.overview_levels, 0);
  EXPECT_EQ(ra.spool_bytes, 0u);  // one block, not spooled: the path of today's cook
  EXPECT_TRUE(file_bytes(a.output) == file_bytes(off.output));
  ArchiveReader r;
  ASSERT_TRUE(r.open(a.output).ok());
  EXPECT_TRUE(r.world().overview_step_log2.empty());
  EXPECT_EQ(r.format_version(), 3u);  // every archive is version 3 (SPEC 20)
}

// A 1 x 1 degree SRTM tile (~3000 roots): the default cook has overview levels, verifies and
// opens in the streamer's default budget. Roots only (--finest-level 5) to stay fast.
TEST(OverviewCook, SrtmTileOpensWithTheDefaultBudget) {
  const auto dem = data_file("N22W160.hgt.zip");
  TERRAIN_REQUIRE_DATA(dem);
  cook::CookOptions o;
  o.inputs = {dem.string()};
  o.output = (scratch() / "n22w160.terrain").string();
  o.threads = 2;
  o.finest_level = 5;
  cook::CookReport report;
  const Status st = cook::cook(o, nullptr, report);
  ASSERT_TRUE(st.ok()) << st.message;
  ArchiveReader r;
  ASSERT_TRUE(r.open(o.output).ok());
  ASSERT_TRUE(r.verify().ok());
  const WorldInfo& w = r.world();
  EXPECT_GT(uint64_t(w.roots_x) * w.roots_y, cook::kOverviewAutoRoots);
  EXPECT_GT(r.level_nodes(kRootLevel).size(), 512u);
  EXPECT_EQ(int(w.overview_step_log2.size()), overview_levels_needed(w.roots_x, w.roots_y));
  EXPECT_LE(r.level_nodes(top_level(w)).size(), size_t(kMaxTopNodes));
  std::printf("N22W160: %u x %u root cells, %zu roots, %d overview levels (step 2^%d, roots 2^%d, range bound %.1f m), "
              "%llu overview nodes, error max %.2f m, overview cpu %.2f s of %.2f s\n",
              w.roots_x, w.roots_y, r.level_nodes(kRootLevel).size(), int(w.overview_step_log2.size()),
              int(w.overview_step_log2[0]), int(w.step_log2[kRootLevel]), report.overview_range_bound_m,
              static_cast<unsigned long long>(report.overview_nodes), report.overview_error_max_m,
              report.cpu_overview, report.cpu_total);
  Streamer s;
  const Status so = s.open(o.output);
  ASSERT_TRUE(so.ok()) << so.message;
}

}  // namespace
