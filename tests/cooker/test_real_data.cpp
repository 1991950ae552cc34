// Real DEMs of ../shared/data cooked by the CMake fixtures (tests/cooker/CMakeLists.txt) with the
// default options into <build>/cooker-test-archives/NAME.terrain, checked against an independent oracle (GDAL through /usr/bin/python3, oracle_points.py) via
// terrain-inspect --sample-file, and walked for seams.
#include <gtest/gtest.h>

#include <map>

#include <array>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <algorithm>
#include <fstream>
#include <sstream>
#include <string_view>

#include "cooker_test_util.h"
#include "inputs/inputs.h"
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
  // Known failure (see the oracle test): sample-scale relief on samples that are not on the 0.5 m
  // lattice, which no sampled surface on that lattice can follow.
  bool lattice_limited = false;
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
    {"puget", "ps_height_1k.png", false, 0.1, 160.0},
    // Default cook with every section refines its cliffs and coast to 1-8 m: a few seconds in a
    // release build, too slow for the sanitizer run.
    {"kilauea", "kilauea_utm5n.tif", false},
};
#else
void PrintTo(const RealDem& d, std::ostream* os) { *os << d.name; }

const RealDem kDems[] = {
    // Bare earth at 0.5 m: too smooth for a half-sample (0.24 m) shift to exceed the tolerance.
    {"tahoe_bare", "tahoe_lidar_bareearth.tif", true, 1.0, 0.0, false},
    // First-return lidar: tree canopy varying by 5-17 m from one 0.47 x 0.61 m sample to the next
    // (a third of neighbour differences exceed 1 m). The same heights re-georeferenced at 0.5 m or
    // 1 m with every sample ON a lattice vertex cook to 7.6 mm; at 0.47, 0.53 or 0.61 m off the
    // lattice to 13-17 m: the lattice, not the cooker's error measure, is the limit.
    {"tahoe_highest", "tahoe_lidar_highesthit.tif", true, 1.0, 0.0, true, true},
    // 1 m lidar: half a sample (0.5 m) times its slopes stays mostly within the 0.5 m tolerance.
    {"slovenia", "slovenia_TM1_564_146.tif", false, 1.0, 0.0, false},
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

// The default cook (tests/cooker/CMakeLists.txt), which every test here reads.
std::filesystem::path default_archive(const RealDem& d) {
  return bin_dir().parent_path() / "cooker-test-archives" / (std::string(d.name) + ".terrain");
}

// The default cook's --report file: skips the calling test when the fixture has not made it,
// fails it when the file is not a JSON object (the caller checks IsSkipped() || HasFatalFailure()).
void load_default_report(const RealDem& d, nlohmann::json& out) {
  const std::filesystem::path path = std::filesystem::path(default_archive(d)).replace_extension(".json");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " missing (the cooker.cook fixture makes it)";
  std::ifstream f(path);
  out = nlohmann::json::parse(f, nullptr, false);
  ASSERT_TRUE(out.is_object()) << path << " is not JSON";
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
  if (!run_command(cmd + " 2>&1", out)) {
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
  if (!run_command("'" + inspect + "' '" + archive.string() + "' --sample-file '" + file.string() + "'" +
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
  size_t violations = 0;           // |cooked - source| > tolerance + half step + 1 mm
  size_t above_recorded = 0;       // |cooked - source| > the answering node's recorded error + 1 mm
  double tolerance = 0, bound = 0, worst_error = 0, worst_excess_recorded = -INFINITY;
  std::array<double, kLevelCount> level_worst{};   // worst |cooked - source| at points a level-L node answered
  std::array<size_t, kLevelCount> level_points{};
  std::string first_violation, first_above_recorded;
};

// Compares terrain-inspect's heights with the oracle's. The bound: |cooked - source| <=
// tolerance + half the largest quantization step (every vertex is rounded at its coarsest level,
// so the root's step bounds the rounding) + 1 mm. Also counts points beyond the geometric error
// the answering node records (float rounding of heights near 4 km: 1 mm of slack).
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
  r.tolerance = tol;
  r.bound = tol + half + kMm;
  for (size_t i = 0; i < pts.size(); ++i) {
    const OraclePoint& p = pts[i];
    if (!cooked[i]) {
      ++(p.edge ? r.missing_edge : r.missing_inner);
      continue;
    }
    ++r.answered;
    const NodeRecord* node = nullptr;
    const auto lib = ca.height(frame[i].first, frame[i].second, &node);
    const double e = std::fabs(*cooked[i] - p.value);
    auto describe = [&](double bound) {
      std::ostringstream s;
      s.precision(10);
      s << "point " << p.a << " " << p.b << ": cooked " << *cooked[i] << ", source " << p.value << ", bound " << bound;
      return s.str();
    };
    r.worst_error = std::max(r.worst_error, e);
    if (e > r.bound && ++r.violations == 1) r.first_violation = describe(r.bound);
    if (!lib || !node) {
      if (++r.above_recorded == 1) r.first_above_recorded = "the library sampler found no node where inspect answered";
      continue;
    }
    r.level_worst[node->key.level] = std::max(r.level_worst[node->key.level], e);
    ++r.level_points[node->key.level];
    const double recorded = double(node->geometric_error_m) + kMm;
    r.worst_excess_recorded = std::max(r.worst_excess_recorded, e - recorded);
    if (e > recorded && ++r.above_recorded == 1) r.first_above_recorded = describe(recorded);
  }
  return r;
}

std::string dem_name(const ::testing::TestParamInfo<RealDem>& info) { return info.param.name; }

}  // namespace

// The oracle comparison on the default cook of `d` (points shifted by `shift` samples); no points,
// with `why` saying so, when the fixture's archive is missing.
OracleResult oracle_on_default_cook(const RealDem& d, double shift, std::string& why) {
  const auto archive = default_archive(d);
  if (!std::filesystem::exists(archive)) {
    why = archive.string() + " missing (the cooker.cook fixture makes it)";
    return {};
  }
  return compare(d, archive, shift, why);
}

namespace {

// One test per DEM of kDems.
class RealData : public ::testing::TestWithParam<RealDem> {
 protected:
  // The oracle comparison on the default cook of this test's DEM (points shifted by `shift`
  // samples) into `r`; skips the test (IsSkipped()) when the DEM or its cooked archive is missing.
  void oracle_or_skip(double shift, OracleResult& r) {
    TERRAIN_REQUIRE_DATA(dem_path(GetParam()));
    std::string why;
    r = oracle_on_default_cook(GetParam(), shift, why);
    if (r.points == 0) GTEST_SKIP() << why;
  }
};

}  // namespace

// The accuracy test on the default cook: >= 10 000 random source samples with data, every
// one answered and within tolerance + half a step + 1 mm. One documented exception to the bound,
// asserted so that it shows when it changes: tahoe_highest (see kDems).
TEST_P(RealData, OracleAgreesWithinToleranceHalfStepAndAMillimetre) {
  const RealDem& d = GetParam();
  OracleResult r;
  oracle_or_skip(0.0, r);
  if (IsSkipped()) return;
  std::printf("%s: %zu points, %zu answered, worst |cooked - source| %.4f m (bound %.4f m), %zu out of bound, "
              "%zu edge points without terrain\n",
              d.name, r.points, r.answered, r.worst_error, r.bound, r.violations, r.missing_edge);
  EXPECT_GE(r.points, 10000u);
  // The default tolerance: 1/32 of the source spacing in the frame, at least 0.5 m (cooker/README.md,
  // "Levels"); the spacings are the DEMs' (3" at 19-22 N: 85.7-87.5 m across; 1" at 46 S: 21.7 m).
  const std::map<std::string, double> expected_tolerance = {
      {"tahoe_bare", 0.5},        {"tahoe_highest", 0.5},    {"slovenia", 0.5},          {"jacksboro", 74.573 / 32},
      {"kilauea", 30.0 / 32},     {"oetztal", 63.567 / 32},  {"n22w160", 85.747 / 32},   {"n19w155", 87.478 / 32},
      {"s46w066", 21.711 / 32},   {"puget", 160.0 / 32}};
  ASSERT_TRUE(expected_tolerance.count(d.name)) << d.name;
  EXPECT_NEAR(r.tolerance, expected_tolerance.at(d.name), 1e-3);
  // Every point with data answered, on the raster's edge and beside nodata too (SPEC section 10's
  // boundary rule, refinement along data edges to half the source spacing, the outer apron).
  EXPECT_EQ(r.answered, r.points) << r.missing_inner << " inner and " << r.missing_edge << " edge points without terrain";
  if (!d.lattice_limited) {
    EXPECT_EQ(r.violations, 0u) << r.first_violation;
  } else {
    // Known failure, measured: 30 % of the points beyond the bound, worst 15.8 m. Not the cooker's
    // sampling alone: a least-squares fit of every 0.5 m vertex to the samples (no reconstruction)
    // still left 3.2 m and 1.2 % beyond 0.5 m on a 120 x 120 sample patch.
    EXPECT_GT(r.violations, r.answered / 10) << "tahoe_highest now meets the bound more often: update kDems";
  }
}

// Negative control: the same comparison with every oracle point moved half a sample east must fail
// for DEMs with relief, so the bound does catch half-pixel shifts.
TEST_P(RealData, HalfSampleShiftBreaksTheBound) {
  const RealDem& d = GetParam();
  if (!d.relief || d.lattice_limited) GTEST_SKIP() << d.name << ": a half-sample shift cannot show here";
  OracleResult r;
  oracle_or_skip(0.5, r);
  if (IsSkipped()) return;
  std::printf("%s shifted half a sample: %zu of %zu points out of bound (worst %.3f m)\n", d.name, r.violations,
              r.answered, r.worst_error);
  EXPECT_GT(r.violations, r.answered / 100);
}

// The geometric error each node records (for screen-space LOD) is honest: no oracle point is
// further from the source than the recorded error of the node that answered it (+ 1 mm), on every
// DEM including tahoe_highest.
TEST_P(RealData, RecordedErrorsBoundEveryPoint) {
  const RealDem& d = GetParam();
  OracleResult r;
  oracle_or_skip(0.0, r);
  if (IsSkipped()) return;
  std::printf("%s: worst |cooked - source| - recorded node error %.4f m over %zu points\n", d.name,
              r.worst_excess_recorded, r.answered);
  EXPECT_GT(r.answered, 0u);
  EXPECT_EQ(r.above_recorded, 0u) << r.first_above_recorded;
}

// The cook report's per-level error (the fixture's --report file) against the GDAL oracle: for
// each level whose nodes answered oracle points, the report's error_max_m (over every source
// sample the level's nodes cover) is at least the worst error measured at those points, less 1 mm
// (float heights near 4 km). And close to it at the finest level with nodes: only there does every
// sample the level covers belong to a leaf that answers it (a coarser level's maximum may sit under
// finer nodes), so the oracle's random samples must find at least half of the report's maximum
// when >= 1000 of them land there (measured: tahoe_bare level 0 0.117 of 0.151 m, slovenia level 0
// 0.0075 m = 0.0075 m; at the tolerance that follows the source, Kilauea's finest level holds 116
// nodes on its cliffs, 514 points found 0.25 of its 0.53 m). Not where the finest level is the
// roots: nothing was refined, and the maximum sits on a few samples (N19W155's coast: 1.27 m, which
// 10000 points put at 0.15 m).
TEST_P(RealData, ReportLevelErrorsAgreeWithTheOracle) {
  const RealDem& d = GetParam();
  TERRAIN_REQUIRE_DATA(dem_path(d));
  nlohmann::json report;
  load_default_report(d, report);
  if (IsSkipped() || HasFatalFailure()) return;
  OracleResult r;
  oracle_or_skip(0.0, r);
  if (IsSkipped()) return;
  int levels_checked = 0, finest = kLevelCount;
  for (const auto& level : report["levels"])
    if (level["nodes"].get<int>() > 0) finest = std::min(finest, level["level"].get<int>());
  for (const auto& level : report["levels"]) {
    const int l = level["level"].get<int>();
    ASSERT_TRUE(l >= 0 && l < kLevelCount);
    const double reported = level["error_max_m"].get<double>();
    std::printf("%s level %d: report error_max %.4f m, oracle worst %.4f m over %zu points\n", d.name, l, reported,
                r.level_worst[size_t(l)], r.level_points[size_t(l)]);
    if (r.level_points[size_t(l)] == 0) continue;
    EXPECT_GE(reported, r.level_worst[size_t(l)] - kMm) << "level " << l;
    if (l == finest && l < kRootLevel && r.level_points[size_t(l)] >= 1000) {
      EXPECT_GE(r.level_worst[size_t(l)], 0.5 * reported) << "finest level " << l;
    }
    ++levels_checked;
  }
  EXPECT_GT(levels_checked, 0);
}

// The surface statistics of the fixture's --report file, against bounds that follow from the format
// (format/SPEC.md section 16) rather than from the cooker:
// - cones: 8 x 8 patches per node, so 0 < patches <= 64 nodes; every patch is at most a root
//   patch (2048 m / 8 = 256 m on a side) and the valid source samples under drawn triangles lie in
//   patches with triangles, so patches * 256^2 m^2 >= their area, each at least spacing_m^2 (halved
//   for geographic spacing varying over the DEM and the data's ragged edge);
// - a cone holds unit normals with z > 0, so its exact (smallest) half-angle is below 90 degrees;
//   the encoded cone also holds every normal, so it is no narrower than the exact one, and it is
//   stored as 255 steps of 90 degrees: a never-culling patch counts 90, so the encoded mean is at
//   least 90 * never_cull / patches, and at most 90; real relief is not a plane, so the exact
//   mean is positive;
// - normals are measured on every texel (132 x 132 per checked node), albedo per channel of opaque texels;
// - the per-layer CPU times are parts of the per-node surface time.
TEST_P(RealData, ReportStatesTheSurfaceStatistics) {
  const RealDem& d = GetParam();
  TERRAIN_REQUIRE_DATA(dem_path(d));
  nlohmann::json report;
  load_default_report(d, report);
  if (IsSkipped() || HasFatalFailure()) return;
  if (!report["output"]["surface_layers"].get<bool>()) GTEST_SKIP() << d.name << " is cooked heights-only";
  ASSERT_TRUE(report.contains("surface") && report["surface"].contains("cones")) << d.name << ": no cone statistics";
  const auto& surface = report["surface"];
  const auto& cones = surface["cones"];
  const double nodes = report["output"]["nodes"].get<double>();
  const double patches = cones["patches"].get<double>(), never = cones["patches_never_cull"].get<double>();
  const double exact = cones["exact_mean_deg"].get<double>(), encoded = cones["encoded_mean_deg"].get<double>();
  std::printf("%s: %.0f nodes, %.0f patches with triangles, %.0f never cull, mean half-angle %.2f exact, %.2f encoded\n",
              d.name, nodes, patches, never, exact, encoded);
  EXPECT_GT(patches, 0);
  EXPECT_LE(patches, nodes * kPatchesPerSide * kPatchesPerSide);
  const auto& source = report["source"];
  const double spacing = source["spacing_m"].get<double>();
  const double covered = source["valid_samples"].get<double>() - report["full_detail_error"]["uncovered_samples"].get<double>();
  const double root_patch_m = node_size_m(kRootLevel) / kPatchesPerSide;
  EXPECT_GE(patches * root_patch_m * root_patch_m, 0.5 * covered * spacing * spacing);
  EXPECT_GE(never, 0);
  EXPECT_LE(never, patches);
  EXPECT_GT(exact, 0.0);
  EXPECT_LT(exact, 90.0);
  EXPECT_GE(encoded, exact);
  EXPECT_LE(encoded, 90.0);
  EXPECT_GE(encoded, 90.0 * never / patches - 1e-9);

  // The default cook measures errors on a sample (--error-checks sample): one node in 8 by a hash of
  // its key (every DEM here has at least 36 nodes and at least one of them sampled); hole alpha on
  // every node.
  const double checked = surface["checked_nodes"].get<double>();
  EXPECT_EQ(surface["nodes"].get<double>(), nodes);
  EXPECT_GE(checked, 1.0);
  EXPECT_LE(checked, nodes);
  EXPECT_EQ(surface["normal_samples"].get<double>(), checked * kTexels * kTexels);
  const double max_deg = surface["normal_err_max_deg"].get<double>(), mean_deg = surface["normal_err_mean_deg"].get<double>();
  EXPECT_GT(max_deg, 0.0);  // 8-bit BC3 normals cannot be exact everywhere on real relief
  EXPECT_LE(mean_deg, max_deg);
  EXPECT_GT(surface["albedo_samples"].get<double>(), 0);
  EXPECT_LE(surface["albedo_samples"].get<double>(), 3 * checked * kTexels * kTexels);
  // Every albedo texel is either opaque (3 colour samples) or a hole, and hole alpha is exact
  // (format/SPEC.md: BC1 1-bit alpha marks holes): the opaque texels of the checked nodes and the
  // holes of all nodes cover at most every texel, at least the checked nodes' texels.
  const double opaque = surface["albedo_samples"].get<double>() / 3, holes = surface["albedo_hole_texels"].get<double>();
  EXPECT_LE(opaque + holes, nodes * kTexels * kTexels);
  EXPECT_GE(opaque + holes, checked * kTexels * kTexels);
  EXPECT_EQ(surface["albedo_alpha_mismatches"].get<uint64_t>(), 0u);
  double layer_cpu = 0;
  for (const char* layer : {"normals", "albedo", "splat", "cones"}) {
    const double s = surface["cpu_s"][layer].get<double>();
    EXPECT_GT(s, 0.0) << layer;
    layer_cpu += s;
  }
  EXPECT_LE(layer_cpu, report["time_s"]["cpu_surface"].get<double>() + 1e-3);
  // The finer split: the parts of each layer add up to its time, the parts of the encode stage (zstd
  // per section) to cpu_encode, and the per-node figures are the totals over the node count.
  const auto& parts = report["time_s"]["cpu_parts"];
  auto part = [&](const char* name) { return parts[name].get<double>(); };
  const double eps = 1e-9 * nodes + 1e-6;
  EXPECT_NEAR(part("splat_fields") + part("splat_rules"), surface["cpu_s"]["splat"].get<double>(), eps);
  EXPECT_NEAR(part("cones_normals") + part("cones_fit") + part("cones_bc3"), surface["cpu_s"]["cones"].get<double>(), eps);
  EXPECT_NEAR(part("normals_texels") + part("normals_bc3"), surface["cpu_s"]["normals"].get<double>(), eps);
  EXPECT_NEAR(part("albedo_bake") + part("albedo_bc1"), surface["cpu_s"]["albedo"].get<double>(), eps);
  EXPECT_GT(part("checks"), 0.0);
  EXPECT_LE(layer_cpu + part("checks"), report["time_s"]["cpu_surface"].get<double>() + 1e-3);
  double zstd = 0;
  for (const char* s : {"zstd_heights", "zstd_normals", "zstd_albedo", "zstd_splat", "zstd_cones"}) {
    EXPECT_GT(part(s), 0.0) << s;
    zstd += part(s);
  }
  EXPECT_NEAR(zstd, report["time_s"]["cpu_encode"].get<double>(), 1e-6);
  EXPECT_NEAR(report["time_s"]["cpu_ms_per_node"]["zstd_heights"].get<double>(), 1e3 * part("zstd_heights") / nodes, 1e-9);
  // Level by level: every level with nodes has its own figures, and the levels' CPU (ms per node
  // times the level's nodes) adds up to the cook's for every stage and part.
  for (const char* name : {"heights", "error", "surface", "encode", "total", "normals_bc3", "albedo_bc1", "splat_rules",
                           "zstd_heights", "zstd_normals"}) {
    double sum_ms = 0;
    for (const auto& level : report["levels"]) {
      const double n = level["nodes"].get<double>();
      const double ms = level["cpu_ms_per_node"][name].get<double>();
      if (n == 0) {
        EXPECT_EQ(ms, 0.0) << name;
      } else if (std::string_view(name) == "total") {
        EXPECT_GT(ms, 0.0) << "level " << level["level"];
      }
      sum_ms += ms * n;
    }
    const double whole_ms = report["time_s"]["cpu_ms_per_node"][name].get<double>() * nodes;
    EXPECT_NEAR(sum_ms, whole_ms, 1e-6 * whole_ms + 1e-6) << name;
  }
}

// Every shared edge and parent/child vertex of the archive: bit-identical float heights and
// identical hole flags (zero mismatches), over a non-trivial number of vertex pairs.
TEST_P(RealData, SeamsAreBitIdentical) {
  const RealDem& d = GetParam();
  TERRAIN_REQUIRE_DATA(dem_path(d));
  int walked = 0;
  for (const auto& archive : {default_archive(d)}) {
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

#endif

#if TERRAIN_REAL_SET_LARGE
// Cooking twice with 1 and 2 threads, every section included: identical bytes (no_sanitizer:
// two full default cooks of Kilauea).
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
