// An input in another CRS or at another sample spacing, resampled onto the first input's pixel grid
// so that mosaic() can place it like a tile (issue 13: mixed CRSs and resolutions in one cook).
#pragma once
#include <cstdint>

#include "raster.h"
#include "terrain/status.h"

namespace terrain::cook {

// True when `r` must be resampled before it can join `ref`'s grid: another CRS or another sample
// spacing / axis orientation. Same CRS and spacing (whatever the origin) is mosaic()'s exact path.
bool needs_resampling(const Raster& ref, const Raster& r);

// Resamples `in` onto `ref`'s pixel grid (same CRS, spacing and sample phase), over the part of
// that grid that covers `in`'s footprint: GDAL's warper, bilinear, nodata (NaN) honoured (a grid
// sample gets data only where all 4 of its source neighbours have it). `held_bytes` (the inputs in
// memory) plus the resampled raster and the warper's buffer are checked against
// memory_limit_bytes first. `out` keeps `in`'s path and says in its description what was done.
Status resample_onto_grid(const Raster& ref, const Raster& in, uint64_t held_bytes, uint64_t memory_limit_bytes,
                          Raster& out);

}  // namespace terrain::cook
