// Several inputs on one pixel grid become one raster.
#pragma once
#include <cstdint>
#include <vector>

#include "inputs/raster.h"
#include "terrain/status.h"

namespace terrain::cook {

// Merges `inputs` into one raster covering their union, on the FIRST input's pixel grid. Inputs in
// its CRS at its spacing whose origins are a whole number of samples apart (adjacent HGT tiles, a
// tiled GeoTIFF export) are copied exactly; an input in another CRS or at another spacing is first
// resampled onto that grid (resample_inputs.h: exact CRS transform at anchors, tent filter, nodata honoured), so the
// result then depends on the order: the first input sets grid and CRS and wins every overlap. Overlap rule: where
// several inputs have data for a sample, the one listed FIRST wins; later inputs only fill samples
// the earlier ones leave as nodata (HGT tiles share their edge rows, which then agree anyway).
// Geographic inputs are placed by longitude modulo 360 (tiles either side of the antimeridian join).
// A single input is moved through unchanged. The mosaic (plus the inputs it copies from) is
// checked against memory_limit_bytes before it is allocated (tiles far apart make a huge one).
// Implemented as MosaicSource (mosaic_source.h) over the inputs held whole, read as one window: the
// windowed cook's reader places and overlaps inputs with the same code. The inputs are taken in the
// order given: the cook's reader (open_mosaic_source) first puts them in its order of precedence.
Status mosaic(std::vector<Raster>& inputs, Raster& out, uint64_t memory_limit_bytes = UINT64_MAX);

}  // namespace terrain::cook
