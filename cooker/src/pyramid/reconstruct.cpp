#include "pyramid/reconstruct.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "avx2_clones.h"

namespace terrain::cook {
namespace {

constexpr int kRun = 64;  // points per pass of sample_points (its scratch lives on the stack)

// The Axis of every point of a run, as SourceSurface::axis() computes it (same operations; the floor
// goes through int32, exact for the coordinates inside the raster's band, |x| < size + 2), in
// structure-of-arrays form. AVX2 only widens the lanes: no FMA, so the bits are the baseline's.
struct RunAxes {
  alignas(32) double t[2][kRun];
  alignas(32) double w[2][4][kRun];
  alignas(32) int32_t i[2][kRun];
  alignas(32) int32_t in[kRun];
};

// GCC's vector extensions: 4 lanes (one AVX2 register, two SSE2 ones), written out because the
// auto-vectoriser keeps the floor's select as a branch.
typedef double V4d __attribute__((vector_size(32)));
typedef int32_t V4i __attribute__((vector_size(16)));

// Unaligned loads and stores as memcpy (no function passes a V4d by value: that ABI needs AVX).
#define TERRAIN_STORE4(p, v) \
  do {                       \
    const V4d v_ = (v);      \
    std::memcpy((p), &v_, sizeof v_); \
  } while (0)

TERRAIN_AVX2_CLONES void run_axes(const double* __restrict cols, const double* __restrict rows, int n, int width,
                                  int height, RunAxes& a) {
  alignas(32) double cp[kRun] = {}, rp[kRun] = {};
  std::memcpy(cp, cols, sizeof(double) * size_t(n));
  std::memcpy(rp, rows, sizeof(double) * size_t(n));
  const V4d lo = {-2.0, -2.0, -2.0, -2.0};
  const V4d wmax = {width + 1.0, width + 1.0, width + 1.0, width + 1.0};
  const V4d hmax = {height + 1.0, height + 1.0, height + 1.0, height + 1.0};
  const V4d one = {1.0, 1.0, 1.0, 1.0}, zero = {0.0, 0.0, 0.0, 0.0};
  for (int k = 0; k < n; k += 4) {
    V4d c, r;
    std::memcpy(&c, cp + k, sizeof c);
    std::memcpy(&r, rp + k, sizeof r);
    const auto in = (c > lo) & (c < wmax) & (r > lo) & (r < hmax);  // NaN-safe
    const V4i in32 = __builtin_convertvector(in, V4i);
    std::memcpy(&a.in[k], &in32, sizeof in32);
    // Clamped (NaN to -2) so that every lane converts; lanes outside are not read further.
    V4d cs = c > lo ? c : lo, rs = r > lo ? r : lo;
    cs = cs < wmax ? cs : wmax;
    rs = rs < hmax ? rs : hmax;
    const V4d tc = __builtin_convertvector(__builtin_convertvector(cs, V4i), V4d);
    const V4d tr = __builtin_convertvector(__builtin_convertvector(rs, V4i), V4d);
    const V4d fc = tc - (tc > cs ? one : zero), fr = tr - (tr > rs ? one : zero);  // fast_floor
    const V4i ic = __builtin_convertvector(fc, V4i), ir = __builtin_convertvector(fr, V4i);
    std::memcpy(&a.i[0][k], &ic, sizeof ic);
    std::memcpy(&a.i[1][k], &ir, sizeof ir);
    const V4d xc = cs - fc, xr = rs - fr;
    TERRAIN_STORE4(&a.t[0][k], xc);
    TERRAIN_STORE4(&a.t[1][k], xr);
    // catmull_rom_weights(), term for term.
    const V4d c2 = xc * xc, c3 = c2 * xc, r2 = xr * xr, r3 = r2 * xr;
    TERRAIN_STORE4(&a.w[0][0][k], 0.5 * (-c3 + 2.0 * c2 - xc));
    TERRAIN_STORE4(&a.w[0][1][k], 0.5 * (3.0 * c3 - 5.0 * c2 + 2.0));
    TERRAIN_STORE4(&a.w[0][2][k], 0.5 * (-3.0 * c3 + 4.0 * c2 + xc));
    TERRAIN_STORE4(&a.w[0][3][k], 0.5 * (c3 - c2));
    TERRAIN_STORE4(&a.w[1][0][k], 0.5 * (-r3 + 2.0 * r2 - xr));
    TERRAIN_STORE4(&a.w[1][1][k], 0.5 * (3.0 * r3 - 5.0 * r2 + 2.0));
    TERRAIN_STORE4(&a.w[1][2][k], 0.5 * (-3.0 * r3 + 4.0 * r2 + xr));
    TERRAIN_STORE4(&a.w[1][3][k], 0.5 * (r3 - r2));
  }
}
#undef TERRAIN_STORE4

// The interior 16-tap sums of a run: per point, the four rows' horizontal sums in the lanes of one
// register (lane j: x0 p0 + x1 p1 + x2 p2 + x3 p3 of row j, the scalar order), then the vertical
// sum over the lanes in order from +0. Consecutive points in one source cell (sources coarser than
// the vertices) reuse its taps, already widened and transposed. Points outside the interior are
// marked 2 in `done` for the general path; 1 = h written (a NaN sum included, see the caller).
TERRAIN_AVX2_CLONES void interior_sums(const RunAxes& a, int m, const float* z, ptrdiff_t stride, int c0, int r0,
                                       int width, int height, double* h, uint8_t* done) {
  typedef float V4f __attribute__((vector_size(16)));
  V4d col[4] = {};
  int cell_c = -1 << 30, cell_r = -1 << 30;
  for (int k = 0; k < m; ++k) {
    const int ic = a.i[0][k], ir = a.i[1][k];
    if (!a.in[k] || !(SourceSurface::taps_inside(ic, width) && SourceSurface::taps_inside(ir, height))) {
      done[k] = 2;
      continue;
    }
    if (ic != cell_c || ir != cell_r) {
      const float* p = z + ptrdiff_t(ir - 1 - r0) * stride + ptrdiff_t(ic - 1 - c0);
      V4d row[4];
      for (int j = 0; j < 4; ++j) {
        V4f f;
        std::memcpy(&f, p + j * stride, sizeof f);
        row[j] = __builtin_convertvector(f, V4d);
      }
      // Transpose: col[i] lane j = tap i of row j.
      const V4d t0 = __builtin_shufflevector(row[0], row[1], 0, 4, 2, 6), t1 = __builtin_shufflevector(row[0], row[1], 1, 5, 3, 7);
      const V4d t2 = __builtin_shufflevector(row[2], row[3], 0, 4, 2, 6), t3 = __builtin_shufflevector(row[2], row[3], 1, 5, 3, 7);
      col[0] = __builtin_shufflevector(t0, t2, 0, 1, 4, 5);
      col[1] = __builtin_shufflevector(t1, t3, 0, 1, 4, 5);
      col[2] = __builtin_shufflevector(t0, t2, 2, 3, 6, 7);
      col[3] = __builtin_shufflevector(t1, t3, 2, 3, 6, 7);
      cell_c = ic;
      cell_r = ir;
    }
    const double x0 = a.w[0][0][k], x1 = a.w[0][1][k], x2 = a.w[0][2][k], x3 = a.w[0][3][k];
    const V4d r = ((x0 * col[0] + x1 * col[1]) + x2 * col[2]) + x3 * col[3];
    double sum = 0;
    for (int j = 0; j < 4; ++j) sum += a.w[1][j][k] * r[j];
    h[k] = sum;
    done[k] = 1;
  }
}

}  // namespace

void SourceSurface::sample_points(const double* cols, const double* rows, int n, double* h, uint8_t* ok) const {
  RunAxes a;
  uint8_t done[kRun];
  for (int k0 = 0; k0 < n; k0 += kRun) {
    const int m = std::min(kRun, n - k0);
    run_axes(cols + k0, rows + k0, m, w_, h_, a);
    interior_sums(a, m, z_, stride_, c0_, r0_, w_, h_, h + k0, done);
    for (int k = 0; k < m; ++k) {
      if (!a.in[k]) {
        ok[k0 + k] = 0;
        continue;
      }
      if (done[k] == 1 && !std::isnan(h[k0 + k])) {
        ok[k0 + k] = 1;
        continue;
      }
      Axis x, y;  // edges and nodata taps: sample()'s general path
      x.in = y.in = true;
      x.i = a.i[0][k];
      y.i = a.i[1][k];
      x.t = a.t[0][k];
      y.t = a.t[1][k];
      for (int j = 0; j < 4; ++j) x.w[j] = a.w[0][j][k], y.w[j] = a.w[1][j][k];
      ok[k0 + k] = sample_general(x, y, h[k0 + k]);
    }
  }
}

bool SourceSurface::zeros_in(int c0, int r0, int c1, int r1) const {
  if (c0 < std::max(0, c0_) || r0 < std::max(0, r0_) || c1 >= std::min(w_, c0_ + int(stride_)) ||
      r1 >= std::min(h_, r0_ + rows_) || c1 < c0 || r1 < r0)
    return false;
  for (int r = r0; r <= r1; ++r) {
    const float* p = at(c0, r);
    bool zero = true;  // the whole row at once (no early exit per sample: the loop vectorises)
    for (int c = 0; c <= c1 - c0; ++c) zero &= p[c] == 0.0f;  // false for NaN
    if (!zero) return false;
  }
  return true;
}

SourceSurface::ZeroBounds SourceSurface::zero_bounds(double cmin, double cmax, double rmin, double rmax, int spare) const {
  ZeroBounds b;
  constexpr double kFar = 1e9;  // beyond any raster (and NaN): no bounds
  if (!(cmin > -kFar && cmax < kFar && rmin > -kFar && rmax < kFar && cmin <= cmax && rmin <= rmax)) return b;
  // A point's taps are columns floor(c) - 1 .. floor(c) + 2: inside c0..c1 for c0 + 1 <= c < c1 - 1.
  const int c0 = int(std::floor(cmin)) - 1 - spare, c1 = int(std::floor(cmax)) + 2 + spare;
  const int r0 = int(std::floor(rmin)) - 1 - spare, r1 = int(std::floor(rmax)) + 2 + spare;
  if (!zeros_in(c0, r0, c1, r1)) return b;
  b.c_lo = c0 + 1.0;
  b.c_hi = c1 - 1.0;
  b.r_lo = r0 + 1.0;
  b.r_hi = r1 - 1.0;
  return b;
}

bool SourceSurface::sample_general(const Axis& x, const Axis& y, double& h) const {
  const int ic = x.i, ir = y.i;
  const double tx = x.t, ty = y.t;
  const double* wx = x.w;
  const double* wy = y.w;
  if (!nearest_valid(ic, ir, tx, ty)) return false;  // the hole test of covered()
  double sum = 0;
  if (taps_inside(ic, w_) && taps_inside(ir, h_)) {
    const float* p = at(ic - 1, ir - 1);
    for (int j = 0; j < 4; ++j, p += stride_)
      sum += wy[j] * (wx[0] * p[0] + wx[1] * p[1] + wx[2] * p[2] + wx[3] * p[3]);
  } else {
    // Next to the raster's edge: taps beyond it continue the two outermost samples linearly along
    // each axis, so planes (and the data's slope) carry on to the edge and across the half-sample
    // apron instead of flattening.
    for (int j = 0; j < 4; ++j) {
      const int r = ir - 1 + j;
      double along = 0;
      for (int i = 0; i < 4; ++i) along += wx[i] * extended(ic - 1 + i, r);
      sum += wy[j] * along;
    }
  }
  if (!std::isnan(sum)) {  // a NaN tap (nodata) poisons the sum: fall back below
    h = sum;
    return true;
  }
  // Bilinear over the valid taps of the 2x2 cell; a nearest tap is valid (covered) and carries
  // weight >= 1/4, so the normaliser is positive.
  sum = 0;
  double wsum = 0;
  for (int j = 0; j < 2; ++j) {
    const int r = ir + j;
    if (r < 0 || r >= h_) continue;
    const double wr = j ? ty : 1.0 - ty;
    for (int i = 0; i < 2; ++i) {
      const int c = ic + i;
      if (c < 0 || c >= w_) continue;
      const float v = *at(c, r);
      if (std::isnan(v)) continue;
      const double wgt = wr * (i ? tx : 1.0 - tx);
      sum += wgt * v;
      wsum += wgt;
    }
  }
  // No valid tap in the cell: a point in the widened outer apron (set_outer_apron) more than a
  // sample beyond the raster; the outermost sample it is covered by carries it.
  h = wsum > 0 ? sum / wsum : clamped_nearest(ic, ir, tx, ty);
  return true;
}

}  // namespace terrain::cook
