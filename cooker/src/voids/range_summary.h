// Height-range summaries of the source, gathered by the first pass (void_plan.h) while it reads
// every sample once, from which every level's quantization step is chosen before any node is
// cooked (format/SPEC.md section 7): no pass re-reads the source for the steps.
//
// The bound. A Catmull-Rom value lies within [min - 0.28125 r, max + 0.28125 r] of its 16 taps
// (r = their range; 0.28125 is the largest total negative weight of the 2-D kernel), and the
// bilinear fallback within [min, max]. So over a rectangle the surface range is at most
//   (max - min of its samples) + 0.5625 * (largest 4x4 tap range inside it),
// computed over blocks of 4 << k samples (aligned to the whole source; blocks of level k + 1 hold
// 2 x 2 of level k) covering the rectangle, k chosen from the rectangle's span (level_for).
//
// What is kept: cells of G x G samples (G = cell_for(w, h): 4, or larger so that a source has at
// most kMaxCells cells), each with the min and max of its samples and the largest range of the
// taps of one of its 4 x 4 blocks (the block's samples with one more before and two after, in
// both directions, clipped to the source), and the blocks of coarser levels built from them.
// Queries use level max(level_for, log2(G / 4)): with G = 4 the bound of the steps pass it
// replaces, bit for bit.
//
// Filled voids: their values are not known in the first pass, but the harmonic fill of a void lies
// within its rim's [min, max] (the valid samples next to it; void_fill.cpp clamps to it), so
// every cell meeting the void's bounding box takes that interval into its min and max, and every
// cell whose taps meet the box takes it into its tap range. Unfilled voids (holes) hold no data.
#pragma once
#include <cstdint>
#include <vector>

#include "base/sample_window.h"

namespace terrain::cook {

class RangeSummary {
 public:
  // At most ~7 MB of cells and levels; while the first pass runs, also one row of its tiles
  // (64 rows x the source width) and 8 rows of per-block minima and maxima.
  static constexpr uint64_t kMaxCells = uint64_t(1) << 18;
  // The cell side for a w x h source: the smallest power of two >= 4 giving at most kMaxCells cells.
  static int cell_for(int w, int h);
  // The level a query of rectangle q uses in a source of w x h samples (blocks of 4 << level).
  static int level_for(const SampleRect& q, int w, int h);

  // Starts a summary of a w x h source (forgets any earlier one).
  void start(int w, int h);
  // Samples [c0, c0 + cw) x [r0, r0 + rh), row-major, NaN = nodata: the tiles of the first pass,
  // rows of tiles from the top, each row of tiles left to right across the whole width.
  void add_tile(int c0, int r0, int cw, int rh, const float* z);
  // A void that will be filled: its bounding box and its rim's [min, max].
  void add_filled_void(const SampleRect& bbox, float rim_lo, float rim_hi);
  // After every tile and void: builds the coarser levels.
  void finish();
  // Upper bound (metres) on the surface range over the sample rectangle [c0, c1] x [r0, r1]
  // (taps included by the caller); 0 when it holds no data.
  double surface_range_bound(int c0, int r0, int c1, int r1) const;

  int cell() const { return cell_; }
  uint64_t bytes() const;

 private:
  struct Level {
    int gw = 0, gh = 0;                // blocks of the whole source at this level
    std::vector<float> lo, hi, local;  // per block; lo > hi = no data
  };
  void process_row(int r, const float* z);
  void process_block_row(int by);

  int w_ = 0, h_ = 0, cell_ = 4, g_ = 0;  // g_: the level of the cells (cell_ = 4 << g_)
  std::vector<Level> levels_;             // levels_[i]: level g_ + i
  std::vector<float> tlo_, thi_;          // per cell: its tap range (valid samples, then voids)
  std::vector<uint8_t> void_touched_;     // per cell: a filled void meets its taps
  // The first pass's current row of tiles, and per row of 4 x 4 block columns: the blocks' own
  // min/max and their taps' min/max in that row (a ring of the last 8 rows).
  std::vector<float> strip_;
  int strip_r0_ = 0, strip_rows_ = 0;
  int nbx_ = 0, next_row_ = 0, next_block_row_ = 0;
  std::vector<float> ring_;  // 8 rows x 4 arrays x nbx_
};

}  // namespace terrain::cook
