// The memory budget of a cook (--memory-limit): every allocation whose size comes from the input
// is checked against it BEFORE it is made, so a huge or lying header is a named error (exit 1)
// instead of std::bad_alloc or the OOM killer.
//
// The cook reads the source by windows, one block of roots at a time (pyramid.h): the budget sets
// the block size (memory_shares, kWindowBytesPerSample). kCookBytesPerSample is what the in-memory
// whole-raster path (load_inputs + mosaic, kept for tools and tests) needs per sample.
#pragma once
#include <cstdint>
#include <string>

#include "terrain/status.h"

namespace terrain::cook {

struct CookOptions;

// Peak bytes of a whole-raster, in-memory cook per source sample (heights-only and full cooks alike, measured
// with /usr/bin/time -v on real DEMs: see memory_budget.cpp).
inline constexpr uint64_t kCookBytesPerSample = 16;
// Extra bytes per nodata sample while one void is filled (void_fill.cpp: its sample list, BFS
// order and queue, the local index pairs and 4 neighbour codes of 8 bytes).
inline constexpr uint64_t kFillBytesPerVoidSample = 64;

// How a cook spends its budget: a fixed reserve (the process itself: libraries, PROJ's database, the
// node batches in flight, the spool's records; memory_budget.cpp sizes it), GDAL's block cache,
// the inputs held whole (own readers, resampled inputs), and one block's source window (384 MB at
// the default 2 GB, plus half of any budget above 2 GB; memory_budget.cpp).
struct MemoryShares {
  uint64_t reserve = 0, gdal_cache = 0, inputs = 0, window = 0;
};
MemoryShares memory_shares(uint64_t limit_bytes);
// Bytes per sample of a block's window: the heights (4), filled flags (1), the fill's visited flags
// (1), the grid families of a mosaic of several (1), the reader's copy with its one-sample ring (4,
// mosaic_source.cpp), rounded up (the steps
// need no window: range_summary.h, at most ~7 MB plus one row of first-pass tiles).
inline constexpr uint64_t kWindowBytesPerSample = 12;

// The limit in force: options.memory_limit_bytes, or default_memory_limit_bytes() when it is 0.
uint64_t memory_limit_of(const CookOptions& options);
// The same for a limit given on its own (0: the default).
uint64_t memory_limit_of(uint64_t given_bytes);

// Success when `need_bytes` fits in `limit_bytes`; else a no_memory-style failure (exit 1) that
// reads "<what>: needs <need> for <purpose>, over --memory-limit <limit>; <advice>".
Status check_memory(uint64_t need_bytes, uint64_t limit_bytes, const std::string& what, const std::string& purpose,
                    const std::string& advice);

// "57.6 GB", "512 MB", "12 KB" (decimal units: what --memory-limit's suffixes mean, times 1024).
std::string format_bytes(uint64_t bytes);
// "3.6 G", "64 M", "1201": sample counts.
std::string format_count(uint64_t n);

}  // namespace terrain::cook
