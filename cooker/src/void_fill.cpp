#include "void_fill.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>

#include "memory_budget.h"

namespace terrain::cook {
namespace {

struct Void {
  std::vector<uint32_t> samples;  // indices, in breadth-first order from the void's first sample
  bool touches_border = false;
};

// Harmonic fill of one void: breadth-first initial guess from the rim, then SOR sweeps.
double fill_one(Raster& r, const Void& v, std::vector<uint8_t>& filled) {
  const int w = r.width, h = r.height;
  float* z = r.values.data();
  // Initial guess: visit samples nearest the rim first (multi-source BFS from valid neighbours).
  std::vector<uint32_t> order;
  order.reserve(v.samples.size());
  std::vector<uint8_t> done(v.samples.size(), 0);
  // Local index of each void sample (the void's own samples only).
  std::vector<std::pair<uint32_t, uint32_t>> local(v.samples.size());
  for (uint32_t i = 0; i < v.samples.size(); ++i) local[i] = {v.samples[i], i};
  std::sort(local.begin(), local.end());
  auto local_of = [&](uint32_t idx) -> int64_t {
    auto it = std::lower_bound(local.begin(), local.end(), std::make_pair(idx, 0u));
    return it != local.end() && it->first == idx ? int64_t(it->second) : -1;
  };
  std::vector<std::array<int64_t, 4>> nbr(v.samples.size());  // local index, -1 valid/outside handled below
  for (uint32_t i = 0; i < v.samples.size(); ++i) {
    const uint32_t idx = v.samples[i];
    const int x = int(idx % uint32_t(w)), y = int(idx / uint32_t(w));
    const int64_t cand[4] = {x > 0 ? int64_t(idx) - 1 : -2, x + 1 < w ? int64_t(idx) + 1 : -2,
                             y > 0 ? int64_t(idx) - w : -2, y + 1 < h ? int64_t(idx) + w : -2};
    for (int k = 0; k < 4; ++k) {
      if (cand[k] == -2) { nbr[i][size_t(k)] = -2; continue; }                    // outside the raster
      const int64_t l = local_of(uint32_t(cand[k]));
      nbr[i][size_t(k)] = l >= 0 ? l : -(cand[k] + 3);                             // <= -3: valid sample
    }
  }
  auto value_of = [&](int64_t code) -> float { return z[size_t(-code - 3)]; };
  std::vector<uint32_t> queue;
  for (uint32_t i = 0; i < v.samples.size(); ++i)
    for (int64_t c : nbr[i])
      if (c <= -3) { queue.push_back(i); done[i] = 1; break; }
  for (size_t qi = 0; qi < queue.size(); ++qi) {
    const uint32_t i = queue[qi];
    double sum = 0;
    int n = 0;
    for (int64_t c : nbr[i]) {
      if (c <= -3) { sum += value_of(c); ++n; }
      else if (c >= 0 && done[size_t(c)] == 2) { sum += z[v.samples[size_t(c)]]; ++n; }
    }
    z[v.samples[i]] = float(sum / std::max(n, 1));
    done[i] = 2;
    for (int64_t c : nbr[i])
      if (c >= 0 && done[size_t(c)] == 0) { done[size_t(c)] = 1; queue.push_back(uint32_t(c)); }
  }
  // Successive over-relaxation towards the discrete Laplace equation.
  const double omega = 1.85;
  const size_t max_sweeps = 4000;
  double last = 0;
  for (size_t sweep = 0; sweep < max_sweeps; ++sweep) {
    double change = 0;
    for (uint32_t i = 0; i < v.samples.size(); ++i) {
      double sum = 0;
      int n = 0;
      for (int64_t c : nbr[i]) {
        if (c <= -3) { sum += value_of(c); ++n; }
        else if (c >= 0) { sum += z[v.samples[size_t(c)]]; ++n; }
      }
      if (n == 0) continue;
      float& zi = z[v.samples[i]];
      const double next = zi + omega * (sum / n - zi);
      change = std::max(change, std::fabs(next - zi));
      zi = float(next);
    }
    last = change;
    if (change < 1e-4) break;
  }
  for (uint32_t idx : v.samples) filled[idx] = 1;
  return last;
}

}  // namespace

Status fill_voids(Raster& r, NodataPolicy policy, int64_t max_fill_samples, std::vector<uint8_t>& filled,
                  VoidStats& stats, uint64_t memory_limit_bytes) {
  stats = VoidStats{};
  filled.assign(r.values.size(), 0);
  const int w = r.width, h = r.height;
  std::vector<uint8_t> seen(r.values.size(), 0);
  std::vector<uint32_t> stack;
  for (size_t start = 0; start < r.values.size(); ++start) {
    if (!std::isnan(r.values[start]) || seen[start]) continue;
    Void v;
    stack.assign(1, uint32_t(start));
    seen[start] = 1;
    while (!stack.empty()) {
      const uint32_t idx = stack.back();
      stack.pop_back();
      v.samples.push_back(idx);
      const int x = int(idx % uint32_t(w)), y = int(idx / uint32_t(w));
      if (x == 0 || y == 0 || x == w - 1 || y == h - 1) v.touches_border = true;
      const int64_t cand[4] = {x > 0 ? int64_t(idx) - 1 : -1, x + 1 < w ? int64_t(idx) + 1 : -1,
                               y > 0 ? int64_t(idx) - w : -1, y + 1 < h ? int64_t(idx) + w : -1};
      for (int64_t c : cand)
        if (c >= 0 && !seen[size_t(c)] && std::isnan(r.values[size_t(c)])) {
          seen[size_t(c)] = 1;
          stack.push_back(uint32_t(c));
        }
    }
    const bool fill = policy == NodataPolicy::fill ||
                      (policy == NodataPolicy::automatic && !v.touches_border &&
                       int64_t(v.samples.size()) <= max_fill_samples);
    if (fill && v.samples.size() < r.values.size()) {
      const uint64_t need = uint64_t(r.values.size()) * kCookBytesPerSample + uint64_t(v.samples.size()) * kFillBytesPerVoidSample;
      if (Status st = check_memory(need, memory_limit_bytes, r.path,
                                   fmt::format("filling a void of {} samples next to sample ({}, {})",
                                               format_count(v.samples.size()), v.samples[0] % uint32_t(w),
                                               v.samples[0] / uint32_t(w)),
                                   "raise --memory-limit, or leave large voids as holes (--nodata auto or hole)");
          !st.ok())
        return st;
      stats.max_residual_m = std::max(stats.max_residual_m, fill_one(r, v, filled));
      stats.filled_samples += v.samples.size();
      stats.filled_regions += 1;
    } else {
      stats.hole_samples += v.samples.size();
      stats.hole_regions += 1;
    }
  }
  return Status::success();
}

}  // namespace terrain::cook
