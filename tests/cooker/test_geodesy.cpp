// Geodesy edge cases of the cooker (issue 11, items 8 and 9): input crossing the antimeridian,
// tiles either side of it, and data reaching the poles.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sys/wait.h>

#include "cooker_test_util.h"
#include "frame/frame.h"
#include "frame/crs.h"
#include "mosaic/mosaic.h"
#include "inputs/raster.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;

namespace {

constexpr double kMm = 1e-3;

// A WGS 84 geographic raster of w x h samples at `spacing` degrees whose north-west sample centre
// is (lon, lat) (longitudes may exceed 180: the antimeridian cases).
cook::Raster geographic_raster(int w, int h, double spacing, double lon, double lat) {
  cook::Raster r;
  r.width = w;
  r.height = h;
  r.values.assign(size_t(w) * size_t(h), 1.0f);
  r.geo.c[0] = lon;
  r.geo.c[1] = spacing;
  r.geo.c[3] = lat;
  r.geo.c[5] = -spacing;
  r.geo.valid = true;
  r.crs = cook::wgs84_geographic();
  return r;
}

// Worst distance (metres on the ground) between the interpolated and the exact frame -> sample
// mapping over the raster's footprint, at random points (GeographicLib per point as the oracle).
double worst_anchor_error_m(const cook::Raster& r) {
  FrameCrs frame;
  std::string reason;
  cook::SourceMapping m;
  const Status st = cook::choose_frame(r, "", frame, reason);
  const Status init = st.ok() ? m.init(r, frame, 2) : st;
  EXPECT_TRUE(init.ok()) << init.to_string();
  if (!init.ok()) return INFINITY;
  double x0, y0, x1, y1;
  m.frame_bounds(0, 0, r.width - 1, r.height - 1, 0.0, x0, y0, x1, y1);
  m.cover_frame_area(x0 - 3000, y0 - 3000, x1 + 3000, y1 + 3000, 2);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> uc(0, r.width - 1), ur(0, r.height - 1);
  double worst = 0;
  for (int k = 0; k < 20000; ++k) {
    double x, y, c1, r1, c2, r2;
    m.exact_sample_to_frame(uc(rng), ur(rng), x, y);  // a point of the footprint
    m.frame_to_sample(x, y, c1, r1);
    m.exact_frame_to_sample(x, y, c2, r2);
    // Back to the frame: the ground distance between where the two answers sample the source.
    double xa, ya, xb, yb;
    m.exact_sample_to_frame(c1, r1, xa, ya);
    m.exact_sample_to_frame(c2, r2, xb, yb);
    worst = std::max(worst, std::hypot(xa - xb, ya - yb));
  }
  return worst;
}


// A smooth surface of longitude/latitude with 20 m of relief every ~1 km, continuous across the
// antimeridian (it depends on lon through sin/cos of whole turns).
double surface(double lon, double lat) {
  return 500.0 + 20.0 * std::sin(2 * M_PI * lon * 100.0) * std::cos(2 * M_PI * lat * 60.0) + 300.0 * (lat - 19.0);
}

SyntheticDem geographic_dem(int w, int h, double spacing, double lon, double lat, bool point) {
  SyntheticDem d;
  d.width = w;
  d.height = h;
  d.dx = d.dy = spacing;
  d.x0 = lon;
  d.y0 = lat;
  d.point = point;
  d.epsg_geographic = 4326;
  d.values.resize(size_t(w) * size_t(h));
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) d.at(col, row) = surface(d.mx(col), d.my(row));
  return d;
}

struct Cooked {
  cook::CookReport report;
  CookedArchive archive;
};

// Cooks the GeoTIFFs `dems` (written into `dir`) as one mosaic, heights only; checks the result
// verifies and has no seam mismatch.
void cook_dems(const std::filesystem::path& dir, const std::vector<SyntheticDem>& dems, Cooked& out) {
  cook::CookOptions o;
  for (size_t i = 0; i < dems.size(); ++i) {
    o.inputs.push_back((dir / ("in" + std::to_string(i) + ".tif")).string());
    std::string error;
    ASSERT_TRUE(write_geotiff(o.inputs.back(), dems[i], true, error)) << error;
  }
  o.output = (dir / "out.terrain").string();
  o.heights_only = true;
  o.threads = 2;
  uint64_t compared = 0;
  ASSERT_NO_FATAL_FAILURE(cook_and_verify(o, out.report, out.archive, compared));
  EXPECT_GT(compared, 0u);
}

// Every sample of `d` read back at its own position (projected by GeographicLib in the test
// utilities, independently of the cooker): counts samples east / west of 180 and without height,
// and returns the worst |cooked - source|.
struct Readback {
  uint64_t east = 0, west = 0, missing = 0;
  double worst = 0;
};
Readback read_back(const SyntheticDem& d, Cooked& c) {
  Readback r;
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col) {
      double x = 0, y = 0;
      lonlat_to_frame(c.archive.reader.world().crs, d.mx(col), d.my(row), x, y);
      const auto h = c.archive.height(x, y);
      if (!h) {
        ++r.missing;
        continue;
      }
      ++(std::remainder(d.mx(col), 360.0) < 0 ? r.west : r.east);
      r.worst = std::max(r.worst, std::fabs(*h - d.values[size_t(row) * size_t(d.width) + size_t(col)]));
    }
  return r;
}

}  // namespace

// The case: a geographic raster whose origin is 179.975 E reaching 180.025 E (half its
// columns beyond 180). Bounds: every valid sample is measured by the cook (report's leaf error
// samples == valid samples), every sample has a height when read back on both sides of 180, all
// within tolerance + half the root step + 1 mm; the frame's central meridian is in [-180, 180].
TEST(Antimeridian, InputCrossingTheAntimeridianIsCookedWhole) {
  const auto dir = scratch_dir("geodesy-antimeridian");
  const SyntheticDem d = geographic_dem(500, 300, 0.0001, 179.975 + 0.00005, 19.03 - 0.00005, false);
  Cooked c;
  cook_dems(dir, {d}, c);
  const FrameCrs& f = c.archive.reader.world().crs;
  EXPECT_LE(std::fabs(f.lon0_deg), 180.0);
  EXPECT_NEAR(std::fabs(f.lon0_deg), 180.0, 1.0 / 3600);
  EXPECT_EQ(c.report.source_valid_samples, uint64_t(d.width) * uint64_t(d.height));
  EXPECT_EQ(c.report.leaf_error_samples, c.report.source_valid_samples);
  const Readback r = read_back(d, c);
  EXPECT_EQ(r.missing, 0u);
  EXPECT_EQ(r.east, 250u * 300u);
  EXPECT_EQ(r.west, 250u * 300u);
  const double bound = 0.5 + c.archive.half_step(5) + kMm;  // default --tolerance 0.5
  EXPECT_LE(r.worst, bound);
  EXPECT_LE(c.report.leaf_error_max_m, bound);
  std::filesystem::remove_all(dir);
}

// Two HGT-like tiles (point samples sharing the 180 column: 179.98 .. 180 E and -180 .. -179.98 W)
// listed in either order. Bounds: one mosaic of 2 x 201 - 1 columns (the shared column once), no
// seam mismatch in the archive, every sample of both tiles read back within tolerance + half the
// root step + 1 mm, and the samples either side of 180 a continuous surface.
TEST(Antimeridian, TilesEitherSideOfTheAntimeridianMosaicWithoutASeam) {
  const SyntheticDem west = geographic_dem(201, 201, 0.0001, 179.98, 19.02, true);
  const SyntheticDem east = geographic_dem(201, 201, 0.0001, -180.0, 19.02, true);
  for (bool east_first : {false, true}) {
    const auto dir = scratch_dir(std::string("geodesy-antimeridian-tiles-") + (east_first ? "e" : "w"));
    Cooked c;
    cook_dems(dir, east_first ? std::vector<SyntheticDem>{east, west} : std::vector<SyntheticDem>{west, east}, c);
    EXPECT_EQ(c.report.source_samples, 401u * 201u);
    EXPECT_EQ(c.report.source_valid_samples, 401u * 201u);
    EXPECT_EQ(c.report.leaf_error_samples, c.report.source_valid_samples);
    const double bound = 0.5 + c.archive.half_step(5) + kMm;
    EXPECT_LE(c.report.leaf_error_max_m, bound);
    for (const SyntheticDem* t : {&west, &east}) {
      const Readback r = read_back(*t, c);
      EXPECT_EQ(r.missing, 0u);
      EXPECT_LE(r.worst, bound);
    }
    // Across the antimeridian, 1 m steps along the parallel: cooked heights follow the surface.
    const FrameCrs& f = c.archive.reader.world().crs;
    double worst = 0;
    int seen = 0;
    for (int k = 0; k <= 200; ++k) {
      const double lon = 179.999 + k * 0.00001;
      double x = 0, y = 0;
      lonlat_to_frame(f, lon, 19.01, x, y);
      if (const auto h = c.archive.height(x, y)) {
        worst = std::max(worst, std::fabs(*h - surface(lon, 19.01)));
        ++seen;
      }
    }
    EXPECT_EQ(seen, 201);
    EXPECT_LE(worst, bound);
    std::filesystem::remove_all(dir);
  }
}

// The mosaic function alone: tiles at 179 E and -180 (W) join on one grid (not 359 degrees apart).
TEST(Antimeridian, MosaicPlacesTilesByLongitudeModulo360) {
  std::vector<cook::Raster> tiles = {geographic_raster(121, 121, 1.0 / 120, 179.0, 20.0),
                                     geographic_raster(121, 121, 1.0 / 120, -180.0, 20.0)};
  tiles[1].values.assign(tiles[1].values.size(), 2.0f);
  tiles[0].geo.point_samples = tiles[1].geo.point_samples = true;
  cook::Raster m;
  ASSERT_TRUE(cook::mosaic(tiles, m).ok());
  EXPECT_EQ(m.width, 241);
  EXPECT_EQ(m.height, 121);
  EXPECT_DOUBLE_EQ(m.geo.c[0], 179.0);
  EXPECT_EQ(m.values[120], 1.0f);  // the shared column: the first listed tile wins
  EXPECT_EQ(m.values[121], 2.0f);
}

// Up to the accepted latitude (89 N/S, frame.cpp) the interpolated frame -> sample map is within
// 1 mm on the ground of the exact chain (GeographicLib per point) over the whole footprint. The
// same measurement beyond it (with the limit lifted) gave 1.4 mm at 89.5, 25 mm at 89.9, 0.32 m
// at 89.99 and 83 m for data reaching 90: the error grows as 1 / (distance to the pole)^2.
TEST(Polar, InterpolatedMappingHoldsAMillimetreUpToTheLimit) {
  const double half = 0.5 / 3600;  // the footprint reaches half a sample beyond the outer centres
  for (double top : {85.0 - half, 89.0 - half}) {
    const double worst = worst_anchor_error_m(geographic_raster(1801, 1801, 1.0 / 3600, 10.0, top));
    EXPECT_LT(worst, 1e-3) << "data up to " << top << " N";
    const double south = worst_anchor_error_m(geographic_raster(1801, 1801, 1.0 / 3600, -70.0, -top + 0.5));
    EXPECT_LT(south, 1e-3) << "data down to " << -top << " S";
  }
}

namespace {
// A paraboloid round the pole: smooth there (heights of the distance to the pole, not of lon).
double polar_surface(double lat) {
  const double d = (90.0 - std::fabs(lat)) * 111320.0;
  return 1000.0 + 1e-5 * d * d;
}
}  // namespace

// The case: data spanning 89.95 .. 90 N (and S) are refused before any output, with a
// message naming the latitude limit and a gdalwarp line; that line, run as printed, gives a
// Transverse Mercator raster that cooks with every sample within tolerance + half the root step
// + 1 mm (no nodata at the pole). The terrain-cook tool exits 1 and leaves an existing output file
// byte-identical.
TEST(Polar, PolarCapIsRefusedWithTheWayRoundAndTheWayRoundWorks) {
  for (double sign : {1.0, -1.0}) {
    const auto dir = scratch_dir(sign > 0 ? "geodesy-polar-n" : "geodesy-polar-s");
    SyntheticDem d;
    d.width = 720;
    d.height = 50;
    d.dx = 0.5;
    d.dy = 0.001;
    d.x0 = -180.0 + 0.25;
    d.y0 = sign > 0 ? 90.0 - 0.0005 : -89.95 - 0.0005;
    d.epsg_geographic = 4326;
    d.values.resize(size_t(d.width) * size_t(d.height));
    for (int row = 0; row < d.height; ++row)
      for (int col = 0; col < d.width; ++col) d.at(col, row) = polar_surface(d.my(row));
    cook::CookOptions o;
    ASSERT_NO_FATAL_FAILURE(write_cook_input(dir, "cap", d, true, o));
    const std::string tif = o.inputs[0], out = o.output;
    o.heights_only = true;
    cook::CookReport report;
    const Status st = cook::cook(o, {}, report);
    expect_refusal(st, Error::unsupported_input, {"up to 89 N/S", sign > 0 ? "EPSG:3413" : "EPSG:3031"});
    EXPECT_FALSE(std::filesystem::exists(out));

    {  // The tool: exit 1, the message, and an existing output untouched.
      { std::ofstream(out) << "keep me"; }
      const std::string cmd = (bin_dir() / "terrain-cook").string() + " " + tif + " -o " + out + " --quiet 2>" +
                              (dir / "stderr.txt").string();
      const int rc = std::system(cmd.c_str());
      EXPECT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 1) << rc;
      std::ifstream err(dir / "stderr.txt"), kept(out);
      const std::string err_text((std::istreambuf_iterator<char>(err)), {}), kept_text((std::istreambuf_iterator<char>(kept)), {});
      EXPECT_NE(err_text.find("gdalwarp -t_srs"), std::string::npos) << err_text;
      EXPECT_EQ(kept_text, "keep me");
      std::filesystem::remove(out);
    }

    // The way round, exactly as printed.
    const size_t a = st.message.find("gdalwarp "), b = st.message.find(" polar_tm.tif");
    ASSERT_TRUE(a != std::string::npos && b != std::string::npos) << st.message;
    const std::string warp = "cd " + dir.string() + " && " + st.message.substr(a, b + 13 - a) + " -q >/dev/null 2>&1";
    ASSERT_EQ(std::system(warp.c_str()), 0) << warp;
    o.inputs = {(dir / "polar_tm.tif").string()};
    report = {};
    const Status st2 = cook::cook(o, {}, report);
    ASSERT_TRUE(st2.ok()) << st2.to_string();
    CookedArchive c;
    ASSERT_TRUE(c.open(out).ok());
    ASSERT_TRUE(c.reader.verify().ok());
    // gdalwarp's cubic resampling of a paraboloid adds its own error (well below 1 cm here):
    // compare against the surface itself, at the pole and every 500 m out to 5 km.
    const double bound = 0.5 + c.half_step(5) + kMm + 0.01;
    const FrameCrs& f = c.reader.world().crs;
    int seen = 0;
    for (int k = 0; k <= 10; ++k)
      for (double az : {0.0, 90.0, 200.0}) {
        const double lat = sign * (90.0 - k * 500.0 / 111320.0);
        double x = 0, y = 0;
        lonlat_to_frame(f, az, lat, x, y);
        const auto h = c.height(x, y);
        ASSERT_TRUE(h.has_value()) << "nodata at " << az << "," << lat;
        EXPECT_NEAR(*h, polar_surface(lat), bound) << az << "," << lat;
        ++seen;
      }
    EXPECT_EQ(seen, 33);
    std::filesystem::remove_all(dir);
  }
}

namespace {
// The first line a command prints (empty when it fails).
std::string first_line_of(const std::string& cmd) {
  std::string line;
  if (FILE* p = popen(cmd.c_str(), "r")) {
    char buf[256];
    if (std::fgets(buf, sizeof buf, p)) line = buf;
    pclose(p);
  }
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.pop_back();
  return line;
}
}  // namespace

// A cook in NAD27 / UTM zone 11N (EPSG:26711) sampled with terrain-inspect --sample-lonlat at a
// WGS 84 point: the height must be the one at the frame point gdaltransform (GDAL + PROJ, another
// program) gives for that point; the data is a plane rising 1 m per metre east, so the old
// answer (the point read on NAD27, no datum shift: ~80 m west here) would be ~80 m off. Debian
// ships no NAD27 grid, so both use PROJ's grid-less transformation (good to metres, not mm).
// --lonlat-crs EPSG:4267 reads the same numbers on NAD27 and gets the no-shift answer.
TEST(LonLat, Nad27CookSampledAtAWgs84PointMatchesGdaltransform) {
  const auto dir = scratch_dir("geodesy-nad27");
  SyntheticDem d;
  d.width = d.height = 200;
  d.dx = d.dy = 2.0;
  d.x0 = 453601.0;
  d.y0 = 3762299.0;
  d.epsg_projected = 26711;
  d.values.resize(size_t(d.width) * size_t(d.height));
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col) d.at(col, row) = d.mx(col) - 453000.0;
  cook::CookOptions o;
  ASSERT_NO_FATAL_FAILURE(write_cook_input(dir, "nad27", d, true, o));
  const std::string out = o.output;
  o.heights_only = true;
  cook::CookReport report;
  ASSERT_TRUE(cook::cook(o, {}, report).ok());
  const std::string inspect = (bin_dir() / "terrain-inspect").string() + " " + out;
  const std::string xy = first_line_of("echo '-117.5 34.0' | gdaltransform -s_srs EPSG:4326 -t_srs EPSG:26711 -output_xy");
  double gx = 0, gy = 0;
  ASSERT_EQ(std::sscanf(xy.c_str(), "%lf %lf", &gx, &gy), 2) << "gdaltransform (gdal-bin): '" << xy << "'";
  const std::string at_oracle = first_line_of(inspect + " --sample " + std::to_string(gx) + "," + std::to_string(gy));
  const std::string at_wgs84 = first_line_of(inspect + " --sample-lonlat -117.5,34.0");
  ASSERT_NE(at_oracle, "nodata");
  EXPECT_EQ(at_wgs84, at_oracle);
  EXPECT_NEAR(std::stod(at_wgs84), gx - 453000.0, 0.5 + kMm);  // the plane itself at the oracle's x
  const std::string nad27 = first_line_of("echo '-117.5 34.0' | gdaltransform -s_srs EPSG:4267 -t_srs EPSG:26711 -output_xy");
  double nx = 0, ny = 0;
  ASSERT_EQ(std::sscanf(nad27.c_str(), "%lf %lf", &nx, &ny), 2);
  const std::string at_nad27 = first_line_of(inspect + " --sample-lonlat -117.5,34.0 --lonlat-crs EPSG:4267");
  EXPECT_NEAR(std::stod(at_nad27), nx - 453000.0, 0.5 + kMm);
  EXPECT_GT(std::fabs(std::stod(at_wgs84) - std::stod(at_nad27)), 50.0);
  std::filesystem::remove_all(dir);
}
