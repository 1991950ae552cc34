// The table of the cook options (cooker/src/session/cook_options_table.h): every CookOptions field
// is in it once, every plan option round-trips through a plan, per-process options stay out of it,
// and the cook info's options keep their keys and order.
//
// A new CookOptions field makes this file fail to compile (options_fields' structured binding
// names every field: "only N names provided for structured binding"); add the field there, to
// kFieldNames, to set_every_field and to the table.
#include <gtest/gtest.h>

#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>
#include <nlohmann/json.hpp>

#include "session/cook_options_table.h"
#include "units/plan_file.h"

namespace terrain::cook {
namespace {

using json = nlohmann::ordered_json;

// Every field of CookOptions, in declaration order: the binding only compiles with all of them.
auto options_fields(CookOptions& o) {
  auto& [inputs, output, overlap, tolerance_m, finest_level, height_step_m, threads, crs, frame, origin, spacing, height_scale, height_offset,
         height_scale_set, nodata_value, valid_range_m, memory_limit_bytes, block_roots, block_order, work_dir,
         unit_roots, raw_size, raw_type, raw_big_endian, tile_encoding, nodata, fill_max_samples, materials_path,
         surface_quality, error_checks, normals, bc_rdo, albedo_path, holes_path, landcover_path, landcover_table_path,
         heights_only, force, overview_levels, zstd_level, surface_zstd_level] = o;
  return std::tie(inputs, output, overlap, tolerance_m, finest_level, height_step_m, threads, crs, frame, origin, spacing, height_scale,
                  height_offset, height_scale_set, nodata_value, valid_range_m, memory_limit_bytes, block_roots,
                  block_order, work_dir, unit_roots, raw_size, raw_type, raw_big_endian, tile_encoding, nodata,
                  fill_max_samples, materials_path, surface_quality, error_checks, normals, bc_rdo, albedo_path, holes_path,
                  landcover_path, landcover_table_path, heights_only, force, overview_levels, zstd_level,
                  surface_zstd_level);
}
const std::vector<std::string> kFieldNames = {
    "inputs", "output", "overlap", "tolerance_m", "finest_level", "height_step_m", "threads", "crs", "frame", "origin", "spacing", "height_scale",
    "height_offset", "height_scale_set", "nodata_value", "valid_range_m", "memory_limit_bytes", "block_roots",
    "block_order", "work_dir", "unit_roots", "raw_size", "raw_type", "raw_big_endian", "tile_encoding", "nodata",
    "fill_max_samples", "materials_path", "surface_quality", "error_checks", "normals", "bc_rdo", "albedo_path", "holes_path",
    "landcover_path", "landcover_table_path", "heights_only", "force", "overview_levels", "zstd_level",
    "surface_zstd_level"};
constexpr size_t kFieldCount = std::tuple_size_v<decltype(options_fields(std::declval<CookOptions&>()))>;

// Per field (declaration order), whether `a` and `b` hold the same value.
std::vector<bool> same_fields(CookOptions a, CookOptions b) {
  const auto ta = options_fields(a), tb = options_fields(b);
  std::vector<bool> same;
  [&]<size_t... I>(std::index_sequence<I...>) {
    (same.push_back(std::get<I>(ta) == std::get<I>(tb)), ...);
  }(std::make_index_sequence<kFieldCount>{});
  return same;
}

// Every field away from its default.
CookOptions set_every_field() {
  CookOptions o;
  o.inputs = {"a.tif", "dir/b.vrt"};
  o.output = "out.terrain";
  o.overlap = OverlapRule::list;
  o.tolerance_m = 1.25;
  o.finest_level = 3;
  o.height_step_m = 0.0625;
  o.threads = 7;
  o.crs = "EPSG:32633";
  o.frame = "tm:lon0=15";
  o.origin = std::array<double, 2>{10.5, -20.25};
  o.spacing = std::array<double, 2>{2.0, 3.0};
  o.height_scale = 0.3048;
  o.height_offset = -12.5;
  o.height_scale_set = true;
  o.nodata_value = -9999.0;
  o.valid_range_m = {-500.0, 5000.0};
  o.memory_limit_bytes = uint64_t(3) << 30;
  o.block_roots = 4;
  o.block_order = 99;
  o.work_dir = "wd";
  o.unit_roots = 2;
  o.raw_size = {1025, 513};
  o.raw_type = "i16";
  o.raw_big_endian = true;
  o.tile_encoding = "mapbox";
  o.nodata = NodataPolicy::fill;
  o.fill_max_samples = 12345;
  o.materials_path = "rules.json";
  o.surface_quality = SurfaceQuality::best;
  o.error_checks = ErrorChecks::all;
  o.normals = NormalsMode::stored;
  o.bc_rdo = 5.5f;
  o.albedo_path = "ortho.tif";
  o.holes_path = "holes.tif";
  o.landcover_path = "lc.tif";
  o.landcover_table_path = "lc.json";
  o.heights_only = true;
  o.force = true;
  o.overview_levels = OverviewMode::off;
  o.zstd_level = 12;
  o.surface_zstd_level = 3;
  return o;
}

const CookOptionRow& row(const std::string& field) {
  for (const CookOptionRow& r : cook_option_rows())
    if (field == r.field) return r;
  ADD_FAILURE() << field << ": not in the table";
  static const CookOptionRow none{};
  return none;
}

TEST(CookOptionsTable, ListsEveryFieldOnce) {
  ASSERT_EQ(kFieldNames.size(), kFieldCount);
  std::multiset<std::string> in_table;
  for (const CookOptionRow& r : cook_option_rows()) in_table.insert(r.field);
  EXPECT_EQ(in_table, std::multiset<std::string>(kFieldNames.begin(), kFieldNames.end()));
  std::set<std::string> plan_keys, info_keys;
  std::set<int> ranks;
  for (const CookOptionRow& r : cook_option_rows()) {
    EXPECT_EQ(r.scope == OptionScope::process, r.plan_key == nullptr) << r.field;
    if (r.plan_key) {
      EXPECT_TRUE(plan_keys.insert(r.plan_key).second) << r.field;
      EXPECT_TRUE(r.put && r.get) << r.field;
    }
    if (r.info_key) {
      EXPECT_TRUE(info_keys.insert(r.info_key).second) << r.field;
      EXPECT_TRUE(ranks.insert(r.info_rank).second) << r.field;
      EXPECT_NE(r.info_put, nullptr) << r.field;
    }
  }
  EXPECT_EQ(plan_keys.size(), 35u);  // the 41 fields less output, threads, work dir, unit size, block size and order
  EXPECT_EQ(info_keys.size(), 23u);
}

TEST(CookOptionsTable, EveryPlanOptionRoundTripsThroughAPlan) {
  const CookOptions set = set_every_field();
  const CookOptions defaults;
  // The test's own values must all differ from the defaults, or a field lost on the way would pass.
  const std::vector<bool> unchanged = same_fields(set, defaults);
  for (size_t i = 0; i < kFieldCount; ++i) EXPECT_FALSE(unchanged[i]) << kFieldNames[i] << " is at its default";

  // Through the plan's text, as `unit` and `merge` read it.
  const std::string text = json{{"options", plan_options_json(set)}}.dump(1);
  const CookOptions back = options_of_plan_json(json::parse(text).at("options"));
  const std::vector<bool> kept = same_fields(back, set), reset = same_fields(back, defaults);
  for (size_t i = 0; i < kFieldCount; ++i) {
    if (row(kFieldNames[i]).scope == OptionScope::process)
      EXPECT_TRUE(reset[i]) << kFieldNames[i] << ": per process, yet read back from the plan";
    else
      EXPECT_TRUE(kept[i]) << kFieldNames[i] << ": lost in the plan";
  }
  // And the defaults, which leave some keys out (plans written before those options).
  const CookOptions back_defaults = options_of_plan_json(json::parse(plan_options_json(defaults).dump()));
  for (bool same : same_fields(back_defaults, defaults)) EXPECT_TRUE(same);
  // The input paths of "resolved_paths".
  const CookOptions paths = with_input_paths_of(defaults, json::parse(input_paths_json(set).dump()));
  EXPECT_EQ(paths.inputs, set.inputs);
  EXPECT_EQ(paths.landcover_table_path, set.landcover_table_path);
  EXPECT_EQ(paths.tolerance_m, defaults.tolerance_m);
}

TEST(CookOptionsTable, PlanKeysKeepTheirOrderAndForms) {
  const json j = plan_options_json(set_every_field());
  std::vector<std::string> keys;
  for (const auto& [k, v] : j.items()) keys.push_back(k);
  const std::vector<std::string> expected = {
      "inputs", "tolerance_m", "finest_level", "crs", "frame", "origin", "spacing", "height_scale", "height_offset",
      "height_scale_set", "nodata_value", "valid_range_m", "memory_limit_bytes", "raw_size", "raw_type",
      "raw_big_endian", "tile_encoding", "nodata", "fill_max_samples", "materials", "surface_quality", "bc_rdo",
      "error_checks", "albedo", "holes", "landcover", "landcover_table", "heights_only", "force", "zstd_level",
      "surface_zstd_level", "overview_levels", "height_step_m", "normals", "overlap"};  // new keys go last: plans already written
  EXPECT_EQ(keys, expected);
  EXPECT_EQ(j.at("nodata"), "fill");
  EXPECT_EQ(j.at("surface_quality"), 2);
  EXPECT_EQ(j.at("error_checks"), "all");
  EXPECT_EQ(j.at("overview_levels"), 2);
  EXPECT_EQ(j.at("normals"), "stored");
  EXPECT_EQ(j.at("overlap"), "list");
  // At their defaults, the options added after the first plans are left out or null.
  const json d = plan_options_json(CookOptions{});
  EXPECT_FALSE(d.contains("height_scale_set"));
  EXPECT_FALSE(d.contains("error_checks"));
  EXPECT_FALSE(d.contains("normals"));
  EXPECT_FALSE(d.contains("overlap"));
  EXPECT_TRUE(d.at("origin").is_null());
  EXPECT_TRUE(d.at("nodata_value").is_null());
  EXPECT_EQ(d.at("bc_rdo"), 28.0);
  EXPECT_FALSE(plan_options_json(CookOptions{}, /*budget=*/false).contains("memory_limit_bytes"));
}

TEST(CookOptionsTable, SamePlanOptionsIgnoresOnlyWhatChangesNoByte) {
  const CookOptions a = set_every_field();
  CookOptions b = a;
  b.threads = 1;
  b.output = "elsewhere.terrain";
  b.memory_limit_bytes = uint64_t(1) << 28;
  b.block_roots = 1;
  EXPECT_TRUE(same_plan_options(a, b));
  b.error_checks = ErrorChecks::sample;
  EXPECT_FALSE(same_plan_options(a, b));
}

TEST(CookOptionsTable, CookInfoRecordsItsOptionsInTheArchivesOrder) {
  // The bytes every archive of default options holds (the cook info, SPEC section 6).
  EXPECT_EQ(cook_info_options_json(CookOptions{}).dump(),
            R"({"tolerance_m":0.0,"finest_level":-1,"crs":"","frame":"","height_scale":1.0,"height_offset":0.0,)"
            R"("nodata":"auto","fill_max_samples":4096,"materials":"","albedo":"","holes":"","landcover":"",)"
            R"("landcover_table":"","heights_only":false,"zstd_level":9,"surface_zstd_level":6,"bc_rdo":28.0})");
  CookOptions o;
  o.bc_rdo = 0;
  o.spacing = std::array<double, 2>{2.0, 2.0};
  o.nodata_value = -32768.0;
  const json j = cook_info_options_json(o);
  EXPECT_FALSE(j.contains("bc_rdo"));
  EXPECT_FALSE(j.contains("origin"));
  EXPECT_EQ(j.at("spacing"), json::array({2.0, 2.0}));
  EXPECT_EQ(j.at("nodata_value"), -32768.0);
  EXPECT_EQ(std::prev(j.end()).key(), "nodata_value");
  // --height-step (issue 50) is recorded only when given, after every older key.
  EXPECT_FALSE(j.contains("height_step_m"));
  o.height_step_m = 0.03125;
  const json k = cook_info_options_json(o);
  EXPECT_EQ(std::prev(k.end()).key(), "height_step_m");
  EXPECT_EQ(k.at("height_step_m"), 0.03125);
  // --normals stored (SPEC 16.7's codec 4 is the default) likewise, after it.
  EXPECT_FALSE(k.contains("normals"));
  o.normals = NormalsMode::stored;
  const json n = cook_info_options_json(o);
  EXPECT_EQ(std::prev(n.end()).key(), "normals");
  EXPECT_EQ(n.at("normals"), "stored");
  // --overlap list (issue 51: finer wins by default) likewise, after it.
  EXPECT_FALSE(n.contains("overlap"));
  o.overlap = OverlapRule::list;
  const json v = cook_info_options_json(o);
  EXPECT_EQ(std::prev(v.end()).key(), "overlap");
  EXPECT_EQ(v.at("overlap"), "list");
}

TEST(CookOptionsTable, EnumNamesRoundTrip) {
  EXPECT_STREQ(enum_name(NodataPolicy::automatic), "auto");
  EXPECT_EQ(enum_of<NodataPolicy>("hole"), NodataPolicy::hole);
  EXPECT_EQ(enum_of<NodataPolicy>("hol"), std::nullopt);
  EXPECT_EQ(enum_spellings<SurfaceQuality>(), (std::vector<std::string>{"fast", "balanced", "best"}));
  EXPECT_EQ(enum_spellings<OverviewMode>(), (std::vector<std::string>{"auto", "on", "off"}));
  EXPECT_EQ(enum_spellings<ErrorChecks>(), (std::vector<std::string>{"sample", "all"}));
  auto round_trips = []<class E>(E) {
    for (const EnumName<E>& n : enum_names<E>()) EXPECT_EQ(enum_of<E>(enum_name(n.value)), n.value) << n.name;
  };
  round_trips(NodataPolicy{});
  round_trips(SurfaceQuality{});
  round_trips(ErrorChecks{});
  round_trips(OverviewMode{});
}

}  // namespace
}  // namespace terrain::cook
