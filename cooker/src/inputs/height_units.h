// Units of heights (terrain/height_unit.h HeightUnit): the names the cooker converts to metres, and the
// JSON record of an input's unit shared by the cook report, the plan and the cook info.
#pragma once
#include <nlohmann/json.hpp>
#include <string>

#include "terrain/height_unit.h"

namespace terrain::cook {

// Metres per unit named `name` (case and surrounding blanks ignored): metre, international foot
// (0.3048), US survey foot (1200 / 3937), centimetre, millimetre, in the spellings GDAL and PROJ
// use ("m", "metre", "ft", "foot", "US survey foot", "us-ft", "ftUS", "cm", ...); NaN for any other.
double height_unit_metres(const std::string& name);

// {"unit", "declared_by", "unit_m", "scale", "scale_from"}; scale_from is "--height-scale",
// "declared unit" or "none declared: metres". A NaN unit_m (unknown unit) is null.
nlohmann::ordered_json height_unit_json(const HeightUnit& u);
// The inverse of height_unit_json; throws (nlohmann) on a malformed record.
HeightUnit height_unit_of_json(const nlohmann::ordered_json& j);

}  // namespace terrain::cook
