// A source elevation raster after reading: float heights in metres (NaN = nodata), where its
// samples sit in its CRS, and what that CRS is.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "terrain/format.h"
#include "terrain/height_unit.h"

namespace terrain::cook {

// What a source's coordinates mean.
enum class CrsKind : uint8_t {
  none,                 // the file carries no georeferencing CRS
  geographic,           // longitude/latitude in degrees on an ellipsoid
  transverse_mercator,  // projected TM (UTM included), metres
  local,                // metric coordinates without geodetic meaning
  unsupported,          // some other CRS: `name` says which
  projected,            // any other projected CRS PROJ resolves: `tm` has kind proj, its WKT2 and ellipsoid
};

struct SourceCrs {
  CrsKind kind = CrsKind::none;
  FrameCrs tm;             // transverse_mercator: the projection; geographic: ellipsoid fields only
  int32_t epsg = 0;
  std::string name;        // e.g. "WGS 84 / UTM zone 5N", "EPSG:4326"
  std::string projection;  // unsupported: the projection method, for the error message
  double center_lon = NAN, center_lat = NAN;  // unsupported: the data centre when PROJ could say
  double model_unit = 1.0;  // one file coordinate unit in degrees (geographic) or metres (projected)
};

// Model coordinates (CRS units: degrees or metres) of sample centre (col, row):
//   x = c[0] + c[1] * col + c[2] * row,  y = c[3] + c[4] * col + c[5] * row.
struct SampleGeo {
  double c[6] = {0, 1, 0, 0, 0, -1};
  bool valid = false;  // false: the file carries no position (images without --origin/--spacing)
  // true: samples are points (HGT, PixelIsPoint, heightmap images and raw): the archive's
  // footprint (extent, grid origin) is their hull; false: pixel areas (PixelIsArea): the footprint
  // reaches half a sample beyond the outer samples. Coverage is the same either way (reconstruct.h).
  bool point_samples = false;
};

// The affine georeferencing from the model positions of sample (0, 0), (1, 0) and (0, 1); valid
// when the map is not singular. Shared by the GeoTIFF readers (libgeotiff and GDAL).
inline SampleGeo sample_geo_from_points(double x0, double y0, double x1, double y1, double x2, double y2,
                                        bool point_samples) {
  SampleGeo g;
  g.c[0] = x0;
  g.c[1] = x1 - x0;
  g.c[2] = x2 - x0;
  g.c[3] = y0;
  g.c[4] = y1 - y0;
  g.c[5] = y2 - y0;
  g.valid = g.c[1] * g.c[5] - g.c[2] * g.c[4] != 0.0;
  g.point_samples = point_samples;
  return g;
}

struct Raster {
  std::string path;
  std::string description;   // format, type, size, compression: for the report
  int width = 0, height = 0;
  std::vector<float> values; // row-major, row 0 as stored (north-up files: north); NaN = nodata
  SampleGeo geo;
  SourceCrs crs;
  bool nodata_declared = false;  // the file (or --nodata-value) says which value is nodata
  HeightUnit height_unit;        // what the file declares; scale set by open_input_layer
  // Samples load_inputs turned into nodata because they cannot be elevations (inputs.h).
  struct Implausible {
    uint64_t out_of_range = 0;   // outside the valid range after scale/offset (incl. +-Inf)
    uint64_t sentinel = 0;       // undeclared -9999 with no neighbour within 1000 m of it
    double lowest = NAN, highest = NAN;  // extremes of the out-of-range ones (metres)
  } implausible;

  float at(int col, int row) const { return values[size_t(row) * size_t(width) + size_t(col)]; }
};

// Bounding box (inclusive, sample indices) of the valid samples and their count; false when none.
inline bool valid_bounds(const Raster& r, int& c0, int& r0, int& c1, int& r1, uint64_t& valid) {
  c0 = r.width;
  r0 = r.height;
  c1 = r1 = -1;
  valid = 0;
  for (int row = 0; row < r.height; ++row) {
    const float* p = &r.values[size_t(row) * size_t(r.width)];
    int first = -1, last = -1;
    for (int col = 0; col < r.width; ++col)
      if (!std::isnan(p[col])) {
        if (first < 0) first = col;
        last = col;
        ++valid;
      }
    if (first < 0) continue;
    c0 = std::min(c0, first);
    c1 = std::max(c1, last);
    r0 = std::min(r0, row);
    r1 = std::max(r1, row);
  }
  return c1 >= 0;
}

// Model coordinates <-> sample coordinates for a SampleGeo (affine, inverted once).
struct AffineMap {
  double c[6];    // sample -> model
  double inv[6];  // model -> sample, applied to (x - c[0], y - c[3]) (no cancellation at UTM sizes)
  static AffineMap from(const SampleGeo& g) {
    AffineMap m{};
    for (int i = 0; i < 6; ++i) m.c[i] = g.c[i];
    const double det = g.c[1] * g.c[5] - g.c[2] * g.c[4];
    m.inv[1] = g.c[5] / det;
    m.inv[2] = -g.c[2] / det;
    m.inv[4] = -g.c[4] / det;
    m.inv[5] = g.c[1] / det;
    return m;
  }
  void to_model(double col, double row, double& x, double& y) const {
    x = c[0] + c[1] * col + c[2] * row;
    y = c[3] + c[4] * col + c[5] * row;
  }
  void to_sample(double x, double y, double& col, double& row) const {
    const double dx = x - c[0], dy = y - c[3];
    col = inv[1] * dx + inv[2] * dy;
    row = inv[4] * dx + inv[5] * dy;
  }
};

}  // namespace terrain::cook
