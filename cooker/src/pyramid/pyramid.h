// The block-wise pyramid. The root grid is cut into square blocks of roots; a block's
// nodes (its roots and all their descendants) read only a window of source samples around it, so
// memory follows the block, never the input.
//
// Steps first, then one pass over the blocks, each independent of the others and of the block size
// and order:
//  1. steps: every node of every level that could exist (its sample rectangle holds data) bounds
//     its surface range from the first pass's summary (range_summary.h); a level's quantization
//     step comes from the worst bound of the level (quantize.h), so it is known before any node
//     is cooked.
//  2. cook: per block, the level loop (roots with terrain, then the children the parents' error
//     asks for), nodes in parallel batches; results in key order (level 5 first, then y, x)
//     within the block. The caller restores the global key order (node_spool.h).
#pragma once
#include <algorithm>
#include <array>
#include <functional>
#include <vector>

#include "pyramid/node_cook.h"
#include "voids/range_summary.h"
#include "base/sample_window.h"
#include "terrain/cook_stats.h"

namespace terrain::cook {

// Roots [x0, x1) x [y0, y1) of the node grid.
struct RootBlock {
  uint32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

// The node grid cut into blocks of `side` x `side` roots, row-major from the south-west.
struct BlockGrid {
  uint32_t roots_x = 0, roots_y = 0, side = 1;
  uint32_t blocks_x() const { return (roots_x + side - 1) / side; }
  uint32_t blocks_y() const { return (roots_y + side - 1) / side; }
  uint32_t count() const { return blocks_x() * blocks_y(); }
  RootBlock block(uint32_t i) const {
    const uint32_t bx = i % blocks_x(), by = i / blocks_x();
    return {bx * side, by * side, std::min(roots_x, (bx + 1) * side), std::min(roots_y, (by + 1) * side)};
  }
};

// Frame rectangle (metres) every vertex of block `b`'s node windows lies in: its roots' square
// grown by the root windows' margin (ctx.window_margin() root vertex spacings).
void block_frame_rect(const CookContext& ctx, const RootBlock& b, double& x0, double& y0, double& x1, double& y1);
// Source samples the cook of block `b` reads: its nodes' windows, Catmull-Rom taps and the error
// measurement's ring, clipped to the source.
SampleRect block_cook_rect(const CookContext& ctx, const RootBlock& b);

// Step 1: worst[level] = the largest range bound of every node of the roots_x x roots_y root grid
// at levels ctx.finest_level .. 5 (a max: independent of threads and of any order).
void level_range_bounds(const CookContext& ctx, const RangeSummary& ranges, uint32_t roots_x, uint32_t roots_y,
                        int threads, std::array<double, kLevelCount>& worst);
// The largest range bound of a node of the overview levels 6 .. 5 + levels (SPEC 19) over the
// root grid: their step's rule is the roots' (every overview level gets one step, at least the
// roots', so steps never decrease upward).
double overview_range_bound(const CookContext& ctx, const RangeSummary& ranges, uint32_t roots_x, uint32_t roots_y,
                            int levels);
// The levels' steps from the worst bounds: the range's step or the tolerance's, whichever is
// coarser; each level capped by the next coarser one's, so steps never decrease towards the roots.
// Levels finer than ctx.finest_level get the finest level's step.
// overview_step >= 0: the step of overview levels above the roots, which rounds the roots' even
// vertices (SPEC 19 rule 7) and so widens every level's range by up to half of it.
// floor_step: the finest step any level takes (tolerance_step, or --height-step's step_at_most).
void choose_steps(const std::array<double, kLevelCount>& worst, int floor_step, int finest_level,
                  std::array<uint8_t, kLevelCount>& steps, int overview_step = -1);

// Totals of the cook that blocks add to (summed in block order: floating sums may differ in the
// last bits between block orders; they go to the report only).
struct PyramidTotals {
  std::array<ErrorStats, kLevelCount> level_error{};
  ErrorStats leaf;  // each source sample against the finest node covering it
  // Per level, what cook_block counts: nodes, vertices and CPU seconds (the other LevelStats
  // fields are the report's, fill_report).
  std::array<LevelStats, kLevelCount> levels{};
  double cpu_heights = 0, cpu_error = 0, cpu_surface = 0, cpu_encode = 0;  // of every node, summed over threads
  SurfaceTotals surface;
  // The blocks' windows (the session's reads): the largest residual of a filled void and the
  // largest window (samples).
  double void_fill_residual_m = 0;
  uint64_t window_samples_max = 0;
  // A mosaic of several grid families (CookContext::family_rules): per family, the finest level of
  // a node where it takes precedence (kLevelCount: none yet); empty for one family.
  std::vector<int> family_finest_level;
  void reach_family_level(size_t family, int level) {
    if (family_finest_level.size() <= family) family_finest_level.resize(family + 1, kLevelCount);
    family_finest_level[family] = std::min(family_finest_level[family], level);
  }
};

// Pass 2 for one block (ctx's window covering block_cook_rect()): cooks its nodes and hands each
// result to `sink` in key order within the block. Adds its nodes' counts, errors, CPU seconds and
// surface statistics to `totals`.
using NodeSink = std::function<Status(NodeResult&)>;
Status cook_block(const CookContext& ctx, const RootBlock& b, int threads, const NodeSink& sink, PyramidTotals& totals);

}  // namespace terrain::cook
