// Nodata voids: which are filled and how.
//
// Voids are the 4-connected regions of nodata samples. Under the automatic policy a void is filled
// when it is enclosed by data (touches no raster border) and has at most `max_fill_samples`
// samples; other voids stay nodata and become holes. A filled void gets the harmonic (Laplace)
// interpolation of the data around it: every filled sample is the mean of its four neighbours,
// with the surrounding valid samples held fixed (solved by successive over-relaxation from a
// breadth-first initial guess), so the fill meets the data continuously with no new extrema.
#pragma once
#include <cstdint>
#include <vector>

#include "raster.h"
#include "terrain/cook.h"
#include "terrain/status.h"

namespace terrain::cook {

struct VoidStats {
  uint64_t filled_samples = 0, filled_regions = 0;
  uint64_t hole_samples = 0, hole_regions = 0;
  double max_residual_m = 0;  // largest change of the last relaxation sweep
};

// Fills voids of `raster` in place. `filled` (one byte per sample) is set to 1 where a sample was
// filled, so error statistics can leave those samples out. Filling a void takes
// kFillBytesPerVoidSample per void sample on top of the cook's own need (the raster's samples at
// kCookBytesPerSample); a void that would exceed memory_limit_bytes is refused before it is filled.
Status fill_voids(Raster& raster, NodataPolicy policy, int64_t max_fill_samples, std::vector<uint8_t>& filled,
                  VoidStats& stats, uint64_t memory_limit_bytes = UINT64_MAX);

}  // namespace terrain::cook
