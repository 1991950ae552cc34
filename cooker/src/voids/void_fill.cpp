#include "voids/void_fill.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <fmt/format.h>

#include "base/large_buffer.h"
#include "base/memory_budget.h"

namespace terrain::cook {
namespace {

// Sample indices are window-local; 32 bits when the window allows (half the memory per void sample).
template <class Index>
using Samples = std::vector<Index>;  // in depth-first order from the void's first sample

// Harmonic fill of one void of a w x h window: breadth-first initial guess from the rim, then SOR
// sweeps. Every neighbour of the void's samples lies in the window or outside the raster.
template <class Index>
double fill_one(float* z, int w, int h, const Samples<Index>& samples, uint8_t* filled) {
  std::vector<uint8_t> done(samples.size(), 0);
  // Local index of each void sample (the void's own samples only).
  std::vector<std::pair<Index, Index>> local(samples.size());
  for (Index i = 0; i < samples.size(); ++i) local[i] = {samples[i], i};
  std::sort(local.begin(), local.end());
  auto local_of = [&](Index idx) -> int64_t {
    auto it = std::lower_bound(local.begin(), local.end(), std::make_pair(idx, Index(0)));
    return it != local.end() && it->first == idx ? int64_t(it->second) : -1;
  };
  std::vector<std::array<int64_t, 4>> nbr(samples.size());  // local index, -1 valid/outside handled below
  for (Index i = 0; i < samples.size(); ++i) {
    const Index idx = samples[i];
    const int x = int(idx % Index(w)), y = int(idx / Index(w));
    const int64_t cand[4] = {x > 0 ? int64_t(idx) - 1 : -2, x + 1 < w ? int64_t(idx) + 1 : -2,
                             y > 0 ? int64_t(idx) - w : -2, y + 1 < h ? int64_t(idx) + w : -2};
    for (int k = 0; k < 4; ++k) {
      if (cand[k] == -2) { nbr[i][size_t(k)] = -2; continue; }                    // outside the raster
      const int64_t l = local_of(Index(cand[k]));
      nbr[i][size_t(k)] = l >= 0 ? l : -(cand[k] + 3);                             // <= -3: valid sample
    }
  }
  auto value_of = [&](int64_t code) -> float { return z[size_t(-code - 3)]; };
  // The rim: the valid samples next to the void. The harmonic solution lies within their
  // [min, max]; the fill is clamped to it so that an unconverged over-relaxation cannot leave it
  // either (range_summary.h bounds the filled values by it).
  float rim_lo = INFINITY, rim_hi = -INFINITY;
  for (const auto& n4 : nbr)
    for (int64_t c : n4)
      if (c <= -3) {
        rim_lo = std::min(rim_lo, value_of(c));
        rim_hi = std::max(rim_hi, value_of(c));
      }
  std::vector<Index> queue;
  for (Index i = 0; i < samples.size(); ++i)
    for (int64_t c : nbr[i])
      if (c <= -3) { queue.push_back(i); done[i] = 1; break; }
  for (size_t qi = 0; qi < queue.size(); ++qi) {
    const Index i = queue[qi];
    double sum = 0;
    int n = 0;
    for (int64_t c : nbr[i]) {
      if (c <= -3) { sum += value_of(c); ++n; }
      else if (c >= 0 && done[size_t(c)] == 2) { sum += z[samples[size_t(c)]]; ++n; }
    }
    z[samples[i]] = float(sum / std::max(n, 1));
    done[i] = 2;
    for (int64_t c : nbr[i])
      if (c >= 0 && done[size_t(c)] == 0) { done[size_t(c)] = 1; queue.push_back(Index(c)); }
  }
  // Successive over-relaxation towards the discrete Laplace equation.
  const double omega = 1.85;
  const size_t max_sweeps = 4000;
  double last = 0;
  for (size_t sweep = 0; sweep < max_sweeps; ++sweep) {
    double change = 0;
    for (Index i = 0; i < samples.size(); ++i) {
      double sum = 0;
      int n = 0;
      for (int64_t c : nbr[i]) {
        if (c <= -3) { sum += value_of(c); ++n; }
        else if (c >= 0) { sum += z[samples[size_t(c)]]; ++n; }
      }
      if (n == 0) continue;
      float& zi = z[samples[i]];
      const double next = zi + omega * (sum / n - zi);
      change = std::max(change, std::fabs(next - zi));
      zi = float(next);
    }
    last = change;
    if (change < 1e-4) break;
  }
  if (rim_lo <= rim_hi)
    for (Index idx : samples) z[idx] = std::clamp(z[idx], rim_lo, rim_hi);
  for (Index idx : samples) filled[idx] = 1;
  return last;
}

template <class Index>
Status fill_complete_voids_as(const FillWindow& win, float* z, uint8_t* filled, NodataPolicy policy,
                              int64_t max_fill_samples, uint64_t base_bytes, const std::string& what,
                              VoidStats& stats, uint64_t memory_limit_bytes) {
  const int w = win.w, h = win.h;
  const int rw = win.raster_width, rh = win.raster_height;
  const size_t n = size_t(w) * size_t(h);
  const uint64_t raster_samples = uint64_t(rw) * uint64_t(rh);
  // Window edges inside the raster: a void reaching one may continue beyond the window.
  const bool open_left = win.c0 > 0, open_right = win.c0 + w < rw;
  const bool open_top = win.r0 > 0, open_bottom = win.r0 + h < rh;
  // Most windows of real data hold no nodata at all: find the first one with a branch-free scan
  // (it vectorises) before clearing a flag per sample.
  size_t first = n;
  for (size_t base = 0; base < n && first == n; base += 256) {
    const size_t end = std::min(n, base + 256);
    bool any = false;
    for (size_t i = base; i < end; ++i) any |= z[i] != z[i];
    if (any)
      for (size_t i = base; i < end; ++i)
        if (std::isnan(z[i])) {
          first = i;
          break;
        }
  }
  if (first == n) return Status::success();
  thread_local LargeVector<uint8_t> seen;  // reused: a cook fills one window per block and pass
  seen.assign(n, 0);
  std::vector<Index> stack;
  Samples<Index> samples;
  for (size_t start = first; start < n; ++start) {
    if (!std::isnan(z[start]) || seen[start]) continue;
    // Depth-first from the void's first sample, neighbours left, right, up, down: this order
    // (through fill_one) decides the filled values' bits, so it must not change.
    samples.clear();
    bool touches_border = false, cut = false;
    stack.assign(1, Index(start));
    seen[start] = 1;
    while (!stack.empty()) {
      const Index idx = stack.back();
      stack.pop_back();
      samples.push_back(idx);
      const int x = int(idx % Index(w)), y = int(idx / Index(w));
      const int gx = win.c0 + x, gy = win.r0 + y;
      if (gx == 0 || gy == 0 || gx == rw - 1 || gy == rh - 1) touches_border = true;
      if ((x == 0 && open_left) || (x == w - 1 && open_right) || (y == 0 && open_top) || (y == h - 1 && open_bottom))
        cut = true;
      const int64_t cand[4] = {x > 0 ? int64_t(idx) - 1 : -1, x + 1 < w ? int64_t(idx) + 1 : -1,
                               y > 0 ? int64_t(idx) - w : -1, y + 1 < h ? int64_t(idx) + w : -1};
      for (int64_t c : cand)
        if (c >= 0 && !seen[size_t(c)] && std::isnan(z[size_t(c)])) {
          seen[size_t(c)] = 1;
          stack.push_back(Index(c));
        }
    }
    if (cut) continue;  // not all of it is here: its caller leaves it nodata
    const bool fill = policy == NodataPolicy::fill ||
                      (policy == NodataPolicy::automatic && !touches_border &&
                       int64_t(samples.size()) <= max_fill_samples);
    if (fill && samples.size() < raster_samples) {
      const uint64_t need = base_bytes + uint64_t(samples.size()) * kFillBytesPerVoidSample;
      if (Status st = check_memory(need, memory_limit_bytes, what,
                                   fmt::format("filling a void of {} samples next to sample ({}, {})",
                                               format_count(samples.size()), win.c0 + int(samples[0] % Index(w)),
                                               win.r0 + int(samples[0] / Index(w))),
                                   "raise --memory-limit, or leave large voids as holes (--nodata auto or hole)");
          !st.ok())
        return st;
      stats.max_residual_m = std::max(stats.max_residual_m, fill_one<Index>(z, w, h, samples, filled));
      stats.filled_samples += samples.size();
      stats.filled_regions += 1;
    } else {
      stats.hole_samples += samples.size();
      stats.hole_regions += 1;
    }
  }
  return Status::success();
}

}  // namespace

Status fill_complete_voids(const FillWindow& window, float* values, uint8_t* filled, NodataPolicy policy,
                           int64_t max_fill_samples, uint64_t base_bytes, const std::string& what, VoidStats& stats,
                           uint64_t memory_limit_bytes) {
  if (uint64_t(window.w) * uint64_t(window.h) <= UINT32_MAX)
    return fill_complete_voids_as<uint32_t>(window, values, filled, policy, max_fill_samples, base_bytes, what, stats,
                                            memory_limit_bytes);
  return fill_complete_voids_as<uint64_t>(window, values, filled, policy, max_fill_samples, base_bytes, what, stats,
                                          memory_limit_bytes);
}

Status fill_voids(Raster& r, NodataPolicy policy, int64_t max_fill_samples, std::vector<uint8_t>& filled,
                  VoidStats& stats, uint64_t memory_limit_bytes) {
  stats = VoidStats{};
  filled.assign(r.values.size(), 0);
  // The whole raster is one window: every void is complete in it.
  const FillWindow whole{r.width, r.height, 0, 0, r.width, r.height};
  return fill_complete_voids(whole, r.values.data(), filled.data(), policy, max_fill_samples,
                             uint64_t(r.values.size()) * kCookBytesPerSample, r.path, stats, memory_limit_bytes);
}

}  // namespace terrain::cook
