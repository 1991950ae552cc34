// Splat coherence on the shared real DEMs (issue 18, label real_data): on nodes at the level
// nearest each DEM's own spacing, the built-in rules give at most 1 % isolated samples and at most
// 15 % neighbour id changes, and on the 30 m DEMs every material's share stays within 3 points of
// the same rules read per sample (today's classification).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "splat.h"
#include "surface_test_support.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::cook;
using namespace terrain::cook::test;

namespace {

struct Tally {
  uint64_t iso = 0, iso_n = 0, chg = 0, pairs = 0, samples = 0;
  std::array<uint64_t, 256> count{};
  void add(const SplatLattice& l, const bench::DemNode& node) {
    // The node's 65x65 samples (lattice 1..65); samples without data are left out.
    auto data = [&](int k, int m) {
      const int i = 2 * k - 2, j = 2 * m - 2;
      return !std::isnan(node.window[size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin)]);
    };
    auto id = [&](int k, int m) { return l.ids[size_t(m * kSplatLattice + k)]; };
    for (int m = 1; m <= kSplatSamples; ++m)
      for (int k = 1; k <= kSplatSamples; ++k) {
        if (!data(k, m)) continue;
        ++samples;
        ++count[id(k, m)];
        if (k < kSplatSamples && data(k + 1, m)) chg += id(k, m) != id(k + 1, m), ++pairs;
        if (m < kSplatSamples && data(k, m + 1)) chg += id(k, m) != id(k, m + 1), ++pairs;
        if (k > 1 && m > 1 && k < kSplatSamples && m < kSplatSamples && data(k - 1, m) && data(k + 1, m) &&
            data(k, m - 1) && data(k, m + 1)) {
          const uint8_t v = id(k, m);
          ++iso_n;
          iso += v != id(k - 1, m) && v != id(k + 1, m) && v != id(k, m - 1) && v != id(k, m + 1);
        }
      }
  }
  double iso_pct() const { return iso_n ? 100.0 * double(iso) / double(iso_n) : 0; }
  double chg_pct() const { return pairs ? 100.0 * double(chg) / double(pairs) : 0; }
  double share(int id) const { return samples ? 100.0 * double(count[size_t(id)]) / double(samples) : 0; }
};

void check_dem(const char* file, bool check_shares) {
  TERRAIN_REQUIRE_DATA(terrain::test::data_file(file));
  bench::DemRaster dem;
  ASSERT_TRUE(bench::load_dem(terrain::test::data_file(file).string(), dem).ok());
  // The finest level whose spacing is not finer than the DEM's: where its own noise shows.
  const double src = std::min(dem.dx_m, dem.dy_m);
  uint32_t level = 0;
  while (level < 5 && vertex_spacing_m(int(level) + 1) <= src + 1e-9) ++level;
  const MaterialRules& now = default_rules();
  const MaterialRules before = per_sample(now);
  Tally a, b;
  const uint32_t nx = bench::nodes_across(dem, level, false), ny = bench::nodes_across(dem, level, true);
  // Up to 36 nodes spread over the DEM.
  const uint32_t step_x = std::max(1u, nx / 6), step_y = std::max(1u, ny / 6);
  for (uint32_t y = 0; y < ny; y += step_y)
    for (uint32_t x = 0; x < nx; x += step_x) {
      bench::DemNode n;
      bench::make_dem_node(dem, level, x, y, 2, n);
      if (n.data_vertices < 1000) continue;
      SplatLattice l;
      compute_splat_lattice(n.input(&now, BcQuality::balanced), now, l);
      a.add(l, n);
      compute_splat_lattice(n.input(&before, BcQuality::balanced), before, l);
      b.add(l, n);
    }
  ASSERT_GT(a.samples, 10000u);
  std::printf("%-28s level %u: isolated %.2f -> %.2f %%, changes %.2f -> %.2f %%\n", file, level, b.iso_pct(),
              a.iso_pct(), b.chg_pct(), a.chg_pct());
  EXPECT_LE(a.iso_pct(), 1.0);
  EXPECT_LE(a.chg_pct(), 15.0);
  for (int id = 0; id < int(now.palette.size()); ++id) {
    if (a.count[size_t(id)] + b.count[size_t(id)] == 0) continue;
    std::printf("    %-14s %6.2f -> %6.2f %%\n", now.palette[size_t(id)].name.c_str(), b.share(id), a.share(id));
    if (check_shares) {
      EXPECT_NEAR(a.share(id), b.share(id), 3.0) << now.palette[size_t(id)].name;
    }
  }
}

}  // namespace

TEST(SplatReal, SloveniaLidar) { check_dem("slovenia_TM1_564_146.tif", false); }
TEST(SplatReal, TahoeBareEarth) { check_dem("tahoe_lidar_bareearth.tif", false); }
TEST(SplatReal, TahoeHighestHit) { check_dem("tahoe_lidar_highesthit.tif", false); }
TEST(SplatReal, Kilauea) { check_dem("kilauea_utm5n.tif", true); }
TEST(SplatReal, SrtmOetztal) { check_dem("srtm_oetztal.tif", true); }
TEST(SplatReal, HgtN19W155) { check_dem("N19W155.hgt.zip", true); }
TEST(SplatReal, HgtN22W160) { check_dem("N22W160.hgt.zip", true); }
