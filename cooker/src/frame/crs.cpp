// CRS descriptions and comparisons (crs.h); resolving them through PROJ and libgeotiff is
// crs_resolve.cpp's.
#include "frame/crs.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>

namespace terrain::cook {

SourceCrs wgs84_geographic() {
  SourceCrs crs;
  crs.kind = CrsKind::geographic;
  crs.epsg = 4326;
  crs.name = "WGS 84 (EPSG:4326)";
  crs.tm.semi_major_m = kWgs84A;
  crs.tm.inverse_flattening = kWgs84Rf;
  return crs;
}

std::string utm_zone_name(const FrameCrs& tm) {
  if (tm.kind != ProjectionKind::transverse_mercator) return "";
  if (tm.lat0_deg != 0 || tm.scale_k0 != 0.9996 || tm.false_easting_m != 500000) return "";
  if (tm.false_northing_m != 0 && tm.false_northing_m != 10000000) return "";
  const double zone = (tm.lon0_deg + 183.0) / 6.0;
  if (zone != std::floor(zone) || zone < 1 || zone > 60) return "";
  return fmt::format("UTM zone {}{}", int(zone), tm.false_northing_m == 0 ? 'N' : 'S');
}

std::string describe_frame(const FrameCrs& f) {
  if (f.kind == ProjectionKind::local) return "local metric frame";
  if (f.kind == ProjectionKind::proj)
    return fmt::format("{}{}: projected CRS (PROJ WKT2, {} bytes) a={:.3f} rf={:.9f}", f.name.empty() ? "CRS" : f.name,
                       f.epsg && f.name.find("EPSG") == std::string::npos ? fmt::format(" (EPSG:{})", f.epsg) : "",
                       f.definition.size(), f.semi_major_m, f.inverse_flattening);
  return fmt::format("{}{}: Transverse Mercator lon0={:.9g} lat0={:.9g} k0={:.9g} x0={:.9g} y0={:.9g} a={:.3f} rf={:.9f}",
                     f.name.empty() ? std::string("TM") : f.name, f.epsg ? fmt::format(" (EPSG:{})", f.epsg) : "",
                     f.lon0_deg, f.lat0_deg, f.scale_k0, f.false_easting_m, f.false_northing_m, f.semi_major_m,
                     f.inverse_flattening);
}

std::string describe_crs(const SourceCrs& c) {
  switch (c.kind) {
    case CrsKind::none: return "no CRS";
    case CrsKind::local: return "local metric coordinates";
    case CrsKind::geographic:
      return fmt::format("{}: geographic lon/lat, a={:.3f} rf={:.9f}", c.name, c.tm.semi_major_m,
                         c.tm.inverse_flattening);
    case CrsKind::transverse_mercator:
    case CrsKind::projected: return describe_frame(c.tm);
    case CrsKind::unsupported:
      return fmt::format("{}{} ({})", c.name.empty() ? std::string("unnamed CRS") : c.name,
                         c.epsg && c.name.find("EPSG") == std::string::npos ? fmt::format(" (EPSG:{})", c.epsg) : "",
                         c.projection);
  }
  return "?";
}

bool same_ellipsoid(const FrameCrs& a, const FrameCrs& b) {
  return std::fabs(a.semi_major_m - b.semi_major_m) < 1e-6 &&
         std::fabs(a.inverse_flattening - b.inverse_flattening) < 1e-6;
}

bool same_crs(const SourceCrs& a, const SourceCrs& b) {
  if (a.kind != b.kind) return false;
  switch (a.kind) {
    case CrsKind::none:
    case CrsKind::local: return true;
    case CrsKind::geographic: return same_ellipsoid(a.tm, b.tm);
    case CrsKind::transverse_mercator:
      return same_ellipsoid(a.tm, b.tm) && a.tm.lon0_deg == b.tm.lon0_deg && a.tm.lat0_deg == b.tm.lat0_deg &&
             a.tm.scale_k0 == b.tm.scale_k0 && a.tm.false_easting_m == b.tm.false_easting_m &&
             a.tm.false_northing_m == b.tm.false_northing_m;
    case CrsKind::projected: return a.tm.definition == b.tm.definition;
    case CrsKind::unsupported: return false;
  }
  return false;
}

std::string conversion_hint(const SourceCrs& crs, const std::string& path) {
  std::string target = "EPSG:326<zone>";
  if (std::isfinite(crs.center_lon) && std::isfinite(crs.center_lat)) {
    const int zone = std::clamp(int(std::floor((crs.center_lon + 180.0) / 6.0)) + 1, 1, 60);
    target = fmt::format("EPSG:{}{:02d}", crs.center_lat >= 0 ? 326 : 327, zone);
  }
  std::string out = path;
  const size_t dot = out.find_last_of('.');
  out = (dot == std::string::npos ? out : out.substr(0, dot)) + "_utm.tif";
  return fmt::format("reproject it to UTM (or any Transverse Mercator) first, e.g. gdalwarp -t_srs {} -r cubic {} {}",
                     target, path, out);
}

}  // namespace terrain::cook
