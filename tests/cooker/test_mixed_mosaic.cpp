// Inputs in different CRSs and at different spacings in one cook (issue 13): every input but the
// one that takes precedence is resampled onto its grid (cooker/src/mosaic/resample_inputs.h), then
// mosaicked, the input that takes precedence winning overlaps: by default the finest (issue 51, in
// either order), with --overlap list the first listed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <gdal.h>
#include <iterator>
#include <ogr_srs_api.h>

#include "session/cook_session.h"
#include "cooker_test_util.h"
#include "mosaic/mosaic_source.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;
namespace fs = std::filesystem;

namespace {

std::string file_bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

// Transforms (x, y) from EPSG `from` to EPSG `to` (x = easting/longitude) with OSR, not the cooker.
void transform(int from, int to, double& x, double& y) {
  OGRSpatialReferenceH a = OSRNewSpatialReference(nullptr), b = OSRNewSpatialReference(nullptr);
  OSRImportFromEPSG(a, from);
  OSRImportFromEPSG(b, to);
  OSRSetAxisMappingStrategy(a, OAMS_TRADITIONAL_GIS_ORDER);
  OSRSetAxisMappingStrategy(b, OAMS_TRADITIONAL_GIS_ORDER);
  OGRCoordinateTransformationH t = OCTNewCoordinateTransformation(a, b);
  ASSERT_NE(t, nullptr);
  EXPECT_TRUE(OCTTransform(t, 1, &x, &y, nullptr));
  OCTDestroyCoordinateTransformation(t);
  OSRDestroySpatialReference(a);
  OSRDestroySpatialReference(b);
}

// A: 100x100 samples of 30 m in UTM 33N, all 100 m. B: a geographic (EPSG:4326) grid of 0.0005 deg
// over A and 0.01 deg around it, 500 m plus a 100 m ripple, with a nodata hole of 0.004 deg inside
// A's area (around the point `hole_lon`, `hole_lat`).
struct Pair {
  SyntheticDem a, b;
  double hole_lon = 0, hole_lat = 0;
};

void make_pair_dems(Pair& p) {
  SyntheticDem& a = p.a;
  a.width = a.height = 100;
  a.values.assign(100 * 100, 100.0);
  a.x0 = 500015;
  a.y0 = 4984985;
  a.dx = a.dy = 30;
  a.epsg_projected = 32633;
  double lon0 = 500000, lat1 = 4985000, lon1 = 503000, lat0 = 4982000;
  ASSERT_NO_FATAL_FAILURE(transform(32633, 4326, lon0, lat1));
  ASSERT_NO_FATAL_FAILURE(transform(32633, 4326, lon1, lat0));
  p.hole_lon = 500000 + 30 * 70;
  p.hole_lat = 4985000 - 30 * 70;
  ASSERT_NO_FATAL_FAILURE(transform(32633, 4326, p.hole_lon, p.hole_lat));
  SyntheticDem& b = p.b;
  b.dx = b.dy = 0.0005;
  b.x0 = std::min(lon0, lon1) - 0.01;
  b.y0 = std::max(lat0, lat1) + 0.01;
  b.width = int((std::max(lon0, lon1) + 0.01 - b.x0) / b.dx) + 1;
  b.height = int((b.y0 - std::min(lat0, lat1) + 0.01) / b.dy) + 1;
  b.values.resize(size_t(b.width) * size_t(b.height));
  b.nodata = -9999;
  b.epsg_geographic = 4326;
  for (int row = 0; row < b.height; ++row)
    for (int col = 0; col < b.width; ++col) {
      const double lon = b.mx(col), lat = b.my(row);
      const bool hole = std::fabs(lon - p.hole_lon) < 0.002 && std::fabs(lat - p.hole_lat) < 0.002;
      b.at(col, row) = hole ? NAN : 500 + 100 * std::sin(col * 0.1) * std::cos(row * 0.13);
    }
}

class MixedSynthetic : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = scratch_dir("mixed_mosaic");
    ASSERT_NO_FATAL_FAILURE(make_pair_dems(pair_));
    std::string error;
    ASSERT_TRUE(write_geotiff((dir_ / "a_utm.tif").string(), pair_.a, true, error)) << error;
    ASSERT_TRUE(write_geotiff((dir_ / "b_geo.tif").string(), pair_.b, false, error)) << error;
  }
  void cook(std::vector<std::string> names, const std::string& out, int threads, CookedArchive& ca,
            cook::OverlapRule overlap = cook::OverlapRule::list) {
    cook::CookOptions o;
    o.overlap = overlap;
    for (const std::string& n : names) o.inputs.push_back((dir_ / n).string());
    o.output = (dir_ / out).string();
    o.threads = threads;
    cook::CookReport report;
    uint64_t compared = 0;
    ASSERT_NO_FATAL_FAILURE(cook_and_verify(o, report, ca, compared));
  }
  fs::path dir_;
  Pair pair_;
};

// --overlap list: the first listed wins across CRSs: with the UTM input first, every one of its samples cooks to its
// 100 m (within tolerance + half the root step + 1 mm), although the geographic input under it
// holds 400..600 m there; the geographic input still fills around it.
TEST_F(MixedSynthetic, FirstListedWinsAcrossCrss) {
  CookedArchive ca;
  ASSERT_NO_FATAL_FAILURE(cook({"a_utm.tif", "b_geo.tif"}, "ab.terrain", 2, ca));
  EXPECT_EQ(ca.reader.world().crs.epsg, 32633);
  const double bound = ca.tolerance() + ca.max_half_step() + 0.001;
  size_t checked = 0, bad = 0;
  for (int row = 0; row < 100; ++row)
    for (int col = 0; col < 100; ++col) {
      const auto h = ca.height(pair_.a.mx(col), pair_.a.my(row));
      ++checked;
      if (!h || std::fabs(*h - 100.0) > bound) {
        if (bad++ < 5) ADD_FAILURE() << "A sample (" << col << ", " << row << "): " << (h ? *h : NAN);
      }
    }
  EXPECT_EQ(checked, 10000u);
  EXPECT_EQ(bad, 0u);
  // 200 m east of A (0.4 deg of B's ripple amplitude away from 100 m): B's data, resampled.
  const auto outside = ca.height(503300, 4983500);
  ASSERT_TRUE(outside.has_value());
  EXPECT_GT(*outside, 390.0);
  EXPECT_LT(*outside, 610.0);
}

// --overlap list, the other order gives the documented other result: the geographic input sets the
// frame and wins over A's area (400..600 m there), and A only fills the hole B leaves (100 m).
TEST_F(MixedSynthetic, TheOtherOrderLetsTheGeographicInputWin) {
  CookedArchive ab, ba;
  ASSERT_NO_FATAL_FAILURE(cook({"a_utm.tif", "b_geo.tif"}, "ab.terrain", 2, ab));
  ASSERT_NO_FATAL_FAILURE(cook({"b_geo.tif", "a_utm.tif"}, "ba.terrain", 2, ba));
  EXPECT_NE(ba.reader.world().crs.epsg, 32633);
  const double bound = ba.tolerance() + ba.max_half_step() + 0.001;
  // A's sample (30, 30): away from the hole (which is around A's sample (70, 70)).
  double lon = pair_.a.mx(30), lat = pair_.a.my(30);
  const auto h_ab = ab.height(pair_.a.mx(30), pair_.a.my(30));
  ASSERT_NO_FATAL_FAILURE(transform(32633, 4326, lon, lat));
  double x = 0, y = 0;
  lonlat_to_frame(ba.reader.world().crs, lon, lat, x, y);
  const auto h_ba = ba.height(x, y);
  ASSERT_TRUE(h_ab && h_ba);
  EXPECT_NEAR(*h_ab, 100.0, bound);
  EXPECT_GT(*h_ba, 390.0) << "B listed first must win over A's area";
  // The hole's centre: B has no data there, so A (resampled into B's grid) fills it in both orders.
  lonlat_to_frame(ba.reader.world().crs, pair_.hole_lon, pair_.hole_lat, x, y);
  const auto hole_ba = ba.height(x, y);
  const auto hole_ab = ab.height(pair_.a.mx(70), pair_.a.my(70));
  ASSERT_TRUE(hole_ba && hole_ab);
  EXPECT_NEAR(*hole_ba, 100.0, bound);
  EXPECT_NEAR(*hole_ab, 100.0, bound);
}

// By default the finer input wins (issue 51): A's 30 m against B's 0.0005 deg (39 x 55 m at 45 N),
// so A sets the frame and holds its area whichever is listed first, and the two orders give the
// same bytes. (A's samples within the seam band, twice B's 39 m spacing, ramp towards B's: checked
// from 3 samples in.)
TEST_F(MixedSynthetic, TheFinerInputWinsInEitherOrderWithTheSameBytes) {
  CookedArchive ab, ba;
  ASSERT_NO_FATAL_FAILURE(cook({"a_utm.tif", "b_geo.tif"}, "ab.terrain", 2, ab, cook::OverlapRule::finer));
  ASSERT_NO_FATAL_FAILURE(cook({"b_geo.tif", "a_utm.tif"}, "ba.terrain", 2, ba, cook::OverlapRule::finer));
  EXPECT_EQ(ba.reader.world().crs.epsg, 32633);
  EXPECT_TRUE(file_bytes(dir_ / "ab.terrain") == file_bytes(dir_ / "ba.terrain"));
  const double bound = ba.tolerance() + ba.max_half_step() + 0.001;
  size_t bad = 0;
  for (int row = 3; row < 97; row += 3)
    for (int col = 3; col < 97; col += 3) {
      const auto h = ba.height(pair_.a.mx(col), pair_.a.my(row));
      if (!h || std::fabs(*h - 100.0) > bound)
        if (bad++ < 5) ADD_FAILURE() << "A sample (" << col << ", " << row << "): " << (h ? *h : NAN);
    }
  EXPECT_EQ(bad, 0u);
  // B still fills around A.
  const auto outside = ba.height(503300, 4983500);
  ASSERT_TRUE(outside.has_value());
  EXPECT_GT(*outside, 390.0);
}

// Determinism: the mixed cook (seam blend included) with 1 and 2 threads is byte-identical.
TEST_F(MixedSynthetic, OneAndTwoThreadsAreByteIdentical) {
  CookedArchive one, two;
  ASSERT_NO_FATAL_FAILURE(cook({"a_utm.tif", "b_geo.tif"}, "t1.terrain", 1, one, cook::OverlapRule::finer));
  ASSERT_NO_FATAL_FAILURE(cook({"a_utm.tif", "b_geo.tif"}, "t2.terrain", 2, two, cook::OverlapRule::finer));
  const std::string a = file_bytes(dir_ / "t1.terrain"), b = file_bytes(dir_ / "t2.terrain");
  EXPECT_GT(a.size(), 1000u);
  EXPECT_TRUE(a == b) << "archives differ (" << a.size() << " vs " << b.size() << " bytes)";
}

// The resampled input is read by windows like any other (issue 13: nothing sized by the whole
// input): nothing of it is held, and a small window reads a small part of it.
TEST_F(MixedSynthetic, TheResampledInputIsReadByWindowsNotHeldWhole) {
  cook::CookOptions o;
  o.inputs = {(dir_ / "a_utm.tif").string(), (dir_ / "b_geo.tif").string()};
  cook::MosaicSource src;
  ASSERT_TRUE(cook::open_mosaic_source(cook::input_options(o), UINT64_MAX, src).ok());
  ASSERT_EQ(src.inputs().size(), 2u);
  EXPECT_TRUE(src.inputs()[1].windowed);
  EXPECT_EQ(src.held_input_bytes(), 0u);
  const uint64_t whole_b = uint64_t(pair_.b.width) * uint64_t(pair_.b.height) * sizeof(float);
  // Opening counts B's implausible heights once, reading it in strips.
  const uint64_t after_open = src.inputs()[1].bytes_read;
  EXPECT_GE(after_open, whole_b);
  // 12 x 12 grid samples (360 m) beside A: the samples of B within them and the filter reach.
  std::vector<float> out(144);
  ASSERT_TRUE(src.read(4, src.header().height / 2, 12, 12, out.data()).ok());  // west of A: B only
  const uint64_t window = src.inputs()[1].bytes_read - after_open;
  EXPECT_GT(window, 0u);
  EXPECT_LT(window * 20, whole_b) << window << " bytes for 144 samples of a " << whole_b << "-byte input";
  for (float v : out) EXPECT_TRUE(std::isfinite(v) && v >= 399.0f && v <= 601.0f) << v;  // B's 500 +- 100 m
}

// Block size and order change no byte of a mixed cook: every resampled sample depends on its own
// position and the input's samples only, whichever window asks for it.
TEST_F(MixedSynthetic, EveryBlockSplitAndOrderGivesTheSameBytes) {
  cook::CookOptions o;
  o.inputs = {(dir_ / "a_utm.tif").string(), (dir_ / "b_geo.tif").string()};
  o.threads = 2;
  o.heights_only = true;
  o.block_roots = 4096;
  o.output = (dir_ / "whole.terrain").string();
  cook::CookReport whole;
  ASSERT_TRUE(cook::cook(o, nullptr, whole).ok());
  ASSERT_EQ(whole.blocks, 1u);
  const std::string expected = file_bytes(o.output);
  ASSERT_GT(expected.size(), 1000u);
  for (const auto& [roots, seed] : std::vector<std::pair<uint32_t, uint32_t>>{{1, 0}, {1, 5}, {2, 3}}) {
    o.block_roots = roots;
    o.block_order = seed;
    o.output = (dir_ / fmt::format("b{}s{}.terrain", roots, seed)).string();
    cook::CookReport r;
    const Status st = cook::cook(o, nullptr, r);
    ASSERT_TRUE(st.ok()) << st.message;
    EXPECT_GE(r.blocks, 2u);
    EXPECT_LT(r.block_window_samples_max, whole.block_window_samples_max);
    EXPECT_TRUE(file_bytes(o.output) == expected) << "block_roots " << roots << ", order seed " << seed;
  }
}

// Kilauea (UTM 5N, 30 m) cut in two overlapping halves: the west half as is, the east half
// gdalwarp'ed (bilinear, exact transformer) to EPSG:4326 at 0.0004 deg (about 42 x 44 m). The mixed
// cook (west first) is checked at the uncut DEM's samples, read here with GDAL.
//
// The bound: at a sample the cook answers the mosaic's value within tolerance + half the root step
// + 1 mm (the cooker's bound, test_real_data.cpp). West of column 440 the mosaic IS the uncut DEM.
// East of it the mosaic value is two bilinear resamplings of the uncut DEM, each a convex
// combination (weights >= 0, sum 1; nodata neighbours are dropped and the rest renormalised) of
// samples near the point: gdalwarp's at a 4326 sample draws on uncut samples within its kernel,
// at most 2 samples (60 m) per axis when it downsamples 30 -> 42 m (GDAL widens the kernel by
// the ratio, 1.5 < 2), so within 85 m; ours at a uncut grid point draws on 4326 samples of the
// cell around it, within its diagonal, 62 m. So the resampled value lies between the min and max
// of the uncut samples within 85 + 62 < 150 m = 5 samples: the resampling error at P is at most
// max(max - f(P), f(P) - min) over the 11 x 11 window around P (a square holds that disk). The seam
// band's ramp (mosaic_source.h) mixes the west half's value and the resampled east half's with
// weights in [0, 1]: between them, so within the same allowance.
TEST(MixedReal, KilaueaHalfInGeographicCooksWithinTheDerivedBound) {
  const fs::path dem = data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(dem);
  const fs::path dir = scratch_dir("mixed_mosaic_real");
  const fs::path west = dir / "west.tif", east_utm = dir / "east_utm.tif", east = dir / "east_geo.tif";
  for (const std::string& cmd :
       {fmt::format("gdal_translate -q -srcwin 0 0 440 793 '{}' '{}'", dem.string(), west.string()),
        fmt::format("gdal_translate -q -srcwin 420 0 437 793 '{}' '{}'", dem.string(), east_utm.string()),
        fmt::format("gdalwarp -q -et 0 -t_srs EPSG:4326 -tr 0.0004 0.0004 -r bilinear '{}' '{}'", east_utm.string(),
                    east.string())})
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;

  cook::CookOptions o;
  o.inputs = {west.string(), east.string()};
  o.output = (dir / "mixed.terrain").string();
  o.threads = 2;
  cook::CookReport report;
  CookedArchive ca;
  uint64_t compared = 0;
  ASSERT_NO_FATAL_FAILURE(cook_and_verify(o, report, ca, compared));
  EXPECT_EQ(ca.reader.world().crs.lon0_deg, -153.0);  // the west half's UTM 5N frame

  // The uncut DEM through GDAL (the oracle), independent of the cooker's readers.
  GDALAllRegister();
  GDALDatasetH ds = GDALOpen(dem.string().c_str(), GA_ReadOnly);
  ASSERT_NE(ds, nullptr);
  const int w = GDALGetRasterXSize(ds), h = GDALGetRasterYSize(ds);
  double gt[6];
  GDALGetGeoTransform(ds, gt);
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  int has_nodata = 0;
  const double nodata = GDALGetRasterNoDataValue(band, &has_nodata);
  std::vector<double> z(size_t(w) * size_t(h));
  ASSERT_EQ(GDALRasterIO(band, GF_Read, 0, 0, w, h, z.data(), w, h, GDT_Float64, 0, 0), CE_None);
  GDALClose(ds);
  for (double& v : z)
    if (has_nodata && v == nodata) v = NAN;

  const double base = ca.tolerance() + ca.max_half_step() + 0.001;
  constexpr int kWindow = 5;
  size_t west_points = 0, east_points = 0, bad = 0;
  double worst_excess = -INFINITY, sum_resampling = 0, sum_east_error = 0, sum_east_step = 0;
  for (int row = kWindow + 1; row < h - kWindow - 1; row += 3)
    for (int col = kWindow + 1; col < w - kWindow - 1; col += 3) {
      const double f = z[size_t(row) * size_t(w) + size_t(col)];
      double lo = INFINITY, hi = -INFINITY;
      for (int dr = -kWindow; dr <= kWindow; ++dr)
        for (int dc = -kWindow; dc <= kWindow; ++dc) {
          const double v = z[size_t(row + dr) * size_t(w) + size_t(col + dc)];
          lo = std::min(lo, v);  // NaN never wins a min/max: checked below
          hi = std::max(hi, v);
          if (std::isnan(v)) lo = NAN;
        }
      if (std::isnan(f) || std::isnan(lo)) continue;  // nodata nearby: the void filler's business
      // The seam band (twice the east half's 42 m: 84 m) ramps the west half's last 2 samples
      // (30 and 60 m from the east half's data) towards the resampled east half: they get its allowance.
      const bool east_side = col >= 440 - 2;
      const double resampling = east_side ? std::max(hi - f, f - lo) : 0.0;
      const double bound = base + resampling;
      const auto cooked = ca.height(gt[0] + gt[1] * (col + 0.5), gt[3] + gt[5] * (row + 0.5));
      (east_side ? east_points : west_points)++;
      sum_resampling += resampling;
      if (east_side && cooked) {
        sum_east_error += std::fabs(*cooked - f);
        sum_east_step += std::fabs(z[size_t(row) * size_t(w) + size_t(col + 1)] - f);
      }
      const double err = cooked ? std::fabs(*cooked - f) : INFINITY;
      worst_excess = std::max(worst_excess, err - bound);
      if (err > bound && bad++ < 5)
        ADD_FAILURE() << "sample (" << col << ", " << row << "): cooked " << (cooked ? *cooked : NAN) << " source " << f
                      << " bound " << bound;
    }
  const double n_east = double(std::max<size_t>(east_points, 1));
  std::printf("mixed kilauea: %zu west + %zu east points, east: mean resampling allowance %.3f m, mean error %.3f m, "
              "mean one-sample step %.3f m; worst excess over the bound %.4f m\n",
              west_points, east_points, sum_resampling / n_east, sum_east_error / n_east, sum_east_step / n_east,
              worst_excess);
  EXPECT_GT(west_points, 10000u);
  EXPECT_GT(east_points, 10000u);
  EXPECT_EQ(bad, 0u);
  // The allowance above is loose where the relief is steep (11 x 11 windows); placement itself is
  // checked on average: the east half put half a sample off would err by about half the mean
  // one-sample height step on average (on top of the tolerance), so the mean error stays below it.
  EXPECT_LT(sum_east_error / n_east, 0.5 * sum_east_step / n_east);
}

}  // namespace

namespace {

// Smooth hills with relief at several wavelengths (metres), in UTM 33N coordinates.
double hills(double x, double y) {
  return 300 + 60 * std::sin(x / 400) * std::cos(y / 500) + 20 * std::sin(x / 130 + y / 170) +
         12 * std::sin(x / 45) * std::sin(y / 52);
}

}  // namespace

// Issue 51: each grid family refines by its own source's rules (node_cook.h, node_refine_rules).
// A 30 m DEM of 3.6 x 3.6 km with a 1 m tile of 200 x 200 m in its middle holding the same hills
// plus 0.8 m of detail at a 5-6 m wavelength (1 m vertices hold it within 0.5 m, 2 m ones do not). The 30 m part follows the 30 m rules: tolerance
// 30 / 32 = 0.9375 m, and its data edges are resolved to vertices at most half its spacing apart
// (15 m: level 4, 8 m vertices; the 1 m tile's rule would take them to level 0, 0.5 m). The 1 m tile keeps
// its own: 0.5 m, within which every sample beyond the seam band (60 m) is held (+ half a step +
// 1 mm; the band: ASeamBecomesARampAcrossTheStatedBand).
TEST(MixedRules, EachGridFamilyRefinesByItsOwnSpacing) {
  const fs::path dir = scratch_dir("mixed_rules");
  SyntheticDem coarse;
  coarse.width = coarse.height = 120;
  coarse.dx = coarse.dy = 30;
  coarse.x0 = 500015;
  coarse.y0 = 4999985;
  coarse.epsg_projected = 32633;
  coarse.values.resize(120 * 120);
  for (int r = 0; r < 120; ++r)
    for (int c = 0; c < 120; ++c) coarse.at(c, r) = hills(coarse.mx(c), coarse.my(r));
  SyntheticDem fine;
  fine.width = fine.height = 200;
  fine.dx = fine.dy = 1;
  fine.x0 = 501700.5;
  fine.y0 = 4998299.5;
  fine.epsg_projected = 32633;
  fine.values.resize(200 * 200);
  for (int r = 0; r < 200; ++r)
    for (int c = 0; c < 200; ++c) {
      const double x = fine.mx(c), y = fine.my(r);
      fine.at(c, r) = hills(x, y) + 0.8 * std::sin(x / 0.8) * std::cos(y / 0.9);
    }
  std::string error;
  ASSERT_TRUE(write_geotiff((dir / "coarse.tif").string(), coarse, true, error)) << error;
  ASSERT_TRUE(write_geotiff((dir / "fine.tif").string(), fine, true, error)) << error;
  cook::CookOptions o;
  o.inputs = {(dir / "coarse.tif").string(), (dir / "fine.tif").string()};
  o.output = (dir / "world.terrain").string();
  o.heights_only = true;
  o.threads = 2;
  cook::CookReport report;
  CookedArchive ca;
  uint64_t compared = 0;
  ASSERT_NO_FATAL_FAILURE(cook_and_verify(o, report, ca, compared));
  EXPECT_DOUBLE_EQ(ca.tolerance(), 0.5);  // the finest family's, the archive's
  for (const std::string& w : report.warnings)  // each family's leaves meet its own tolerance
    EXPECT_EQ(w.find("is not met everywhere"), std::string::npos) << w;
  // The report per input, in the order of precedence: the 1 m tile first.
  ASSERT_EQ(report.input_samples.size(), 2u);
  const cook::InputSamples& fi = report.input_samples[0];
  const cook::InputSamples& ci = report.input_samples[1];
  EXPECT_EQ(fi.path, (dir / "fine.tif").string());
  EXPECT_EQ(fi.family, 0u);
  EXPECT_EQ(ci.family, 1u);
  EXPECT_DOUBLE_EQ(fi.spacing_m, 1.0);
  EXPECT_DOUBLE_EQ(ci.spacing_m, 30.0);
  EXPECT_DOUBLE_EQ(fi.tolerance_m, 0.5);
  EXPECT_DOUBLE_EQ(ci.tolerance_m, 0.9375);
  EXPECT_NEAR(fi.area_km2, 0.04, 1e-9);                   // 200 x 200 samples of 1 m2
  // The 30 m DEM resampled onto the 1 m grid has data between its outer sample centres (a bilinear
  // tent needs its 2 x 2 samples): 3570 x 3570 samples of 1 m2, less the tile's.
  EXPECT_NEAR(ci.area_km2, 3.57 * 3.57 - 0.04, 1e-9);
  const int fine_finest = fi.finest_level, coarse_finest = ci.finest_level;  // checked below
  const WorldInfo& world = ca.reader.world();
  // The fine tile's square, grown by 300 m: nodes wholly outside it hold 30 m data only.
  const double fx0 = 501700 - 300, fx1 = 501900 + 300, fy0 = 4998100 - 300, fy1 = 4998300 + 300;
  int coarse_only = 0, coarse_min_level = kLevelCount, near_min_level = kLevelCount, coarse_leaves_over_half = 0;
  for (const NodeRecord& n : ca.reader.nodes()) {
    const double size = node_size_m(int(n.key.level));
    const double x0 = world.origin_x_m + n.key.x * size, y0 = world.origin_y_m + n.key.y * size;
    const bool outside = x0 >= fx1 || x0 + size <= fx0 || y0 >= fy1 || y0 + size <= fy0;
    if (outside) {
      ++coarse_only;
      coarse_min_level = std::min(coarse_min_level, int(n.key.level));
      if (n.child_mask == 0) {
        EXPECT_LE(n.geometric_error_m, 0.9375f) << "leaf " << int(n.key.level) << "/" << n.key.x << "/" << n.key.y;
        coarse_leaves_over_half += n.geometric_error_m > 0.5f ? 1 : 0;
      }
    } else {
      near_min_level = std::min(near_min_level, int(n.key.level));
    }
  }
  EXPECT_GT(coarse_only, 0);
  // The 1 m tile's rules would resolve the 30 m DEM's data edges to 0.5 m vertices (level 0); its
  // own stop them at 8 m (level 4), and its 0.94 m is met at 4 m vertices (level 3) on these hills.
  EXPECT_GE(coarse_min_level, 3);
  EXPECT_GT(coarse_leaves_over_half, 0) << "no 30 m leaf uses its 0.94 m tolerance";
  EXPECT_LE(near_min_level, 1) << "the 1 m detail is refined";
  // The report's finest levels: the tile's is the finest node near it; the 30 m DEM's lies between
  // (the siblings of the tile's nodes that hold only 30 m data) and that of the nodes away from it.
  EXPECT_EQ(fine_finest, near_min_level);
  EXPECT_GE(coarse_finest, fine_finest);
  EXPECT_LE(coarse_finest, coarse_min_level);
  // The 1 m tile within its own bound beyond the seam band, every 4th sample.
  const double bound = 0.5 + ca.max_half_step() + 0.001;
  size_t bad = 0, checked = 0;
  for (int r = 60; r < 140; r += 4)
    for (int c = 60; c < 140; c += 4) {
      const auto h = ca.height(fine.mx(c), fine.my(r));
      ++checked;
      if (!h || std::fabs(*h - fine.at(c, r)) > bound)
        if (bad++ < 5) ADD_FAILURE() << "fine sample (" << c << ", " << r << "): " << (h ? *h : NAN) << " vs " << fine.at(c, r);
    }
  EXPECT_EQ(checked, 400u);
  EXPECT_EQ(bad, 0u);
}

// Issue 51's seam blend (mosaic_source.h): a 1 m tile 3 m below the 30 m DEM around it (lidar
// and national DEMs disagree by metres). Within 60 m (twice the 30 m spacing) of where the DEM
// takes over, the tile's heights ramp linearly to the DEM's: expected = coarse + d / 60 (fine -
// coarse), coarse the DEM's bilinear surface (computed here), d the distance to the nearest DEM
// sample outside the tile. Beyond the band the tile is unchanged, and the 3 m step is gone: the
// largest change between neighbouring samples across the tile's edge is a sixtieth of it plus the
// terrain's slope. With --overlap list (no blend) the step stays, 3 m.
TEST(MixedRules, ASeamBecomesARampAcrossTheStatedBand) {
  const fs::path dir = scratch_dir("mixed_seam");
  SyntheticDem coarse;
  coarse.width = coarse.height = 40;
  coarse.dx = coarse.dy = 30;
  coarse.x0 = 500015;
  coarse.y0 = 4999985;
  coarse.epsg_projected = 32633;
  coarse.values.resize(40 * 40);
  for (int r = 0; r < 40; ++r)
    for (int c = 0; c < 40; ++c) coarse.at(c, r) = hills(coarse.mx(c), coarse.my(r)) + 3.0;
  SyntheticDem fine;
  fine.width = fine.height = 200;
  fine.x0 = 500500.5;
  fine.y0 = 4999499.5;
  fine.epsg_projected = 32633;
  fine.values.resize(200 * 200);
  for (int r = 0; r < 200; ++r)
    for (int c = 0; c < 200; ++c) fine.at(c, r) = hills(fine.mx(c), fine.my(r));
  std::string error;
  ASSERT_TRUE(write_geotiff((dir / "coarse.tif").string(), coarse, true, error)) << error;
  ASSERT_TRUE(write_geotiff((dir / "fine.tif").string(), fine, true, error)) << error;
  // The DEM's bilinear surface (the resampling's tent of radius 1 for a coarser input).
  const auto coarse_at = [&](double x, double y) {
    const double u = (x - coarse.x0) / 30, v = (coarse.y0 - y) / 30;
    const int i = int(std::floor(u)), j = int(std::floor(v));
    const double a = u - i, b = v - j;
    return (1 - a) * (1 - b) * coarse.at(i, j) + a * (1 - b) * coarse.at(i + 1, j) + (1 - a) * b * coarse.at(i, j + 1) +
           a * b * coarse.at(i + 1, j + 1);
  };
  for (const cook::OverlapRule rule : {cook::OverlapRule::finer, cook::OverlapRule::list}) {
    cook::CookOptions o;
    o.inputs = {(dir / "fine.tif").string(), (dir / "coarse.tif").string()};
    o.output = (dir / (rule == cook::OverlapRule::finer ? "blend.terrain" : "list.terrain")).string();
    o.heights_only = true;
    o.overlap = rule;
    cook::CookReport report;
    CookedArchive ca;
    uint64_t compared = 0;
    ASSERT_NO_FATAL_FAILURE(cook_and_verify(o, report, ca, compared));
    const double bound = ca.tolerance() + ca.max_half_step() + 0.001 + 0.005;  // + the tent's float rounding
    size_t bad = 0, in_band = 0;
    double worst_step = 0;
    for (int r = 0; r < 200; ++r)
      for (int c = 0; c < 200; ++c) {
        const double x = fine.mx(c), y = fine.my(r);
        const int d = std::min({c, 199 - c, r, 199 - r}) + 1;  // metres to the nearest sample outside
        double expected = fine.at(c, r);
        if (rule == cook::OverlapRule::finer && d < 60) {
          const double ramp = coarse_at(x, y);
          expected = ramp + d / 60.0 * (fine.at(c, r) - ramp);
          ++in_band;
        }
        const auto h = ca.height(x, y);
        if (!h || std::fabs(*h - expected) > bound)
          if (bad++ < 5) ADD_FAILURE() << "sample (" << c << ", " << r << ") d " << d << ": " << (h ? *h : NAN) << " vs " << expected;
        if (c == 0 && r % 10 == 5) {  // across the west edge: the last tile sample and 1 m west of it
          const auto outside = ca.height(x - 1, y);
          ASSERT_TRUE(h && outside);
          worst_step = std::max(worst_step, std::fabs(*h - *outside));
        }
      }
    EXPECT_EQ(bad, 0u) << (rule == cook::OverlapRule::finer ? "blend" : "list");
    if (rule == cook::OverlapRule::finer) {
      EXPECT_EQ(in_band, 200u * 200u - 82u * 82u);
      // A sixtieth of the 3 m step, the hills' slope over 1 m (at most 0.15 + 0.16 + 0.27 m/m)
      // and twice the bound.
      EXPECT_LT(worst_step, 3.0 / 60 + 1.0 + 2 * bound);
      EXPECT_DOUBLE_EQ(report.input_samples[0].tolerance_m, 0.5);
    } else {
      EXPECT_GT(worst_step, 3.0 - 1.0 - 2 * bound) << "the unblended control keeps the step";
    }
  }
}
