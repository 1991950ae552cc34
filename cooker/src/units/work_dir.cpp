#include "units/work_dir.h"

#include <filesystem>
#include <fmt/format.h>

#include "terrain/cook.h"
#include "units/plan_file.h"

namespace terrain::cook {

std::string plan_file(const std::string& work_dir) { return work_dir + "/plan.json"; }
std::string units_dir(const std::string& work_dir) { return work_dir + "/units"; }
std::string inputs_file(const std::string& work_dir, const std::string& fingerprint) {
  return fmt::format("{}/inputs-{}.json", work_dir, fingerprint);
}
std::string unit_file(const std::string& work_dir, uint32_t index) {
  return fmt::format("{}/unit-{}.tcu", units_dir(work_dir), index);
}
std::string unit_vrt_file(const std::string& work_dir, const UnitPlan& unit) {
  return fmt::format("{}/unit-{}-{}.vrt", units_dir(work_dir), unit.index, unit.fingerprint);
}

std::string unit_inputs_file(const std::string& work_dir, const UnitPlan& unit) {
  return fmt::format("{}/unit-{}-{}.inputs.json", units_dir(work_dir), unit.index, unit.fingerprint);
}

// ---- terrain/cook.h ----
bool work_dir_owns(const std::string& work_dir, const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path dir = fs::weakly_canonical(fs::absolute(work_dir, ec), ec);
  if (ec) return false;
  const fs::path p = fs::weakly_canonical(fs::absolute(path, ec), ec);
  if (ec) return false;
  const std::string name = p.filename().string();
  if (p.parent_path() == dir / "units") return true;
  return p.parent_path() == dir &&
         (name.starts_with("plan.json") || (name.starts_with("inputs") && name.find(".json") != std::string::npos));
}

}  // namespace terrain::cook
