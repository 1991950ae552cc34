// The memory budget of a cook (--memory-limit): every allocation whose size comes from the input
// is checked against it BEFORE it is made, so a huge or lying header is a named error (exit 1)
// instead of std::bad_alloc or the OOM killer.
//
// Today's cook holds the whole source in memory (issue 13 will bound it by blocks), so its need is
// estimated from the source sample count: kCookBytesPerSample is measured (see memory_budget.cpp).
#pragma once
#include <cstdint>
#include <string>

#include "terrain/status.h"

namespace terrain::cook {

struct CookOptions;

// Peak bytes of the in-memory cook per source sample (heights-only and full cooks alike, measured
// with /usr/bin/time -v on real DEMs: see memory_budget.cpp).
inline constexpr uint64_t kCookBytesPerSample = 16;
// Extra bytes per nodata sample while one void is filled (void_fill.cpp: its sample list, BFS
// order and queue, the local index pairs and 4 neighbour codes of 8 bytes).
inline constexpr uint64_t kFillBytesPerVoidSample = 64;

// The limit in force: options.memory_limit_bytes, or default_memory_limit_bytes() when it is 0.
uint64_t memory_limit_of(const CookOptions& options);

// Success when `need_bytes` fits in `limit_bytes`; else a no_memory-style failure (exit 1) that
// reads "<what>: needs <need> for <purpose>, over --memory-limit <limit>; <advice>".
Status check_memory(uint64_t need_bytes, uint64_t limit_bytes, const std::string& what, const std::string& purpose,
                    const std::string& advice);

// "57.6 GB", "512 MB", "12 KB" (decimal units: what --memory-limit's suffixes mean, times 1024).
std::string format_bytes(uint64_t bytes);
// "3.6 G", "64 M", "1201": sample counts.
std::string format_count(uint64_t n);

}  // namespace terrain::cook
