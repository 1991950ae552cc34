// The level loop: roots with terrain, then each level's children where the parent's error asks
// for them, cooked in parallel batches and handed to the writer in key order (level 5 first, then
// y, x), so the archive bytes do not depend on the thread count. Memory: one batch of nodes.
// Each level's quantization step is chosen when the level's node list is known, from a bound on
// those nodes' surface ranges (range_index.h); ctx.step_log2 holds the result for every level.
#pragma once
#include <array>

#include "node_cook.h"
#include "range_index.h"
#include "terrain/archive_writer.h"
#include "terrain/cook.h"

namespace terrain::cook {

// Fills the pyramid's part of `report` (levels, nodes, full-detail error, output vertices, the CPU
// seconds per node stage and the surface totals), summed in key order onto the zeros cook() starts
// the report with.
Status build_pyramid(CookContext& ctx, const RangeIndex& index, uint32_t roots_x, uint32_t roots_y, int threads, ArchiveWriter& writer,
                     const ProgressFn& progress, CookReport& report);

}  // namespace terrain::cook
