// Conservative height-range queries over source sample rectangles, for choosing quantization steps
// before any node is cooked.
//
// A Catmull-Rom value lies within [min - 0.28125 r, max + 0.28125 r] of its 16 taps (r = their
// range; 0.28125 is the largest total negative weight of the 2-D kernel), and the bilinear
// fallback within [min, max]. So over a rectangle the surface range is at most
//   (max - min of its samples) + 0.5625 * (largest 4x4 tap range inside it).
#pragma once
#include <cmath>
#include <vector>

#include "raster.h"

namespace terrain::cook {

class RangeIndex {
 public:
  void build(const Raster& raster);
  // Upper bound (metres) on the surface range over the sample rectangle [c0, c1] x [r0, r1]
  // (taps included by the caller); 0 when it holds no data. May look up to a few samples beyond.
  double surface_range_bound(int c0, int r0, int c1, int r1) const;

 private:
  struct Level {
    int w = 0, h = 0;
    std::vector<float> lo, hi, local;  // per block; NaN lo/hi = no data
    static Level empty(int w, int h) {  // w x h blocks without data
      const size_t n = size_t(w) * size_t(h);
      return {w, h, std::vector<float>(n, NAN), std::vector<float>(n, NAN), std::vector<float>(n, 0.0f)};
    }
  };
  std::vector<Level> levels_;  // levels_[k]: blocks of 4 << k samples
};

}  // namespace terrain::cook
