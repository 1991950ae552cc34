// Several inputs on one pixel grid become one raster.
#pragma once
#include <cstdint>
#include <vector>

#include "raster.h"
#include "terrain/status.h"

namespace terrain::cook {

// Merges `inputs` (same CRS, same sample spacing, origins a whole number of samples apart: adjacent
// HGT tiles, a tiled GeoTIFF export) into one raster covering their union. Overlap rule: where
// several inputs have data for a sample, the one listed FIRST wins; later inputs only fill samples
// the earlier ones leave as nodata (HGT tiles share their edge rows, which then agree anyway).
// Geographic inputs are placed by longitude modulo 360 (tiles either side of the antimeridian join).
// A single input is moved through unchanged. The mosaic (plus the inputs it copies from) is
// checked against memory_limit_bytes before it is allocated (tiles far apart make a huge one).
Status mosaic(std::vector<Raster>& inputs, Raster& out, uint64_t memory_limit_bytes = UINT64_MAX);

}  // namespace terrain::cook
