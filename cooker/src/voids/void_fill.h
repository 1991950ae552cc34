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
#include <string>
#include <vector>

#include "inputs/raster.h"
#include "terrain/nodata_policy.h"
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

// The one fill algorithm, on a window of samples [c0, c0 + w) x [r0, r0 + h) of a raster of
// raster_width x raster_height (fill_voids() passes the whole raster, void_plan.h its windows).
struct FillWindow {
  int raster_width = 0, raster_height = 0;
  int c0 = 0, r0 = 0, w = 0, h = 0;
};
// Fills, in `values` (the window's samples, row-major, NaN = nodata), every void COMPLETE inside
// the window (none of its samples on a window edge that is not a raster edge) that fill_voids()'s
// rule fills; voids cut by the window edge are left as they are. `filled` (window-sized, set by the
// caller) gets 1 where a sample was filled; `stats` counts the complete voids only. The memory
// check is base_bytes + kFillBytesPerVoidSample per sample of the void, `what` names the source.
Status fill_complete_voids(const FillWindow& window, float* values, uint8_t* filled, NodataPolicy policy,
                           int64_t max_fill_samples, uint64_t base_bytes, const std::string& what, VoidStats& stats,
                           uint64_t memory_limit_bytes);

}  // namespace terrain::cook
