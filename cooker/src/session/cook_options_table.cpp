#include "session/cook_options_table.h"

#include <algorithm>
#include <array>
#include <type_traits>
#include <nlohmann/json.hpp>

namespace terrain::cook {
namespace {

using json = nlohmann::ordered_json;
template <auto M>
using FieldOf = std::remove_cvref_t<decltype(std::declval<CookOptions&>().*M)>;

// ---- how a field is written into a JSON object and read back ----
// The value as it is.
template <auto M>
void put_value(const CookOptions& o, const char* key, json& j) {
  j[key] = o.*M;
}
template <auto M>
void get_value(const json& j, const char* key, CookOptions& o) {
  o.*M = j.at(key).get<FieldOf<M>>();
}
// An optional: null when unset (the plan); left out when unset (the cook info).
template <auto M>
void put_or_null(const CookOptions& o, const char* key, json& j) {
  j[key] = o.*M ? json(*(o.*M)) : json(nullptr);
}
template <auto M>
void put_if_set(const CookOptions& o, const char* key, json& j) {
  if (o.*M) j[key] = *(o.*M);
}
template <auto M>
void get_or_null(const json& j, const char* key, CookOptions& o) {
  if (!j.at(key).is_null()) o.*M = j.at(key).get<typename FieldOf<M>::value_type>();
}
// Left out at zero (false, 0, off): plans and archives from before the option keep their bytes.
template <auto M>
void put_if_positive(const CookOptions& o, const char* key, json& j) {
  if (o.*M > FieldOf<M>{}) j[key] = o.*M;
}
template <auto M>
void get_or_zero(const json& j, const char* key, CookOptions& o) {
  o.*M = j.value(key, FieldOf<M>{});
}
// An enum by name.
template <auto M>
void put_name(const CookOptions& o, const char* key, json& j) {
  j[key] = enum_name(o.*M);
}
template <auto M>
void get_name(const json& j, const char* key, CookOptions& o) {
  o.*M = enum_of<FieldOf<M>>(j.at(key).get<std::string>()).value_or(FieldOf<M>{});
}
// An enum by name, left out at its first value (absent: that value).
template <auto M>
void put_name_unless_first(const CookOptions& o, const char* key, json& j) {
  if (o.*M != FieldOf<M>{}) j[key] = enum_name(o.*M);
}
template <auto M>
void get_name_or_first(const json& j, const char* key, CookOptions& o) {
  o.*M = j.contains(key) ? enum_of<FieldOf<M>>(j.at(key).get<std::string>()).value_or(FieldOf<M>{}) : FieldOf<M>{};
}
// An enum by number (absent: 0 with get_number_or_zero).
template <auto M>
void put_number(const CookOptions& o, const char* key, json& j) {
  j[key] = int(o.*M);
}
template <auto M>
void get_number(const json& j, const char* key, CookOptions& o) {
  o.*M = FieldOf<M>(j.at(key).get<int>());
}
template <auto M>
void get_number_or_zero(const json& j, const char* key, CookOptions& o) {
  o.*M = FieldOf<M>(j.value(key, 0));
}

using O = CookOptions;
constexpr OptionScope kPlan = OptionScope::plan, kBudget = OptionScope::plan_budget, kProcess = OptionScope::process;

// A field the plan holds as it is and the cook info records as it is.
template <auto M>
constexpr CookOptionRow both(const char* field, const char* flag, const char* key, int rank, bool path = false) {
  return {field, flag, kPlan, key, key, rank, path, put_value<M>, get_value<M>, put_value<M>};
}
// A field the plan holds as it is; not recorded in the cook info.
template <auto M>
constexpr CookOptionRow plan_only(const char* field, const char* flag, const char* key) {
  return {field, flag, kPlan, key, nullptr, -1, false, put_value<M>, get_value<M>, nullptr};
}
// A field of the process: not in the plan's options, not in the cook info.
constexpr CookOptionRow process(const char* field, const char* flag) {
  return {field, flag, kProcess, nullptr, nullptr, -1, false, nullptr, nullptr, nullptr};
}

// In the plan's order (that of plans already written: CookOptions declares error_checks
// before bc_rdo and overview_levels before the zstd levels); the cook info's is info_rank's.
const CookOptionRow kRows[] = {
    {"inputs", "inputs", kPlan, "inputs", nullptr, -1, true, put_value<&O::inputs>, get_value<&O::inputs>, nullptr},
    process("output", "-o,--output"),
    both<&O::tolerance_m>("tolerance_m", "--tolerance", "tolerance_m", 0),
    both<&O::finest_level>("finest_level", "--finest-level", "finest_level", 1),
    process("threads", "--threads"),
    both<&O::crs>("crs", "--crs", "crs", 2),
    both<&O::frame>("frame", "--frame", "frame", 3),
    {"origin", "--origin", kPlan, "origin", "origin", 17, false, put_or_null<&O::origin>, get_or_null<&O::origin>,
     put_if_set<&O::origin>},
    {"spacing", "--spacing", kPlan, "spacing", "spacing", 18, false, put_or_null<&O::spacing>,
     get_or_null<&O::spacing>, put_if_set<&O::spacing>},
    both<&O::height_scale>("height_scale", "--height-scale", "height_scale", 4),
    both<&O::height_offset>("height_offset", "--height-offset", "height_offset", 5),
    {"height_scale_set", "--height-scale", kPlan, "height_scale_set", nullptr, -1, false,
     put_if_positive<&O::height_scale_set>, get_or_zero<&O::height_scale_set>, nullptr},
    {"nodata_value", "--nodata-value", kPlan, "nodata_value", "nodata_value", 19, false,
     put_or_null<&O::nodata_value>, get_or_null<&O::nodata_value>, put_if_set<&O::nodata_value>},
    plan_only<&O::valid_range_m>("valid_range_m", "--valid-range", "valid_range_m"),
    {"memory_limit_bytes", "--memory-limit", kBudget, "memory_limit_bytes", nullptr, -1, false,
     put_value<&O::memory_limit_bytes>, get_value<&O::memory_limit_bytes>, nullptr},
    process("block_roots", "--block-roots"),
    process("block_order", "--block-order"),
    process("work_dir", "--work-dir"),
    process("unit_roots", "--unit-roots"),  // the plan keeps its unit size in "grid"
    plan_only<&O::raw_size>("raw_size", "--raw-size", "raw_size"),
    plan_only<&O::raw_type>("raw_type", "--raw-type", "raw_type"),
    plan_only<&O::raw_big_endian>("raw_big_endian", "--raw-big-endian", "raw_big_endian"),
    plan_only<&O::tile_encoding>("tile_encoding", "--tile-encoding", "tile_encoding"),
    {"nodata", "--nodata", kPlan, "nodata", "nodata", 6, false, put_name<&O::nodata>, get_name<&O::nodata>,
     put_name<&O::nodata>},
    both<&O::fill_max_samples>("fill_max_samples", "--fill-max", "fill_max_samples", 7),
    both<&O::materials_path>("materials_path", "--materials", "materials", 8, true),
    {"surface_quality", "--bc-quality", kPlan, "surface_quality", nullptr, -1, false,
     put_number<&O::surface_quality>, get_number<&O::surface_quality>, nullptr},
    {"bc_rdo", "--bc-rdo", kPlan, "bc_rdo", "bc_rdo", 16, false, put_if_positive<&O::bc_rdo>,
     get_or_zero<&O::bc_rdo>, put_if_positive<&O::bc_rdo>},
    {"error_checks", "--error-checks", kPlan, "error_checks", nullptr, -1, false,
     put_name_unless_first<&O::error_checks>, get_name_or_first<&O::error_checks>, nullptr},
    both<&O::albedo_path>("albedo_path", "--albedo", "albedo", 9, true),
    both<&O::holes_path>("holes_path", "--holes", "holes", 10, true),
    both<&O::landcover_path>("landcover_path", "--landcover", "landcover", 11, true),
    both<&O::landcover_table_path>("landcover_table_path", "--landcover-table", "landcover_table", 12, true),
    both<&O::heights_only>("heights_only", "--heights-only", "heights_only", 13),
    plan_only<&O::force>("force", "--force", "force"),
    both<&O::zstd_level>("zstd_level", "", "zstd_level", 14),
    both<&O::surface_zstd_level>("surface_zstd_level", "", "surface_zstd_level", 15),
    {"overview_levels", "--overview-levels", kPlan, "overview_levels", nullptr, -1, false,
     put_number<&O::overview_levels>, get_number_or_zero<&O::overview_levels>, nullptr},
    {"height_step_m", "--height-step", kPlan, "height_step_m", "height_step_m", 20, false,
     put_if_positive<&O::height_step_m>, get_or_zero<&O::height_step_m>, put_if_positive<&O::height_step_m>},
    {"normals", "--normals", kPlan, "normals", "normals", 21, false, put_name_unless_first<&O::normals>,
     get_name_or_first<&O::normals>, put_name_unless_first<&O::normals>},
    {"overlap", "--overlap", kPlan, "overlap", "overlap", 22, false, put_name_unless_first<&O::overlap>,
     get_name_or_first<&O::overlap>, put_name_unless_first<&O::overlap>},
};

constexpr EnumName<NodataPolicy> kNodataNames[] = {
    {NodataPolicy::automatic, "auto"}, {NodataPolicy::hole, "hole"}, {NodataPolicy::fill, "fill"}};
constexpr EnumName<SurfaceQuality> kQualityNames[] = {
    {SurfaceQuality::fast, "fast"}, {SurfaceQuality::balanced, "balanced"}, {SurfaceQuality::best, "best"}};
constexpr EnumName<ErrorChecks> kErrorCheckNames[] = {{ErrorChecks::sample, "sample"}, {ErrorChecks::all, "all"}};
constexpr EnumName<NormalsMode> kNormalsNames[] = {{NormalsMode::derived, "derived"}, {NormalsMode::stored, "stored"}};
constexpr EnumName<OverlapRule> kOverlapNames[] = {{OverlapRule::finer, "finer"}, {OverlapRule::list, "list"}};
constexpr EnumName<OverviewMode> kOverviewNames[] = {
    {OverviewMode::automatic, "auto"}, {OverviewMode::on, "on"}, {OverviewMode::off, "off"}};

}  // namespace

std::span<const CookOptionRow> cook_option_rows() { return kRows; }

json plan_options_json(const CookOptions& o, bool budget) {
  json j = json::object();
  for (const CookOptionRow& r : kRows)
    if (r.scope == OptionScope::plan || (budget && r.scope == OptionScope::plan_budget)) r.put(o, r.plan_key, j);
  return j;
}

CookOptions options_of_plan_json(const json& j) {
  CookOptions o;
  for (const CookOptionRow& r : kRows)
    if (r.plan_key) r.get(j, r.plan_key, o);
  return o;
}

json input_paths_json(const CookOptions& o) {
  json j = json::object();
  for (const CookOptionRow& r : kRows)
    if (r.input_path) r.put(o, r.plan_key, j);
  return j;
}

CookOptions with_input_paths_of(CookOptions o, const json& j) {
  for (const CookOptionRow& r : kRows)
    if (r.input_path) r.get(j, r.plan_key, o);
  return o;
}

json cook_info_options_json(const CookOptions& o) {
  std::vector<const CookOptionRow*> recorded;
  for (const CookOptionRow& r : kRows)
    if (r.info_key) recorded.push_back(&r);
  std::sort(recorded.begin(), recorded.end(),
            [](const CookOptionRow* a, const CookOptionRow* b) { return a->info_rank < b->info_rank; });
  json j = json::object();
  for (const CookOptionRow* r : recorded) r->info_put(o, r->info_key, j);
  return j;
}

template <>
std::span<const EnumName<NodataPolicy>> enum_names<NodataPolicy>() {
  return kNodataNames;
}
template <>
std::span<const EnumName<SurfaceQuality>> enum_names<SurfaceQuality>() {
  return kQualityNames;
}
template <>
std::span<const EnumName<ErrorChecks>> enum_names<ErrorChecks>() {
  return kErrorCheckNames;
}
template <>
std::span<const EnumName<NormalsMode>> enum_names<NormalsMode>() {
  return kNormalsNames;
}
template <>
std::span<const EnumName<OverlapRule>> enum_names<OverlapRule>() {
  return kOverlapNames;
}
template <>
std::span<const EnumName<OverviewMode>> enum_names<OverviewMode>() {
  return kOverviewNames;
}

}  // namespace terrain::cook
