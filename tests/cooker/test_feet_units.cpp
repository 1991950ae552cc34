// Feet in the inputs (issue 48, items 1 and 2), on small cuts of the shared DEMs warped at test time.
//
// Horizontal (item 1): a DEM in a non-Transverse-Mercator CRS in US survey feet (California zones
// 3 and 5, Lambert, EPSG:2227 / 2229) lands where its data is: the frame is a Transverse Mercator
// centred on the data (a frame is metric), the archive's extent is the data's, and
// terrain-inspect --lonlat at source sample centres answers the source height. A Lambert in
// metres and a Transverse Mercator in US feet keep working. A hole mask in the same feet CRS (read by
// libgeotiff, not GDAL) lands on the same place as the DEM (GDAL), and a feet input resampled
// onto a metre input's grid lands where it belongs.
//
// Vertical (item 2): heights declared in US survey feet or international feet (compound CRS
// EPSG:32611+6360 / +8228, or the band's unit type "ft" / "US survey foot") come out in metres;
// an explicit --height-scale replaces that conversion; an undeclared unit stays metres; a declared
// unit the cooker does not know is refused by name; the factor is in the cook report, the plan,
// the cook info and terrain-inspect.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <sstream>
#include <tuple>
#include <vector>

#include "cooker_test_util.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;

namespace {

constexpr double kUsFootM = 1200.0 / 3937.0;
constexpr double kFootM = 0.3048;
constexpr double kMm = 1e-3;
const char* const kTahoe = "tahoe_lidar_bareearth.tif";  // WGS 84 lon/lat, 39.29 N 119.93 W, 0.5 m lidar
const char* const kKilauea = "kilauea_utm5n.tif";        // UTM 5N, 30 m, 19.3 N 155.2 W
// A box inside the Tahoe tile (lon/lat): its warps hold data everywhere.
const char* const kTahoeBox = "-te_srs EPSG:4326 -te -119.9326 39.2894 -119.9308 39.2912";

std::string q(const std::filesystem::path& p) {
  std::string s(1, '\'');
  s.append(p.string());
  s.push_back('\'');
  return s;
}

// A fresh folder per test (ctest may run this executable's tests side by side).
std::filesystem::path work_dir() {
  static std::string test;
  static std::filesystem::path dir;
  const auto* t = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = std::string("cooker-feet-units-") + t->test_suite_name() + "-" + t->name();
  for (char& ch : name)
    if (ch == '/') ch = '-';
  if (name != test) {
    test = name;
    dir = scratch_dir(name);
  }
  return dir;
}

std::string tool(const char* name) { return q(bin_dir() / name); }

// Runs `cmd` (stderr with stdout into `out`); its exit status.
int run_status(const std::string& cmd, std::string& out) {
  run_command("(" + cmd + ") 2>&1; echo \"exit=$?\"", out);
  const size_t at = out.rfind("exit=");
  const int rc = at == std::string::npos ? -1 : std::atoi(out.c_str() + at + 5);
  if (at != std::string::npos) out.resize(at);
  return rc;
}

// `name`.tif made once by `command` (which writes `@OUT@`), in the work dir.
bool made(const std::string& name, std::string command, std::filesystem::path& out, std::string& why) {
  out = work_dir() / name;
  if (std::filesystem::exists(out)) return true;
  command.replace(command.find("@OUT@"), 5, q(out));
  std::string text;
  if (!run_command(command + " 2>&1", text)) {
    why = "making " + name + " failed: " + text;
    return false;
  }
  return true;
}

// The Tahoe box warped to `srs` at `res` CRS units per sample (Float32, bilinear).
bool tahoe_in(const std::string& name, const std::string& srs, double res, std::filesystem::path& out, std::string& why) {
  return made(name,
              "gdalwarp -q -overwrite -t_srs " + srs + " " + kTahoeBox + " -tr " + std::to_string(res) + " " +
                  std::to_string(res) + " -r bilinear -ot Float32 " + q(data_file(kTahoe)) + " @OUT@",
              out, why);
}

bool cook_cli(const std::filesystem::path& input, const std::string& name, const std::string& flags,
          std::filesystem::path& archive, std::string& out) {
  archive = work_dir() / (name + ".terrain");
  return run_command(tool("terrain-cook") + " " + q(input) + " -q -o " + q(archive) + " " + flags + " 2>&1", out);
}

struct Point {
  double x, y, value;  // the tif's CRS units (or lon/lat after to_lonlat), its value
};

// `count` random valid samples of `tif` away from its edges and nodata (oracle_points.py, GDAL),
// at their centres, values times `scale`.
bool source_points(const std::filesystem::path& tif, int count, double scale, std::vector<Point>& pts, std::string& why) {
  const std::string script = (source_dir() / "tests" / "cooker" / "oracle_points.py").string();
  std::string text;
  if (!run_command("/usr/bin/python3 " + q(script) + " " + q(tif) + " --count " + std::to_string(4 * count) +
                       " --seed 7 --scale " + std::to_string(scale) + " 2>&1",
                   text)) {
    why = "oracle_points.py failed: " + text.substr(0, 300);
    return false;
  }
  std::istringstream in(text);
  double x, y, v;
  int edge;
  pts.clear();
  while (in >> x >> y >> v >> edge && int(pts.size()) < count)
    if (!edge) pts.push_back({x, y, v});
  if (pts.empty()) why = "no points";
  return !pts.empty();
}

// The points' CRS coordinates to longitude/latitude on `geo` (gdaltransform, no datum shift when
// `geo` is the CRS's own geographic CRS).
bool to_lonlat(std::vector<Point>& pts, const std::string& srs, const std::string& geo, std::string& why) {
  const auto file = work_dir() / "points_in.txt";
  {
    std::ofstream f(file);
    f.precision(15);
    for (const Point& p : pts) f << p.x << " " << p.y << "\n";
  }
  std::string text;
  if (!run_command("gdaltransform -s_srs " + srs + " -t_srs " + geo + " -output_xy < " + q(file) + " 2>&1", text)) {
    why = "gdaltransform failed: " + text;
    return false;
  }
  std::istringstream in(text);
  for (Point& p : pts)
    if (!(in >> p.x >> p.y)) {
      why = "gdaltransform: short output " + text.substr(0, 200);
      return false;
    }
  return true;
}

// terrain-inspect's heights at the points (frame metres, or lon/lat on `lonlat_crs` when given);
// NaN for nodata.
bool inspect_heights(const std::filesystem::path& archive, const std::vector<Point>& pts, const std::string& lonlat_crs,
                     std::vector<double>& heights, std::string& why) {
  const auto file = work_dir() / (archive.stem().string() + "_points.txt");
  {
    std::ofstream f(file);
    f.precision(15);
    for (const Point& p : pts) f << p.x << " " << p.y << "\n";
  }
  std::string text;
  const std::string ll = lonlat_crs.empty() ? "" : " --lonlat --lonlat-crs " + lonlat_crs;
  if (!run_command(tool("terrain-inspect") + " " + q(archive) + " --sample-file " + q(file) + ll + " 2>&1", text)) {
    why = "terrain-inspect failed: " + text.substr(0, 300);
    return false;
  }
  std::istringstream in(text);
  std::string line;
  heights.clear();
  while (std::getline(in, line)) heights.push_back(line == "nodata" ? NAN : std::stod(line));
  if (heights.size() != pts.size()) {
    why = "terrain-inspect answered " + std::to_string(heights.size()) + " of " + std::to_string(pts.size()) + " points";
    return false;
  }
  return true;
}

// The bound of the RealData oracle: the cook's tolerance, half the coarsest step, 1 mm.
double bound_of(const std::filesystem::path& archive) {
  CookedArchive ca;
  if (!ca.open(archive.string()).ok()) return 0;
  const auto info = nlohmann::json::parse(ca.reader.world().cook_info_json, nullptr, false);
  const double tol = info.is_object() ? info["options"].value("tolerance_m", 0.0) : 0.0;
  return tol + ca.max_half_step() + kMm;
}

struct Agreement {
  size_t answered = 0, violations = 0;
  double worst = 0;
  std::string first;
};
Agreement agree(const std::vector<Point>& pts, const std::vector<double>& heights, double bound) {
  Agreement a;
  for (size_t i = 0; i < pts.size(); ++i) {
    if (std::isnan(heights[i])) continue;
    ++a.answered;
    const double e = std::fabs(heights[i] - pts[i].value);
    a.worst = std::max(a.worst, e);
    if (e > bound && ++a.violations == 1)
      a.first = "point " + std::to_string(pts[i].x) + " " + std::to_string(pts[i].y) + ": cooked " +
                std::to_string(heights[i]) + ", source " + std::to_string(pts[i].value);
  }
  return a;
}

nlohmann::json gdalinfo(const std::filesystem::path& tif) {
  std::string text;
  run_command("gdalinfo -json " + q(tif), text);
  return nlohmann::json::parse(text, nullptr, false);
}

// The archive's frame as gdaltransform takes it: a Transverse Mercator by its parameters on its
// ellipsoid (no datum: no shift), any other projected frame by its EPSG code.
std::string frame_srs(const FrameCrs& f) {
  if (f.kind != ProjectionKind::transverse_mercator) return "EPSG:" + std::to_string(f.epsg);
  char text[400];
  std::snprintf(text, sizeof text,
                "'+proj=tmerc +lat_0=%.17g +lon_0=%.17g +k=%.17g +x_0=%.17g +y_0=%.17g +a=%.17g +rf=%.17g +units=m "
                "+no_defs'",
                f.lat0_deg, f.lon0_deg, f.scale_k0, f.false_easting_m, f.false_northing_m, f.semi_major_m,
                f.inverse_flattening);
  return text;
}

// Runs the points `xy` through gdaltransform from `from` to `to`.
bool transform(std::vector<std::array<double, 2>>& xy, const std::string& from, const std::string& to, std::string& why) {
  const auto file = work_dir() / "transform_in.txt";
  {
    std::ofstream f(file);
    f.precision(17);
    for (const auto& p : xy) f << p[0] << " " << p[1] << "\n";
  }
  std::string text;
  if (!run_command("gdaltransform -s_srs " + from + " -t_srs " + to + " -output_xy < " + q(file) + " 2>&1", text)) {
    why = "gdaltransform failed: " + text;
    return false;
  }
  std::istringstream in(text);
  for (auto& p : xy)
    if (!(in >> p[0] >> p[1])) {
      why = "gdaltransform: short output " + text.substr(0, 200);
      return false;
    }
  return true;
}

// Where a raster lies in an archive's frame, by GDAL: the outline of its pixel areas (64 points
// per edge) through gdaltransform, its bounding box (min x, min y, max x, max y); and the
// longitude of its centre on `geo`.
struct Footprint {
  double min_x = INFINITY, min_y = INFINITY, max_x = -INFINITY, max_y = -INFINITY;
  double centre_lon = NAN;
};
bool footprint_in_frame(const std::filesystem::path& tif, const std::string& srs, const FrameCrs& frame,
                        const std::string& geo, Footprint& out, std::string& why) {
  const auto gi = gdalinfo(tif);
  if (!gi.is_object()) {
    why = "gdalinfo failed";
    return false;
  }
  const auto& gt = gi["geoTransform"];
  const double w = gi["size"][0], h = gi["size"][1];
  const auto at = [&](double col, double row) {
    return std::array<double, 2>{double(gt[0]) + col * double(gt[1]) + row * double(gt[2]),
                                 double(gt[3]) + col * double(gt[4]) + row * double(gt[5])};
  };
  std::vector<std::array<double, 2>> outline;
  constexpr int kPerEdge = 64;
  for (int k = 0; k < kPerEdge; ++k) {
    const double t = double(k) / kPerEdge;
    outline.push_back(at(t * w, 0));
    outline.push_back(at(w, t * h));
    outline.push_back(at(w - t * w, h));
    outline.push_back(at(0, h - t * h));
  }
  if (!transform(outline, srs, frame_srs(frame), why)) return false;
  for (const auto& p : outline) {
    out.min_x = std::min(out.min_x, p[0]);
    out.max_x = std::max(out.max_x, p[0]);
    out.min_y = std::min(out.min_y, p[1]);
    out.max_y = std::max(out.max_y, p[1]);
  }
  std::vector<std::array<double, 2>> centre{at(0.5 * w, 0.5 * h)};
  if (!transform(centre, srs, geo, why)) return false;
  out.centre_lon = centre[0][0];
  return true;
}

// ---- item 1: horizontal feet -------------------------------------------------------------------

struct FrameCase {
  const char* name;
  const char* srs;      // gdalwarp -t_srs
  double res;           // CRS units per sample
  double unit_m;        // metres per CRS unit
  ProjectionKind kind;  // the archive's frame
  int epsg;             // its EPSG code (0: a Transverse Mercator centred on the data)
};
void PrintTo(const FrameCase& c, std::ostream* os) { *os << c.name; }

// A frame is metric: a Lambert in feet gets a Transverse Mercator centred on the data, one in
// metres is kept; a Transverse Mercator is kept in any unit (its parameters are metres).
const FrameCase kFrameCases[] = {
    {"lambert_ftus_2227", "EPSG:2227", 2.0, kUsFootM, ProjectionKind::transverse_mercator, 0},  // CA zone 3, US ft
    {"lambert_m_26943", "EPSG:26943", 0.6, 1.0, ProjectionKind::proj, 26943},                   // CA zone 3, metres
    {"tm_ftus_3423", "EPSG:3423", 2.0, kUsFootM, ProjectionKind::transverse_mercator, 3423},    // Nevada W, US ft
};

class FeetFrame : public ::testing::TestWithParam<FrameCase> {};

// The frame's checks shared by the Tahoe and Kilauea cases: its kind and code, a centred
// frame's central meridian on the data's centre (to the arc-second it is rounded to), and the
// archive's extent on the file's footprint in the frame (GDAL's), within a sample.
void expect_frame_on_data(const std::filesystem::path& tif, const std::string& srs, double sample_m,
                          const WorldInfo& w, ProjectionKind kind, int epsg, const char* name) {
  EXPECT_EQ(w.crs.kind, kind) << name;
  EXPECT_EQ(w.crs.epsg, epsg) << name;
  Footprint fp;
  std::string why;
  ASSERT_TRUE(footprint_in_frame(tif, srs, w.crs, "EPSG:4269", fp, why)) << why;
  std::printf("%s: frame %s lon0 %.6f (data centre %.6f); archive extent x %.3f .. %.3f, y %.3f .. %.3f m; file "
              "footprint x %.3f .. %.3f, y %.3f .. %.3f m\n",
              name, w.crs.name.c_str(), w.crs.lon0_deg, fp.centre_lon, w.extent_min_x_m, w.extent_max_x_m,
              w.extent_min_y_m, w.extent_max_y_m, fp.min_x, fp.max_x, fp.min_y, fp.max_y);
  if (kind == ProjectionKind::transverse_mercator && epsg == 0) {
    EXPECT_NEAR(w.crs.lon0_deg, fp.centre_lon, 1.0 / 3600) << name;
  }
  EXPECT_NEAR(w.extent_min_x_m, fp.min_x, sample_m) << name;
  EXPECT_NEAR(w.extent_max_x_m, fp.max_x, sample_m) << name;
  EXPECT_NEAR(w.extent_min_y_m, fp.min_y, sample_m) << name;
  EXPECT_NEAR(w.extent_max_y_m, fp.max_y, sample_m) << name;
}

}  // namespace

// The frame lies on the data (above), and every inner source sample centre, given as lon/lat on
// NAD83, answers its height within the oracle's bound. Before the fix the US-feet Lambert's
// coordinates were taken as metres and divided by the foot again: the frame's central meridian
// and extent 3.3 times off, every point nodata.
TEST_P(FeetFrame, FrameExtentAndHeightsAtSourceSampleCentres) {
  TERRAIN_REQUIRE_DATA(data_file(kTahoe));
  const FrameCase& c = GetParam();
  std::filesystem::path tif, archive;
  std::string why, out;
  ASSERT_TRUE(tahoe_in(std::string(c.name) + ".tif", c.srs, c.res, tif, why)) << why;
  ASSERT_TRUE(cook_cli(tif, c.name, "--heights-only", archive, out)) << out;
  CookedArchive ca;
  ASSERT_TRUE(ca.open(archive.string()).ok());
  expect_frame_on_data(tif, c.srs, c.res * c.unit_m, ca.reader.world(), c.kind, c.epsg, c.name);

  std::vector<Point> pts;
  ASSERT_TRUE(source_points(tif, 300, 1.0, pts, why)) << why;
  ASSERT_TRUE(to_lonlat(pts, c.srs, "EPSG:4269", why)) << why;
  std::vector<double> heights;
  ASSERT_TRUE(inspect_heights(archive, pts, "EPSG:4269", heights, why)) << why;
  const double bound = bound_of(archive);
  const Agreement a = agree(pts, heights, bound);
  std::printf("%s: %zu points, %zu answered, worst |cooked - source| %.4f m (bound %.4f m)\n", c.name, pts.size(),
              a.answered, a.worst, bound);
  EXPECT_EQ(a.answered, pts.size());
  EXPECT_EQ(a.violations, 0u) << a.first;
}

INSTANTIATE_TEST_SUITE_P(Tahoe, FeetFrame, ::testing::ValuesIn(kFrameCases),
                         [](const ::testing::TestParamInfo<FrameCase>& i) { return std::string(i.param.name); });

// A Kilauea cut warped to California zone 5 (US feet), 37 degrees east of Hawaii: the Lambert's
// scale error there is far beyond the frame bound, so the frame is a Transverse Mercator centred
// on the data. Its central meridian is the data's (155.24 W; before the fix 176.24 E), the
// archive's extent is the file's footprint in it (before: 29.6 km for a raster of 8 km), and the
// source sample centres answer their heights (before: none).
TEST(FeetFrameChoice, FarFromItsZoneTheCentredFrameIsOnTheData) {
  TERRAIN_REQUIRE_DATA(data_file(kKilauea));
  std::filesystem::path tif, archive;
  std::string why, out;
  // The 6 x 6 km UTM square, then warped: a square turned by 21 degrees in the zone's Lambert,
  // nodata around it.
  const auto cut = work_dir() / "kilauea_cut.tif";
  ASSERT_TRUE(made("kilauea_2229.tif",
                   "gdal_translate -q -projwin 262000 2142000 268000 2136000 " + q(data_file(kKilauea)) + " " + q(cut) +
                       " && gdalwarp -q -overwrite -t_srs EPSG:2229 -tr 100 100 -r bilinear -ot Float32 -dstnodata "
                       "-32768 " + q(cut) + " @OUT@",
                   tif, why))
      << why;
  ASSERT_TRUE(cook_cli(tif, "kilauea_2229", "--heights-only", archive, out)) << out;
  CookedArchive ca;
  ASSERT_TRUE(ca.open(archive.string()).ok());
  const WorldInfo& w = ca.reader.world();
  // The cut's centre, UTM 5N (265000, 2139000), is 155.237 W (gdaltransform).
  EXPECT_NEAR(w.crs.lon0_deg, -155.237, 0.005);
  expect_frame_on_data(tif, "EPSG:2229", 100 * kUsFootM, w, ProjectionKind::transverse_mercator, 0, "kilauea_2229");
  // The warped raster is the 6 km square turned by 21 degrees (the zone's meridians' convergence
  // so far east of it), its bounding box 8 km: turned back, at most 8 * (cos 21 + sin 21) km.
  EXPECT_LT(w.extent_max_x_m - w.extent_min_x_m, 8000 * 1.3);
  EXPECT_LT(w.extent_max_y_m - w.extent_min_y_m, 8000 * 1.3);

  std::vector<Point> pts;
  ASSERT_TRUE(source_points(tif, 300, 1.0, pts, why)) << why;
  ASSERT_TRUE(to_lonlat(pts, "EPSG:2229", "EPSG:4269", why)) << why;
  std::vector<double> heights;
  ASSERT_TRUE(inspect_heights(archive, pts, "EPSG:4269", heights, why)) << why;
  // 30 m cliffs resampled to 100 ft: the oracle's bound holds at the warped file's own samples.
  const double bound = bound_of(archive);
  const Agreement a = agree(pts, heights, bound);
  std::printf("kilauea in EPSG:2229: %zu points, %zu answered, worst %.4f m (bound %.4f m)\n", pts.size(), a.answered,
              a.worst, bound);
  EXPECT_EQ(a.answered, pts.size());
  EXPECT_EQ(a.violations, 0u) << a.first;
}

// A hole mask in the DEM's own US-feet Lambert (--holes, read by libgeotiff while the DEM is read
// by GDAL): a square of ones in the middle. Points well inside the square are holes, points
// around it hold the source's heights: mask and DEM land on the same place.
TEST(FeetFrameChoice, HoleMaskInTheSameFeetCrsLandsOnTheDem) {
  TERRAIN_REQUIRE_DATA(data_file(kTahoe));
  std::filesystem::path tif, archive, holes;
  std::string why, out;
  ASSERT_TRUE(tahoe_in("holes_dem_2227.tif", "EPSG:2227", 2.0, tif, why)) << why;
  const auto gi = gdalinfo(tif);
  ASSERT_TRUE(gi.is_object());
  const auto& gt = gi["geoTransform"];
  const double fx0 = gt[0], fy1 = gt[3], fres = gt[1];
  const int fw = gi["size"][0], fh = gi["size"][1];
  // The mask: the DEM's grid, zeros, with a square of ones over the middle third.
  const double sx0 = fx0 + fres * (fw / 3), sx1 = fx0 + fres * (2 * fw / 3);
  const double sy1 = fy1 - fres * (fh / 3), sy0 = fy1 - fres * (2 * fh / 3);
  const auto ullr = [](double a, double b, double c, double d) {
    return " -a_ullr " + std::to_string(a) + " " + std::to_string(b) + " " + std::to_string(c) + " " + std::to_string(d);
  };
  ASSERT_TRUE(run_command("cd " + q(work_dir()) + " && gdal_create -q -of GTiff -outsize " + std::to_string(fw) + " " +
                              std::to_string(fh) + " -bands 1 -ot Byte -burn 0 -a_srs EPSG:2227" +
                              ullr(fx0, fy1, fx0 + fres * fw, fy1 - fres * fh) +
                              " zeros.tif && gdal_create -q -of GTiff -outsize " + std::to_string(fw / 3) + " " +
                              std::to_string(fh / 3) + " -bands 1 -ot Byte -burn 1 -a_srs EPSG:2227" +
                              ullr(sx0, sy1, sx1, sy0) +
                              " ones.tif && gdalbuildvrt -q mask.vrt zeros.tif ones.tif && gdal_translate -q mask.vrt "
                              "holes_2227.tif 2>&1",
                          out))
      << out;
  holes = work_dir() / "holes_2227.tif";
  ASSERT_TRUE(cook_cli(tif, "holes_2227", "--holes " + q(holes), archive, out)) << out;

  std::vector<Point> pts;
  ASSERT_TRUE(source_points(tif, 600, 1.0, pts, why)) << why;
  // Inside the square by 4 samples: holes; outside it by 4 samples: heights.
  const double m = 4 * fres;
  std::vector<Point> inside, outside;
  for (const Point& p : pts) {
    if (p.x > sx0 + m && p.x < sx1 - m && p.y > sy0 + m && p.y < sy1 - m) inside.push_back(p);
    if (p.x < sx0 - m || p.x > sx1 + m || p.y < sy0 - m || p.y > sy1 + m) outside.push_back(p);
  }
  ASSERT_GT(inside.size(), 20u);
  ASSERT_GT(outside.size(), 100u);
  std::vector<double> hin, hout;
  ASSERT_TRUE(to_lonlat(inside, "EPSG:2227", "EPSG:4269", why)) << why;
  ASSERT_TRUE(to_lonlat(outside, "EPSG:2227", "EPSG:4269", why)) << why;
  ASSERT_TRUE(inspect_heights(archive, inside, "EPSG:4269", hin, why)) << why;
  ASSERT_TRUE(inspect_heights(archive, outside, "EPSG:4269", hout, why)) << why;
  size_t holes_inside = 0;
  for (double h : hin) holes_inside += std::isnan(h) ? 1 : 0;
  const Agreement a = agree(outside, hout, bound_of(archive));
  std::printf("holes in EPSG:2227: %zu of %zu points inside the square are holes; %zu of %zu outside answered, worst "
              "%.4f m\n", holes_inside, inside.size(), a.answered, outside.size(), a.worst);
  EXPECT_EQ(holes_inside, inside.size());
  EXPECT_EQ(a.answered, outside.size());
  EXPECT_EQ(a.violations, 0u) << a.first;
}

// Two inputs: the Tahoe box in UTM 11N metres, then the same in California zone 3 US feet: the
// second is resampled onto the first's grid through GDAL's transformation, whose coordinates are
// the CRS's own units. Cooked with the metre file first (--overlap list: the 2 ft feet file is the
// finer and would otherwise take precedence) and only over its west half, the east half comes from
// the feet file and must hold the metre source's heights.
TEST(FeetFrameChoice, FeetInputResampledOntoAMetreGridLandsInPlace) {
  TERRAIN_REQUIRE_DATA(data_file(kTahoe));
  std::filesystem::path utm, west, feet, archive;
  std::string why, out;
  ASSERT_TRUE(tahoe_in("mix_utm.tif", "EPSG:32611", 1.0, utm, why)) << why;
  ASSERT_TRUE(tahoe_in("mix_2227.tif", "EPSG:2227", 2.0, feet, why)) << why;
  const auto gi = gdalinfo(utm);
  ASSERT_TRUE(gi.is_object());
  const int w = gi["size"][0], h = gi["size"][1];
  ASSERT_TRUE(made("mix_utm_west.tif",
                   "gdal_translate -q -srcwin 0 0 " + std::to_string(w / 2) + " " + std::to_string(h) + " " + q(utm) +
                       " @OUT@",
                   west, why))
      << why;
  archive = work_dir() / "mix.terrain";
  ASSERT_TRUE(run_command(tool("terrain-cook") + " " + q(west) + " " + q(feet) + " -q --heights-only --overlap list -o " +
                              q(archive) + " 2>&1",
                          out))
      << out;
  std::vector<Point> pts, east;
  ASSERT_TRUE(source_points(utm, 600, 1.0, pts, why)) << why;
  // East of the metre file's half by 4 samples, 10 samples inside the footprints (the two warps'
  // footprints differ by their meridians' convergence, 1.5 degrees: 5 m at the corners).
  const auto& g = gi["geoTransform"];
  const double x_mid = double(g[0]) + double(g[1]) * (w / 2 + 4), x_east = double(g[0]) + double(g[1]) * (w - 10);
  const double y_north = double(g[3]) + double(g[5]) * 10, y_south = double(g[3]) + double(g[5]) * (h - 10);
  for (const Point& p : pts)
    if (p.x > x_mid && p.x < x_east && p.y < y_north && p.y > y_south) east.push_back(p);
  ASSERT_GT(east.size(), 100u);
  std::vector<double> heights;
  ASSERT_TRUE(inspect_heights(archive, east, "", heights, why)) << why;  // the frame is UTM 11N: metres
  // Two resamplings (gdalwarp's of the feet file, the cooker's onto the UTM grid) of 0.5 m lidar
  // at 0.6 and 1 m: the source's roughness enters; 0.25 m beyond the oracle's bound.
  const double bound = bound_of(archive) + 0.25;
  const Agreement a = agree(east, heights, bound);
  std::printf("feet input resampled onto UTM: %zu points, %zu answered, worst %.4f m (bound %.4f m)\n", east.size(),
              a.answered, a.worst, bound);
  EXPECT_EQ(a.answered, east.size());
  EXPECT_EQ(a.violations, 0u) << a.first;
}

// ---- item 2: heights in feet -------------------------------------------------------------------

namespace {

// The Tahoe box in UTM 11N at 1 m, heights in metres, no unit declared.
bool tahoe_metres(std::filesystem::path& out, std::string& why) {
  return tahoe_in("heights_m.tif", "EPSG:32611", 1.0, out, why);
}

// The metre source with its values in `per_metre` units per metre (gdal_translate -scale) and
// `srs` assigned (a compound CRS declares the heights' unit), optionally a band unit type.
bool tahoe_heights(const std::string& name, double per_metre, const std::string& srs, const std::string& unit_type,
                   std::filesystem::path& out, std::string& why) {
  std::filesystem::path m;
  if (!tahoe_metres(m, why)) return false;
  char scale[64];
  std::snprintf(scale, sizeof scale, "%.17g", per_metre);
  if (unit_type.empty())
    return made(name, "gdal_translate -q -ot Float32 -scale 0 1 0 " + std::string(scale) + " -a_srs " + srs + " " + q(m) +
                          " @OUT@",
                out, why);
  // The band's unit type through a VRT (gdal_translate has no flag for it); GDAL keeps it in the
  // GeoTIFF's GDAL_METADATA tag.
  const auto vrt = work_dir() / (name + ".vrt");
  return made(name,
              "gdal_translate -q -of VRT -ot Float32 -scale 0 1 0 " + std::string(scale) + " -a_srs " + srs + " " + q(m) +
                  " " + q(vrt) + " && sed -i 's|\\(<VRTRasterBand[^>]*>\\)|\\1<UnitType>" + unit_type +
                  "</UnitType>|' " + q(vrt) + " && gdal_translate -q " + q(vrt) + " @OUT@",
              out, why);
}

struct HeightCase {
  const char* name;
  double unit_m;          // metres per stored unit
  const char* srs;        // gdal_translate -a_srs
  const char* unit_type;  // band unit type ("" none)
  const char* declared;   // what the report names
  const char* declared_by;
};
void PrintTo(const HeightCase& c, std::ostream* os) { *os << c.name; }

const HeightCase kHeightCases[] = {
    {"navd88_ftus", kUsFootM, "EPSG:32611+6360", "", "US survey foot", "vertical CRS"},
    {"navd88_ft", kFootM, "EPSG:32611+8228", "", "foot", "vertical CRS"},
    {"band_ft", kFootM, "EPSG:32611", "ft", "ft", "band unit type"},
    {"band_us_survey_foot", kUsFootM, "EPSG:32611", "US survey foot", "US survey foot", "band unit type"},
};

class FeetHeights : public ::testing::TestWithParam<HeightCase> {};

// Heights of the metre source at `pts` (frame metres: the UTM frame) in `archive`, against the
// metre source's values; fails the test on disagreement.
void expect_metres(const std::filesystem::path& archive, const std::vector<Point>& pts, const char* what) {
  std::vector<double> heights;
  std::string why;
  ASSERT_TRUE(inspect_heights(archive, pts, "", heights, why)) << why;
  const double bound = bound_of(archive);
  const Agreement a = agree(pts, heights, bound);
  std::printf("%s: %zu points, %zu answered, worst |cooked - metre source| %.4f m (bound %.4f m)\n", what, pts.size(),
              a.answered, a.worst, bound);
  EXPECT_EQ(a.answered, pts.size()) << what;
  EXPECT_EQ(a.violations, 0u) << what << ": " << a.first;
}

}  // namespace

// The heights come out in metres (the metre source's, at its sample centres, within the oracle's
// bound; in feet they were 3.28 times too high), and the unit and factor are in the report
// (JSON), the cook info and terrain-inspect (text and JSON).
TEST_P(FeetHeights, HeightsInMetresAndTheFactorIsRecorded) {
  TERRAIN_REQUIRE_DATA(data_file(kTahoe));
  const HeightCase& c = GetParam();
  std::filesystem::path m, tif, archive;
  std::string why, out;
  ASSERT_TRUE(tahoe_metres(m, why)) << why;
  ASSERT_TRUE(tahoe_heights(std::string(c.name) + ".tif", 1.0 / c.unit_m, c.srs, c.unit_type, tif, why)) << why;
  const auto report = work_dir() / (std::string(c.name) + ".json");
  ASSERT_TRUE(cook_cli(tif, c.name, "--heights-only --report " + q(report), archive, out)) << out;
  std::vector<Point> pts;
  ASSERT_TRUE(source_points(m, 300, 1.0, pts, why)) << why;
  expect_metres(archive, pts, c.name);

  std::ifstream rf(report);
  const auto r = nlohmann::json::parse(rf, nullptr, false);
  ASSERT_TRUE(r.is_object());
  ASSERT_EQ(r["input_height_units"].size(), 1u);
  const auto& u = r["input_height_units"][0];
  EXPECT_EQ(u["unit"], c.declared);
  EXPECT_EQ(u["declared_by"], c.declared_by);
  EXPECT_NEAR(double(u["unit_m"]), c.unit_m, 1e-12);
  EXPECT_NEAR(double(u["scale"]), c.unit_m, 1e-12);
  EXPECT_EQ(u["scale_from"], "declared unit");

  CookedArchive ca;
  ASSERT_TRUE(ca.open(archive.string()).ok());
  const auto info = nlohmann::json::parse(ca.reader.world().cook_info_json);
  EXPECT_NEAR(double(info["inputs"][0]["heights"]["scale"]), c.unit_m, 1e-12);
  EXPECT_EQ(info["inputs"][0]["heights"]["unit"], c.declared);

  std::string js, text;
  ASSERT_TRUE(run_command(tool("terrain-inspect") + " " + q(archive) + " --json", js)) << js;
  const auto ij = nlohmann::json::parse(js, nullptr, false);
  ASSERT_TRUE(ij.is_object());
  EXPECT_NEAR(double(ij["input_height_units"][0]["scale"]), c.unit_m, 1e-12);
  EXPECT_EQ(ij["input_height_units"][0]["path"], tif.string());
  ASSERT_TRUE(run_command(tool("terrain-inspect") + " " + q(archive), text)) << text;
  char factor[32];
  std::snprintf(factor, sizeof factor, "%.10g", c.unit_m);
  const std::string line = std::string("values x ") + factor + " to metres ('" + c.declared + "', " + c.declared_by + ")";
  EXPECT_NE(text.find(line), std::string::npos) << "no '" << line << "' in\n" << text;
}

INSTANTIATE_TEST_SUITE_P(Tahoe, FeetHeights, ::testing::ValuesIn(kHeightCases),
                         [](const ::testing::TestParamInfo<HeightCase>& i) { return std::string(i.param.name); });

// An explicit --height-scale replaces the declared unit's conversion, never multiplies it: on the
// US-feet file, 0.3048 gives metres (multiplied, 0.093 m per stored unit) and 1 gives the stored
// feet values (multiplied, metres). The report says where the scale came from.
TEST(FeetHeightsScale, ExplicitHeightScaleReplacesTheDeclaredUnit) {
  TERRAIN_REQUIRE_DATA(data_file(kTahoe));
  std::filesystem::path m, tif, archive;
  std::string why, out;
  ASSERT_TRUE(tahoe_metres(m, why)) << why;
  ASSERT_TRUE(tahoe_heights("scale_ftus.tif", 1.0 / kUsFootM, "EPSG:32611+6360", "", tif, why)) << why;
  std::vector<Point> pts;
  ASSERT_TRUE(source_points(m, 200, 1.0, pts, why)) << why;

  const auto report = work_dir() / "scale_0.3048.json";
  ASSERT_TRUE(cook_cli(tif, "scale_0.3048", "--heights-only --height-scale 0.3048 --report " + q(report), archive, out)) << out;
  // metres * (1 / 0.3048006) * 0.3048: 2 ppm low, 5 mm at 2500 m, inside the bound.
  expect_metres(archive, pts, "--height-scale 0.3048 on US feet");
  std::ifstream rf(report);
  const auto r = nlohmann::json::parse(rf, nullptr, false);
  ASSERT_TRUE(r.is_object());
  EXPECT_EQ(r["input_height_units"][0]["scale"], 0.3048);
  EXPECT_EQ(r["input_height_units"][0]["scale_from"], "--height-scale");
  EXPECT_EQ(r["input_height_units"][0]["unit"], "US survey foot");

  ASSERT_TRUE(cook_cli(tif, "scale_1", "--heights-only --height-scale 1", archive, out)) << out;
  std::vector<Point> feet = pts;
  for (Point& p : feet) p.value /= kUsFootM;
  expect_metres(archive, feet, "--height-scale 1 on US feet (the stored values)");
  CookedArchive ca;
  ASSERT_TRUE(ca.open(archive.string()).ok());
  const auto info = nlohmann::json::parse(ca.reader.world().cook_info_json);
  EXPECT_EQ(info["inputs"][0]["heights"]["scale"], 1.0);
  EXPECT_EQ(info["inputs"][0]["heights"]["scale_from"], "--height-scale");
}

// No declared unit: metres, as before (scale 1, "none declared: metres"); a declared metre is
// metres too.
TEST(FeetHeightsScale, UndeclaredAndMetreHeightsStayMetres) {
  TERRAIN_REQUIRE_DATA(data_file(kTahoe));
  std::filesystem::path m, navd88_m, archive;
  std::string why, out;
  ASSERT_TRUE(tahoe_metres(m, why)) << why;
  ASSERT_TRUE(tahoe_heights("navd88_m.tif", 1.0, "EPSG:32611+5703", "", navd88_m, why)) << why;
  std::vector<Point> pts;
  ASSERT_TRUE(source_points(m, 200, 1.0, pts, why)) << why;
  for (const auto& [tif, name, unit, from] :
       {std::tuple{m, "undeclared", "", "none declared: metres"}, std::tuple{navd88_m, "navd88_m", "metre", "declared unit"}}) {
    const auto report = work_dir() / (std::string(name) + ".json");
    ASSERT_TRUE(cook_cli(tif, name, "--heights-only --report " + q(report), archive, out)) << out;
    expect_metres(archive, pts, name);
    std::ifstream rf(report);
    const auto r = nlohmann::json::parse(rf, nullptr, false);
    ASSERT_TRUE(r.is_object());
    EXPECT_EQ(r["input_height_units"][0]["scale"], 1.0) << name;
    EXPECT_EQ(r["input_height_units"][0]["unit"], unit) << name;
    EXPECT_EQ(r["input_height_units"][0]["scale_from"], from) << name;
  }
}

// A declared unit the cooker does not know is refused with exit 1, naming the unit and the file,
// and leaves the archive it would replace as it was; --height-scale says what the unit is.
TEST(FeetHeightsScale, UnknownDeclaredUnitIsRefusedByName) {
  TERRAIN_REQUIRE_DATA(data_file(kTahoe));
  std::filesystem::path tif, archive;
  std::string why, out;
  ASSERT_TRUE(tahoe_heights("furlong.tif", 1.0 / 201.168, "EPSG:32611", "furlong", tif, why)) << why;
  archive = work_dir() / "furlong.terrain";
  {
    std::ofstream f(archive);
    f << "an older archive";
  }
  const int rc = run_status(tool("terrain-cook") + " " + q(tif) + " -q --heights-only -o " + q(archive), out);
  EXPECT_EQ(rc, 1) << out;
  EXPECT_NE(out.find("'furlong'"), std::string::npos) << out;
  EXPECT_NE(out.find("furlong.tif"), std::string::npos) << out;
  EXPECT_NE(out.find("--height-scale"), std::string::npos) << out;
  std::ifstream f(archive);
  EXPECT_EQ(std::string((std::istreambuf_iterator<char>(f)), {}), "an older archive");
  std::vector<std::string> left;
  for (const auto& e : std::filesystem::directory_iterator(work_dir()))
    if (e.path().filename().string().find("tmp-") != std::string::npos) left.push_back(e.path().string());
  EXPECT_TRUE(left.empty()) << left[0];
  // Told what it is, it cooks.
  std::filesystem::path told;
  ASSERT_TRUE(cook_cli(tif, "furlong_told", "--heights-only --height-scale 201.168", told, out)) << out;
}

// The plan records the factor of each input, and the merge writes it into the cook info: a cook
// through work units is byte-identical to the one-process cook of a US-feet file.
TEST(FeetHeightsScale, PlanRecordsTheFactorAndTheMergeKeepsIt) {
  TERRAIN_REQUIRE_DATA(data_file(kTahoe));
  std::filesystem::path tif, one;
  std::string why, out;
  ASSERT_TRUE(tahoe_heights("plan_ftus.tif", 1.0 / kUsFootM, "EPSG:32611+6360", "", tif, why)) << why;
  ASSERT_TRUE(cook_cli(tif, "plan_one", "--heights-only", one, out)) << out;
  const auto wd = work_dir() / "plan_work";
  const auto merged = work_dir() / "plan_merged.terrain";
  ASSERT_TRUE(run_command(tool("terrain-cook") + " " + q(tif) + " -q --heights-only -o " + q(merged) + " --work-dir " +
                              q(wd) + " 2>&1",
                          out))
      << out;
  std::ifstream pf(wd / "plan.json");
  const auto plan = nlohmann::json::parse(pf, nullptr, false);
  ASSERT_TRUE(plan.is_object());
  const auto& u = plan["report"]["input_height_units"];
  ASSERT_EQ(u.size(), 1u);
  EXPECT_NEAR(double(u[0]["scale"]), kUsFootM, 1e-12);
  EXPECT_EQ(u[0]["unit"], "US survey foot");
  std::ifstream a(one, std::ios::binary), b(merged, std::ios::binary);
  const std::string ba((std::istreambuf_iterator<char>(a)), {}), bb((std::istreambuf_iterator<char>(b)), {});
  ASSERT_GT(ba.size(), 1000u);
  EXPECT_TRUE(ba == bb) << "the work-unit cook differs from the one-process cook";
  CookedArchive ca;
  ASSERT_TRUE(ca.open(merged.string()).ok());
  const auto info = nlohmann::json::parse(ca.reader.world().cook_info_json);
  EXPECT_NEAR(double(info["inputs"][0]["heights"]["scale"]), kUsFootM, 1e-12);
}
