// Conservative height-range queries over source sample rectangles, for choosing quantization steps
// before any node is cooked.
//
// A Catmull-Rom value lies within [min - 0.28125 r, max + 0.28125 r] of its 16 taps (r = their
// range; 0.28125 is the largest total negative weight of the 2-D kernel), and the bilinear
// fallback within [min, max]. So over a rectangle the surface range is at most
//   (max - min of its samples) + 0.5625 * (largest 4x4 tap range inside it).
//
// Blocks are aligned to the whole source (block b of level k holds samples [b, b + 1) * (4 << k)),
// and a query's level depends on its span and the source's size only, so an index built over a
// window (the block-wise cook) answers every query inside it with the bits of an index over the
// whole source.
#pragma once
#include <cmath>
#include <vector>

#include "raster.h"
#include "sample_window.h"

namespace terrain::cook {

class RangeIndex {
 public:
  // The index of the whole raster.
  void build(const Raster& raster);
  // The index of levels 0 .. top over `win`, whose rect must hold window_for(query, top) of every
  // query asked (checked: a query outside answers +infinity).
  void build(const SampleWindow& win, int top);
  // Upper bound (metres) on the surface range over the sample rectangle [c0, c1] x [r0, r1]
  // (taps included by the caller); 0 when it holds no data. May look up to a few samples beyond.
  double surface_range_bound(int c0, int r0, int c1, int r1) const;

  // The level a query of rectangle q uses in a source of w x h samples.
  static int level_for(const SampleRect& q, int w, int h);
  // The samples an index must hold to answer query q at level k: q's blocks and the taps of their
  // local ranges (one sample before, two after), clipped to the w x h source.
  static SampleRect window_for(const SampleRect& q, int k, int w, int h);

 private:
  struct Level {
    int bx0 = 0, by0 = 0;  // the first block held (whole-source block index)
    int w = 0, h = 0;      // blocks held
    int gw = 0, gh = 0;    // blocks of the whole source at this level
    std::vector<float> lo, hi, local;  // per block; NaN lo/hi = no data
  };
  std::vector<Level> levels_;  // levels_[k]: blocks of 4 << k samples
  int w_ = 0, h_ = 0;          // the whole source
};

}  // namespace terrain::cook
