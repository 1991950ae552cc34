// One table of CookOptions (terrain/cook.h): for every field its command-line flag, its key in the
// plan (plan.json "options", format/SPEC.md section 18), its key in the provenance the archive
// stores (the cook info's "options", cook_session.h) or none, and whether it is a decision of the
// plan or per process; and the names of the options' enums, which the command line, the plan and
// the cook info spell alike. The plan and the cook info are written from this table and the plan
// read back from it, so an option cannot be forgotten in one of them (tests/cooker/
// test_cook_options_table.cpp round-trips every field through a plan and fails to compile when
// CookOptions gains a field the table does not list).
//
// The command line (tools/terrain_cook_main.cpp) defines its flags by hand, for their validators,
// defaults and help texts; it takes the enums' spellings from here.
#pragma once
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>
#include <nlohmann/json_fwd.hpp>

#include "terrain/cook.h"

namespace terrain::cook {

enum class OptionScope : uint8_t {
  plan,         // a decision of the plan: in plan.json and its fingerprint; every unit cooks with the plan's
  plan_budget,  // in plan.json (the units use the plan's) but changes no byte: not in its fingerprint
  // Per process (each `unit` and `merge` gives its own, or the plan keeps it elsewhere): not in
  // plan.json's options.
  process,
};

struct CookOptionRow {
  const char* field;     // the CookOptions member
  const char* flag;      // terrain-cook's flag ("" for none; "inputs": the positional arguments)
  OptionScope scope;
  const char* plan_key;  // key in plan.json's "options" (nullptr: process scope)
  const char* info_key;  // key in the cook info's "options" (nullptr: not recorded)
  int info_rank;         // place of info_key in the cook info (its order is fixed by the archives written)
  bool input_path;       // an input file's path: plan.json's "resolved_paths" holds it made absolute
  // The value into / out of a JSON object under `key`. put may leave the key out (a value that
  // plans and archives written before the option existed lacked: get reads its absence as that
  // value). info_put: the cook info's form (an unset optional is left out there, null in the plan).
  void (*put)(const CookOptions& o, const char* key, nlohmann::ordered_json& j);
  void (*get)(const nlohmann::ordered_json& j, const char* key, CookOptions& o);
  void (*info_put)(const CookOptions& o, const char* key, nlohmann::ordered_json& j);
};

// Every field of CookOptions, in the order of plan.json's keys.
std::span<const CookOptionRow> cook_option_rows();

// plan.json's "options": every plan-scope field (with `budget`, the plan_budget ones too), in the
// table's order. The plan's fingerprint and same_plan_options (plan_file.h) hash / compare it
// without the budget.
nlohmann::ordered_json plan_options_json(const CookOptions& o, bool budget = true);
// The options of a plan back (process-scope fields at their defaults); throws on a malformed one.
CookOptions options_of_plan_json(const nlohmann::ordered_json& j);
// plan.json's "resolved_paths": the input_path fields of `o`, and `o` with those of `j`.
nlohmann::ordered_json input_paths_json(const CookOptions& o);
CookOptions with_input_paths_of(CookOptions o, const nlohmann::ordered_json& j);
// The cook info's "options" (the provenance stored in the archive).
nlohmann::ordered_json cook_info_options_json(const CookOptions& o);

// ---- the enums' names ----
template <class E>
struct EnumName {
  E value;
  const char* name;
};
// Every value of E with its name; the first is the default.
template <class E>
std::span<const EnumName<E>> enum_names();
template <>
std::span<const EnumName<NodataPolicy>> enum_names<NodataPolicy>();
template <>
std::span<const EnumName<SurfaceQuality>> enum_names<SurfaceQuality>();
template <>
std::span<const EnumName<ErrorChecks>> enum_names<ErrorChecks>();
template <>
std::span<const EnumName<NormalsMode>> enum_names<NormalsMode>();
template <>
std::span<const EnumName<OverlapRule>> enum_names<OverlapRule>();
template <>
std::span<const EnumName<OverviewMode>> enum_names<OverviewMode>();

template <class E>
const char* enum_name(E value) {
  for (const EnumName<E>& n : enum_names<E>())
    if (n.value == value) return n.name;
  return "?";
}
template <class E>
std::optional<E> enum_of(std::string_view name) {
  for (const EnumName<E>& n : enum_names<E>())
    if (name == n.name) return n.value;
  return std::nullopt;
}
// The names, in the table's order (the command line's choices).
template <class E>
std::vector<std::string> enum_spellings() {
  std::vector<std::string> v;
  for (const EnumName<E>& n : enum_names<E>()) v.emplace_back(n.name);
  return v;
}

}  // namespace terrain::cook
