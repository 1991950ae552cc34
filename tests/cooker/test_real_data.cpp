// Real DEMs of ../shared/data cooked by the CMake fixtures (tests/cooker/CMakeLists.txt):
//   <build>/cooker-test-archives/NAME.terrain          default options (every section)
//   <build>/cooker-test-archives/NAME.oracle.terrain   --finest-level 0 --heights-only
// checked against an independent oracle (GDAL through /usr/bin/python3, oracle_points.py) via
// terrain-inspect --sample-file, and walked for seams.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <algorithm>
#include <fstream>
#include <sstream>

#include "cooker_test_util.h"
#include "inputs.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;

namespace {

constexpr double kMm = 1e-3;

struct RealDem {
  const char* name;
  const char* file;
  bool lonlat;                 // oracle points are longitude/latitude
  double scale = 1.0;          // value -> metres
  double spacing = 0.0;        // heightmap image: frame metres per sample
  bool relief = true;          // enough relief for a half-sample shift to break the bound
  bool reaches_tolerance = true;  // level 0 (0.5 m) can meet the tolerance everywhere
  bool single_archive = false;    // one cook (--finest-level 0 --heights-only) serves both tests
};

// Built twice: the small DEMs (also run under the sanitizers) and the large ones (no_sanitizer).
#if TERRAIN_REAL_SET_LARGE
// gtest prints parameters in test names: the DEM's name only.
void PrintTo(const RealDem& d, std::ostream* os) { *os << d.name; }

const RealDem kDems[] = {
    {"oetztal", "srtm_oetztal.tif", true},
    {"n22w160", "N22W160.hgt.zip", true},
    {"n19w155", "N19W155.hgt.zip", true, 1.0, 0.0, false},
    {"s46w066", "S46W066.hgt.gz", true, 1.0, 0.0, false},
    {"puget", "ps_height_1k.png", false, 0.1, 160.0, true, true, true},
};
#else
void PrintTo(const RealDem& d, std::ostream* os) { *os << d.name; }

const RealDem kDems[] = {
    // Bare earth at 0.5 m: too smooth for a half-sample (0.24 m) shift to exceed the tolerance.
    {"tahoe_bare", "tahoe_lidar_bareearth.tif", true, 1.0, 0.0, false},
    // First-return lidar: one-sample tree spikes of 10-20 m that a 0.5 m lattice offset from the
    // 0.47 x 0.61 m samples cannot pass through (the nodes' recorded errors say so, and bound the
    // comparison, which also hides a half-sample shift there).
    {"tahoe_highest", "tahoe_lidar_highesthit.tif", true, 1.0, 0.0, false, false},
    // 1 m lidar: half a sample (0.5 m) times its slopes stays mostly within the 0.5 m tolerance.
    {"slovenia", "slovenia_TM1_564_146.tif", false, 1.0, 0.0, false},
    {"kilauea", "kilauea_utm5n.tif", false},
    {"jacksboro", "jacksboro_fault_dem.npz", true},
};
#endif

std::filesystem::path dem_path(const RealDem& d) {
  if (std::string(d.file) == "jacksboro_fault_dem.npz")
    return "/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz";
  return data_file(d.file);
}

// How GDAL opens the file (zip and gzip through its virtual file systems).
std::string gdal_path(const RealDem& d) {
  const std::string p = dem_path(d).string();
  const std::string f = d.file;
  if (f.size() > 8 && f.substr(f.size() - 8) == ".hgt.zip") return "/vsizip/" + p + "/" + f.substr(0, f.size() - 4);
  if (f.size() > 7 && f.substr(f.size() - 7) == ".hgt.gz") return "/vsigzip/" + p;
  return p;
}

std::filesystem::path default_archive(const RealDem& d) {
  return bin_dir().parent_path() / "cooker-test-archives" / (std::string(d.name) + ".terrain");
}
// The --finest-level 0 --heights-only cook, or the default one where a single cook serves both.
std::filesystem::path oracle_archive(const RealDem& d) {
  const auto p = bin_dir().parent_path() / "cooker-test-archives" / (std::string(d.name) + ".oracle.terrain");
  return d.single_archive ? default_archive(d) : p;
}

bool run(const std::string& cmd, std::string& out) {
  out.clear();
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return false;
  char buf[1 << 16];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  return pclose(p) == 0;
}

struct OraclePoint {
  double a, b, value;
  bool edge;
};

// Oracle points from GDAL; empty (with a reason) when the oracle cannot run here.
std::vector<OraclePoint> oracle_points(const RealDem& d, double shift, std::string& why) {
  std::string out;
  const std::string script = (source_dir() / "tests" / "cooker" / "oracle_points.py").string();
  std::string cmd = "/usr/bin/python3 '" + script + "' '" + gdal_path(d) + "' --count 10000 --seed 1";
  if (d.scale != 1.0) cmd += " --scale " + std::to_string(d.scale);
  if (d.spacing > 0) cmd += " --spacing " + std::to_string(d.spacing);
  if (shift != 0) cmd += " --shift " + std::to_string(shift);
  if (!run(cmd + " 2>&1", out)) {
    why = "the GDAL oracle failed (needs Debian's python3-gdal under /usr/bin/python3): " + out.substr(0, 300);
    return {};
  }
  std::vector<OraclePoint> pts;
  std::istringstream in(out);
  OraclePoint p;
  int edge = 0;
  while (in >> p.a >> p.b >> p.value >> edge) {
    p.edge = edge != 0;
    pts.push_back(p);
  }
  return pts;
}

// terrain-inspect --sample-file: one height or nullopt ("nodata") per point.
bool inspect_heights(const std::filesystem::path& archive, const std::vector<OraclePoint>& pts, bool lonlat,
                     std::vector<std::optional<double>>& out, std::string& why) {
  const auto file = scratch_dir("cooker-oracle") / "points.txt";
  {
    std::ofstream f(file);
    f.precision(12);
    for (const OraclePoint& p : pts) f << std::fixed << p.a << " " << p.b << "\n";
  }
  const std::string inspect = (bin_dir() / "terrain-inspect").string();
  std::string text;
  if (!run("'" + inspect + "' '" + archive.string() + "' --sample-file '" + file.string() + "'" +
               (lonlat ? " --lonlat" : "") + " 2>&1",
           text)) {
    why = "terrain-inspect failed: " + text.substr(0, 300);
    return false;
  }
  out.clear();
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (line == "nodata") out.emplace_back(std::nullopt);
    else out.emplace_back(std::stod(line));
  }
  if (out.size() != pts.size()) {
    why = "terrain-inspect printed " + std::to_string(out.size()) + " lines for " + std::to_string(pts.size()) + " points";
    return false;
  }
  return true;
}

double cook_tolerance(const ArchiveReader& r) {
  const auto j = nlohmann::json::parse(r.world().cook_info_json, nullptr, false);
  return j.is_object() ? j["options"].value("tolerance_m", 0.0) : 0.0;
}

struct OracleResult {
  size_t points = 0, answered = 0, missing_edge = 0, missing_inner = 0;
  size_t violations = 0, above_tolerance = 0;  // nodes whose recorded error exceeds the tolerance
  double worst_error = 0, worst_excess = -INFINITY;
  std::string first_violation;
};

// Compares terrain-inspect's heights with the oracle's: |cooked - source| <= max(tolerance, error
// of the node that answered) + half the largest quantization step + 1 mm.
OracleResult compare(const RealDem& d, const std::filesystem::path& archive, double shift, std::string& why) {
  OracleResult r;
  std::vector<OraclePoint> pts = oracle_points(d, shift, why);
  if (pts.empty()) return r;
  CookedArchive ca;
  if (!ca.open(archive.string()).ok()) {
    why = "cannot open " + archive.string();
    return r;
  }
  // Frame positions, and the points in 256 m cells so both samplers find their node in cache.
  std::vector<std::pair<double, double>> frame(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    frame[i] = {pts[i].a, pts[i].b};
    if (d.lonlat) lonlat_to_frame(ca.reader.world().crs, pts[i].a, pts[i].b, frame[i].first, frame[i].second);
  }
  std::vector<size_t> order(pts.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  auto cell = [&](size_t i) {
    return std::make_pair(std::floor(frame[i].second / 256.0), std::floor(frame[i].first / 256.0));
  };
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return cell(a) < cell(b); });
  {
    std::vector<OraclePoint> p2;
    std::vector<std::pair<double, double>> f2;
    for (size_t i : order) {
      p2.push_back(pts[i]);
      f2.push_back(frame[i]);
    }
    pts.swap(p2);
    frame.swap(f2);
  }
  std::vector<std::optional<double>> cooked;
  if (!inspect_heights(archive, pts, d.lonlat, cooked, why)) return r;
  const double tol = cook_tolerance(ca.reader), half = ca.max_half_step();
  r.points = pts.size();
  for (size_t i = 0; i < pts.size(); ++i) {
    const OraclePoint& p = pts[i];
    if (!cooked[i]) {
      ++(p.edge ? r.missing_edge : r.missing_inner);
      continue;
    }
    ++r.answered;
    const NodeRecord* node = nullptr;
    const auto lib = ca.height(frame[i].first, frame[i].second, &node);
    const double node_error = lib && node ? double(node->geometric_error_m) : 0.0;
    if (node_error > tol) ++r.above_tolerance;
    const double e = std::fabs(*cooked[i] - p.value);
    const double bound = std::max(tol, node_error) + half + kMm;
    r.worst_error = std::max(r.worst_error, e);
    r.worst_excess = std::max(r.worst_excess, e - bound);
    if (e > bound) {
      if (++r.violations == 1) {
        std::ostringstream s;
        s.precision(10);
        s << "point " << p.a << " " << p.b << ": cooked " << *cooked[i] << ", source " << p.value << ", bound " << bound;
        r.first_violation = s.str();
      }
    }
  }
  return r;
}

class RealData : public ::testing::TestWithParam<RealDem> {};

std::string dem_name(const ::testing::TestParamInfo<RealDem>& info) { return info.param.name; }

}  // namespace

// The accuracy test. Cooked with --finest-level 0 so refinement can reach the tolerance:
// every answered point within tolerance + half a step + 1 mm (or the node's recorded error where
// even 0.5 m vertices cannot follow the data: only the Tahoe first-return spikes); every point not
// on the raster's edge or beside nodata answered.
TEST_P(RealData, OracleAgreesWithinToleranceHalfStepAndAMillimetre) {
  const RealDem& d = GetParam();
  TERRAIN_REQUIRE_DATA(dem_path(d));
  const auto archive = oracle_archive(d);
  if (!std::filesystem::exists(archive)) GTEST_SKIP() << archive << " missing (the cooker.cook_oracle fixture makes it)";
  std::string why;
  const OracleResult r = compare(d, archive, 0.0, why);
  if (r.points == 0) GTEST_SKIP() << why;
  std::printf("%s: %zu points, %zu answered, worst |cooked - source| %.4f m, %zu on nodes above tolerance, "
              "%zu edge points without terrain\n",
              d.name, r.points, r.answered, r.worst_error, r.above_tolerance, r.missing_edge);
  EXPECT_GE(r.points, 10000u);
  EXPECT_EQ(r.violations, 0u) << r.first_violation;
  EXPECT_EQ(r.missing_inner, 0u);
  EXPECT_LE(r.missing_edge, r.points / 100);
  if (d.reaches_tolerance) {
    EXPECT_EQ(r.above_tolerance, 0u);
  } else {
    EXPECT_GT(r.above_tolerance, 0u);  // documented: these points are bounded by their node's error
  }
}

// Negative control: the same comparison with every oracle point moved half a sample east must fail
// for DEMs with relief, so the bound does catch half-pixel shifts.
TEST_P(RealData, HalfSampleShiftBreaksTheBound) {
  const RealDem& d = GetParam();
  if (!d.relief) GTEST_SKIP() << d.name << " is too flat for a half-sample shift to show";
  TERRAIN_REQUIRE_DATA(dem_path(d));
  const auto archive = oracle_archive(d);
  if (!std::filesystem::exists(archive)) GTEST_SKIP() << archive << " missing";
  std::string why;
  const OracleResult r = compare(d, archive, 0.5, why);
  if (r.points == 0) GTEST_SKIP() << why;
  std::printf("%s shifted half a sample: %zu of %zu points out of bound (worst %.3f m)\n", d.name, r.violations,
              r.answered, r.worst_error);
  EXPECT_GT(r.violations, r.answered / 100);
}

// The default cook: the recorded geometric errors are honest (every point within max(tolerance,
// node error) + half a step + 1 mm).
TEST_P(RealData, DefaultCookRecordsHonestErrors) {
  const RealDem& d = GetParam();
  TERRAIN_REQUIRE_DATA(dem_path(d));
  const auto archive = default_archive(d);
  if (!std::filesystem::exists(archive)) GTEST_SKIP() << archive << " missing (the cooker.cook fixture makes it)";
  std::string why;
  const OracleResult r = compare(d, archive, 0.0, why);
  if (r.points == 0) GTEST_SKIP() << why;
  std::printf("%s default: worst |cooked - source| %.4f m, %zu of %zu points on nodes above tolerance\n", d.name,
              r.worst_error, r.above_tolerance, r.answered);
  EXPECT_EQ(r.violations, 0u) << r.first_violation;
  EXPECT_EQ(r.missing_inner, 0u);
}

// Every shared edge and parent/child vertex of both archives: bit-identical float heights and
// identical hole flags (zero mismatches), over a non-trivial number of vertex pairs.
TEST_P(RealData, SeamsAreBitIdentical) {
  const RealDem& d = GetParam();
  TERRAIN_REQUIRE_DATA(dem_path(d));
  int walked = 0;
  std::vector<std::filesystem::path> archives = {default_archive(d)};
  if (!d.single_archive) archives.push_back(oracle_archive(d));
  for (const auto& archive : archives) {
    if (!std::filesystem::exists(archive)) continue;
    ArchiveReader reader;
    ASSERT_TRUE(reader.open(archive.string()).ok());
    uint64_t compared = 0;
    std::string problem;
    EXPECT_EQ(count_seam_mismatches(reader, compared, problem), 0u) << archive << ": " << problem;
    EXPECT_GT(compared, 0u);
    std::printf("%s: %llu shared vertex pairs compared\n", archive.filename().c_str(), (unsigned long long)compared);
    ++walked;
  }
  if (walked == 0) GTEST_SKIP() << "no archives (the cooking fixtures make them)";
}

INSTANTIATE_TEST_SUITE_P(SharedData, RealData, ::testing::ValuesIn(kDems), dem_name);

#if !TERRAIN_REAL_SET_LARGE
// Readers against the README's facts.
TEST(RealInputs, HgtVoidsAndGeoTiffNodataAreCounted) {
  TERRAIN_REQUIRE_DATA(data_file("N22W160.hgt.zip"));
  cook::Raster r;
  ASSERT_TRUE(cook::read_hgt(data_file("N22W160.hgt.zip").string(), {}, r).ok());
  EXPECT_EQ(r.width, 1201);
  size_t voids = 0;
  for (float v : r.values) voids += std::isnan(v);
  EXPECT_EQ(voids, 4279u);
  EXPECT_DOUBLE_EQ(r.geo.c[0], -160.0);  // sample (0, 0) is the north-west corner, on the degree lines
  EXPECT_DOUBLE_EQ(r.geo.c[3], 23.0);
  cook::Raster k;
  ASSERT_TRUE(cook::read_geotiff(data_file("kilauea_utm5n.tif").string(), {}, k).ok());
  size_t sea = 0;
  for (float v : k.values) sea += std::isnan(v);
  EXPECT_EQ(sea, 20656u);
  EXPECT_DOUBLE_EQ(k.geo.c[0], 254340.0);  // PixelIsArea: first sample centre half a pixel in
  EXPECT_DOUBLE_EQ(k.geo.c[3], 2153640.0);
  EXPECT_EQ(k.crs.kind, cook::CrsKind::transverse_mercator);
  EXPECT_EQ(k.crs.tm.lon0_deg, -153.0);
}

// Cooking twice with 1 and 2 threads, every section included: identical bytes.
TEST(RealDeterminism, KilaueaWithOneAndTwoThreadsIsByteIdentical) {
  TERRAIN_REQUIRE_DATA(data_file("kilauea_utm5n.tif"));
  const auto dir = scratch_dir("cooker-real-threads");
  std::vector<std::string> bytes;
  for (int threads : {1, 2}) {
    cook::CookOptions o;
    o.inputs = {data_file("kilauea_utm5n.tif").string()};
    o.output = (dir / (threads == 1 ? "k1.terrain" : "k2.terrain")).string();
    o.threads = threads;
    cook::CookReport report;
    const Status st = cook::cook(o, {}, report);
    ASSERT_TRUE(st.ok()) << st.to_string();
    std::ifstream in(o.output, std::ios::binary);
    bytes.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  ASSERT_GT(bytes[0].size(), 100000u);
  EXPECT_TRUE(bytes[0] == bytes[1]);
}
#endif
