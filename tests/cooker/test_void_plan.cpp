// Void filling by windows (void_plan.h, issue 13): for every sample a block needs, the windowed
// fill gives the value bits and filled flag of whole-raster fill_voids(), whatever the tile size
// of the plan; the plan's counts are fill_voids()' counts; the plan reads each sample once.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>

#include "cooker_test_util.h"
#include "inputs/inputs.h"
#include "voids/range_summary.h"
#include "inputs/raster.h"
#include "test_data.h"
#include "voids/void_fill.h"
#include "voids/void_plan.h"

using namespace terrain;
using namespace terrain::cook;

namespace {

// Smooth terrain with some roughness (so fills differ from sample to sample).
Raster synthetic_raster(int w, int h, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> noise(-2.0f, 2.0f);
  Raster r;
  r.width = w;
  r.height = h;
  r.values.resize(size_t(w) * size_t(h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      r.values[size_t(y) * size_t(w) + size_t(x)] =
          float(500.0 + 80.0 * std::sin(x * 0.043 + seed) + 60.0 * std::cos(y * 0.031 - 0.7 * seed) + 0.3 * x) +
          noise(rng);
  return r;
}

void set_nan(Raster& r, int x, int y) {
  if (x >= 0 && y >= 0 && x < r.width && y < r.height) r.values[size_t(y) * size_t(r.width) + size_t(x)] = NAN;
}
void punch_rect(Raster& r, int c0, int r0, int c1, int r1) {
  for (int y = r0; y <= r1; ++y)
    for (int x = c0; x <= c1; ++x) set_nan(r, x, y);
}

// Voids of many shapes: single samples, blobs, long thin voids and staircases across many tiles,
// a ring around data, voids at the border, one enclosed void larger than 4096 samples.
void punch_voids(Raster& r, uint32_t seed, bool large = true) {
  std::mt19937 rng(seed * 7919u + 1);
  auto uni = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  const int w = r.width, h = r.height;
  for (int i = 0; i < w * h / 150; ++i) set_nan(r, uni(0, w - 1), uni(0, h - 1));  // single samples
  for (int i = 0; i < 40; ++i) {                                                      // blobs
    const int cx = uni(0, w - 1), cy = uni(0, h - 1), rad = uni(1, 7);
    for (int y = cy - rad; y <= cy + rad; ++y)
      for (int x = cx - rad; x <= cx + rad; ++x)
        if ((x - cx) * (x - cx) + (y - cy) * (y - cy) <= rad * rad + uni(-rad, rad)) set_nan(r, x, y);
  }
  for (int i = 0; i < 6; ++i) {  // long thin voids, horizontal and vertical, well inside
    const int len = uni(60, 200), thick = uni(1, 2);
    if (i % 2 == 0) {
      const int y = uni(5, h - 8), x = uni(3, std::max(3, w - len - 3));
      punch_rect(r, x, y, std::min(w - 4, x + len), y + thick - 1);
    } else {
      const int x = uni(5, w - 8), y = uni(3, std::max(3, h - len - 3));
      punch_rect(r, x, y, x + thick - 1, std::min(h - 4, y + len));
    }
  }
  {  // a 4-connected staircase across many tiles
    int x = uni(10, 40), y = uni(10, 40);
    for (int s = 0; s < 150 && x < w - 3 && y < h - 3; ++s) {
      set_nan(r, x, y);
      if (s % 2 == 0) ++x; else ++y;
    }
  }
  {  // a ring of nodata around data
    const int cx = w / 2, cy = h / 2, rad = 30;
    for (int y = cy - rad - 1; y <= cy + rad + 1; ++y)
      for (int x = cx - rad - 1; x <= cx + rad + 1; ++x) {
        const double d = std::hypot(x - cx, y - cy);
        if (d >= rad - 1 && d <= rad + 0.5) set_nan(r, x, y);
      }
  }
  punch_rect(r, 0, uni(10, h - 40), uni(3, 20), uni(h - 30, h - 20));  // touches the left border
  punch_rect(r, uni(10, w - 40), h - uni(2, 6), uni(w - 30, w - 20), h - 1);  // touches the bottom border
  if (large) punch_rect(r, 20, 20, 20 + 79, 20 + 61);  // 80 x 62 = 4960 > 4096, enclosed
}

// Float bits equal (NaN == NaN).
bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

ReadSamples reader_of(const Raster& r) {
  return [&r](int c0, int r0, int w, int h, float* out) {
    for (int y = 0; y < h; ++y)
      std::memcpy(out + size_t(y) * size_t(w), &r.values[size_t(r0 + y) * size_t(r.width) + size_t(c0)],
                  size_t(w) * sizeof(float));
    return Status::success();
  };
}

struct Reference {
  Raster filled_raster;
  std::vector<uint8_t> filled;
  VoidStats stats;
};

Reference reference_fill(const Raster& source, NodataPolicy policy, int64_t max_fill) {
  Reference ref;
  ref.filled_raster = source;
  EXPECT_TRUE(fill_voids(ref.filled_raster, policy, max_fill, ref.filled, ref.stats).ok());
  return ref;
}

// Fills fill_read_rect(plan, need) of `source` by window; counts the samples of `need` whose bits
// or filled flag differ from the reference.
uint64_t window_mismatches(const VoidPlan& plan, const Raster& source, const Reference& ref, const SampleRect& need,
                           SampleRect* window_out = nullptr, double* residual_out = nullptr) {
  const SampleRect win = fill_read_rect(plan, need);
  if (window_out) *window_out = win;
  EXPECT_LE(win.c0, need.c0);
  EXPECT_LE(win.r0, need.r0);
  EXPECT_GE(win.c1, need.c1);
  EXPECT_GE(win.r1, need.r1);
  std::vector<float> values(win.samples());
  EXPECT_TRUE(reader_of(source)(win.c0, win.r0, win.width(), win.height(), values.data()).ok());
  std::vector<uint8_t> filled(win.samples(), 7);
  double residual = -1;
  EXPECT_TRUE(fill_voids_window(plan, win, values.data(), filled.data(), residual).ok());
  if (residual_out) *residual_out = residual;
  uint64_t bad = 0;
  for (int y = need.r0; y <= need.r1; ++y)
    for (int x = need.c0; x <= need.c1; ++x) {
      const size_t g = size_t(y) * size_t(source.width) + size_t(x);
      const size_t l = size_t(y - win.r0) * size_t(win.width()) + size_t(x - win.c0);
      if (!same_bits(values[l], ref.filled_raster.values[g]) || filled[l] != ref.filled[g]) ++bad;
    }
  return bad;
}

void expect_plan_matches(const VoidPlan& plan, const Raster& source, const Reference& ref) {
  EXPECT_EQ(plan.stats.filled_samples, ref.stats.filled_samples);
  EXPECT_EQ(plan.stats.filled_regions, ref.stats.filled_regions);
  EXPECT_EQ(plan.stats.hole_samples, ref.stats.hole_samples);
  EXPECT_EQ(plan.stats.hole_regions, ref.stats.hole_regions);
  int c0, r0, c1, r1;
  uint64_t valid = 0;
  const bool any = valid_bounds(source, c0, r0, c1, r1, valid);
  EXPECT_EQ(plan.valid_samples, valid);
  EXPECT_EQ(!plan.valid_bounds.empty(), any);
  if (any) {
    EXPECT_EQ(plan.valid_bounds, (SampleRect{c0, r0, c1, r1}));
  }
}

// Random `need` rectangles and a grid of blocks covering the raster: every sample checked.
void expect_windows_exact(const Raster& source, NodataPolicy policy, int64_t max_fill, const std::vector<int>& tiles,
                          int random_needs, int block, uint32_t seed) {
  const Reference ref = reference_fill(source, policy, max_fill);
  std::mt19937 rng(seed);
  auto uni = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  for (int tile : tiles) {
    SCOPED_TRACE(testing::Message() << "tile " << tile);
    VoidPlan plan;
    ASSERT_TRUE(plan_voids(source.width, source.height, reader_of(source), policy, max_fill, tile, plan).ok());
    expect_plan_matches(plan, source, ref);
    // One tile over the whole raster: every window is the raster (and costs a whole fill).
    const bool one_tile = tile >= std::max(source.width, source.height);
    for (int i = 0; i < (one_tile ? std::min(random_needs, 3) : random_needs); ++i) {
      const int c0 = uni(0, source.width - 1), r0 = uni(0, source.height - 1);
      const SampleRect need{c0, r0, std::min(source.width - 1, c0 + uni(0, 90)),
                            std::min(source.height - 1, r0 + uni(0, 90))};
      EXPECT_EQ(window_mismatches(plan, source, ref, need), 0u)
          << "need [" << need.c0 << ", " << need.c1 << "] x [" << need.r0 << ", " << need.r1 << "]";
    }
    for (int y = 0; y < (one_tile ? 0 : source.height); y += block)
      for (int x = 0; x < source.width; x += block) {
        const SampleRect need{x, y, std::min(source.width, x + block) - 1, std::min(source.height, y + block) - 1};
        EXPECT_EQ(window_mismatches(plan, source, ref, need), 0u) << "block at " << x << ", " << y;
      }
    // One window over the whole raster is fill_voids() itself, residual included.
    double residual = -1;
    EXPECT_EQ(window_mismatches(plan, source, ref, {0, 0, source.width - 1, source.height - 1}, nullptr, &residual), 0u);
    EXPECT_EQ(residual, ref.stats.max_residual_m);
  }
}

const NodataPolicy kPolicies[] = {NodataPolicy::automatic, NodataPolicy::fill, NodataPolicy::hole};

}  // namespace

TEST(VoidPlan, WindowsFillExactlyLikeTheWholeRaster) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    Raster r = synthetic_raster(300, 220, seed);
    punch_voids(r, seed);
    for (NodataPolicy policy : {NodataPolicy::automatic, NodataPolicy::hole})
      for (int64_t max_fill : {int64_t(4096), int64_t(300)}) {
        if (policy != NodataPolicy::automatic && max_fill != 4096) continue;
        SCOPED_TRACE(testing::Message() << "seed " << seed << " policy " << int(policy) << " fill max " << max_fill);
        expect_windows_exact(r, policy, max_fill, {16, 37, 64, 1000}, 25, 45, seed);
      }
  }
}

TEST(VoidPlan, FillEverythingPolicyFillsBorderVoidsExactly) {
  // Border voids and all: spanning fills are large here, so fewer and larger blocks (without the
  // enclosed 4960-sample void, whose SOR fill in every window would take minutes).
  for (uint32_t seed : {1u, 2u, 3u}) {
    Raster r = synthetic_raster(300, 220, seed);
    punch_voids(r, seed, false);
    SCOPED_TRACE(testing::Message() << "seed " << seed);
    expect_windows_exact(r, NodataPolicy::fill, 4096, {16, 37, 64, 1000}, 10, 75, seed);
  }
}

TEST(VoidPlan, TheSyntheticVoidsAreWhatTheTestNeeds) {
  // The rasters above hold filled voids spanning tiles, holes enclosed (too large) and at the
  // border, and blocks whose windows are much smaller than the raster: else the test proves little.
  Raster r = synthetic_raster(300, 220, 1);
  punch_voids(r, 1);
  const Reference ref = reference_fill(r, NodataPolicy::automatic, 4096);
  VoidPlan plan;
  ASSERT_TRUE(plan_voids(r.width, r.height, reader_of(r), NodataPolicy::automatic, 4096, 16, plan).ok());
  EXPECT_GE(plan.spanning_fills.size(), 8u);
  EXPECT_GE(ref.stats.filled_regions, 300u);
  EXPECT_GE(ref.stats.hole_regions, 3u);
  EXPECT_GE(ref.stats.hole_samples, 4960u);
  uint64_t small_windows = 0, blocks = 0;
  for (int y = 0; y < r.height; y += 45)
    for (int x = 0; x < r.width; x += 45) {
      const SampleRect win = fill_read_rect(plan, {x, y, std::min(r.width, x + 45) - 1, std::min(r.height, y + 45) - 1});
      ++blocks;
      if (win.samples() * 4 <= uint64_t(r.width) * uint64_t(r.height)) ++small_windows;
    }
  EXPECT_GE(small_windows * 2, blocks);
  // And the comparison can fail: filling only `need` itself (no tiles, no spanning boxes) cuts
  // voids, which stay nodata where fill_voids() fills them.
  uint64_t cut_samples = 0;
  for (int y = 0; y < r.height; y += 45)
    for (int x = 0; x < r.width; x += 45) {
      const SampleRect need{x, y, std::min(r.width, x + 45) - 1, std::min(r.height, y + 45) - 1};
      std::vector<float> v(need.samples());
      ASSERT_TRUE(reader_of(r)(need.c0, need.r0, need.width(), need.height(), v.data()).ok());
      std::vector<uint8_t> f(need.samples());
      double res = 0;
      ASSERT_TRUE(fill_voids_window(plan, need, v.data(), f.data(), res).ok());
      for (int yy = need.r0; yy <= need.r1; ++yy)
        for (int xx = need.c0; xx <= need.c1; ++xx)
          cut_samples += ref.filled[size_t(yy) * size_t(r.width) + size_t(xx)] !=
                         f[size_t(yy - need.r0) * size_t(need.width()) + size_t(xx - need.c0)];
    }
  EXPECT_GT(cut_samples, 100u);
}

TEST(VoidPlan, AllNodataAndNoVoids) {
  Raster empty = synthetic_raster(90, 70, 5);
  std::fill(empty.values.begin(), empty.values.end(), NAN);
  Raster full = synthetic_raster(90, 70, 6);
  for (NodataPolicy policy : kPolicies) {
    SCOPED_TRACE(int(policy));
    expect_windows_exact(empty, policy, 4096, {16, 37, 1000}, 10, 30, 11);
    expect_windows_exact(full, policy, 4096, {16, 37, 1000}, 10, 30, 12);
    VoidPlan plan;
    ASSERT_TRUE(plan_voids(90, 70, reader_of(empty), policy, 4096, 16, plan).ok());
    EXPECT_EQ(plan.stats.hole_regions, 1u);  // the whole raster as one void is never filled
    EXPECT_EQ(plan.stats.hole_samples, 90u * 70u);
    EXPECT_TRUE(plan.valid_bounds.empty());
    EXPECT_TRUE(plan.spanning_fills.empty());
  }
}

// The fill first looks for any nodata in chunks of 256 samples (void_fill.cpp): a lone void
// sample anywhere, on either side of a chunk edge or as the very last sample, is still found.
TEST(VoidPlan, ALoneVoidSampleIsFoundAtEveryChunkEdge) {
  const int w = 40, h = 30;  // 1200 samples: chunk edges at 256, 512, 768, 1024
  for (int p : {41, 255, 256, 257, 511, 512, 1023, 1024, 1158, w * h - 1}) {
    SCOPED_TRACE(p);
    Raster r = synthetic_raster(w, h, 3);
    const std::vector<float> before = r.values;
    r.values[size_t(p)] = NAN;
    std::vector<uint8_t> filled;
    VoidStats st;
    ASSERT_TRUE(fill_voids(r, NodataPolicy::automatic, 4096, filled, st).ok());
    const bool border = p % w == 0 || p % w == w - 1 || p / w == 0 || p / w == h - 1;
    EXPECT_EQ(st.filled_regions + st.hole_regions, 1u);
    EXPECT_EQ(st.filled_regions, border ? 0u : 1u);  // border voids stay holes under auto
    for (size_t i = 0; i < r.values.size(); ++i) {
      if (int(i) == p) continue;
      ASSERT_EQ(std::memcmp(&r.values[i], &before[i], sizeof(float)), 0) << i;
      ASSERT_EQ(filled[i], 0) << i;
    }
    if (!border) {
      EXPECT_EQ(filled[size_t(p)], 1);
      // Filled from its 4 neighbours: within their range.
      const float n[4] = {before[size_t(p - 1)], before[size_t(p + 1)], before[size_t(p - w)], before[size_t(p + w)]};
      EXPECT_GE(r.values[size_t(p)], *std::min_element(n, n + 4));
      EXPECT_LE(r.values[size_t(p)], *std::max_element(n, n + 4));
    } else {
      EXPECT_TRUE(std::isnan(r.values[size_t(p)]));
    }
  }
  // No nodata: nothing is counted and no value changes.
  Raster r = synthetic_raster(w, h, 4);
  const std::vector<float> before = r.values;
  std::vector<uint8_t> filled;
  VoidStats st;
  ASSERT_TRUE(fill_voids(r, NodataPolicy::fill, 4096, filled, st).ok());
  EXPECT_EQ(st.filled_regions + st.hole_regions, 0u);
  EXPECT_EQ(std::memcmp(r.values.data(), before.data(), before.size() * sizeof(float)), 0);
}

TEST(VoidPlan, FirstPassReadsEachSampleOnceATileAtATime) {
  Raster r = synthetic_raster(300, 220, 4);
  punch_voids(r, 4);
  for (int tile : {16, 37, 64}) {
    std::vector<int> reads(r.values.size(), 0);
    int last_r0 = 0;
    bool rows_in_order = true, within_tile = true;
    const ReadSamples base = reader_of(r);
    const ReadSamples counting = [&](int c0, int r0, int w, int h, float* out) {
      within_tile = within_tile && w <= tile && h <= tile && w > 0 && h > 0;
      rows_in_order = rows_in_order && r0 >= last_r0;
      last_r0 = r0;
      for (int y = r0; y < r0 + h; ++y)
        for (int x = c0; x < c0 + w; ++x) ++reads[size_t(y) * size_t(r.width) + size_t(x)];
      return base(c0, r0, w, h, out);
    };
    VoidPlan plan;
    ASSERT_TRUE(plan_voids(r.width, r.height, counting, NodataPolicy::automatic, 4096, tile, plan).ok());
    EXPECT_TRUE(within_tile) << "tile " << tile;
    EXPECT_TRUE(rows_in_order) << "tile " << tile;
    EXPECT_EQ(std::count(reads.begin(), reads.end(), 1), std::ptrdiff_t(reads.size())) << "tile " << tile;
  }
  // A failing read is the plan's failure.
  VoidPlan plan;
  const Status st = plan_voids(50, 50, [](int, int, int, int, float*) {
    return Status::failure(Error::io_read, "broken");
  }, NodataPolicy::automatic, 4096, 16, plan);
  EXPECT_EQ(st.code, Error::io_read);
}

// Read-ahead (the cook's first pass on 2+ threads): the same plan and range summary as reading a
// tile at a time on the caller's thread, every sample read exactly once, in chunks of at most
// kReadAheadTiles tiles of one row of tiles, rows in order; a failing read is still the failure.
TEST(VoidPlan, ReadAheadGivesThePlanOfTileReads) {
  Raster r = synthetic_raster(700, 230, 5);  // 700 = 10 chunks of 2 x 32 + a partial one at tile 2
  punch_voids(r, 5);
  punch_rect(r, 100, 50, 600, 51);  // a filled void across many chunks
  for (int tile : {2, 16, 37, 64}) {
    SCOPED_TRACE(testing::Message() << "tile " << tile);
    VoidPlan plain, ahead;
    RangeSummary plain_ranges, ahead_ranges;
    plain_ranges.start(r.width, r.height);
    ahead_ranges.start(r.width, r.height);
    ASSERT_TRUE(plan_voids(r.width, r.height, reader_of(r), NodataPolicy::automatic, 4096, tile, plain, {},
                           &plain_ranges).ok());
    std::vector<int> reads(r.values.size(), 0);
    int last_r0 = 0, widest = 0;
    bool rows_in_order = true, one_tile_row = true;
    const ReadSamples base = reader_of(r);
    const ReadSamples counting = [&](int c0, int r0, int w, int h, float* out) {
      one_tile_row = one_tile_row && r0 % tile == 0 && h == std::min(tile, r.height - r0);
      rows_in_order = rows_in_order && r0 >= last_r0;
      last_r0 = r0;
      widest = std::max(widest, w);
      for (int y = r0; y < r0 + h; ++y)
        for (int x = c0; x < c0 + w; ++x) ++reads[size_t(y) * size_t(r.width) + size_t(x)];
      return base(c0, r0, w, h, out);
    };
    ASSERT_TRUE(plan_voids(r.width, r.height, counting, NodataPolicy::automatic, 4096, tile, ahead, {}, &ahead_ranges,
                           /*read_ahead=*/true).ok());
    EXPECT_TRUE(one_tile_row);
    EXPECT_TRUE(rows_in_order);
    EXPECT_EQ(widest, std::min(r.width, tile * kReadAheadTiles));
    EXPECT_EQ(std::count(reads.begin(), reads.end(), 1), std::ptrdiff_t(reads.size()));
    EXPECT_EQ(ahead.stats.filled_samples, plain.stats.filled_samples);
    EXPECT_EQ(ahead.stats.filled_regions, plain.stats.filled_regions);
    EXPECT_EQ(ahead.stats.hole_samples, plain.stats.hole_samples);
    EXPECT_EQ(ahead.stats.hole_regions, plain.stats.hole_regions);
    EXPECT_EQ(ahead.valid_samples, plain.valid_samples);
    EXPECT_EQ(ahead.valid_bounds, plain.valid_bounds);
    EXPECT_EQ(ahead.spanning_fills, plain.spanning_fills);
    EXPECT_GE(plain.spanning_fills.size(), 1u);
    plain_ranges.finish();
    ahead_ranges.finish();
    for (const SampleRect& q : {SampleRect{0, 0, r.width - 1, r.height - 1}, SampleRect{90, 40, 610, 60},
                                SampleRect{3, 7, 11, 200}, SampleRect{650, 100, 699, 229}})
      EXPECT_EQ(ahead_ranges.surface_range_bound(q.c0, q.r0, q.c1, q.r1),
                plain_ranges.surface_range_bound(q.c0, q.r0, q.c1, q.r1));
  }
  // A failing read, here in the third chunk, is the plan's failure (and the thread stops).
  VoidPlan plan;
  int calls = 0;
  const Status st = plan_voids(700, 100, [&](int, int, int w, int h, float* out) {
    std::fill(out, out + size_t(w) * size_t(h), 1.0f);
    return ++calls == 3 ? Status::failure(Error::io_read, "broken") : Status::success();
  }, NodataPolicy::automatic, 4096, 8, plan, {}, nullptr, /*read_ahead=*/true);
  EXPECT_EQ(st.code, Error::io_read);
  EXPECT_EQ(st.message, "broken");
}

TEST(VoidPlan, FillReadRectIsTilesRingAndSpanningFills) {
  Raster r = synthetic_raster(200, 100, 8);
  punch_rect(r, 50, 40, 150, 41);  // 202 samples across tiles 16..37 wide: filled under auto
  VoidPlan plan;
  ASSERT_TRUE(plan_voids(r.width, r.height, reader_of(r), NodataPolicy::automatic, 4096, 32, plan).ok());
  ASSERT_EQ(plan.spanning_fills.size(), 1u);
  EXPECT_EQ(plan.spanning_fills[0], (SampleRect{50, 40, 150, 41}));
  // Away from the void: tiles plus a ring, clipped.
  EXPECT_EQ(fill_read_rect(plan, {5, 5, 10, 10}), (SampleRect{0, 0, 32, 32}));
  EXPECT_EQ(fill_read_rect(plan, {70, 70, 70, 70}), (SampleRect{63, 63, 96, 96}));
  // Meeting the void: its box and ring too.
  EXPECT_EQ(fill_read_rect(plan, {140, 41, 141, 45}), (SampleRect{49, 31, 160, 64}));
  EXPECT_TRUE(fill_read_rect(plan, {300, 0, 310, 5}).empty());
}

TEST(VoidPlan, KilaueaWithPunchedVoids) {
  const auto path = test::data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(path);
  Raster r;
  ASSERT_TRUE(read_geotiff(path.string(), ReadOptions{}, r).ok());
  ASSERT_GT(r.width, 600);
  ASSERT_GT(r.height, 600);
  punch_rect(r, 300, 300, 329, 304);  // a 30 x 5 lake
  punch_rect(r, 60, 500, 760, 501);   // a strip across many tile edges (1402 samples)
  punch_rect(r, 63, 100, 64, 400);    // a strip along a tile edge (64)
  punch_rect(r, 0, 200, 9, 230);      // at the border
  punch_rect(r, 500, 600, 600, 700);  // enclosed, too large under auto
  for (NodataPolicy policy : {NodataPolicy::automatic, NodataPolicy::fill}) {
    SCOPED_TRACE(int(policy));
    expect_windows_exact(r, policy, 4096, {64, 256}, 20, 128, 21);
  }
}
