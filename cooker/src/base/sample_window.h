// A rectangle of the source's samples held in memory: the unit of the block-wise cook.
// Coordinates are always the whole source's (the mosaic's) sample indices, so every block maps a
// frame position to the same sample and reads the same bits, whatever block it belongs to.
#pragma once
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "base/large_buffer.h"

namespace terrain::cook {

// Inclusive sample rectangle [c0, c1] x [r0, r1] in whole-source coordinates.
struct SampleRect {
  int c0 = 0, r0 = 0, c1 = -1, r1 = -1;
  bool empty() const { return c1 < c0 || r1 < r0; }
  int width() const { return empty() ? 0 : c1 - c0 + 1; }
  int height() const { return empty() ? 0 : r1 - r0 + 1; }
  uint64_t samples() const { return uint64_t(width()) * uint64_t(height()); }
  bool operator==(const SampleRect&) const = default;
  bool contains(const SampleRect& o) const {
    return o.empty() || (!empty() && o.c0 >= c0 && o.r0 >= r0 && o.c1 <= c1 && o.r1 <= r1);
  }
};
inline SampleRect unite(const SampleRect& a, const SampleRect& b) {
  if (a.empty()) return b;
  if (b.empty()) return a;
  return {std::min(a.c0, b.c0), std::min(a.r0, b.r0), std::max(a.c1, b.c1), std::max(a.r1, b.r1)};
}
inline SampleRect intersect(const SampleRect& a, const SampleRect& b) {
  return {std::max(a.c0, b.c0), std::max(a.r0, b.r0), std::min(a.c1, b.c1), std::min(a.r1, b.r1)};
}
inline SampleRect grow(const SampleRect& a, int by) { return {a.c0 - by, a.r0 - by, a.c1 + by, a.r1 + by}; }

// Heights (NaN = nodata) and filled-void flags of `rect`, row-major; the whole source is
// `source_width` x `source_height` samples (edges of the surface are the source's, not the window's).
struct SampleWindow {
  SampleRect rect;
  int source_width = 0, source_height = 0;
  LargeVector<float> values;    // resize() leaves new samples uninitialised: the reader fills them
  LargeVector<uint8_t> filled;  // 1 = a filled void sample (not source data); empty = none
  // The grid family of the input that gave each sample (MosaicSource::read; 255 = none, a filled
  // void among them); empty when the inputs form one family (every sample is family 0's).
  LargeVector<uint8_t> family;
  size_t index(int c, int r) const { return size_t(r - rect.r0) * size_t(rect.width()) + size_t(c - rect.c0); }
  float at(int c, int r) const { return values[index(c, r)]; }
  bool is_filled(int c, int r) const { return !filled.empty() && filled[index(c, r)]; }
  static constexpr uint8_t kNoFamily = 255;
};

}  // namespace terrain::cook
