#include "quantize.h"

#include <algorithm>
#include <fmt/format.h>

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

int tolerance_step(double tolerance_m) {
  int s = 0;
  while (s < kMaxStepLog2 && std::ldexp(1.0, s + 1) * kHeightUnitM <= tolerance_m / 32.0) ++s;
  return s;
}

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
