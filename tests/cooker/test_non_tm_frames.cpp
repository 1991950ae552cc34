// Frames in projected CRSs other than Transverse Mercator (issue 13, "Any CRS that PROJ knows"):
// the shared Oetztal SRTM DEM is warped at test time with gdalwarp into Lambert-93 (EPSG:2154,
// Lambert conformal conic), a custom Albers equal-area centred on it (PROJ string, no EPSG code)
// and CH1903+ / LV95 (EPSG:2056, oblique Mercator); each is cooked with the default options, its
// archive's frame must be the input's own CRS (format v2, WKT2), and the GDAL oracle of the
// RealData tests (oracle_points.py, same bound: tolerance + half the root step + 1 mm, every
// point answered) must hold. Also: Web Mercator at 47 N falls back to a Transverse Mercator,
// --frame picks an LCC for geographic input, a CRS PROJ cannot resolve is a named error that
// touches no archive, and terrain-inspect --sample-lonlat agrees with gdaltransform.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cooker_test_util.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;

namespace {

constexpr double kMm = 1e-3;
const char* const kSource = "srtm_oetztal.tif";  // WGS 84 lon/lat, 47 N 11 E, 582 x 444 samples
// --frame: a Lambert conformal conic on the source's own ellipsoid (WGS 84), centred on the data.
const char* const kLccFrame = "+proj=lcc +lat_0=46.9 +lon_0=10.85 +lat_1=46.6 +lat_2=47.2 +x_0=500000 +y_0=300000 "
                              "+datum=WGS84 +units=m +no_defs";
const char* const kAlbers = "+proj=aea +lat_0=46.9 +lon_0=10.85 +lat_1=46.5 +lat_2=47.3 +x_0=100000 +y_0=200000 "
                            "+ellps=GRS80 +units=m +no_defs";

// Single-quoted for the shell (appended, not "'" + s: GCC 12's -Wrestrict misfires on that).
std::string q(const std::filesystem::path& p) {
  std::string s(1, '\'');
  s.append(p.string());
  s.push_back('\'');
  return s;
}

std::filesystem::path work_dir() {
  static const std::filesystem::path dir = scratch_dir("cooker-non-tm");
  return dir;
}

// `name`.tif: the source warped to `srs` (cubic, 60 m), made once per test run, over a lon/lat box
// 6-8 km inside the source's so the warped raster holds data everywhere. (With the whole footprint,
// its border is a rotated staircase of nodata; on Lambert-93 one of 10 000 edge samples on a steep
// slope beside it was then 0.80 m off (bound 0.53 m): the cooker's handling of nodata edges, the
// same in any frame, not the frame's.)
bool warped(const std::string& name, const std::string& srs, std::filesystem::path& out, std::string& why) {
  out = work_dir() / (name + ".tif");
  if (std::filesystem::exists(out)) return true;
  std::string text;
  if (!run_command("gdalwarp -q -overwrite -t_srs '" + srs + "' -te_srs EPSG:4326 -te 10.70 46.73 11.03 46.96 -r cubic -tr 60 60 -ot Float32 -dstnodata -32768 " +
               q(data_file(kSource)) + " " + q(out) + " 2>&1",
           text)) {
    why = "gdalwarp failed: " + text;
    return false;
  }
  return true;
}

// Cooks `input` (default options plus `flags`) into `name`.terrain; false with the output on failure.
bool cook_input(const std::filesystem::path& input, const std::string& name, const std::string& flags,
          std::filesystem::path& archive, std::string& out) {
  archive = work_dir() / (name + ".terrain");
  if (std::filesystem::exists(archive)) return true;
  return run_command(q(bin_dir() / "terrain-cook") + " " + q(input) + " -o " + q(archive) + " " + flags + " 2>&1", out);
}

struct OracleResult {
  size_t points = 0, answered = 0, violations = 0;
  double bound = 0, worst = 0;
  std::string first_violation;
};

// The RealData oracle (tests/cooker/test_real_data.cpp) on a projected or geographic `tif`: 10 000
// random valid samples from GDAL, their heights from terrain-inspect --sample-file.
bool oracle(const std::filesystem::path& tif, const std::filesystem::path& archive, bool lonlat, OracleResult& r,
            std::string& why, double shift = 0.0) {
  std::string pts_text;
  const std::string script = (source_dir() / "tests" / "cooker" / "oracle_points.py").string();
  if (!run_command("/usr/bin/python3 '" + script + "' " + q(tif) + " --count 10000 --seed 1 --shift " + std::to_string(shift) + " 2>&1", pts_text)) {
    why = "the GDAL oracle failed: " + pts_text.substr(0, 300);
    return false;
  }
  std::vector<std::array<double, 3>> pts;
  {
    std::istringstream in(pts_text);
    double a, b, v;
    int edge;
    while (in >> a >> b >> v >> edge) pts.push_back({a, b, v});
  }
  const auto file = work_dir() / (archive.stem().string() + "_points.txt");
  {
    std::ofstream f(file);
    f.precision(12);
    for (const auto& p : pts) f << std::fixed << p[0] << " " << p[1] << "\n";
  }
  std::string text;
  if (!run_command(q(bin_dir() / "terrain-inspect") + " " + q(archive) + " --sample-file " + q(file) + (lonlat ? " --lonlat" : "") +
               " 2>&1",
           text)) {
    why = "terrain-inspect failed: " + text.substr(0, 300);
    return false;
  }
  CookedArchive ca;
  if (!ca.open(archive.string()).ok()) {
    why = "cannot open " + archive.string();
    return false;
  }
  const auto info = nlohmann::json::parse(ca.reader.world().cook_info_json, nullptr, false);
  const double tol = info.is_object() ? info["options"].value("tolerance_m", 0.0) : 0.0;
  r.bound = tol + ca.max_half_step() + kMm;
  r.points = pts.size();
  std::istringstream in(text);
  std::string line;
  for (size_t i = 0; i < pts.size() && std::getline(in, line); ++i) {
    if (line == "nodata") continue;
    ++r.answered;
    const double e = std::fabs(std::stod(line) - pts[i][2]);
    r.worst = std::max(r.worst, e);
    if (e > r.bound && ++r.violations == 1)
      r.first_violation = "point " + std::to_string(pts[i][0]) + " " + std::to_string(pts[i][1]) + ": cooked " + line +
                          ", source " + std::to_string(pts[i][2]);
  }
  return true;
}

struct NonTmCase {
  const char* name;
  const char* srs;      // gdalwarp -t_srs
  int epsg;             // expected frame EPSG code (0: none)
  const char* method;   // expected in the frame's WKT2
  double semi_major_m;  // the CRS's ellipsoid
};
void PrintTo(const NonTmCase& c, std::ostream* os) { *os << c.name; }

const NonTmCase kCases[] = {
    {"lambert93", "EPSG:2154", 2154, "Lambert Conic Conformal", 6378137.0},            // GRS 1980
    {"albers_custom", kAlbers, 0, "Albers Equal Area", 6378137.0},                     // GRS 1980
    {"lv95", "EPSG:2056", 2056, "Hotine Oblique Mercator", 6377397.155},               // Bessel 1841
};

class NonTmFrame : public ::testing::TestWithParam<NonTmCase> {};

}  // namespace

TEST_P(NonTmFrame, InputCrsIsTheFrameAndTheOracleHolds) {
  TERRAIN_REQUIRE_DATA(data_file(kSource));
  const NonTmCase& c = GetParam();
  std::filesystem::path tif, archive;
  std::string why, out;
  if (!warped(c.name, c.srs, tif, why)) GTEST_SKIP() << why;
  ASSERT_TRUE(cook_input(tif, c.name, "", archive, out)) << out;
  CookedArchive ca;
  ASSERT_TRUE(ca.open(archive.string()).ok());
  const FrameCrs& f = ca.reader.world().crs;
  EXPECT_EQ(ca.reader.format_version(), 3u);
  EXPECT_EQ(f.kind, ProjectionKind::proj);
  EXPECT_EQ(f.epsg, c.epsg);
  EXPECT_NE(f.definition.find(c.method), std::string::npos) << f.definition;
  EXPECT_NEAR(f.semi_major_m, c.semi_major_m, 1e-6);
  // The frame is the file's own coordinates: the archive's extent lies on the raster's footprint.
  std::string info;
  ASSERT_TRUE(run_command("gdalinfo -json " + q(tif), info));
  const auto gi = nlohmann::json::parse(info);
  const auto& gt = gi["geoTransform"];
  const double x0 = gt[0], y1 = gt[3], w = gi["size"][0], h = gi["size"][1];
  const double x1 = x0 + w * double(gt[1]), y0 = y1 + h * double(gt[5]);
  const auto& wi = ca.reader.world();
  EXPECT_GE(wi.extent_min_x_m, x0 - 1e-6);
  EXPECT_LE(wi.extent_max_x_m, x1 + 1e-6);
  EXPECT_GE(wi.extent_min_y_m, y0 - 1e-6);
  EXPECT_LE(wi.extent_max_y_m, y1 + 1e-6);
  EXPECT_GT(wi.extent_max_x_m - wi.extent_min_x_m, 0.5 * (x1 - x0));

  OracleResult r;
  ASSERT_TRUE(oracle(tif, archive, false, r, why)) << why;
  std::printf("%s: %zu points, %zu answered, worst |cooked - source| %.4f m (bound %.4f m), %zu out of bound\n", c.name,
              r.points, r.answered, r.worst, r.bound, r.violations);
  EXPECT_GE(r.points, 10000u);
  EXPECT_EQ(r.answered, r.points);
  EXPECT_EQ(r.violations, 0u) << r.first_violation;
}

// Negative control: the same oracle with every point moved half a sample (30 m) east fails, so the
// bound does see a misplaced frame.
TEST(NonTmFrameChoice, HalfSampleShiftBreaksTheBoundOnLambert93) {
  TERRAIN_REQUIRE_DATA(data_file(kSource));
  std::filesystem::path tif, archive;
  std::string why, out;
  if (!warped("lambert93_shift", "EPSG:2154", tif, why)) GTEST_SKIP() << why;
  ASSERT_TRUE(cook_input(tif, "lambert93_shift", "--heights-only", archive, out)) << out;
  OracleResult r;
  ASSERT_TRUE(oracle(tif, archive, false, r, why, 0.5)) << why;
  std::printf("lambert93 shifted half a sample: %zu of %zu answered points out of bound\n", r.violations, r.answered);
  EXPECT_GT(r.violations, r.answered / 100);
}

INSTANTIATE_TEST_SUITE_P(Oetztal, NonTmFrame, ::testing::ValuesIn(kCases),
                         [](const ::testing::TestParamInfo<NonTmCase>& i) { return std::string(i.param.name); });

// Web Mercator at 47 N stretches distances by 1 / cos(47) = 1.47: far beyond the 0.5 % bound, so
// the frame is a Transverse Mercator centred on the data (no frame_definition record), as for
// geographic input.
TEST(NonTmFrameChoice, WebMercatorFarFromTheEquatorFallsBackToTransverseMercator) {
  TERRAIN_REQUIRE_DATA(data_file(kSource));
  std::filesystem::path tif, archive;
  std::string why, out;
  if (!warped("webmerc", "EPSG:3857", tif, why)) GTEST_SKIP() << why;
  ASSERT_TRUE(cook_input(tif, "webmerc", "", archive, out)) << out;
  CookedArchive ca;
  ASSERT_TRUE(ca.open(archive.string()).ok());
  const FrameCrs& f = ca.reader.world().crs;
  // Version 2 for the derived normals alone (SPEC 16.7), not for the frame.
  EXPECT_TRUE(ca.reader.world().derived_normals);
  EXPECT_EQ(ca.reader.format_version(), 3u);
  EXPECT_EQ(f.kind, ProjectionKind::transverse_mercator);
  EXPECT_NEAR(f.lon0_deg, 10.865, 0.05);  // the data's centre longitude (source 10.62 .. 11.11 E)
  EXPECT_EQ(f.scale_k0, 1.0);
  EXPECT_TRUE(f.definition.empty());
}

// --frame with a custom Lambert conformal conic: geographic input mapped through PROJ, oracle in lon/lat
// (terrain-inspect --lonlat converts with PROJ from the archive's WKT2).
TEST(NonTmFrameChoice, FrameFlagPicksLambertForGeographicInput) {
  TERRAIN_REQUIRE_DATA(data_file(kSource));
  std::filesystem::path archive;
  std::string why, out;
  ASSERT_TRUE(cook_input(data_file(kSource), "frame_flag_lcc", std::string("--frame '") + kLccFrame + "'", archive, out)) << out;
  CookedArchive ca;
  ASSERT_TRUE(ca.open(archive.string()).ok());
  EXPECT_EQ(ca.reader.world().crs.kind, ProjectionKind::proj);
  EXPECT_NE(ca.reader.world().crs.definition.find("Lambert Conic Conformal (2SP)"), std::string::npos);
  // The data's centre (10.87 E, 46.85 N) lies near the false origin (500 km, 300 km).
  EXPECT_NEAR(0.5 * (ca.reader.world().extent_min_x_m + ca.reader.world().extent_max_x_m), 500000 + 1500, 3000);
  EXPECT_NEAR(0.5 * (ca.reader.world().extent_min_y_m + ca.reader.world().extent_max_y_m), 300000 - 5500, 3000);
  OracleResult r;
  ASSERT_TRUE(oracle(data_file(kSource), archive, true, r, why)) << why;
  std::printf("--frame custom LCC: %zu points, %zu answered, worst %.4f m (bound %.4f m), %zu out of bound\n", r.points,
              r.answered, r.worst, r.bound, r.violations);
  EXPECT_GE(r.points, 10000u);
  EXPECT_EQ(r.answered, r.points);
  EXPECT_EQ(r.violations, 0u) << r.first_violation;
}

// The PROJ chain (geographic input, LCC frame, anchors built on threads) gives the same bytes for
// any thread count: every vertex maps through the same anchors, and PROJ answers the same bits.
TEST(NonTmFrameChoice, ProjChainIsByteIdenticalAcrossThreadCounts) {
  TERRAIN_REQUIRE_DATA(data_file(kSource));
  std::filesystem::path a1, a2;
  std::string out;
  const std::string flags = std::string("--heights-only --frame '") + kLccFrame + "' --threads ";
  ASSERT_TRUE(cook_input(data_file(kSource), "threads1", flags + "1", a1, out)) << out;
  ASSERT_TRUE(cook_input(data_file(kSource), "threads2", flags + "2", a2, out)) << out;
  std::ifstream f1(a1, std::ios::binary), f2(a2, std::ios::binary);
  const std::string b1((std::istreambuf_iterator<char>(f1)), {}), b2((std::istreambuf_iterator<char>(f2)), {});
  ASSERT_GT(b1.size(), 1000u);
  EXPECT_EQ(b1.size(), b2.size());
  EXPECT_TRUE(b1 == b2) << "thread count changed the archive's bytes";
}

// terrain-inspect --sample-lonlat on the Lambert-93 archive lands where gdaltransform puts the point.
TEST(NonTmFrameChoice, InspectSampleLonLatAgreesWithGdaltransform) {
  TERRAIN_REQUIRE_DATA(data_file(kSource));
  std::filesystem::path tif, archive;
  std::string why, out;
  if (!warped("lambert93", "EPSG:2154", tif, why)) GTEST_SKIP() << why;
  ASSERT_TRUE(cook_input(tif, "lambert93", "--heights-only", archive, out)) << out;
  const double pts[][2] = {{10.80, 46.90}, {10.95, 46.80}, {10.76, 46.78}};
  for (const auto& p : pts) {
    std::string gt, js;
    ASSERT_TRUE(run_command("echo '" + std::to_string(p[0]) + " " + std::to_string(p[1]) +
                        "' | gdaltransform -s_srs EPSG:4326 -t_srs EPSG:2154 -output_xy",
                    gt));
    double gx = 0, gy = 0;
    std::istringstream(gt) >> gx >> gy;
    ASSERT_TRUE(run_command(q(bin_dir() / "terrain-inspect") + " " + q(archive) + " --json --sample-lonlat " +
                        std::to_string(p[0]) + "," + std::to_string(p[1]),
                    js))
        << js;
    const auto j = nlohmann::json::parse(js);
    const auto& s = j["samples"][0];
    EXPECT_NEAR(double(s["frame_m"][0]), gx, 0.01) << gt;
    EXPECT_NEAR(double(s["frame_m"][1]), gy, 0.01) << gt;
    EXPECT_FALSE(s["height_m"].is_null());
  }
}

// What has no metric frame meaning is refused by name, with a non-zero exit, before any archive
// is touched: a CRS PROJ cannot resolve, a geographic --frame.
TEST(NonTmFrameChoice, UnresolvableCrsAndGeographicFrameAreNamedErrors) {
  TERRAIN_REQUIRE_DATA(data_file(kSource));
  const auto archive = work_dir() / "refused.terrain";
  {
    std::ofstream f(archive);
    f << "an older archive";
  }
  struct Case {
    const char* flags;
    const char* message;
  } cases[] = {{"--crs '+proj=no_such_projection +ellps=GRS80'", "PROJ cannot resolve"},
               {"--frame EPSG:4326", "no metric meaning"}};
  for (const Case& c : cases) {
    std::string out;
    EXPECT_FALSE(run_command(q(bin_dir() / "terrain-cook") + " " + q(data_file(kSource)) + " -o " + q(archive) + " " + c.flags + " 2>&1",
                     out))
        << c.flags;
    EXPECT_NE(out.find(c.message), std::string::npos) << c.flags << ": " << out;
    std::ifstream f(archive);
    std::string kept((std::istreambuf_iterator<char>(f)), {});
    EXPECT_EQ(kept, "an older archive") << c.flags;
  }
}
