// The unit an input declares for its heights and the factor the cook applies (CookReport, the
// plan's records and the archive's cook info carry it). A light header: stage headers include it
// without the whole of terrain/cook.h.
#pragma once
#include <string>

namespace terrain::cook {

// The unit an input declares for its heights and the factor the cook applies to its values
// (metres = value * scale + height_offset). Declared: the vertical CRS's linear unit (a compound
// CRS such as EPSG:32611+6360, NAVD88 height in US survey feet), else the band's unit type ("ft",
// "US survey foot", "m"). An input that declares none is in metres (HGT, PNG, most GeoTIFFs).
struct HeightUnit {
  std::string declared;     // the unit as the file names it; empty: none declared
  std::string declared_by;  // "vertical CRS" or "band unit type"; empty when none is declared
  double declared_m = 1.0;  // metres per declared unit; NaN for a unit the cooker does not know
  double scale = 1.0;       // the factor applied: CookOptions::height_scale when given (it replaces declared_m), else declared_m
  bool scale_from_flag = false;  // scale is CookOptions::height_scale's
};

}  // namespace terrain::cook
