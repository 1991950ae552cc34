// Coordinate reference systems of the inputs: what the GeoTIFF keys say (through libgeotiff, which
// resolves EPSG codes such as 3794 through PROJ's database) and what --crs / --frame spell.
#pragma once
#include <string>

#include "inputs/raster.h"
#include "terrain/status.h"

struct gtiff;  // libgeotiff's GTIF

namespace terrain::cook {

inline constexpr double kWgs84A = 6378137.0, kWgs84Rf = 298.257223563;
inline constexpr double kGrs80A = 6378137.0, kGrs80Rf = 298.257222101;

// Accepted spellings (case-insensitive prefixes):
//   EPSG:4326 (or any geographic EPSG code), EPSG:32633 / 32733 (UTM), any EPSG code that PROJ
//   resolves to Transverse Mercator (EPSG:3794, EPSG:27700, ...),
//   tm:lon0=15,lat0=0,k0=0.9999,x0=500000,y0=-5000000,ellps=GRS80   (lat0, k0, x0, y0 default to
//     0, 1, 0, 0; ellps WGS84 (default) or GRS80, or a=<metres>,rf=<inverse flattening>),
//   local   (metric coordinates with no geodetic meaning, e.g. game heightmaps).
// Other EPSG codes parse (kind = unsupported) so the caller can name them in its error.
Status parse_crs_spec(const std::string& spec, SourceCrs& out);

// WGS 84 longitude/latitude (EPSG:4326) without a database lookup (SRTM HGT).
SourceCrs wgs84_geographic();

// The CRS of an open GeoTIFF from its keys (GTIFGetDefn). `center_x/center_y` (model units) let
// an unsupported CRS report where the data is, for the gdalwarp hint.
SourceCrs crs_from_geotiff(gtiff* gtif, double center_x, double center_y);

// Human-readable one-liner, e.g. "EPSG:3794 Slovenia 1996 / Slovene National Grid (TM lon0 15 ...)".
std::string describe_crs(const SourceCrs& crs);
std::string describe_frame(const FrameCrs& frame);

// Same projection and ellipsoid (EPSG codes may differ, e.g. an explicit TM vs its EPSG twin).
bool same_crs(const SourceCrs& a, const SourceCrs& b);
bool same_ellipsoid(const FrameCrs& a, const FrameCrs& b);

// "Use gdalwarp -t_srs EPSG:32633 -r cubic IN OUT.tif" for a CRS we cannot use.
std::string conversion_hint(const SourceCrs& crs, const std::string& path);

// "UTM zone 5N" when TM parameters are exactly a WGS 84 UTM zone's, else "".
std::string utm_zone_name(const FrameCrs& tm);

}  // namespace terrain::cook
