#include "range_index.h"

#include <algorithm>
#include <cmath>

namespace terrain::cook {
namespace {

constexpr int kBase = 4;  // samples per block side at level 0

void merge(float& lo, float& hi, float vlo, float vhi) {
  if (std::isnan(vlo)) return;
  if (std::isnan(lo) || vlo < lo) lo = vlo;
  if (std::isnan(hi) || vhi > hi) hi = vhi;
}

}  // namespace

void RangeIndex::build(const Raster& r) {
  levels_.clear();
  Level base = Level::empty((r.width + kBase - 1) / kBase, (r.height + kBase - 1) / kBase);
  for (int by = 0; by < base.h; ++by)
    for (int bx = 0; bx < base.w; ++bx) {
      const size_t b = size_t(by) * size_t(base.w) + size_t(bx);
      // Block samples for lo/hi; the block's cells' Catmull-Rom taps (one more sample west/south,
      // two more east/north) for the local range.
      float lo = NAN, hi = NAN, tlo = NAN, thi = NAN;
      const int c0 = bx * kBase, r0 = by * kBase;
      for (int row = std::max(r0 - 1, 0); row < std::min(r0 + kBase + 2, r.height); ++row)
        for (int col = std::max(c0 - 1, 0); col < std::min(c0 + kBase + 2, r.width); ++col) {
          const float v = r.at(col, row);
          if (std::isnan(v)) continue;
          merge(tlo, thi, v, v);
          if (row >= r0 && row < r0 + kBase && col >= c0 && col < c0 + kBase) merge(lo, hi, v, v);
        }
      base.lo[b] = lo;
      base.hi[b] = hi;
      base.local[b] = std::isnan(tlo) ? 0.0f : thi - tlo;
    }
  levels_.push_back(std::move(base));
  while (levels_.back().w > 1 || levels_.back().h > 1) {
    const Level& f = levels_.back();
    Level c = Level::empty((f.w + 1) / 2, (f.h + 1) / 2);
    for (int y = 0; y < f.h; ++y)
      for (int x = 0; x < f.w; ++x) {
        const size_t s = size_t(y) * size_t(f.w) + size_t(x), d = size_t(y / 2) * size_t(c.w) + size_t(x / 2);
        merge(c.lo[d], c.hi[d], f.lo[s], f.hi[s]);
        c.local[d] = std::max(c.local[d], f.local[s]);
      }
    levels_.push_back(std::move(c));
  }
}

double RangeIndex::surface_range_bound(int c0, int r0, int c1, int r1) const {
  if (levels_.empty() || c1 < c0 || r1 < r0) return 0.0;
  // The level whose blocks cover the rectangle with at most ~16 blocks per side.
  const int span = std::max(c1 - c0, r1 - r0) + 1;
  size_t k = 0;
  while (k + 1 < levels_.size() && (kBase << k) * 16 < span) ++k;
  const Level& l = levels_[k];
  const int size = kBase << k;
  const int bx0 = std::clamp(c0 < 0 ? -1 : c0 / size, 0, l.w - 1), bx1 = std::clamp(c1 / size, 0, l.w - 1);
  const int by0 = std::clamp(r0 < 0 ? -1 : r0 / size, 0, l.h - 1), by1 = std::clamp(r1 / size, 0, l.h - 1);
  if (c1 < 0 || r1 < 0) return 0.0;
  float lo = NAN, hi = NAN, local = 0;
  for (int by = by0; by <= by1; ++by)
    for (int bx = bx0; bx <= bx1; ++bx) {
      const size_t b = size_t(by) * size_t(l.w) + size_t(bx);
      merge(lo, hi, l.lo[b], l.hi[b]);
      local = std::max(local, l.local[b]);
    }
  if (std::isnan(lo)) return 0.0;
  return double(hi) - double(lo) + 0.5625 * double(local);
}

}  // namespace terrain::cook
