// The block-wise cook (issue 13): the archive must not change by one byte whatever the block size
// (--block-roots) and the order blocks are cooked in (--block-order), and a block reads only its
// window of the source. Each case compares whole files against the cook in one block.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "session/cook_session.h"
#include "cooker_test_util.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;

namespace {

std::string file_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

struct BlockRun {
  uint32_t block_roots;
  uint64_t order_seed;
};

// Cooks `base` once as one block and once per run; every archive must equal the first.
// `smaller_windows`: blocks must read less than the whole source (false for sources so small that
// a block's window, grown to whole void-plan tiles, covers them).
void expect_same_bytes_for_every_block_split(cook::CookOptions base, const std::vector<BlockRun>& runs,
                                             uint32_t min_blocks_in_split = 2, bool smaller_windows = true) {
  base.block_roots = 4096;  // one block holds every root
  cook::CookReport whole;
  const std::string whole_path = base.output;
  ASSERT_TRUE(cook::cook(base, nullptr, whole).ok());
  ASSERT_EQ(whole.blocks, 1u);
  EXPECT_EQ(whole.spool_bytes, 0u);
  const std::string expected = file_bytes(whole_path);
  ASSERT_GT(expected.size(), 1000u);
  for (const BlockRun& run : runs) {
    cook::CookOptions o = base;
    o.block_roots = run.block_roots;
    o.block_order = run.order_seed;
    o.output = whole_path + ".b" + std::to_string(run.block_roots) + "s" + std::to_string(run.order_seed);
    cook::CookReport r;
    const Status st = cook::cook(o, nullptr, r);
    ASSERT_TRUE(st.ok()) << st.message;
    EXPECT_GE(r.blocks, min_blocks_in_split) << "block_roots " << run.block_roots;
    EXPECT_GT(r.spool_bytes, 0u);
    // Each block reads only a window: at most the block's roots plus margins, never the source.
    if (smaller_windows) EXPECT_LT(r.block_window_samples_max, whole.block_window_samples_max);
    else EXPECT_LE(r.block_window_samples_max, whole.block_window_samples_max);
    EXPECT_EQ(r.nodes, whole.nodes);
    EXPECT_TRUE(file_bytes(o.output) == expected)
        << "block_roots " << run.block_roots << ", order seed " << run.order_seed << ": " << o.output
        << " differs from " << whole_path;
    // No spool file is left behind.
    for (const auto& e : std::filesystem::directory_iterator(std::filesystem::path(o.output).parent_path()))
      EXPECT_EQ(e.path().string().find(".spool-"), std::string::npos) << e.path();
  }
}

// Hills, a cliff and voids placed across root boundaries: an enclosed void filled harmonically
// that straddles a block edge, a lake too large to fill (a hole) across another, a void on the
// raster's border (a hole).
SyntheticDem blocky_dem() {
  SyntheticDem d;
  d.width = 1400;
  d.height = 1100;
  d.dx = d.dy = 4.0;
  d.x0 = 500002.0;  // sample centres; the frame origin is a multiple of 2048 m below
  d.y0 = 5200002.0;
  d.epsg_projected = 32632;
  d.values.resize(size_t(d.width) * size_t(d.height));
  for (int r = 0; r < d.height; ++r)
    for (int c = 0; c < d.width; ++c) {
      const double x = c * 4.0, y = r * 4.0;
      double h = 800 + 120 * std::sin(x / 700.0) * std::cos(y / 530.0) + 15 * std::sin(x / 37.0 + y / 53.0);
      if (x > 3000) h += 140;  // a 140 m cliff
      d.at(c, r) = h;
    }
  auto punch = [&](int c0, int r0, int c1, int r1) {
    for (int r = r0; r <= r1; ++r)
      for (int c = c0; c <= c1; ++c) d.at(c, r) = NAN;
  };
  // Frame x = 500000 + 4 c: a root edge at x = 501760 + 2048 k (origin floor(500000 / 2048) * 2048
  // = 499712), i.e. columns 440, 952; rows likewise cross y roots.
  punch(430, 300, 452, 330);    // 23 x 31 = 713 samples: filled, straddling column 440
  punch(900, 500, 1010, 640);   // 111 x 141: larger than --fill-max 4096: a hole, across column 952
  punch(0, 700, 25, 760);       // on the western border: a hole
  return d;
}

// The plan-size refusal (cook_session.h check_plan_size) at its bounds, without cooking anything:
// 65536 roots per side (kStreamerMaxRootsPerSide, the format's and the streamer's limit) is the
// widest plan, with --force or without; kMaxPlannedRoots roots in all needs --force beyond it.
TEST(PlanSize, RefusedJustPastEachBoundAndAcceptedAtIt) {
  ASSERT_EQ(kStreamerMaxRootsPerSide, 65536u);
  const double side = kStreamerMaxRootsPerSide;
  EXPECT_TRUE(cook::check_plan_size(side, 1, false, 1, 1).ok());
  EXPECT_TRUE(cook::check_plan_size(1, side, false, 1, 1).ok());
  EXPECT_TRUE(cook::check_plan_size(side, 15, false, 1, 1).ok());  // 983 040 roots: under 10^6
  for (const bool force : {false, true}) {
    const Status wide = cook::check_plan_size(side + 1, 1, force, 134219, 2);
    EXPECT_EQ(wide.code, Error::unsupported_input);
    EXPECT_NE(wide.message.find("65537 x 1 root nodes"), std::string::npos) << wide.message;
    EXPECT_NE(wide.message.find("beyond 65536 per side"), std::string::npos) << wide.message;
    EXPECT_EQ(wide.message.find("--force"), std::string::npos) << "--force cannot help: " << wide.message;
    EXPECT_FALSE(cook::check_plan_size(1, side + 1, force, 2, 134219).ok());
  }
  EXPECT_TRUE(cook::check_plan_size(1000, 1000, false, 1, 1).ok());  // 10^6 = kMaxPlannedRoots
  const Status many = cook::check_plan_size(1000, 1001, false, 1, 1);
  EXPECT_EQ(many.code, Error::unsupported_input);
  EXPECT_NE(many.message.find("beyond 1000000 roots"), std::string::npos) << many.message;
  EXPECT_NE(many.message.find("--force"), std::string::npos) << many.message;
  EXPECT_TRUE(cook::check_plan_size(1000, 1001, true, 1, 1).ok());
}

TEST(BlockCook, BlockSizeAndOrderDoNotChangeAByteOnSyntheticVoidsAndCliffs) {
  cook::CookOptions o;
  ASSERT_NO_FATAL_FAILURE(write_cook_input(scratch_dir("block-synthetic"), "blocky", blocky_dem(), true, o));
  o.threads = 2;
  o.heights_only = true;
  expect_same_bytes_for_every_block_split(o, {{1, 0}, {1, 3}, {2, 5}}, 4);
}

// The steps' range bound (range_summary.h, format/SPEC.md section 7), taken in the first pass
// from cells of the source and from the rims of filled voids, holds for every cooked node: its
// quantized range is at most the level's bound plus one root step (values are rounded at coarser
// levels by up to half a step each way), so it fits the level's step in 16 bits. Returns the
// widest quantized range per level (units).
std::array<int64_t, kLevelCount> expect_range_bound_holds(const cook::CookOptions& o, cook::CookReport& r) {
  std::array<int64_t, kLevelCount> widest{};
  const Status st = cook::cook(o, nullptr, r);
  EXPECT_TRUE(st.ok()) << st.message;
  ArchiveReader reader;
  EXPECT_TRUE(reader.open(o.output).ok());
  for (const NodeRecord& n : reader.nodes()) {
    // Levels 0-5 only: overview levels (a world of more than 256 roots, SPEC 19) take their step
    // from their own bound (cooker.overview_levels checks them).
    if (n.key.level > uint32_t(kRootLevel)) continue;
    int64_t& w = widest[n.key.level];
    w = std::max(w, int64_t(n.max_height) - int64_t(n.min_height));
  }
  const double root_step = std::ldexp(1.0, r.levels[kRootLevel].step_log2);
  for (int l = 0; l < kLevelCount; ++l)
    if (r.levels[size_t(l)].nodes)
      std::printf("level %d: bound %.3f m, widest node %.3f m, step 2^%d\n", l, r.levels[size_t(l)].range_bound_m,
                  double(widest[size_t(l)]) / 1024.0, r.levels[size_t(l)].step_log2);
  for (int l = 0; l < kLevelCount; ++l) {
    const cook::LevelStats& ls = r.levels[size_t(l)];
    if (ls.nodes == 0) continue;
    EXPECT_GT(ls.range_bound_m, 0.0) << "level " << l;
    EXPECT_LE(double(widest[size_t(l)]), ls.range_bound_m * 1024.0 + root_step) << "level " << l;
    EXPECT_LE(widest[size_t(l)] >> ls.step_log2, 65535) << "level " << l;
  }
  return widest;
}

TEST(BlockCook, RangeBoundHoldsOverACliffAndFilledVoids) {
  cook::CookOptions o;
  ASSERT_NO_FATAL_FAILURE(write_cook_input(scratch_dir("block-bound"), "blocky", blocky_dem(), true, o));
  o.threads = 2;
  o.heights_only = true;
  cook::CookReport r;
  const auto widest = expect_range_bound_holds(o, r);
  EXPECT_GT(r.voids_filled_samples, 700u);  // the void across a tile and root edge is filled
  // The 140 m cliff and the hills: a root spans ~400 m of relief; the bound is conservative but
  // not wild (measured: 487 m against 386 m at the roots).
  EXPECT_GT(double(widest[kRootLevel]) / 1024.0, 300.0);
  EXPECT_LT(r.levels[kRootLevel].range_bound_m, 1.5 * double(widest[kRootLevel]) / 1024.0);
}

// Kauai: voids on the Na Pali cliffs, filled across void-plan tiles (their rims span up to 1216 m):
// measured bound 1998 m at levels 3..5 (the steps pass bounded 1502..1632 m) against 724..1125 m.
TEST(BlockCook, RangeBoundHoldsOnRealCliffsWithVoids) {
  const auto dem = data_file("N22W160.hgt.zip");
  TERRAIN_REQUIRE_DATA(dem);
  cook::CookOptions o;
  o.inputs = {dem.string()};
  o.output = (scratch_dir("block-bound-kauai") / "kauai.terrain").string();
  o.threads = 2;
  o.heights_only = true;
  o.tolerance_m = 0.5;  // steps of 2^4 units from the tolerance: the range bound decides levels 3..5
  cook::CookReport r;
  const auto widest = expect_range_bound_holds(o, r);
  EXPECT_EQ(r.voids_filled_samples, 4279u);
  EXPECT_GT(double(widest[kRootLevel]) / 1024.0, 1000.0);
  EXPECT_LT(r.levels[kRootLevel].range_bound_m, 2048.0);  // the step of 2^5 units holds it
  for (int l = 3; l <= kRootLevel; ++l) EXPECT_EQ(r.levels[size_t(l)].step_log2, 5) << "level " << l;
}

TEST(BlockCook, SurfaceLayersToo) {
  cook::CookOptions o;
  ASSERT_NO_FATAL_FAILURE(write_cook_input(scratch_dir("block-surface"), "blocky", blocky_dem(), true, o));
  o.threads = 2;
  o.tolerance_m = 2.0;  // fewer nodes: the surface layers are the point here
  expect_same_bytes_for_every_block_split(o, {{1, 11}}, 4);
}

// The rate-distortion pass (--bc-rdo, on by default) reads only its own node's blocks: the same
// bytes for any split and order, and fewer normal and albedo bytes than without it (--bc-rdo 0).
TEST(BlockCook, BcRdoToo) {
  cook::CookOptions o;
  ASSERT_NO_FATAL_FAILURE(write_cook_input(scratch_dir("block-rdo"), "blocky", blocky_dem(), true, o));
  o.normals = cook::NormalsMode::stored;  // the pass shapes stored normal blocks (derived ones have none)
  o.threads = 2;
  o.tolerance_m = 2.0;
  cook::CookOptions plain = o;
  plain.output += ".plain";
  plain.bc_rdo = 0;
  cook::CookReport without;
  ASSERT_TRUE(cook::cook(plain, nullptr, without).ok());
  o.bc_rdo = 32;
  expect_same_bytes_for_every_block_split(o, {{1, 11}, {2, 5}}, 4);
  cook::CookReport with;
  o.output += ".again";
  ASSERT_TRUE(cook::cook(o, nullptr, with).ok());
  // section_stored_bytes: heights, normals, albedo, splat, cones.
  for (size_t s : {1u, 2u}) {
    std::printf("section %zu: %llu bytes without, %llu with --bc-rdo 32\n", s, (unsigned long long)without.section_stored_bytes[s],
                (unsigned long long)with.section_stored_bytes[s]);
    EXPECT_LT(with.section_stored_bytes[s], without.section_stored_bytes[s]);
  }
  EXPECT_EQ(with.section_stored_bytes[0], without.section_stored_bytes[0]);
  EXPECT_EQ(with.nodes, without.nodes);
  EXPECT_EQ(with.surface.albedo_alpha_mismatches, 0u);
}

// --error-checks: sampled checks measure fewer nodes (one in 8) with the same
// archive bytes; `all` measures every texel of every node; hole alpha is counted on every node both ways.
TEST(BlockCook, ErrorChecksSampleOrAllSameBytes) {
  cook::CookOptions o;
  ASSERT_NO_FATAL_FAILURE(write_cook_input(scratch_dir("block-checks"), "blocky", blocky_dem(), true, o));
  o.threads = 2;
  o.tolerance_m = 2.0;
  cook::CookOptions all = o;
  all.output += ".all";
  all.error_checks = cook::ErrorChecks::all;
  cook::CookReport sampled, every;
  ASSERT_TRUE(cook::cook(o, nullptr, sampled).ok());
  ASSERT_TRUE(cook::cook(all, nullptr, every).ok());
  EXPECT_EQ(file_bytes(o.output), file_bytes(all.output));
  const double texels = double(kTexels) * kTexels;
  EXPECT_EQ(every.surface.nodes, every.nodes);
  EXPECT_EQ(every.surface.checked_nodes, every.nodes);
  EXPECT_EQ(double(every.surface.normal_samples), double(every.nodes) * texels);
  EXPECT_EQ(double(every.surface.albedo_samples) / 3 + double(every.surface.albedo_hole_texels), double(every.nodes) * texels);
  EXPECT_EQ(sampled.surface.nodes, sampled.nodes);
  EXPECT_GE(sampled.surface.checked_nodes, 1u);
  EXPECT_LT(sampled.surface.checked_nodes, sampled.nodes);
  EXPECT_EQ(double(sampled.surface.normal_samples), double(sampled.surface.checked_nodes) * texels);
  EXPECT_EQ(sampled.surface.albedo_hole_texels, every.surface.albedo_hole_texels);
  EXPECT_GT(every.surface.albedo_hole_texels, 0u);  // the DEM has holes: the alpha count is exercised
  EXPECT_EQ(sampled.surface.albedo_alpha_mismatches, 0u);
  EXPECT_EQ(every.surface.albedo_alpha_mismatches, 0u);
  std::printf("%llu nodes, %llu checked; mean normal error %.4f (sampled) vs %.4f (all) degrees\n",
              (unsigned long long)sampled.nodes, (unsigned long long)sampled.surface.checked_nodes,
              sampled.surface.normal_err_mean_deg(), every.surface.normal_err_mean_deg());
}

// A spooled cook gives the spool's space back while it copies the payloads into the archive
// (1 MiB chunks punched out once copied), so the disk does not hold the payloads twice at the end;
// the archive is the one-block cook's.
TEST(BlockCook, DrainGivesTheSpoolSpaceBack) {
  cook::CookOptions o;
  ASSERT_NO_FATAL_FAILURE(write_cook_input(scratch_dir("block-spool"), "blocky", blocky_dem(), true, o));
  o.normals = cook::NormalsMode::stored;  // payloads large enough to spool more than one chunk
  {  // a file system that cannot punch holes keeps the space: nothing to check there
    const std::string probe = o.output + ".probe";
    const int fd = ::open(probe.c_str(), O_RDWR | O_CREAT | O_TRUNC, 0600);
    ASSERT_GE(fd, 0);
    const std::vector<char> mib(size_t(1) << 20, 'x');
    const bool wrote = ::pwrite(fd, mib.data(), mib.size(), 0) == ssize_t(mib.size());
    const bool punches = wrote && ::fallocate(fd, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, 0, off_t(mib.size())) == 0;
    ::close(fd);
    ::unlink(probe.c_str());
    if (!punches) GTEST_SKIP() << "the scratch file system cannot punch holes";
  }
  o.threads = 2;
  o.block_roots = 1;
  cook::CookReport r;
  ASSERT_TRUE(cook::cook(o, nullptr, r).ok());
  ASSERT_GT(r.blocks, 1u);
  ASSERT_GT(r.spool_bytes, 1u << 20);  // more than one chunk
  const uint64_t mib = uint64_t(1) << 20;
  std::printf("%u blocks, %llu bytes spooled, %llu given back\n", r.blocks, (unsigned long long)r.spool_bytes,
              (unsigned long long)r.spool_bytes_returned);
  EXPECT_GE(r.spool_bytes_returned, r.spool_bytes);  // every chunk, the last partial one included
  EXPECT_LT(r.spool_bytes_returned, r.spool_bytes + 2 * mib);
  cook::CookOptions whole = o;
  whole.output += ".whole";
  whole.block_roots = 64;
  cook::CookReport w;
  ASSERT_TRUE(cook::cook(whole, nullptr, w).ok());
  EXPECT_EQ(w.spool_bytes, 0u);
  EXPECT_EQ(w.spool_bytes_returned, 0u);
  EXPECT_EQ(file_bytes(o.output), file_bytes(whole.output));
}

// A heights-only cook evaluates only the vertices its payload needs (the node and the hole
// albedo's apron of kApron vertices), so its blocks read windows narrower than a full cook's by
// the surface filters' margin, and its nodes' heights, ranges and errors are the full cook's.
TEST(BlockCook, HeightsOnlyReadsNarrowerWindowsAndCooksTheSameHeights) {
  cook::CookOptions o;
  ASSERT_NO_FATAL_FAILURE(write_cook_input(scratch_dir("block-heights-only"), "blocky", blocky_dem(), true, o));
  o.threads = 2;
  o.tolerance_m = 2.0;
  o.block_roots = 1;
  const std::string full_path = o.output + ".full", heights_path = o.output + ".heights";
  cook::CookReport full, heights;
  o.output = full_path;
  ASSERT_TRUE(cook::cook(o, nullptr, full).ok());
  o.output = heights_path;
  o.heights_only = true;
  ASSERT_TRUE(cook::cook(o, nullptr, heights).ok());
  // Windows of one 2048 m root of 4 m samples: the full cook's margin is the surface filters' 18
  // root vertices (288 m) per side, the heights-only one's the albedo apron's 2 (32 m); plus the
  // Catmull-Rom taps and the error ring (4 samples per side) and one sample of rounding.
  const double root_samples = 2048.0 / 4.0, taps = 2 * 4 + 1;
  const double full_side = root_samples + 2 * 288.0 / 4.0 + taps;
  const double heights_side = root_samples + 2 * 32.0 / 4.0 + taps;
  std::printf("window samples: full %llu, heights-only %llu\n", (unsigned long long)full.block_window_samples_max,
              (unsigned long long)heights.block_window_samples_max);
  EXPECT_LT(double(heights.block_window_samples_max), double(full.block_window_samples_max));
  // Bounds from the geometry above, not from the code: a window is at most the margin square,
  // grown by the void plan's 64-sample tiles where a filled void reaches in.
  EXPECT_LE(double(full.block_window_samples_max), (full_side + 2 * 64) * (full_side + 2 * 64));
  EXPECT_LE(double(heights.block_window_samples_max), (heights_side + 2 * 64) * (heights_side + 2 * 64));
  EXPECT_LT(double(heights.block_window_samples_max), 0.8 * double(full.block_window_samples_max));
  ArchiveReader a, b;
  ASSERT_TRUE(a.open(full_path).ok());
  ASSERT_TRUE(b.open(heights_path).ok());
  ASSERT_EQ(a.nodes().size(), b.nodes().size());
  NodeData da, db;
  for (size_t i = 0; i < a.nodes().size(); ++i) {
    const NodeRecord &na = a.nodes()[i], &nb = b.nodes()[i];
    ASSERT_EQ(na.key, nb.key);
    EXPECT_EQ(na.min_height, nb.min_height);
    EXPECT_EQ(na.max_height, nb.max_height);
    EXPECT_EQ(na.geometric_error_m, nb.geometric_error_m);
    EXPECT_EQ(na.child_mask, nb.child_mask);
    ASSERT_TRUE(a.decode_node(i, da, kSectionHeights).ok());
    ASSERT_TRUE(b.decode_node(i, db, kSectionHeights).ok());
    EXPECT_TRUE(da.heights == db.heights) << "node " << i;
  }
}

// Geographic input: the frame -> sample mapping goes through the anchors (not affine), and the
// Debian DEM needs no shared data.
TEST(BlockCook, GeographicInputThroughTheAnchors) {
  const std::string dem = "/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz";
  if (!std::filesystem::exists(dem)) GTEST_SKIP() << dem << " not found (python3-matplotlib-data)";
  cook::CookOptions o;
  o.inputs = {dem};
  o.crs = "EPSG:4326";
  o.output = (scratch_dir("block-jacksboro") / "jb.terrain").string();
  o.threads = 2;
  o.heights_only = true;
  expect_same_bytes_for_every_block_split(o, {{1, 2}, {3, 0}}, 2, false);
}

TEST(BlockCook, RealDemKilauea) {
  const auto dem = data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(dem);
  cook::CookOptions o;
  o.inputs = {dem.string()};
  o.output = (scratch_dir("block-kilauea") / "kil.terrain").string();
  o.threads = 2;
  o.heights_only = true;
  expect_same_bytes_for_every_block_split(o, {{2, 9}});
}

}  // namespace

// A work unit by default: whole memory blocks, as many as stay within kUnitSamples source samples
// and kUnitNodes possible nodes (one more block per side would exceed one of them), so its fixed
// costs (process start, opening the inputs, fresh memory) are small next to its work.
TEST(BlockCook, DefaultUnitsAreWholeBlocksWithinTheirBounds) {
  struct Case {
    const char* what;
    uint32_t block_side;
    double spacing_m;
    int finest_level;
    uint32_t roots;
  };
  const Case cases[] = {{"1 m lidar, 2-root blocks", 2, 1.0, 0, 100},
                        {"0.25 m lidar, 1-root blocks", 1, 0.25, 0, 100},
                        {"5 m DEM, 4-root blocks", 4, 5.0, 2, 200},
                        {"2 m DEM, 3-root blocks", 3, 2.0, 1, 300}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    const uint32_t side =
        cook::default_unit_roots(c.block_side, c.spacing_m, c.spacing_m, c.finest_level, c.roots, c.roots);
    const double samples_per_root = std::pow(2048.0 / c.spacing_m, 2);
    double nodes_per_root = 0;
    for (int l = c.finest_level; l <= 5; ++l) nodes_per_root += std::pow(4.0, 5 - l);
    auto within = [&](uint32_t s) {
      const double roots = double(s) * s;
      return roots * samples_per_root <= cook::kUnitSamples && roots * nodes_per_root <= cook::kUnitNodes;
    };
    EXPECT_EQ(side % c.block_side, 0u) << side;
    EXPECT_GE(side, c.block_side);
    if (side > c.block_side) {
      EXPECT_TRUE(within(side)) << side;
    }
    EXPECT_FALSE(within(side + c.block_side)) << side;
  }
  // 1 m lidar: units of 6 x 6 roots (9 blocks, 151 M samples, at most 49 140 nodes).
  EXPECT_EQ(cook::default_unit_roots(2, 1.0, 1.0, 0, 100, 100), 6u);
  // A block that holds the whole world is the one unit.
  EXPECT_EQ(cook::default_unit_roots(64, 30.0, 30.0, 3, 40, 50), 64u);
}
