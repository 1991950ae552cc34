// Void filling by windows (bounded memory). A first pass over the source, tile by tile,
// finds which voids will be filled and records the bounding box of every filled void that spans
// more than one tile; a block of the cook then reads only fill_read_rect() of its samples and
// fills them with fill_voids_window(), which gives every sample of the block exactly the value
// bits and filled flag of the whole-raster fill_voids() (void_fill.h).
//
// Why it is exact: a void's fill depends only on its samples, their order (depth-first from its
// first sample in raster order, neighbours left, right, up, down) and its rim. Row-major order
// restricted to a window is the global order, so a void COMPLETE inside a window (none of its
// samples on a window edge that is not a raster edge) is filled exactly as over the whole raster.
// The window of fill_read_rect() holds every void that meets `need` completely unless it stays
// a hole; voids cut by the window edge are left nodata.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "voids/range_summary.h"
#include "base/sample_window.h"
#include "terrain/nodata_policy.h"
#include "terrain/progress.h"
#include "terrain/status.h"
#include "voids/void_fill.h"

namespace terrain::cook {

// Reads samples [c0, c0 + w) x [r0, r0 + h) of the whole source (always inside the raster) into
// `out`, row-major, NaN = nodata.
using ReadSamples = std::function<Status(int c0, int r0, int w, int h, float* out)>;

struct VoidPlan {
  int width = 0, height = 0;  // raster size (samples)
  int tile = 0;               // tile side (samples) of the first pass
  NodataPolicy policy = NodataPolicy::automatic;
  int64_t max_fill_samples = 0;
  // Bounding box of every void that will be filled and spans more than one tile, sorted by
  // (r0, c0, r1, c1).
  std::vector<SampleRect> spanning_fills;
  // Filled and hole samples and regions over the whole raster: what fill_voids() reports
  // (max_residual_m stays 0: nothing is filled here).
  VoidStats stats;
  uint64_t valid_samples = 0;  // non-NaN samples
  SampleRect valid_bounds;     // their bounding box (empty when none)
  std::string source_name;     // names the source in memory-limit errors; the caller may set it
};

// The first pass: reads the raster once, tile by tile (tile x tile samples per read, rows of tiles
// from the top), labels the voids of each tile, joins them across tile edges (union-find over the
// labels of the last row and column read) and decides fill or hole per void with fill_voids()'s
// rule. Memory: one tile, two raster rows of labels and the records of the voids still open,
// plus spanning_fills; never the raster. The tile size changes no result of fill_voids_window()
// (tile: 1..46340, tile * tile samples indexed with 32 bits; invalid_argument otherwise).
// `progress` (optional) hears the fraction of rows done after each row of tiles. `summary`
// (optional, started for this raster) is handed every tile read and every void that will be
// filled, with its rim's [min, max] (the valid samples 4-adjacent to it); the caller finishes it.
// `read_ahead`: `read` runs on a second thread (one call at a time, never beside the caller's
// other use of the source), a chunk of kReadAheadTiles tiles of one row of tiles per call, the
// next chunk read while this one is labelled; the same results, plus two chunks of memory
// (2 x 32 x 64 x 64 floats = 1 MB at the cook's tile).
inline constexpr int kReadAheadTiles = 32;
Status plan_voids(int width, int height, const ReadSamples& read, NodataPolicy policy, int64_t max_fill_samples,
                  int tile, VoidPlan& out, const ProgressFn& progress = {}, RangeSummary* summary = nullptr,
                  bool read_ahead = false);

// The rectangle a block must read so that its `need` rectangle can be filled exactly: `need`
// grown to whole tiles plus a one-sample ring, plus the bounding box and a one-sample ring of
// every spanning fill that meets `need`, clipped to the raster. Empty when `need` misses the raster.
SampleRect fill_read_rect(const VoidPlan& plan, const SampleRect& need);

// Fills the voids of `values` (the samples of `window`, row-major, NaN = nodata; `window` is
// fill_read_rect(plan, need) or any larger rectangle inside the raster): afterwards every sample
// inside `need` has the value bits and filled flag whole-raster fill_voids() gives it. `filled`
// (window-sized) is cleared, then set to 1 where a sample was filled. Voids cut by the window edge
// stay nodata. max_residual_m: the largest of the voids filled here. The memory check is
// fill_voids()'s, with the window's samples in place of the raster's.
Status fill_voids_window(const VoidPlan& plan, const SampleRect& window, float* values, uint8_t* filled,
                         double& max_residual_m, uint64_t memory_limit_bytes = UINT64_MAX);

}  // namespace terrain::cook
