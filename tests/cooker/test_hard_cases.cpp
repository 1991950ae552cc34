// Hard cases from issue 3, each cooked from a synthetic GeoTIFF through the library and read back
// as a renderer sees it. Every test states the bound it checks.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <nlohmann/json.hpp>

#include "cooker_test_util.h"
#include "pyramid/node_cook.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;

namespace {

constexpr double kMm = 1e-3;

struct Cooked {
  cook::CookReport report;
  CookedArchive archive;
  std::string path;
};

// Writes `dem`, cooks it with `options` (inputs/output filled in; heights only unless
// `surface_layers`), opens the result and checks that it verifies and has no seam mismatch.
void cook_dem(const std::string& name, const SyntheticDem& dem, cook::CookOptions options, Cooked& out,
              bool tiled = true, bool surface_layers = false) {
  ASSERT_NO_FATAL_FAILURE(write_cook_input(scratch_dir("cooker-" + name), name, dem, tiled, options));
  out.path = options.output;
  options.heights_only = !surface_layers;
  if (options.threads == 0) options.threads = 2;
  uint64_t compared = 0;
  cook_and_verify(options, out.report, out.archive, compared);
}

// Writes `dem` as a stripped GeoTIFF <name>.tif in scratch folder cooker-<name> and sets `options`
// for a heights-only cook of it.
void heights_only_input(const std::string& name, const SyntheticDem& dem, cook::CookOptions& options) {
  ASSERT_NO_FATAL_FAILURE(write_cook_input(scratch_dir("cooker-" + name), name, dem, false, options));
  options.heights_only = true;
}

SyntheticDem utm_dem(int w, int h, double spacing, double east, double north) {
  SyntheticDem d;
  d.width = w;
  d.height = h;
  d.values.assign(size_t(w) * size_t(h), 0.0);
  d.dx = d.dy = spacing;
  d.x0 = east;
  d.y0 = north;
  d.epsg_projected = 32632;
  return d;
}

// A DEM at one height, in projected CRS `epsg` (0: a GeoTIFF without geokeys).
SyntheticDem flat_dem(int w, int h, double spacing, double east, double north, double height, int epsg = 32632) {
  SyntheticDem d = utm_dem(w, h, spacing, east, north);
  d.epsg_projected = epsg;
  std::fill(d.values.begin(), d.values.end(), height);
  return d;
}

// A WGS 84 longitude/latitude DEM; (west, north) is the centre of its north-west sample.
SyntheticDem geo_dem(int w, int h, double spacing_deg, double west, double north) {
  SyntheticDem d = utm_dem(w, h, spacing_deg, west, north);
  d.epsg_projected = 0;
  d.epsg_geographic = 4326;
  return d;
}

// Max over the valid source samples of |cooked - source| - (tolerance + half step + 1 mm): the worst excess (<= 0
// means every sample is within its bound). Samples without a cooked height count in `missing`,
// or in `missing_edge` on the raster's outer ring or beside nodata (where a hole vertex, or the
// sampler's choice of quad for a point exactly on the covered area's boundary, may drop them).
struct SourceCheck {
  double worst_error = 0, worst_excess = -INFINITY;
  uint64_t checked = 0, missing = 0, missing_edge = 0;
};
bool edge_sample(const SyntheticDem& d, int col, int row) {
  if (col == 0 || row == 0 || col == d.width - 1 || row == d.height - 1) return true;
  for (int dr = -1; dr <= 1; ++dr)
    for (int dc = -1; dc <= 1; ++dc)
      if (std::isnan(d.values[size_t(row + dr) * size_t(d.width) + size_t(col + dc)])) return true;
  return false;
}
SourceCheck check_samples(const SyntheticDem& dem, Cooked& c, double tolerance, bool geographic = false) {
  SourceCheck r;
  const double half = c.archive.max_half_step();
  for (int row = 0; row < dem.height; ++row)
    for (int col = 0; col < dem.width; ++col) {
      const double z = dem.values[size_t(row) * size_t(dem.width) + size_t(col)];
      if (std::isnan(z)) continue;
      double x = dem.mx(col), y = dem.my(row);
      if (geographic) lonlat_to_frame(c.archive.reader.world().crs, dem.mx(col), dem.my(row), x, y);
      const NodeRecord* node = nullptr;
      const auto h = c.archive.height(x, y, &node);
      if (!h) {
        ++(edge_sample(dem, col, row) ? r.missing_edge : r.missing);
        continue;
      }
      ++r.checked;
      const double e = std::fabs(*h - z);
      r.worst_error = std::max(r.worst_error, e);
      // The bound: tolerance + half a step + 1 mm.
      const double bound = tolerance + half + kMm;
      r.worst_excess = std::max(r.worst_excess, e - bound);
    }
  return r;
}

// The bound at every valid sample of `dem`: none without a cooked height (away from the
// edges), none beyond tolerance + half step + 1 mm.
void expect_samples_within_bound(const SyntheticDem& dem, Cooked& c, double tolerance, bool geographic = false) {
  const SourceCheck s = check_samples(dem, c, tolerance, geographic);
  EXPECT_EQ(s.missing, 0u);
  EXPECT_LE(s.worst_excess, 0.0) << "worst error " << s.worst_error;
  EXPECT_LE(s.worst_error, tolerance + c.archive.max_half_step() + kMm);
}

// Whether a node's box reaches within `margin` of the data footprint's boundary (nodes refined
// only to cover the data up to its edge, where a coarse triangle would drop edge samples).
bool near_footprint_edge(const WorldInfo& w, const NodeKey& k, double margin) {
  const double size = node_size_m(int(k.level));
  const double x0 = w.origin_x_m + k.x * size, y0 = w.origin_y_m + k.y * size;
  return !(x0 > w.extent_min_x_m + margin && x0 + size < w.extent_max_x_m - margin && y0 > w.extent_min_y_m + margin &&
           y0 + size < w.extent_max_y_m - margin);
}

}  // namespace

// Bound: every source sample within half a root step + 1 mm; finer levels only along the data's
// edges (coverage), none inside.
TEST(HardCase, ConstantHeight) {
  const SyntheticDem d = flat_dem(200, 200, 1.0, 500000.5, 5000099.5, 1234.567);
  Cooked c;
  cook_dem("constant", d, {}, c);
  for (const NodeRecord& n : c.archive.reader.nodes()) {
    if (n.key.level < kRootLevel) {
      EXPECT_TRUE(near_footprint_edge(c.archive.reader.world(), parent_of(n.key), 16.0));
    }
    EXPECT_EQ(n.min_height, n.max_height);
    EXPECT_LE(n.geometric_error_m, c.archive.half_step(5) + kMm);
  }
  const SourceCheck s = check_samples(d, c, 0.0);
  EXPECT_EQ(s.missing, 0u);
  EXPECT_LE(s.worst_error, c.archive.half_step(5) + kMm);
}

// Without --tolerance the cook takes 1/32 of the source spacing, at least 0.5 m (cooker/README.md,
// "Levels"): a 30 m DEM of steep hills gets 0.9375 m, states it in the report and the cook info, holds
// every sample within it + half a step + 1 mm, and cooks fewer nodes than the same DEM at 0.5 m
// (which refines further); a 1 m DEM keeps 0.5 m, and --tolerance still sets it.
TEST(HardCase, DefaultToleranceFollowsTheSourceSpacing) {
  SyntheticDem d = utm_dem(160, 160, 30.0, 500015.0, 5004785.0);
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col)
      d.at(col, row) = 800.0 + 300.0 * std::sin(col * 0.31) * std::cos(row * 0.23) + 40.0 * std::sin(col * 1.3 + row * 0.9);
  Cooked c;
  cook_dem("tolerance-30m", d, {}, c);
  if (HasFatalFailure()) return;
  EXPECT_EQ(c.report.source_spacing_m, 30.0);
  EXPECT_EQ(c.report.tolerance_m, 30.0 / 32.0);
  EXPECT_TRUE(c.report.tolerance_from_source);
  const auto info = nlohmann::json::parse(c.archive.reader.world().cook_info_json);
  EXPECT_EQ(info["options"]["tolerance_m"].get<double>(), 30.0 / 32.0);
  EXPECT_EQ(nlohmann::json::parse(cook::report_json(c.report))["tolerance_from"], "source");
  expect_samples_within_bound(d, c, 30.0 / 32.0);
  EXPECT_GT(c.report.leaf_error_max_m, 0.5);  // the wider tolerance is used, not only stated

  cook::CookOptions fine;
  fine.tolerance_m = 0.5;
  Cooked f;
  cook_dem("tolerance-30m-fine", d, fine, f);
  if (HasFatalFailure()) return;
  EXPECT_EQ(f.report.tolerance_m, 0.5);
  EXPECT_FALSE(f.report.tolerance_from_source);
  expect_samples_within_bound(d, f, 0.5);
  EXPECT_LT(c.report.nodes, f.report.nodes);

  SyntheticDem lidar = utm_dem(300, 300, 1.0, 500000.0, 5000299.0);
  for (int row = 0; row < lidar.height; ++row)
    for (int col = 0; col < lidar.width; ++col) lidar.at(col, row) = 300.0 + 5.0 * std::sin(col * 0.05) * std::sin(row * 0.07);
  Cooked l;
  cook_dem("tolerance-1m", lidar, {}, l);
  if (HasFatalFailure()) return;
  EXPECT_EQ(l.report.tolerance_m, 0.5);
  EXPECT_TRUE(l.report.tolerance_from_source);
  expect_samples_within_bound(lidar, l, 0.5);
}

// Flat ground cooked with the surface layers: every triangle's normal is straight up, so every patch
// cone is exactly 0 degrees (format/SPEC.md section 16.5: "Flat patches get angle 0"), and the encoded
// cone is its alpha target ceil(0) + 1 step (90/255 degrees) or more, never the never-cull 255. The
// --report JSON states the same numbers as the report it serialises.
TEST(HardCase, FlatGroundReportsZeroDegreeCones) {
  SyntheticDem d = utm_dem(200, 200, 1.0, 500000.5, 5000099.5);
  std::fill(d.values.begin(), d.values.end(), 1234.567);
  Cooked c;
  cook_dem("flat-cones", d, {}, c, true, /*surface_layers=*/true);
  if (HasFatalFailure()) return;
  const cook::CookReport& report = c.report;
  ASSERT_TRUE(report.surface_layers);
  const cook::SurfaceTotals& t = report.surface;
  EXPECT_GT(t.cone_patches, 0u);
  EXPECT_LE(t.cone_patches, report.nodes * uint64_t(kPatchesPerSide * kPatchesPerSide));
  EXPECT_EQ(t.cone_exact_mean_deg(), 0.0);
  EXPECT_EQ(t.cone_patches_never_cull, 0u);
  EXPECT_GE(t.cone_encoded_mean_deg(), 90.0 / 255.0 - 1e-12);
  EXPECT_LT(t.cone_encoded_mean_deg(), 90.0);
  const auto j = nlohmann::json::parse(cook::report_json(report));
  const auto& cones = j["surface"]["cones"];
  EXPECT_EQ(cones["patches"].get<uint64_t>(), t.cone_patches);
  EXPECT_EQ(cones["patches_never_cull"].get<uint64_t>(), 0u);
  EXPECT_EQ(cones["exact_mean_deg"].get<double>(), 0.0);
  EXPECT_EQ(cones["encoded_mean_deg"].get<double>(), t.cone_encoded_mean_deg());
}

// A 1000 m cliff between two samples. Samples sit on the 1 m lattice, so refinement down to
// level 1 reproduces them. Bounds: tolerance + half step + 1 mm at every sample; no height beyond
// Catmull-Rom's 1/16 overshoot of a step (-62.5 .. 1062.5 m); fine levels only along the cliff.
TEST(HardCase, VerticalStepOf1000m) {
  SyntheticDem d = utm_dem(600, 120, 1.0, 501000.0, 5002000.0);
  d.point = true;
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col) d.at(col, row) = col < 300 ? 0.0 : 1000.0;
  cook::CookOptions o;
  o.tolerance_m = 0.5;
  Cooked c;
  cook_dem("step", d, o, c);
  expect_samples_within_bound(d, c, c.report.tolerance_m);
  const double cliff_x = d.mx(300) - 0.5;
  for (const NodeRecord& n : c.archive.reader.nodes()) {
    EXPECT_GE(units_to_metres(n.min_height), -62.5 - kMm);
    EXPECT_LE(units_to_metres(n.max_height), 1062.5 + kMm);
    if (n.key.level <= 2) {  // fine nodes only under parents that hold the cliff or a data edge
      const NodeKey p = parent_of(n.key);
      const double size = node_size_m(int(p.level));
      const double x0 = c.archive.reader.world().origin_x_m + p.x * size;
      const bool cliff = x0 - 16.0 <= cliff_x && x0 + size + 16.0 >= cliff_x;
      EXPECT_TRUE(cliff || near_footprint_edge(c.archive.reader.world(), p, 16.0)) << n.key.level << "/" << n.key.x;
    }
  }
  EXPECT_GT(c.report.levels[1].nodes, 0u);
  // The report's bytes by level (issue 17) are the archive's: per level, the stored bytes the reader
  // counts in its nodes' payload tables, per km2 of those nodes and per valid source sample.
  SectionBytes sb;
  ASSERT_TRUE(c.archive.reader.section_bytes(sb).ok());
  const auto j = nlohmann::json::parse(cook::report_json(c.report));
  const std::vector<uint32_t> per_level = c.archive.reader.nodes_per_level();
  uint64_t all_levels = 0;
  for (int l = 0; l < kLevelCount; ++l) {
    const auto& lj = j["levels"][size_t(l)];
    uint64_t stored = 0;
    for (int k = 0; k < 5; ++k) stored += sb.stored_by_level[l][k];
    all_levels += stored;
    EXPECT_EQ(lj["stored_bytes"].get<uint64_t>(), stored) << "level " << l;
    const double km2 = double(per_level[size_t(l)]) * node_size_m(l) * node_size_m(l) * 1e-6;
    EXPECT_NEAR(lj["bytes_per_km2"].get<double>(), km2 > 0 ? double(stored) / km2 : 0.0, 1e-6) << "level " << l;
    EXPECT_NEAR(lj["bytes_per_source_sample"].get<double>(), double(stored) / (600.0 * 120.0), 1e-9) << "level " << l;
  }
  EXPECT_GT(all_levels, 0u);
  EXPECT_LT(all_levels, c.report.archive_bytes);  // the rest is the header, directory and metadata
  EXPECT_EQ(c.report.archive_bytes, c.archive.reader.file_size());
  // terrain-inspect's denominator: the cook info records the valid source samples.
  EXPECT_EQ(nlohmann::json::parse(c.archive.reader.world().cook_info_json)["source_valid_samples"].get<uint64_t>(),
            600u * 120u);
  EXPECT_NEAR(j["output"]["bytes_per_source_sample"].get<double>(), double(c.report.archive_bytes) / (600.0 * 120.0), 1e-9);
}

// A 2.5 km cliff reaching the raster's edge, as gdalwarp makes it when it reprojects a lidar tile
// without nodata (the rotated footprint's corners filled with 0 m beside 2500 m terrain): slivers
// of 0 m, 3 .. 0 samples wide, along the west and south edges and a staircase triangle in the
// north-east, at 0.5 m spacing (the outer apron widens to one sample). The two outermost samples
// of some rows are 0 m and 2500 m, and the surface's linear continuation beyond the edge used to
// carry that difference on as a slope of -2500 m per sample, 2 km below the lowest sample (the
// cook then failed: the range bound behind the steps does not foresee it). Bounds: the cook
// succeeds; every node within the data's range widened by Catmull-Rom's 2-D overshoot bound
// (0.28125 of the range, range_summary.h) and the limited continuation (continued_difference():
// 16 times the inner difference, below 0.2 m on the terrain here, plus 256 m per sample, over at
// most two samples: 2 x 259.2 m), far from the 2.5 km below 0 m of the unlimited continuation;
// every sample within tolerance + half step + 1 mm.
TEST(HardCase, CliffOf2500mAtTheRasterEdge) {
  SyntheticDem d = utm_dem(400, 400, 0.5, 511000.0, 5020199.5);
  d.point = true;  // samples on the 0.5 m lattice: refinement reproduces them beside the cliff
  double lo = INFINITY, hi = -INFINITY;
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col) {
      const int west = 3 - 4 * row / d.height, south = 3 - 4 * col / d.width;  // sliver widths 3 .. 0
      const bool fill = col < west || row >= d.height - south || col - row > 300;
      const double z = fill ? 0.0 : 2500.0 + 0.01 * col + 0.005 * row + 2.0 * std::sin(col * 0.05) * std::cos(row * 0.04);
      d.at(col, row) = z;
      lo = std::min(lo, z);
      hi = std::max(hi, z);
    }
  ASSERT_EQ(d.at(0, 250), 0.0);  // a row whose two outermost samples are the cliff
  ASSERT_GT(d.at(1, 250), 2490.0);
  cook::CookOptions o;
  o.threads = 1;
  Cooked c;
  ASSERT_NO_FATAL_FAILURE(cook_dem("cliff_edge", d, o, c));
  const double overshoot = 0.28125 * (hi - lo) + 2 * (16 * 0.2 + 256) + c.archive.max_half_step() + kMm;
  for (const NodeRecord& n : c.archive.reader.nodes()) {
    EXPECT_GE(units_to_metres(n.min_height), lo - overshoot) << n.key.level << "/" << n.key.x << "/" << n.key.y;
    EXPECT_LE(units_to_metres(n.max_height), hi + overshoot) << n.key.level << "/" << n.key.x << "/" << n.key.y;
  }
  expect_samples_within_bound(d, c, c.report.tolerance_m);
}

// Isolated one-sample spikes of +50 m on flat ground. Bounds: tolerance + half step + 1 mm at
// every sample, and each spike's own sample exactly (half a step + 1 mm).
TEST(HardCase, OneSampleSpikes) {
  SyntheticDem d = utm_dem(200, 200, 1.0, 502000.0, 5004000.0);
  d.point = true;
  std::fill(d.values.begin(), d.values.end(), 100.0);
  std::vector<std::pair<int, int>> spikes = {{20, 30}, {55, 170}, {100, 100}, {101, 140}, {150, 20}, {180, 180}};
  for (auto [c, r] : spikes) d.at(c, r) = 150.0;
  cook::CookOptions o;
  Cooked c;
  cook_dem("spikes", d, o, c);
  expect_samples_within_bound(d, c, c.report.tolerance_m);
  for (auto [col, row] : spikes) {
    const auto h = c.archive.height(d.mx(col), d.my(row));
    ASSERT_TRUE(h);
    EXPECT_NEAR(*h, 150.0, c.archive.max_half_step() + kMm);
  }
}

// -430 m to 8848 m inside one 2048 m root. Bounds: root step 2^8 units (0.25 m, the smallest that
// fits 16 bits); node extremes within half a step of those of the samples on its vertices (the
// lattice phase puts sample 0 on a vertex, so the root's 16 m vertices are the samples of even
// columns), widened by the linear continuation over the half-sample apron (half the outermost
// sample difference, 0.18 m here); every sample within tolerance + half step + 1 mm.
TEST(HardCase, NineKilometresOfReliefInOneRoot) {
  // Footprint 501760 .. 503808 E, 5005312 .. 5007360 N (the pixel edges on multiples of 2048 m):
  // one root, which starts at the first sample (the samples' hull decides the root grid).
  SyntheticDem d = utm_dem(256, 256, 8.0, 501760.0 + 4.0, 5007360.0 - 4.0);
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col) {
      const double t = double(col) / (d.width - 1);
      d.at(col, row) = -430.0 + 9278.0 * (0.5 - 0.5 * std::cos(M_PI * t));
    }
  Cooked c;
  cook::CookOptions o;
  cook_dem("relief9km", d, o, c);
  EXPECT_EQ(c.report.roots_x * c.report.roots_y, 1u);
  EXPECT_EQ(c.archive.reader.world().step_log2[5], 8);
  const NodeRecord& root = c.archive.reader.nodes()[size_t(c.archive.reader.find({5, 0, 0}))];
  const double apron = 0.5 * (d.at(1, 0) - d.at(0, 0)), hs = c.archive.half_step(5) + kMm;
  EXPECT_LE(units_to_metres(root.min_height), -430.0 + hs);
  EXPECT_GE(units_to_metres(root.min_height), -430.0 - apron - hs);
  const double top_on_vertex = d.at(d.width - 2, 0);  // the highest even column (heights rise with the column)
  EXPECT_EQ(c.report.origin_x_m, 501764.0);
  EXPECT_GE(units_to_metres(root.max_height), top_on_vertex - hs);
  EXPECT_LE(units_to_metres(root.max_height), 8848.0 + apron + hs);
  expect_samples_within_bound(d, c, c.report.tolerance_m);
}

// 1 mm of relief over 100 m, cooked with a tolerance that resolves it (0.5 mm: the step follows
// the tolerance, 2^4 units = 15.6 mm at the default 0.5 m would flatten it). Bounds: step 1/1024 m
// at every level; every sample within half a unit (0.49 mm) + 1 um; the cooked relief keeps the
// millimetre (>= 0.5 mm between the ends). At the default tolerance the step is 2^4 units.
TEST(HardCase, OneMillimetreOfRelief) {
  SyntheticDem d = utm_dem(100, 100, 1.0, 504000.0, 5006000.0);
  d.point = true;
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col) d.at(col, row) = 500.0 + 0.001 * col / 99.0;
  {
    Cooked coarse;
    cook_dem("relief1mm_default", d, {}, coarse);
    for (uint8_t s : coarse.archive.reader.world().step_log2) EXPECT_EQ(s, 4);
  }
  cook::CookOptions o;
  o.tolerance_m = 0.0005;
  Cooked c;
  cook_dem("relief1mm", d, o, c);
  for (uint8_t s : c.archive.reader.world().step_log2) EXPECT_EQ(s, 0);
  const SourceCheck s = check_samples(d, c, 0.0);
  EXPECT_EQ(s.missing, 0u);
  EXPECT_LE(s.worst_error, 0.5 * kHeightUnitM + 1e-6 + 3e-5 /* float32 source */);
  const auto west = c.archive.height(d.mx(1), d.my(50)), east = c.archive.height(d.mx(98), d.my(50));
  ASSERT_TRUE(west && east);
  EXPECT_GE(*east - *west, 0.0005);  // 0.97 mm apart in the source
}

// A depression below sea level (-430 .. -390 m). Bounds: every node's heights negative, every
// sample within tolerance + half step + 1 mm.
TEST(HardCase, NegativeHeights) {
  SyntheticDem d = utm_dem(150, 150, 2.0, 505001.0, 5008000.0 - 1.0);
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col)
      d.at(col, row) = -430.0 + 40.0 * (std::pow((col - 75) / 75.0, 2) + std::pow((row - 75) / 75.0, 2)) / 2.0;
  cook::CookOptions o;
  Cooked c;
  cook_dem("negative", d, o, c);
  for (const NodeRecord& n : c.archive.reader.nodes()) {
    EXPECT_LT(n.max_height, 0);
    EXPECT_GE(units_to_metres(n.min_height), -430.0 - c.archive.max_half_step() - kMm);
  }
  expect_samples_within_bound(d, c, c.report.tolerance_m);
}

// Bound: a clear no_data error naming the file, and no archive written.
TEST(HardCase, AllNodataIsAClearError) {
  SyntheticDem d = flat_dem(50, 50, 1.0, 506000.0, 5010000.0, NAN);
  d.int16 = true;
  d.nodata = -32768;
  cook::CookOptions o;
  ASSERT_NO_FATAL_FAILURE(write_cook_input(scratch_dir("cooker-allnodata"), "void", d, false, o));
  cook::CookReport report;
  const Status st = cook::cook(o, {}, report);
  expect_refusal(st, Error::no_data, {"void.tif", "nodata"});
  EXPECT_FALSE(std::filesystem::exists(o.output));
}

// Nodata bands along the west and north borders (holes) and one 2x2 enclosed void (filled).
// Bounds: no cooked height inside the band (beyond half a sample from the data), the hole flag on
// every node touching it, every valid sample within tolerance + half step + 1 mm except the ring
// right next to the band (a hole vertex drops its triangles).
TEST(HardCase, NodataAlongBorders) {
  SyntheticDem d = utm_dem(200, 200, 1.0, 507000.5, 5012199.5);
  d.nodata = -9999;
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col)
      d.at(col, row) = (col < 20 || row < 20) ? NAN : 300.0 + 0.2 * col + 0.1 * row;
  for (int row = 100; row < 102; ++row)
    for (int col = 100; col < 102; ++col) d.at(col, row) = NAN;
  Cooked c;
  cook::CookOptions o;
  cook_dem("borders", d, o, c, false);
  EXPECT_EQ(c.report.hole_samples, uint64_t(200 * 20 + 180 * 20));
  EXPECT_EQ(c.report.voids_filled_samples, 4u);
  EXPECT_EQ(c.report.voids_filled_regions, 1u);
  for (int row = 0; row < 18; ++row)
    for (int col = 0; col < 200; col += 7) EXPECT_FALSE(c.archive.height(d.mx(col), d.my(row))) << col << "," << row;
  for (int col = 0; col < 18; ++col)
    for (int row = 0; row < 200; row += 7) EXPECT_FALSE(c.archive.height(d.mx(col), d.my(row))) << col << "," << row;
  bool any_holes = false;
  for (const NodeRecord& n : c.archive.reader.nodes()) any_holes |= (n.flags & kNodeFlagHasHoles) != 0;
  EXPECT_TRUE(any_holes);
  // Interior: everything answers, within the bound.
  SyntheticDem inner = d;
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col)
      if (col < 22 || row < 22) inner.at(col, row) = NAN;
  expect_samples_within_bound(inner, c, c.report.tolerance_m);
  // The filled void carries the plane (harmonic fill of planar surroundings).
  const auto h = c.archive.height(d.mx(100) + 0.5, d.my(100) - 0.5);
  ASSERT_TRUE(h);
  EXPECT_NEAR(*h, 300.0 + 0.2 * 100.5 + 0.1 * 100.5, 0.01);
}

namespace {
// Smooth geographic test surface (metres) of longitude/latitude.
double geo_surface(double lon, double lat) {
  return 300.0 + 40.0 * std::sin(2 * M_PI * lon / 0.02) * std::cos(2 * M_PI * lat / 0.01) + 200.0 * (lat - 70.5);
}
}  // namespace

// Geographic input at 70.5 N (samples 3.7 x 11 m). Bounds: the frame's central meridian at the data
// centre; every sample (projected with GeographicLib independently) within tolerance + half step
// + 1 mm, so no axis flip, half-sample shift or datum slip.
TEST(HardCase, GeographicInputAt70North) {
  SyntheticDem d = geo_dem(400, 300, 0.0001, 25.0 + 0.00005, 70.53 - 0.00005);
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col) d.at(col, row) = geo_surface(d.mx(col), d.my(row));
  Cooked c;
  cook::CookOptions o;
  cook_dem("geo70n", d, o, c);
  const FrameCrs& f = c.archive.reader.world().crs;
  EXPECT_EQ(f.kind, ProjectionKind::transverse_mercator);
  EXPECT_NEAR(f.lon0_deg, 25.02, 1.0 / 3600);
  expect_samples_within_bound(d, c, c.report.tolerance_m, true);
}

// Geographic input across the UTM zone 31/32 boundary (6 E). Bounds: one frame centred on the
// data (lon0 6.0), every sample on both sides within tolerance + half step + 1 mm, and no seam.
TEST(HardCase, InputStraddlingAUtmZoneBoundary) {
  SyntheticDem d = geo_dem(500, 200, 0.0004, 5.9 + 0.0002, 45.04 - 0.0002);
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col)
      d.at(col, row) = 800.0 + 60.0 * std::sin(2 * M_PI * d.mx(col) / 0.05) + 900.0 * (d.my(row) - 45.0);
  Cooked c;
  cook::CookOptions o;
  cook_dem("utmzones", d, o, c);
  EXPECT_NEAR(c.archive.reader.world().crs.lon0_deg, 6.0, 1e-9);
  expect_samples_within_bound(d, c, c.report.tolerance_m, true);
}

// A 45-degree plane at northing 5000 km, 0.5 m samples. Catmull-Rom and the triangulation
// reproduce planes, so at 20 000 random points (not only samples) the cooked height must equal
// the plane within half a step + 1 mm: any float32 position on the way (0.5 m resolution at 5e6)
// would break it.
TEST(HardCase, UtmSizedCoordinatesKeepMillimetres) {
  SyntheticDem d = utm_dem(240, 240, 0.5, 600000.25, 5000119.75);
  const double xc = 600060.0, yc = 5000060.0;
  auto plane = [&](double x, double y) { return 1000.0 + 1.0 * (x - xc) + 0.5 * (y - yc); };
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col) d.at(col, row) = plane(d.mx(col), d.my(row));
  Cooked c;
  cook_dem("utm5000km", d, {}, c);
  EXPECT_GT(c.archive.reader.world().origin_y_m, 4.99e6);
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> ux(d.mx(0), d.mx(239)), uy(d.my(239), d.my(0));
  double worst = 0;
  for (int k = 0; k < 20000; ++k) {
    const double x = ux(rng), y = uy(rng);
    const auto h = c.archive.height(x, y);
    ASSERT_TRUE(h);
    worst = std::max(worst, std::fabs(*h - plane(x, y)));
  }
  EXPECT_LE(worst, c.archive.max_half_step() + kMm) << "worst " << worst;
}

// A NaN in Float32 input without any nodata tag. Bounds: treated as a one-sample void (reported,
// filled from its neighbours within 1 cm of the plane they describe), no NaN anywhere in the
// archive (it verifies; every height is finite).
TEST(HardCase, NanInFloat32Input) {
  SyntheticDem d = utm_dem(100, 100, 1.0, 508000.5, 5014099.5);
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col) d.at(col, row) = 50.0 + 0.3 * col - 0.2 * row;
  d.at(50, 50) = NAN;
  Cooked c;
  cook_dem("nan", d, {}, c);
  EXPECT_EQ(c.report.voids_filled_samples, 1u);
  EXPECT_EQ(c.report.hole_samples, 0u);
  const auto h = c.archive.height(d.mx(50), d.my(50));
  ASSERT_TRUE(h);
  EXPECT_NEAR(*h, 50.0 + 0.3 * 50 - 0.2 * 50, 0.01);
  for (const NodeRecord& n : c.archive.reader.nodes()) EXPECT_TRUE(std::isfinite(n.geometric_error_m));
}

// PixelIsArea and PixelIsPoint descriptions of the same samples, striped and tiled: bound = the
// same cooked height at every sample (identical bytes of the height sections).
TEST(Inputs, PixelIsAreaAndPixelIsPointPlaceSamplesAlike) {
  SyntheticDem a = utm_dem(64, 64, 2.0, 509001.0, 5016127.0);
  for (int row = 0; row < a.height; ++row)
    for (int col = 0; col < a.width; ++col) a.at(col, row) = 10.0 + std::sin(col * 0.3) * 5.0 + row * 0.1;
  SyntheticDem p = a;
  p.point = true;
  Cooked ca, cp;
  cook_dem("area", a, {}, ca, true);
  cook_dem("point", p, {}, cp, false);
  for (int row = 2; row < 62; row += 3)
    for (int col = 2; col < 62; col += 3) {
      const auto ha = ca.archive.height(a.mx(col), a.my(row)), hp = cp.archive.height(a.mx(col), a.my(row));
      ASSERT_TRUE(ha && hp);
      EXPECT_EQ(*ha, *hp);
    }
}

// Four tiles of one DEM mosaicked give the heights of the DEM cooked whole (bound: identical).
TEST(Inputs, MosaicOfTilesEqualsTheWhole) {
  SyntheticDem whole = utm_dem(128, 128, 4.0, 510002.0, 5018110.0);
  for (int row = 0; row < whole.height; ++row)
    for (int col = 0; col < whole.width; ++col) whole.at(col, row) = 200.0 + 30.0 * std::sin(col * 0.1) * std::cos(row * 0.07);
  const auto dir = scratch_dir("cooker-mosaic");
  std::vector<std::string> tiles;
  for (int ty = 0; ty < 2; ++ty)
    for (int tx = 0; tx < 2; ++tx) {
      SyntheticDem t = whole;
      t.width = t.height = 64;
      t.x0 = whole.mx(tx * 64);
      t.y0 = whole.my(ty * 64);
      t.values.assign(64 * 64, 0.0);
      for (int r = 0; r < 64; ++r)
        for (int col = 0; col < 64; ++col) t.at(col, r) = whole.at(tx * 64 + col, ty * 64 + r);
      tiles.push_back((dir / ("tile" + std::to_string(ty * 2 + tx) + ".tif")).string());
      std::string error;
      ASSERT_TRUE(write_geotiff(tiles.back(), t, tx == 0, error)) << error;
    }
  cook::CookOptions o;
  o.inputs = tiles;
  o.output = (dir / "mosaic.terrain").string();
  o.heights_only = true;
  cook::CookReport report;
  ASSERT_TRUE(cook::cook(o, {}, report).ok());
  Cooked ref;
  cook_dem("mosaic-whole", whole, {}, ref);
  CookedArchive m;
  ASSERT_TRUE(m.open(o.output).ok());
  ASSERT_EQ(m.reader.nodes().size(), ref.archive.reader.nodes().size());
  for (size_t i = 0; i < m.reader.nodes().size(); ++i) {
    auto a = std::make_unique<NodeData>(), b = std::make_unique<NodeData>();
    ASSERT_TRUE(m.reader.decode_node(i, *a, kSectionHeights).ok());
    ASSERT_TRUE(ref.archive.reader.decode_node(i, *b, kSectionHeights).ok());
    EXPECT_EQ(a->heights, b->heights);
    EXPECT_EQ(m.reader.nodes()[i].height_offset, ref.archive.reader.nodes()[i].height_offset);
  }
}

// Bound: identical archive bytes with 1 and 2 threads (synthetic, with every section cooked).
TEST(Determinism, OneAndTwoThreadsGiveIdenticalBytes) {
  SyntheticDem d = utm_dem(300, 300, 1.0, 511000.5, 5020299.5);
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col)
      d.at(col, row) = 100.0 + 20.0 * std::sin(col * 0.05) + 15.0 * std::cos(row * 0.08) + ((col * 31 + row * 17) % 7) * 0.3;
  const auto dir = scratch_dir("cooker-threads");
  const std::string tif = (dir / "d.tif").string();
  std::string error;
  ASSERT_TRUE(write_geotiff(tif, d, true, error)) << error;
  std::vector<std::vector<char>> bytes;
  for (int threads : {1, 2}) {
    cook::CookOptions o;
    o.inputs = {tif};
    o.output = (dir / (threads == 1 ? "t1.terrain" : "t2.terrain")).string();
    o.threads = threads;
    cook::CookReport report;
    ASSERT_TRUE(cook::cook(o, {}, report).ok());
    std::ifstream in(o.output, std::ios::binary);
    bytes.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  ASSERT_GT(bytes[0].size(), 1000u);
  EXPECT_TRUE(bytes[0] == bytes[1]);
}

// Bound: the error stage's 4-lane path for sources denser than the node (node_cook.cpp,
// measure_dense_level_rows) reports what the per-sample loop reports, on 1 m rough relief with an
// enclosed void (filled samples, skipped by both) and a nodata corner (hole vertices: uncovered
// samples): per level the same samples, uncovered samples and maximum error (exactly: the same
// operations per sample), the rms within 1e-12 relative (summed in lanes), and the same archive.
TEST(ErrorMeasure, DenseRowsGiveThePerSampleLoopsErrors) {
  SyntheticDem d = utm_dem(1100, 900, 1.0, 511000.5, 5020899.5);
  uint32_t h = 7;
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col) {
      h = h * 1664525u + 1013904223u;
      d.at(col, row) = 300.0 + 40.0 * std::sin(col * 0.013) * std::cos(row * 0.017) + 2.0 * std::sin(col * 0.9 + row * 0.4) +
                       0.6 * double(h >> 24) / 256.0;
    }
  for (int row = 400; row < 406; ++row)
    for (int col = 500; col < 507; ++col) d.at(col, row) = NAN;  // enclosed: filled
  for (int row = 0; row < 150; ++row)
    for (int col = 0; col < 120 - row / 2; ++col) d.at(col, row) = NAN;  // a corner: holes
  cook::CookReport reports[2];
  std::vector<char> bytes[2];
  uint64_t dense_rows[2] = {};
  const bool was = cook::measure_error_dense_rows(true);
  for (int k = 0; k < 2; ++k) {
    cook::measure_error_dense_rows(k == 0);
    const uint64_t before = cook::dense_error_rows_measured();
    Cooked c;
    cook::CookOptions o;
    ASSERT_NO_FATAL_FAILURE(cook_dem("dense-rows", d, o, c));  // one name: the archive records its input
    dense_rows[k] = cook::dense_error_rows_measured() - before;
    reports[k] = c.report;
    std::ifstream in(c.path, std::ios::binary);
    bytes[k].assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  cook::measure_error_dense_rows(was);
  std::printf("dense path: %llu rows; per-sample loop: %llu\n", (unsigned long long)dense_rows[0],
              (unsigned long long)dense_rows[1]);
  EXPECT_GT(dense_rows[0], 10000u);
  EXPECT_EQ(dense_rows[1], 0u);
  EXPECT_TRUE(bytes[0] == bytes[1]);
  EXPECT_EQ(reports[0].voids_filled_samples, 42u);
  uint64_t uncovered = 0, measured = 0;
  for (int l = 0; l < kLevelCount; ++l) {
    const cook::LevelStats& a = reports[0].levels[size_t(l)];
    const cook::LevelStats& b = reports[1].levels[size_t(l)];
    EXPECT_EQ(a.error_samples, b.error_samples) << "level " << l;
    EXPECT_EQ(a.uncovered_samples, b.uncovered_samples) << "level " << l;
    EXPECT_EQ(a.error_max_m, b.error_max_m) << "level " << l;
    EXPECT_NEAR(a.error_rms_m, b.error_rms_m, 1e-12 * b.error_rms_m) << "level " << l;
    uncovered += b.uncovered_samples;
    measured += b.error_samples;
  }
  EXPECT_EQ(reports[0].leaf_error_max_m, reports[1].leaf_error_max_m);
  EXPECT_EQ(reports[0].leaf_error_samples, reports[1].leaf_error_samples);
  EXPECT_EQ(reports[0].leaf_uncovered_samples, reports[1].leaf_uncovered_samples);
  std::printf("%llu samples measured, %llu uncovered, leaf max %.4f m\n", (unsigned long long)measured,
              (unsigned long long)uncovered, reports[1].leaf_error_max_m);
  EXPECT_GT(uncovered, 0u);
}

// A GeoTIFF without geokeys is refused with a message naming --crs; with --crs it cooks.
TEST(Inputs, NoCrsIsRefusedUnlessTheFlagsGiveOne) {
  const SyntheticDem d = flat_dem(40, 40, 2.0, 512001.0, 5022079.0, 77.0, 0);
  cook::CookOptions o;
  cook::CookReport report;
  ASSERT_NO_FATAL_FAILURE(heights_only_input("nocrs", d, o));
  expect_refusal(cook::cook(o, {}, report), Error::invalid_argument, {"--crs"});
  o.crs = "EPSG:32632";
  ASSERT_TRUE(cook::cook(o, {}, report).ok());
  EXPECT_EQ(report.frame.epsg, 32632);
  EXPECT_NEAR(report.frame.lon0_deg, 9.0, 1e-12);
}

// Web Mercator at 46 N (scale 1.44, beyond the 0.5 % bound) is no longer refused (issue 13): it
// is projected through PROJ to a Transverse Mercator centred on the data, and the report says why.
TEST(Inputs, WebMercatorAwayFromTheEquatorGetsACentredTransverseMercator) {
  const SyntheticDem d = flat_dem(40, 40, 10.0, 1113194.9, 5780000.0, 5.0, 3857);
  cook::CookOptions o;
  cook::CookReport report;
  ASSERT_NO_FATAL_FAILURE(heights_only_input("webmerc", d, o));
  ASSERT_TRUE(cook::cook(o, {}, report).ok());
  EXPECT_EQ(report.frame.kind, ProjectionKind::transverse_mercator);
  // x 1113194.9 .. +400 m is 10.0000 .. 10.0036 E; lon0 the centre rounded to an arc-second.
  EXPECT_NEAR(report.frame.lon0_deg, 10.0018, 0.0003);
  EXPECT_NE(report.frame_reason.find("scale error"), std::string::npos) << report.frame_reason;
}

// --frame puts geographic input into a given UTM zone. Bound: every sample within tolerance + half
// step + 1 mm through that zone's projection.
TEST(Inputs, FrameOverrideProjectsIntoTheGivenFrame) {
  SyntheticDem d = geo_dem(120, 100, 0.0002, 9.5 + 0.0001, 46.02 - 0.0001);
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col) d.at(col, row) = 1500.0 + 30.0 * std::sin(col * 0.05) + 0.4 * row;
  cook::CookOptions o;
  o.frame = "EPSG:32632";
  Cooked c;
  cook_dem("frame32632", d, o, c);
  const FrameCrs& f = c.archive.reader.world().crs;
  EXPECT_EQ(f.epsg, 32632);
  EXPECT_EQ(f.false_easting_m, 500000.0);
  EXPECT_EQ(f.scale_k0, 0.9996);
  expect_samples_within_bound(d, c, c.report.tolerance_m, true);
}

// A raw R16 heightmap (little-endian uint16) with --raw-size, --spacing, --height-scale, --crs
// local: bound = every sample within half a step + 1 mm (the data is a plane).
TEST(Inputs, RawR16HeightmapWithExplicitGeoreferencing) {
  const int w = 65, h = 33;
  std::vector<uint16_t> raw(size_t(w) * h);
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) raw[size_t(row) * w + col] = uint16_t(1000 + 10 * col + 3 * (h - 1 - row));
  const auto dir = scratch_dir("cooker-raw");
  const std::string path = (dir / "map.r16").string();
  {
    std::ofstream f(path, std::ios::binary);
    for (uint16_t v : raw) {
      const char b[2] = {char(v & 0xFF), char(v >> 8)};
      f.write(b, 2);
    }
  }
  cook::CookOptions o;
  o.inputs = {path};
  o.output = (dir / "map.terrain").string();
  o.raw_size = {w, h};
  o.spacing = std::array<double, 2>{2.0, 2.0};
  o.origin = std::array<double, 2>{100.0, 200.0};
  o.height_scale = 0.01;
  o.crs = "local";
  o.heights_only = true;
  cook::CookReport report;
  const Status st = cook::cook(o, {}, report);
  ASSERT_TRUE(st.ok()) << st.to_string();
  EXPECT_EQ(report.frame.kind, ProjectionKind::local);
  CookedArchive a;
  ASSERT_TRUE(a.open(o.output).ok());
  EXPECT_EQ(a.reader.world().origin_x_m, 0.0);  // 100 snapped down to a multiple of 2048
  double worst = 0;
  for (int row = 1; row < h - 1; ++row)
    for (int col = 1; col < w - 1; ++col) {
      const double x = 100.0 + 2.0 * col, y = 200.0 + 2.0 * (h - 1 - row);
      const auto z = a.height(x, y);
      ASSERT_TRUE(z) << col << "," << row;
      worst = std::max(worst, std::fabs(*z - 0.01 * (1000 + 10 * col + 3 * (h - 1 - row))));
    }
  EXPECT_LE(worst, a.max_half_step() + kMm);
  // The wrong size is a clear error naming the expected byte count.
  o.raw_size = {w + 1, h};
  expect_refusal(cook::cook(o, {}, report), Error::unsupported_input, {"--raw-size"});
}
