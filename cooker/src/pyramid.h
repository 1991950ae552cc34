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

struct PyramidStats {
  std::array<LevelStats, kLevelCount> levels{};
  std::array<ErrorStats, kLevelCount> level_error{};
  ErrorStats leaf;  // each source sample against the finest node covering it
  uint64_t nodes = 0, vertices = 0, output_vertices = 0;
  double cpu_heights = 0, cpu_error = 0, cpu_surface = 0, cpu_encode = 0;
  SurfaceStats surface;
};

Status build_pyramid(CookContext& ctx, const RangeIndex& index, uint32_t roots_x, uint32_t roots_y, int threads, ArchiveWriter& writer,
                     const ProgressFn& progress, PyramidStats& out);

}  // namespace terrain::cook
