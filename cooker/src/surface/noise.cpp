// fbm_noise over a row of points from per-octave lattice tables (noise.h).
#include "noise.h"

#include <algorithm>

namespace terrain::cook {
namespace {
constexpr int kChunk = 128;  // points summed at once (the row sums live on the stack)
constexpr int kSlackCells = 4;  // cells a table reaches past the row's, for the next rows' points

// The table of one octave covering cells [lo, hi] (and the corner after hi) of lattice row iv.
void prepare_table(NoiseRowTable& t, uint32_t seed, int64_t iv, int64_t lo, int64_t hi) {
  const int64_t count = t.valid ? int64_t(t.below.size()) : 0;
  if (t.valid && t.seed == seed && t.iv == iv && lo >= t.iu0 && hi + 1 < t.iu0 + count) return;
  t.valid = true;
  t.seed = seed;
  t.iv = iv;
  t.iu0 = lo - kSlackCells;
  const size_t cells = size_t(hi - lo + 2 + 2 * kSlackCells);
  t.below.resize(cells);
  t.above.resize(cells);
  for (size_t j = 0; j < cells; ++j) {
    t.below[j] = lattice_value(t.iu0 + int64_t(j), iv, seed);
    t.above[j] = lattice_value(t.iu0 + int64_t(j), iv + 1, seed);
  }
}

void fbm_chunk(const double* x_m, const int* idx, int count, double y_m, double scale_m, int octaves, uint32_t seed,
               double min_wavelength_m, NoiseRowTables& tables, double* out) {
  double x[kChunk], sum[kChunk];
  double x_lo = x_m[idx ? idx[0] : 0], x_hi = x_lo;
  bool finite = true;
  for (int i = 0; i < count; ++i) {
    x[i] = x_m[idx ? idx[i] : i];
    sum[i] = 0;
    finite = finite && std::isfinite(x[i]);
    x_lo = std::min(x_lo, x[i]);
    x_hi = std::max(x_hi, x[i]);
  }
  // fbm_noise's loop, octave by octave for all points (each point's sum in the same order).
  double amp = 1, norm = 0, f = 1.0 / scale_m;
  for (int o = 0; o < octaves; ++o) {
    if (f * min_wavelength_m <= 1.0) {
      const uint32_t s = seed + uint32_t(o) * 0x9E37u;
      const double v = y_m * f;
      // Multiplication by f > 0 keeps the order of the points, so every point's cell lies in
      // [floor(x_lo f), floor(x_hi f)]; 2^52 keeps the cell numbers exact in int64.
      const double u_lo = x_lo * f, u_hi = x_hi * f;
      const bool table = finite && o < 8 && f > 0 && std::isfinite(v) && std::fabs(v) < 0x1p52 &&
                         std::fabs(u_lo) < 0x1p52 && std::fabs(u_hi) < 0x1p52 &&
                         fast_floor(u_hi) - fast_floor(u_lo) < kMaxNoiseTableCells;
      if (!table) {
        for (int i = 0; i < count; ++i) sum[i] += amp * value_noise(x[i] * f, v, s);
      } else {
        const double fv = fast_floor(v);
        const double tv = v - fv;
        const double sv = tv * tv * (3 - 2 * tv);
        NoiseRowTable& t = tables.octave[o];
        prepare_table(t, s, int64_t(fv), int64_t(fast_floor(u_lo)), int64_t(fast_floor(u_hi)));
        const double* below = t.below.data();
        const double* above = t.above.data();
        for (int i = 0; i < count; ++i) {
          // value_noise's arithmetic on the table's corners.
          const double u = x[i] * f;
          const double fu = fast_floor(u);
          const double tu = u - fu;
          const double su = tu * tu * (3 - 2 * tu);
          const size_t j = size_t(int64_t(fu) - t.iu0);
          const double a = below[j], b = below[j + 1], c = above[j], d = above[j + 1];
          const double ab = a + (b - a) * su, cd = c + (d - c) * su;
          sum[i] += amp * (ab + (cd - ab) * sv);
        }
      }
    }
    norm += amp;
    amp *= 0.5;
    f *= 2.0;
  }
  for (int i = 0; i < count; ++i) out[i] = norm > 0 ? sum[i] / norm : 0.0;
}
}  // namespace

void fbm_noise_row(const double* x_m, const int* idx, int count, double y_m, double scale_m, int octaves,
                   uint32_t seed, double min_wavelength_m, NoiseRowTables& tables, double* out) {
  for (int i0 = 0; i0 < count; i0 += kChunk) {
    const int m = std::min(kChunk, count - i0);
    fbm_chunk(idx ? x_m : x_m + i0, idx ? idx + i0 : nullptr, m, y_m, scale_m, octaves, seed, min_wavelength_m, tables,
              out + i0);
  }
}

}  // namespace terrain::cook
