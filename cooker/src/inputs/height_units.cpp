#include "inputs/height_units.h"

#include <algorithm>
#include <cctype>
#include <cmath>

namespace terrain::cook {

double height_unit_metres(const std::string& name) {
  std::string n;
  for (unsigned char c : name) n.push_back(char(std::tolower(c)));
  const auto blank = [](unsigned char c) { return std::isspace(c) != 0; };
  n.erase(n.begin(), std::find_if_not(n.begin(), n.end(), blank));
  n.erase(std::find_if_not(n.rbegin(), n.rend(), blank).base(), n.end());
  struct Known {
    const char* name;
    double metres;
  };
  static const Known kKnown[] = {
      {"m", 1.0},
      {"metre", 1.0},
      {"metres", 1.0},
      {"meter", 1.0},
      {"meters", 1.0},
      {"ft", 0.3048},
      {"foot", 0.3048},
      {"feet", 0.3048},
      {"international foot", 0.3048},
      {"international feet", 0.3048},
      {"foot (international)", 0.3048},
      {"us survey foot", 1200.0 / 3937.0},
      {"us survey feet", 1200.0 / 3937.0},
      {"us-ft", 1200.0 / 3937.0},
      {"us_ft", 1200.0 / 3937.0},
      {"ftus", 1200.0 / 3937.0},
      {"ft_us", 1200.0 / 3937.0},
      {"foot_us", 1200.0 / 3937.0},
      {"us foot", 1200.0 / 3937.0},
      {"us feet", 1200.0 / 3937.0},
      {"survey foot", 1200.0 / 3937.0},
      {"cm", 0.01},
      {"centimetre", 0.01},
      {"centimetres", 0.01},
      {"centimeter", 0.01},
      {"centimeters", 0.01},
      {"mm", 0.001},
      {"millimetre", 0.001},
      {"millimetres", 0.001},
      {"millimeter", 0.001},
      {"millimeters", 0.001},
  };
  for (const Known& k : kKnown)
    if (n == k.name) return k.metres;
  return NAN;
}

nlohmann::ordered_json height_unit_json(const HeightUnit& u) {
  nlohmann::ordered_json j;
  j["unit"] = u.declared;
  j["declared_by"] = u.declared_by;
  j["unit_m"] = std::isfinite(u.declared_m) ? nlohmann::ordered_json(u.declared_m) : nlohmann::ordered_json(nullptr);
  j["scale"] = u.scale;
  j["scale_from"] = u.scale_from_flag ? "--height-scale" : u.declared.empty() ? "none declared: metres" : "declared unit";
  return j;
}

HeightUnit height_unit_of_json(const nlohmann::ordered_json& j) {
  HeightUnit u;
  u.declared = j.at("unit").get<std::string>();
  u.declared_by = j.at("declared_by").get<std::string>();
  u.declared_m = j.at("unit_m").is_null() ? NAN : j.at("unit_m").get<double>();
  u.scale = j.at("scale").get<double>();
  u.scale_from_flag = j.at("scale_from").get<std::string>() == "--height-scale";
  return u;
}

}  // namespace terrain::cook
