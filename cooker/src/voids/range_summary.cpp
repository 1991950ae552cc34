#include "voids/range_summary.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace terrain::cook {
namespace {

constexpr int kBase = 4;  // samples per block side at level 0
constexpr float kInf = std::numeric_limits<float>::infinity();

int blocks(int samples, int size) { return (samples + size - 1) / size; }

// Levels of the whole source: until one block covers it.
int level_count(int w, int h) {
  int k = 0;
  while (blocks(w, kBase << k) > 1 || blocks(h, kBase << k) > 1) ++k;
  return k + 1;
}

// min/max ignoring NaN (a NaN compares false).
inline void take(float v, float& lo, float& hi) {
  if (v < lo) lo = v;
  if (v > hi) hi = v;
}

}  // namespace

int RangeSummary::cell_for(int w, int h) {
  int g = kBase;
  while (uint64_t(blocks(w, g)) * uint64_t(blocks(h, g)) > kMaxCells) g *= 2;
  return g;
}

int RangeSummary::level_for(const SampleRect& q, int w, int h) {
  // The level whose blocks cover the rectangle with at most ~16 blocks per side.
  const int span = std::max(q.c1 - q.c0, q.r1 - q.r0) + 1;
  const int top = level_count(w, h) - 1;
  int k = 0;
  while (k < top && (kBase << k) * 16 < span) ++k;
  return k;
}

void RangeSummary::start(int w, int h) {
  *this = RangeSummary{};
  w_ = std::max(w, 0);
  h_ = std::max(h, 0);
  cell_ = cell_for(w_, h_);
  g_ = 0;
  while ((kBase << g_) < cell_) ++g_;
  Level l;
  l.gw = blocks(w_, cell_);
  l.gh = blocks(h_, cell_);
  const size_t n = size_t(l.gw) * size_t(l.gh);
  l.lo.assign(n, kInf);
  l.hi.assign(n, -kInf);
  l.local.assign(n, 0.0f);
  levels_.push_back(std::move(l));
  tlo_.assign(n, kInf);
  thi_.assign(n, -kInf);
  void_touched_.assign(n, 0);
  nbx_ = blocks(w_, kBase);
  ring_.assign(size_t(8) * 4 * size_t(nbx_), 0.0f);
}

void RangeSummary::add_tile(int c0, int r0, int cw, int rh, const float* z) {
  if (c0 == 0) {
    strip_r0_ = r0;
    strip_rows_ = rh;
    strip_.resize(size_t(w_) * size_t(rh));
  }
  for (int y = 0; y < rh; ++y)
    std::copy(z + size_t(y) * size_t(cw), z + size_t(y + 1) * size_t(cw), strip_.data() + size_t(y) * size_t(w_) + size_t(c0));
  if (c0 + cw < w_) return;
  // The row of tiles is complete: its rows in order.
  for (int y = 0; y < strip_rows_; ++y) process_row(strip_r0_ + y, strip_.data() + size_t(y) * size_t(w_));
}

void RangeSummary::process_row(int r, const float* z) {
  // Per block column: the block's own samples [4 bx, 4 bx + 3] and its taps [4 bx - 1, 4 bx + 5].
  float* ring = ring_.data() + size_t(r % 8) * 4 * size_t(nbx_);
  float *blo = ring, *bhi = ring + nbx_, *tlo = ring + 2 * nbx_, *thi = ring + 3 * nbx_;
  for (int bx = 0; bx < nbx_; ++bx) {
    const int c0 = bx * kBase;
    float lo = kInf, hi = -kInf;
    for (int c = c0; c < std::min(c0 + kBase, w_); ++c) take(z[c], lo, hi);
    blo[bx] = lo;
    bhi[bx] = hi;
    if (c0 > 0) take(z[c0 - 1], lo, hi);
    for (int c = c0 + kBase; c < std::min(c0 + kBase + 2, w_); ++c) take(z[c], lo, hi);
    tlo[bx] = lo;
    thi[bx] = hi;
  }
  next_row_ = r + 1;
  // Block rows whose taps (one row before, two after, clipped) are all here.
  while (next_block_row_ * kBase < h_ && std::min(next_block_row_ * kBase + kBase + 1, h_ - 1) <= r)
    process_block_row(next_block_row_++);
}

void RangeSummary::process_block_row(int by) {
  const int r0 = by * kBase;
  const int own1 = std::min(r0 + kBase - 1, h_ - 1), tap0 = std::max(r0 - 1, 0), tap1 = std::min(r0 + kBase + 1, h_ - 1);
  Level& l = levels_[0];
  const int cy = r0 / cell_;
  for (int bx = 0; bx < nbx_; ++bx) {
    float lo = kInf, hi = -kInf, tl = kInf, th = -kInf;
    for (int r = tap0; r <= tap1; ++r) {
      const float* ring = ring_.data() + size_t(r % 8) * 4 * size_t(nbx_);
      if (r >= r0 && r <= own1) {
        lo = std::min(lo, ring[bx]);
        hi = std::max(hi, ring[nbx_ + bx]);
      }
      tl = std::min(tl, ring[2 * nbx_ + bx]);
      th = std::max(th, ring[3 * nbx_ + bx]);
    }
    const size_t cell = size_t(cy) * size_t(l.gw) + size_t(bx * kBase / cell_);
    l.lo[cell] = std::min(l.lo[cell], lo);
    l.hi[cell] = std::max(l.hi[cell], hi);
    if (tl <= th) l.local[cell] = std::max(l.local[cell], th - tl);  // the steps pass's float subtraction
    tlo_[cell] = std::min(tlo_[cell], tl);
    thi_[cell] = std::max(thi_[cell], th);
  }
}

void RangeSummary::add_filled_void(const SampleRect& b, float rim_lo, float rim_hi) {
  if (levels_.empty() || b.empty() || !(rim_lo <= rim_hi)) return;
  Level& l = levels_[0];
  const int G = cell_;
  // Cells holding its samples.
  for (int cy = std::max(b.r0, 0) / G; cy <= std::min(b.r1, h_ - 1) / G; ++cy)
    for (int cx = std::max(b.c0, 0) / G; cx <= std::min(b.c1, w_ - 1) / G; ++cx) {
      const size_t c = size_t(cy) * size_t(l.gw) + size_t(cx);
      l.lo[c] = std::min(l.lo[c], rim_lo);
      l.hi[c] = std::max(l.hi[c], rim_hi);
    }
  // Cells whose taps [C0 - 1, C0 + G + 1] meet its samples: those holding samples c0 - 2 .. c1 + 1.
  for (int cy = std::max(b.r0 - 2, 0) / G; cy <= std::min(b.r1 + 1, h_ - 1) / G; ++cy)
    for (int cx = std::max(b.c0 - 2, 0) / G; cx <= std::min(b.c1 + 1, w_ - 1) / G; ++cx) {
      const size_t c = size_t(cy) * size_t(l.gw) + size_t(cx);
      tlo_[c] = std::min(tlo_[c], rim_lo);
      thi_[c] = std::max(thi_[c], rim_hi);
      void_touched_[c] = 1;
    }
}

void RangeSummary::finish() {
  if (levels_.empty()) return;
  {
    Level& l = levels_[0];
    // A cell whose taps meet a filled void: every tap range in it is within its valid taps' and
    // the voids' rims' union.
    for (size_t c = 0; c < l.local.size(); ++c)
      if (void_touched_[c] && tlo_[c] <= thi_[c]) l.local[c] = std::max(l.local[c], thi_[c] - tlo_[c]);
  }
  tlo_ = {};
  thi_ = {};
  void_touched_ = {};
  ring_ = {};
  strip_ = {};
  const int top = std::max(level_count(w_, h_) - 1, g_);
  for (int k = g_ + 1; k <= top; ++k) {
    const Level& f = levels_.back();
    Level c;
    c.gw = blocks(w_, kBase << k);
    c.gh = blocks(h_, kBase << k);
    const size_t n = size_t(c.gw) * size_t(c.gh);
    c.lo.assign(n, kInf);
    c.hi.assign(n, -kInf);
    c.local.assign(n, 0.0f);
    for (int y = 0; y < c.gh; ++y)
      for (int x = 0; x < c.gw; ++x) {
        const size_t d = size_t(y) * size_t(c.gw) + size_t(x);
        for (int fy = 2 * y; fy <= std::min(2 * y + 1, f.gh - 1); ++fy)
          for (int fx = 2 * x; fx <= std::min(2 * x + 1, f.gw - 1); ++fx) {
            const size_t s = size_t(fy) * size_t(f.gw) + size_t(fx);
            c.lo[d] = std::min(c.lo[d], f.lo[s]);
            c.hi[d] = std::max(c.hi[d], f.hi[s]);
            c.local[d] = std::max(c.local[d], f.local[s]);
          }
      }
    levels_.push_back(std::move(c));
  }
}

double RangeSummary::surface_range_bound(int c0, int r0, int c1, int r1) const {
  if (levels_.empty() || c1 < c0 || r1 < r0 || c1 < 0 || r1 < 0) return 0.0;
  const int k = std::min(std::max(level_for({c0, r0, c1, r1}, w_, h_), g_), g_ + int(levels_.size()) - 1);
  const Level& l = levels_[size_t(k - g_)];
  const int size = kBase << k;
  const int bx0 = std::clamp(c0 < 0 ? 0 : c0 / size, 0, l.gw - 1), bx1 = std::clamp(c1 / size, 0, l.gw - 1);
  const int by0 = std::clamp(r0 < 0 ? 0 : r0 / size, 0, l.gh - 1), by1 = std::clamp(r1 / size, 0, l.gh - 1);
  float lo = kInf, hi = -kInf, local = 0;
  for (int by = by0; by <= by1; ++by)
    for (int bx = bx0; bx <= bx1; ++bx) {
      const size_t b = size_t(by) * size_t(l.gw) + size_t(bx);
      lo = std::min(lo, l.lo[b]);
      hi = std::max(hi, l.hi[b]);
      local = std::max(local, l.local[b]);
    }
  if (!(lo <= hi)) return 0.0;
  return double(hi) - double(lo) + 0.5625 * double(local);
}

uint64_t RangeSummary::bytes() const {
  uint64_t b = (tlo_.capacity() + thi_.capacity() + ring_.capacity() + strip_.capacity()) * sizeof(float) +
               void_touched_.capacity();
  for (const Level& l : levels_) b += (l.lo.capacity() + l.hi.capacity() + l.local.capacity()) * sizeof(float);
  return b;
}

}  // namespace terrain::cook
