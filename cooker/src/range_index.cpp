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

int blocks(int samples, int k) { return (samples + (kBase << k) - 1) / (kBase << k); }

// Levels of the whole source: until one block covers it.
int level_count(int w, int h) {
  int k = 0;
  while (blocks(w, k) > 1 || blocks(h, k) > 1) ++k;
  return k + 1;
}

// Base-level blocks [bx0, bx0 + bw) x [by0, by0 + bh) from the samples of `win`.
template <class At>
void build_base(int bx0, int by0, int bw, int bh, int w, int h, const At& at, std::vector<float>& lo_out,
                std::vector<float>& hi_out, std::vector<float>& local_out) {
  const size_t n = size_t(bw) * size_t(bh);
  lo_out.assign(n, NAN);
  hi_out.assign(n, NAN);
  local_out.assign(n, 0.0f);
  for (int by = by0; by < by0 + bh; ++by)
    for (int bx = bx0; bx < bx0 + bw; ++bx) {
      const size_t b = size_t(by - by0) * size_t(bw) + size_t(bx - bx0);
      // Block samples for lo/hi; the block's cells' Catmull-Rom taps (one more sample west/south,
      // two more east/north) for the local range.
      float lo = NAN, hi = NAN, tlo = NAN, thi = NAN;
      const int c0 = bx * kBase, r0 = by * kBase;
      for (int row = std::max(r0 - 1, 0); row < std::min(r0 + kBase + 2, h); ++row)
        for (int col = std::max(c0 - 1, 0); col < std::min(c0 + kBase + 2, w); ++col) {
          const float v = at(col, row);
          if (std::isnan(v)) continue;
          merge(tlo, thi, v, v);
          if (row >= r0 && row < r0 + kBase && col >= c0 && col < c0 + kBase) merge(lo, hi, v, v);
        }
      lo_out[b] = lo;
      hi_out[b] = hi;
      local_out[b] = std::isnan(tlo) ? 0.0f : thi - tlo;
    }
}

}  // namespace

int RangeIndex::level_for(const SampleRect& q, int w, int h) {
  // The level whose blocks cover the rectangle with at most ~16 blocks per side.
  const int span = std::max(q.c1 - q.c0, q.r1 - q.r0) + 1;
  const int top = level_count(w, h) - 1;
  int k = 0;
  while (k < top && (kBase << k) * 16 < span) ++k;
  return k;
}

SampleRect RangeIndex::window_for(const SampleRect& q, int k, int w, int h) {
  const int size = kBase << k;
  auto lo = [&](int v) { return v < 0 ? 0 : v / size * size; };
  auto hi = [&](int v, int n) { return v < 0 ? size - 1 : std::min(n - 1, v / size * size + size - 1); };
  const SampleRect a{lo(q.c0), lo(q.r0), hi(q.c1, w), hi(q.r1, h)};
  return intersect(SampleRect{a.c0 - 1, a.r0 - 1, a.c1 + 2, a.r1 + 2}, SampleRect{0, 0, w - 1, h - 1});
}

void RangeIndex::build(const Raster& r) {
  SampleWindow whole;
  whole.rect = {0, 0, r.width - 1, r.height - 1};
  whole.source_width = r.width;
  whole.source_height = r.height;
  // The index reads through the window; a copy-free view would do, but this path is for tests
  // and small sources only.
  whole.values = r.values;
  build(whole, level_count(r.width, r.height) - 1);
}

void RangeIndex::build(const SampleWindow& win, int top) {
  // The previous build's arrays are reused (a cook builds one index per block: no new pages).
  std::vector<Level> old;
  old.swap(levels_);
  auto recycled = [&](size_t k) {
    Level l;
    if (k < old.size()) {
      l.lo = std::move(old[k].lo);
      l.hi = std::move(old[k].hi);
      l.local = std::move(old[k].local);
    }
    return l;
  };
  const int w = win.source_width, h = win.source_height;
  w_ = w;
  h_ = h;
  top = std::min(top, level_count(w, h) - 1);
  // Level 0 holds the blocks whose samples and taps (clipped to the source) lie in the window;
  // level k the blocks all of whose level k-1 children are held, so no block is ever partial.
  Level base = recycled(0);
  base.gw = blocks(w, 0);
  base.gh = blocks(h, 0);
  auto first = [](int lo) { return lo <= 0 ? 0 : (lo + 1 + kBase - 1) / kBase; };
  auto last = [](int hi, int n, int g) { return hi >= n - 1 ? g - 1 : (hi - 2 + 1) / kBase - 1; };
  base.bx0 = first(win.rect.c0);
  base.by0 = first(win.rect.r0);
  base.w = last(win.rect.c1, w, base.gw) - base.bx0 + 1;
  base.h = last(win.rect.r1, h, base.gh) - base.by0 + 1;
  if (base.w <= 0 || base.h <= 0) return;
  build_base(base.bx0, base.by0, base.w, base.h, w, h, [&](int c, int r) { return win.at(c, r); }, base.lo, base.hi,
             base.local);
  levels_.push_back(std::move(base));
  for (int k = 1; k <= top; ++k) {
    const Level& f = levels_.back();
    Level c = recycled(size_t(k));
    c.gw = blocks(w, k);
    c.gh = blocks(h, k);
    const int fx1 = f.bx0 + f.w - 1, fy1 = f.by0 + f.h - 1;
    c.bx0 = (f.bx0 + 1) / 2;
    c.by0 = (f.by0 + 1) / 2;
    c.w = (fx1 == f.gw - 1 ? fx1 / 2 : (fx1 + 1) / 2 - 1) - c.bx0 + 1;
    c.h = (fy1 == f.gh - 1 ? fy1 / 2 : (fy1 + 1) / 2 - 1) - c.by0 + 1;
    if (c.w <= 0 || c.h <= 0) break;
    const size_t n = size_t(c.w) * size_t(c.h);
    c.lo.assign(n, NAN);
    c.hi.assign(n, NAN);
    c.local.assign(n, 0.0f);
    for (int y = 0; y < c.h; ++y)
      for (int x = 0; x < c.w; ++x) {
        const size_t d = size_t(y) * size_t(c.w) + size_t(x);
        for (int fy = 2 * (c.by0 + y); fy <= std::min(2 * (c.by0 + y) + 1, fy1); ++fy)
          for (int fx = 2 * (c.bx0 + x); fx <= std::min(2 * (c.bx0 + x) + 1, fx1); ++fx) {
            const size_t s = size_t(fy - f.by0) * size_t(f.w) + size_t(fx - f.bx0);
            merge(c.lo[d], c.hi[d], f.lo[s], f.hi[s]);
            c.local[d] = std::max(c.local[d], f.local[s]);
          }
      }
    levels_.push_back(std::move(c));
  }
}

double RangeIndex::surface_range_bound(int c0, int r0, int c1, int r1) const {
  if (levels_.empty() || c1 < c0 || r1 < r0) return 0.0;
  const size_t k = size_t(level_for({c0, r0, c1, r1}, w_, h_));
  if (c1 < 0 || r1 < 0) return 0.0;
  if (k >= levels_.size()) return INFINITY;
  const Level& l = levels_[k];
  const int size = kBase << k;
  const int bx0 = std::clamp(c0 < 0 ? -1 : c0 / size, 0, l.gw - 1), bx1 = std::clamp(c1 / size, 0, l.gw - 1);
  const int by0 = std::clamp(r0 < 0 ? -1 : r0 / size, 0, l.gh - 1), by1 = std::clamp(r1 / size, 0, l.gh - 1);
  if (bx0 < l.bx0 || by0 < l.by0 || bx1 >= l.bx0 + l.w || by1 >= l.by0 + l.h) return INFINITY;
  float lo = NAN, hi = NAN, local = 0;
  for (int by = by0; by <= by1; ++by)
    for (int bx = bx0; bx <= bx1; ++bx) {
      const size_t b = size_t(by - l.by0) * size_t(l.w) + size_t(bx - l.bx0);
      merge(lo, hi, l.lo[b], l.hi[b]);
      local = std::max(local, l.local[b]);
    }
  if (std::isnan(lo)) return 0.0;
  return double(hi) - double(lo) + 0.5625 * double(local);
}

}  // namespace terrain::cook
