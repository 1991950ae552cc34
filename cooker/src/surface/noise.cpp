// fbm_noise over a row of points from per-octave lattice tables (noise.h).
#include "noise.h"

#include <algorithm>
#include <cstring>

#include "avx2_clones.h"

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

// GCC's vector extensions, 4 lanes (an AVX2 register, two SSE2 ones).
typedef double V4d __attribute__((vector_size(32)));
typedef int64_t V4l __attribute__((vector_size(32)));

// The table loop below for points 0 .. count rounded down to 4, 4 at a time: each lane the scalar
// loop's operations in order. fast_floor(u) is the integer nearest to u (u + 1.5 * 2^52 - 1.5 *
// 2^52, exact for |u| < 2^51), less 1 where that exceeds u: the same double. The corner's table
// entry is the low bits of (floor - iu0) + 1.5 * 2^52.
TERRAIN_AVX2_CLONES void octave_lanes(const double* x, int count, double f, double sv, double amp, double iu0,
                                      const double* below, const double* above, double* sum) {
  const double magic = 6755399441055744.0;  // 1.5 * 2^52
  const V4d vf = {f, f, f, f}, vsv = {sv, sv, sv, sv}, vamp = {amp, amp, amp, amp};
  const V4d vmagic = {magic, magic, magic, magic}, one = {1, 1, 1, 1}, two = {2, 2, 2, 2}, three = {3, 3, 3, 3};
  const V4d base = {iu0 - magic, iu0 - magic, iu0 - magic, iu0 - magic};
  for (int i = 0; i + 4 <= count; i += 4) {
    V4d xi, acc;
    std::memcpy(&xi, x + i, sizeof xi);
    std::memcpy(&acc, sum + i, sizeof acc);
    const V4d u = xi * vf;
    const V4d r = (u + vmagic) - vmagic;
    const V4d fu = r > u ? r - one : r;
    const V4d tu = u - fu;
    const V4d su = tu * tu * (three - two * tu);
    const V4l j = V4l(fu - base) & V4l{0xFFFFFFFF, 0xFFFFFFFF, 0xFFFFFFFF, 0xFFFFFFFF};
    const V4d a = {below[j[0]], below[j[1]], below[j[2]], below[j[3]]};
    const V4d b = {below[j[0] + 1], below[j[1] + 1], below[j[2] + 1], below[j[3] + 1]};
    const V4d c = {above[j[0]], above[j[1]], above[j[2]], above[j[3]]};
    const V4d d = {above[j[0] + 1], above[j[1] + 1], above[j[2] + 1], above[j[3] + 1]};
    const V4d ab = a + (b - a) * su, cd = c + (d - c) * su;
    acc += vamp * (ab + (cd - ab) * vsv);
    std::memcpy(sum + i, &acc, sizeof acc);
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
      // [floor(x_lo f), floor(x_hi f)]; under 2^51 the lanes' rounding trick is exact.
      const double u_lo = x_lo * f, u_hi = x_hi * f;
      const bool table = finite && o < 8 && f > 0 && std::isfinite(v) && std::fabs(v) < 0x1p51 &&
                         std::fabs(u_lo) < 0x1p51 && std::fabs(u_hi) < 0x1p51 &&
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
        octave_lanes(x, count, f, sv, amp, double(t.iu0), below, above, sum);
        for (int i = count / 4 * 4; i < count; ++i) {
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
