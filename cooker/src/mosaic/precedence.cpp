#include "mosaic/precedence.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "mosaic/resample_inputs.h"

namespace terrain::cook {

double ground_spacing_m(const Raster& r) {
  double sx = 0, sy = 0;
  ground_spacing_axes_m(r, sx, sy);
  return std::sqrt(sx * sy);
}

void ground_spacing_axes_m(const Raster& r, double& sx, double& sy) {
  const double* c = r.geo.c;
  sx = std::hypot(c[1], c[4]);
  sy = std::hypot(c[2], c[5]);
  if (r.crs.kind == CrsKind::geographic) {
    constexpr double kMetresPerDegree = 6371008.8 * 3.14159265358979323846 / 180.0;
    double lon = 0, lat = 0;
    AffineMap::from(r.geo).to_model(0.5 * (r.width - 1), 0.5 * (r.height - 1), lon, lat);
    const double coslat = std::cos(std::clamp(lat, -89.0, 89.0) * (3.14159265358979323846 / 180.0));
    sx *= kMetresPerDegree * coslat;
    sy *= kMetresPerDegree;
  }
}

std::vector<size_t> finer_first_order(std::span<const Raster* const> rasters) {
  const size_t n = rasters.size();
  std::vector<double> own(n), key(n);
  std::vector<size_t> family(n);  // the first listed raster of its grid family
  for (size_t i = 0; i < n; ++i) {
    own[i] = ground_spacing_m(*rasters[i]);
    family[i] = i;
    for (size_t j = 0; j < i; ++j)
      if (family[j] == j && !needs_resampling(*rasters[j], *rasters[i])) {
        family[i] = j;
        break;
      }
  }
  // A family's key: its finest member's spacing (tiles at several latitudes), whatever their order.
  for (size_t i = 0; i < n; ++i) key[i] = own[i];
  for (size_t i = 0; i < n; ++i) key[family[i]] = std::min(key[family[i]], own[i]);
  for (size_t i = 0; i < n; ++i) key[i] = key[family[i]];
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), size_t(0));
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return key[a] < key[b]; });
  return order;
}

}  // namespace terrain::cook
