#include "pyramid/quantize.h"

#include <algorithm>
#include <cstring>
#include <fmt/format.h>

#include "avx2_clones.h"

namespace terrain::cook {
namespace {

// format/SPEC.md caps step_log2 at 14; 16 bits at 2^14 units span 2^20 m, far beyond the
// +-16384 m any vertex may hold (compute_window refuses such heights), so the cap never binds.
constexpr int kMaxStepLog2 = 14;

// Smallest s with (range_units + rounding) <= 65535 * 2^s.
int step_for(double range_units, double rounding_units) {
  int s = 0;
  while (s < kMaxStepLog2 && range_units + rounding_units > 65535.0 * std::ldexp(1.0, s)) ++s;
  return s;
}

}  // namespace

// GCC's vector extensions: 4 doubles (one AVX2 register, two SSE2 ones), no FMA in either clone.
typedef double V4d __attribute__((vector_size(32)));
typedef int64_t V4l __attribute__((vector_size(32)));
typedef int32_t V4i __attribute__((vector_size(16)));

TERRAIN_AVX2_CLONES bool quantize_row(const double* h, const uint8_t* ok, const double* scale, const double* step, int n,
                                      int32_t* units, uint8_t* hole) {
  const double limit = double(kMaxHeightUnits) * kHeightUnitM;
  const double max_units = double(kMaxHeightUnits);
  const V4d zero = {0, 0, 0, 0}, half = {0.5, 0.5, 0.5, 0.5}, one = {1, 1, 1, 1};
  V4l bad = {0, 0, 0, 0};
  int i = 0;
  for (; i + 4 <= n; i += 4) {
    V4d hv, sv, st;
    std::memcpy(&hv, h + i, sizeof hv);
    std::memcpy(&sv, scale + i, sizeof sv);
    std::memcpy(&st, step + i, sizeof st);
    const V4l with = {-int64_t(ok[i] != 0), -int64_t(ok[i + 1] != 0), -int64_t(ok[i + 2] != 0), -int64_t(ok[i + 3] != 0)};
    hv = with ? hv : zero;
    // Range first (as the per-vertex loop): NaN and heights beyond the archive's are bad.
    const V4l in_range = (hv <= limit) & (hv >= -limit);
    bad |= with & ~in_range;
    V4d v = hv * sv + half;
    v = in_range ? v : zero;  // |v| <= 2^24 + 0.5 in range: the int32 conversion is exact
    V4d t = __builtin_convertvector(__builtin_convertvector(v, V4i), V4d);
    t = t - ((t > v) ? one : zero);
    V4d u = t * st;  // an integer times a power of two below 2^53: exact
    bad |= with & ((u > max_units) | (u < -max_units));
    u = (with & ~bad) ? u : zero;
    const V4i ui = __builtin_convertvector(u, V4i);
    std::memcpy(units + i, &ui, sizeof ui);
    for (int l = 0; l < 4; ++l) hole[i + l] = uint8_t(ok[i + l] == 0);
  }
  bool good = (bad[0] | bad[1] | bad[2] | bad[3]) == 0;
  for (; i < n; ++i) {
    if (!ok[i]) {
      units[i] = 0;
      hole[i] = 1;
      continue;
    }
    const bool in_range = std::fabs(h[i]) <= limit;
    const double v = in_range ? h[i] * scale[i] + 0.5 : 0.0;
    const double t = double(int32_t(v)), f = t > v ? t - 1.0 : t;
    const double u = f * step[i];
    good = good && in_range && u <= max_units && u >= -max_units;
    units[i] = good ? int32_t(u) : 0;
    hole[i] = 0;
  }
  return good;
}

int step_at_most(double metres) {
  int s = 0;
  while (s < kMaxStepLog2 && std::ldexp(1.0, s + 1) * kHeightUnitM <= metres) ++s;
  return s;
}

int tolerance_step(double tolerance_m) { return step_at_most(tolerance_m / 32.0); }

int required_step(double range_bound_m, int root_step) {
  const double units = std::max(range_bound_m, 0.0) * 1024.0 + 1.0;
  if (root_step >= 0) return step_for(units, std::ldexp(1.0, root_step));
  for (int s = 0; s < kMaxStepLog2; ++s)
    if (units + std::ldexp(1.0, s) <= 65535.0 * std::ldexp(1.0, s)) return s;
  return kMaxStepLog2;
}

Status pack_heights(const int32_t* units, const uint8_t* hole, int stride, int step_log2, NodeRecord& record,
                    std::array<uint16_t, kHeightCount>& r16) {
  int32_t lo = INT32_MAX, hi = INT32_MIN;
  bool any_hole = false;
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) {
      const size_t k = size_t(j) * size_t(stride) + size_t(i);
      if (hole[k]) { any_hole = true; continue; }
      lo = std::min(lo, units[k]);
      hi = std::max(hi, units[k]);
    }
  if (lo > hi) return Status::failure(Error::no_data, "every vertex of the node is a hole");
  const int32_t mask = (int32_t(1) << step_log2) - 1;
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) {
      const size_t k = size_t(j) * size_t(stride) + size_t(i);
      uint16_t r = 0;
      if (!hole[k]) {
        const int32_t d = units[k] - lo;
        if ((d & mask) != 0 || (d >> step_log2) > 65535)
          return Status::failure(Error::internal,
                                 fmt::format("height {} units does not fit step 2^{} from offset {}", units[k], step_log2, lo));
        r = uint16_t(d >> step_log2);
      }
      r16[size_t(j) * kHeightSamples + size_t(i)] = r;
    }
  record.height_offset = lo;
  record.min_height = lo;
  record.max_height = hi;
  record.flags = uint8_t(any_hole ? (record.flags | kNodeFlagHasHoles) : (record.flags & ~kNodeFlagHasHoles));
  return Status::success();
}

}  // namespace terrain::cook
