// Our block encoders.
//
// BC1 colour (own_encode_bc1_opaque / own_encode_bc1_weighted): PCA extremes, then alternate
//  (a) nearest-palette index assignment and (b) per-channel endpoint optimisation for the fixed
//  indices. (b) is exact over a small window of quantised 5/6-bit endpoint pairs around the
//  least-squares solution: for fixed indices the squared error separates by channel, and each
//  candidate pair costs four multiply-adds from per-index sums (n_k, S_k, Q_k). This is where the
//  quality over stb_dxt comes from (stb rounds its least-squares endpoints once).
// BC4 (own_encode_bc4): min/max start, then the same alternation in one channel for the 8-value
//  mode; the 6-value mode is tried when the block touches 0 or 255.
// Ordering search (own_cluster setting): see ordering_search() below; a sorted-order partition
//  search like libsquish's cluster fit, restricted to coordinate sweeps over the group boundaries.
// Conservative BC4 (own_encode_bc4_upper): every decoded value >= its target, minimising the sum
//  of excesses over one free endpoint (exhaustive, 256 candidates).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include "bc_blocks.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace terrain::cook {
namespace {

inline int expand5(int q) { return (q << 3) | (q >> 2); }
inline int expand6(int q) { return (q << 2) | (q >> 4); }
inline int expand_bits(int q, int bits) { return bits == 5 ? expand5(q) : expand6(q); }

// Principal axis of a colour covariance (xx, xy, xz, yy, yz, zz) by three power iterations,
// starting from `ax` (the bounding-box diagonal) with the covariance's signs; unchanged when the
// covariance is zero.
inline void principal_axis(const float cov[6], float ax[3]) {
  if (cov[1] < 0) ax[1] = -ax[1];
  if (cov[2] < 0) ax[2] = -ax[2];
  for (int it = 0; it < 3; ++it) {
    const float x = cov[0] * ax[0] + cov[1] * ax[1] + cov[2] * ax[2];
    const float y = cov[1] * ax[0] + cov[3] * ax[1] + cov[4] * ax[2];
    const float z = cov[2] * ax[0] + cov[4] * ax[1] + cov[5] * ax[2];
    const float m = std::max({std::fabs(x), std::fabs(y), std::fabs(z)});
    if (!(m > 0)) break;
    const float inv = 1.0f / m;
    ax[0] = x * inv; ax[1] = y * inv; ax[2] = z * inv;
  }
}
constexpr int kBits[3] = {5, 6, 5};

void write16(uint8_t* p, uint16_t v) { p[0] = uint8_t(v); p[1] = uint8_t(v >> 8); }
void write32(uint8_t* p, uint32_t v) {
  p[0] = uint8_t(v); p[1] = uint8_t(v >> 8); p[2] = uint8_t(v >> 16); p[3] = uint8_t(v >> 24);
}

// All three channels at once for fixed indices: the least-squares normal equations depend only on
// the index counts, so they are solved once (integer coefficients scaled by 9 or 4), then each
// channel tries the 2x2 (reach 1) or 4x4 (reach 2) nearest quantised endpoint pairs.
struct ExpandTables {
  int e5[32], e6[64];
  ExpandTables() {
    for (int q = 0; q < 32; ++q) e5[q] = expand5(q);
    for (int q = 0; q < 64; ++q) e6[q] = expand6(q);
  }
};
const ExpandTables& expand_tables() {
  static const ExpandTables t;
  return t;
}

void fit_endpoints(const int n[4], const int s[3][4], const int q[3][4], bool four, int reach, int q0[3], int q1[3]) {
  // Normal equations scaled so the coefficients are integers.
  int A, B, C, X[3], Y[3];
  if (four) {  // weights of e0: 1, 0, 2/3, 1/3 (scale 9)
    A = 9 * n[0] + 4 * n[2] + n[3];
    B = 2 * (n[2] + n[3]);
    C = 9 * n[1] + n[2] + 4 * n[3];
    for (int c = 0; c < 3; ++c) {
      X[c] = 3 * (3 * s[c][0] + 2 * s[c][2] + s[c][3]);
      Y[c] = 3 * (3 * s[c][1] + s[c][2] + 2 * s[c][3]);
    }
  } else {  // weights of e0: 1, 0, 1/2 (scale 4)
    A = 4 * n[0] + n[2];
    B = n[2];
    C = 4 * n[1] + n[2];
    for (int c = 0; c < 3; ++c) {
      X[c] = 2 * (2 * s[c][0] + s[c][2]);
      Y[c] = 2 * (2 * s[c][1] + s[c][2]);
    }
  }
  const int det = A * C - B * B;
  const ExpandTables& ex = expand_tables();
  for (int c = 0; c < 3; ++c) {
    const int bits = kBits[c], qmax = (1 << bits) - 1;
    const int* expand = bits == 5 ? ex.e5 : ex.e6;
    float e0, e1;
    if (det != 0) {
      const float inv = 1.0f / float(det);
      e0 = float(X[c] * C - Y[c] * B) * inv;
      e1 = float(Y[c] * A - X[c] * B) * inv;
    } else {
      const int total = n[0] + n[1] + n[2] + (four ? n[3] : 0);
      const int sum = s[c][0] + s[c][1] + s[c][2] + (four ? s[c][3] : 0);
      e0 = e1 = total ? float(sum) / float(total) : 0.0f;
    }
    const float scale = float(qmax) / 255.0f;
    const int b0 = int(std::clamp(e0, 0.0f, 255.0f) * scale), b1 = int(std::clamp(e1, 0.0f, 255.0f) * scale);
    int best = INT32_MAX, bq0 = b0, bq1 = b1;
    for (int d0 = 1 - reach; d0 <= reach; ++d0) {
      const int c0 = b0 + d0;
      if (c0 < 0 || c0 > qmax) continue;
      const int v0 = expand[c0];
      for (int d1 = 1 - reach; d1 <= reach; ++d1) {
        const int c1 = b1 + d1;
        if (c1 < 0 || c1 > qmax) continue;
        const int v1 = expand[c1];
        const int p2 = four ? (2 * v0 + v1 + 1) / 3 : (v0 + v1 + 1) / 2, p3 = (v0 + 2 * v1 + 1) / 3;
        int err = n[0] * v0 * v0 - 2 * v0 * s[c][0] + q[c][0] + n[1] * v1 * v1 - 2 * v1 * s[c][1] + q[c][1] +
                  n[2] * p2 * p2 - 2 * p2 * s[c][2] + q[c][2];
        if (four) err += n[3] * p3 * p3 - 2 * p3 * s[c][3] + q[c][3];
        if (err < best) { best = err; bq0 = c0; bq1 = c1; }
      }
    }
    q0[c] = bq0;
    q1[c] = bq1;
  }
}

// Single-colour tables: for each 8-bit value, the 5/6-bit endpoint pair whose interpolant
// (2a+b+1)/3 (4-colour mode) or (a+b+1)/2 (3-colour mode) is nearest, and that error.
struct SingleColourTables {
  uint8_t q4[2][256][2], q3[2][256][2];  // [bits == 6][value] -> (q0, q1)
  uint8_t e4[2][256], e3[2][256];
  SingleColourTables() {
    for (int six = 0; six < 2; ++six) {
      const int bits = six ? 6 : 5, qmax = (1 << bits) - 1;
      for (int v = 0; v < 256; ++v) {
        int best4 = 1 << 30, best3 = 1 << 30;
        for (int a = 0; a <= qmax; ++a)
          for (int b = 0; b <= qmax; ++b) {
            const int va = expand_bits(a, bits), vb = expand_bits(b, bits);
            const int d4 = std::abs((2 * va + vb + 1) / 3 - v), d3 = std::abs((va + vb + 1) / 2 - v);
            if (d4 < best4) { best4 = d4; q4[six][v][0] = uint8_t(a); q4[six][v][1] = uint8_t(b); }
            if (d3 < best3) { best3 = d3; q3[six][v][0] = uint8_t(a); q3[six][v][1] = uint8_t(b); }
          }
        e4[six][v] = uint8_t(best4);
        e3[six][v] = uint8_t(best3);
      }
    }
  }
};
const SingleColourTables& single_colour_tables() {
  static const SingleColourTables t;
  return t;
}


struct Pixels {
  alignas(16) float c[3][16];  // channel values
  alignas(16) int v[3][16];
  alignas(16) int v2[3][16];   // squares
  alignas(16) int act[16];     // -1 active (not a hole), 0 inactive
  uint16_t active;             // bit i: texel i takes part
  int count;
};

// Nearest palette entry (weighted squared distance) for every active texel, plus per-index sums
// for the endpoint fit. Written as branch-free loops over the 16 texels so they vectorise.
struct Assignment {
  uint32_t idx = 0;
  int n[4] = {0, 0, 0, 0};
  int s[3][4] = {};
  int q[3][4] = {};
  float werr = 0;
};

void assign(const Pixels& px, const int pal[4][3], int entries, const float w[3], bool with_sums, Assignment& out) {
  alignas(16) float best[16];
  alignas(16) float self[16];  // selected entry as float: keeps the select loop in one lane type
  const float w0 = w[0], w1 = w[1], w2 = w[2];
  {
    const float pr = float(pal[0][0]), pg = float(pal[0][1]), pb = float(pal[0][2]);
    for (int i = 0; i < 16; ++i) {
      const float dr = px.c[0][i] - pr, dg = px.c[1][i] - pg, db = px.c[2][i] - pb;
      best[i] = w0 * dr * dr + w1 * dg * dg + w2 * db * db;
      self[i] = 0.0f;
    }
  }
  for (int k = 1; k < entries; ++k) {
    const float pr = float(pal[k][0]), pg = float(pal[k][1]), pb = float(pal[k][2]);
    const float kf = float(k);
    for (int i = 0; i < 16; ++i) {
      const float dr = px.c[0][i] - pr, dg = px.c[1][i] - pg, db = px.c[2][i] - pb;
      const float d = w0 * dr * dr + w1 * dg * dg + w2 * db * db;
      const float b = best[i];
      const float take = float(d < b);  // 0 or 1: arithmetic select keeps the loop branch-free
      best[i] = std::min(d, b);
      self[i] += take * (kf - self[i]);
    }
  }
  alignas(16) int sel[16];
  for (int i = 0; i < 16; ++i) sel[i] = int(self[i]);
  out = Assignment{};
  float werr = 0;
  for (int i = 0; i < 16; ++i) {
    sel[i] = px.act[i] ? sel[i] : 3;
    werr += px.act[i] ? best[i] : 0.0f;
  }
  out.werr = werr;
  uint32_t idx = 0;
  for (int i = 0; i < 16; ++i) idx |= uint32_t(sel[i]) << (2 * i);
  out.idx = idx;
  if (!with_sums) return;
  for (int k = 0; k < entries; ++k) {
    int n = 0, s0 = 0, s1 = 0, s2 = 0, q0 = 0, q1 = 0, q2 = 0;
    for (int i = 0; i < 16; ++i) {
      const int m = -int(sel[i] == k) & px.act[i];  // all ones when texel i uses entry k
      n -= m;
      s0 += px.v[0][i] & m; s1 += px.v[1][i] & m; s2 += px.v[2][i] & m;
      q0 += px.v2[0][i] & m; q1 += px.v2[1][i] & m; q2 += px.v2[2][i] & m;
    }
    out.n[k] = n;
    out.s[0][k] = s0; out.s[1][k] = s1; out.s[2][k] = s2;
    out.q[0][k] = q0; out.q[1][k] = q1; out.q[2][k] = q2;
  }
}

void palette_of(const int q0[3], const int q1[3], bool four, int pal[4][3]) {
  for (int c = 0; c < 3; ++c) {
    const int v0 = expand_bits(q0[c], kBits[c]), v1 = expand_bits(q1[c], kBits[c]);
    pal[0][c] = v0;
    pal[1][c] = v1;
    if (four) {
      pal[2][c] = (2 * v0 + v1 + 1) / 3;
      pal[3][c] = (v0 + 2 * v1 + 1) / 3;
    } else {
      pal[2][c] = (v0 + v1 + 1) / 2;
      pal[3][c] = 0;
    }
  }
}

uint16_t pack(const int q[3]) { return uint16_t((q[0] << 11) | (q[1] << 5) | q[2]); }

// Shared colour encoder (see the file comment). `four`: 4-colour block (c0 > c1 written);
// otherwise 3-colour punch-through block (c0 <= c1), inactive texels get index 3.
// `iterations`: endpoint refits after the first assignment.
void encode_colour(const uint8_t rgba[64], uint16_t active, bool four, const float w[3], int iterations,
                   uint8_t out[8]) {
  Pixels px;
  px.active = active;
  // Planar copies (channel-major) so the per-texel loops below vectorise.
  for (int i = 0; i < 16; ++i) px.act[i] = (active >> i & 1) ? -1 : 0;
  for (int c = 0; c < 3; ++c)
    for (int i = 0; i < 16; ++i) {
      const int v = rgba[4 * i + c] & px.act[i];  // inactive texels read as 0 and are masked below
      px.v[c][i] = v;
      px.v2[c][i] = v * v;
      px.c[c][i] = float(v);
    }
  int lo[3], hi[3], sum[3], sq[3];
  for (int c = 0; c < 3; ++c) {
    int l = 255, h = 0, s0 = 0, q0 = 0;
    for (int i = 0; i < 16; ++i) {
      const int v = px.v[c][i];
      l = std::min(l, px.act[i] ? v : 255);
      h = std::max(h, v);
      s0 += v;
      q0 += px.v2[c][i];
    }
    lo[c] = l; hi[c] = h; sum[c] = s0; sq[c] = q0;
  }
  px.count = __builtin_popcount(active);
  const int n = px.count;

  // Candidate 1: one colour for every texel (the interpolant of the single-colour tables);
  // its error from the sums: sum (x - p)^2 = Q - 2 p S + n p^2.
  const SingleColourTables& tab = single_colour_tables();
  int sq0[3], sq1[3];
  float best_err = 0;
  for (int c = 0; c < 3; ++c) {
    const int mean = (sum[c] + n / 2) / std::max(n, 1);
    const int six = kBits[c] == 6;
    sq0[c] = four ? tab.q4[six][mean][0] : tab.q3[six][mean][0];
    sq1[c] = four ? tab.q4[six][mean][1] : tab.q3[six][mean][1];
    const int v0 = expand_bits(sq0[c], kBits[c]), v1 = expand_bits(sq1[c], kBits[c]);
    const int p = four ? (2 * v0 + v1 + 1) / 3 : (v0 + v1 + 1) / 2;
    best_err += w[c] * float(sq[c] - 2 * p * sum[c] + n * p * p);
  }
  uint32_t best_idx = 0;
  int best_q0[3] = {sq0[0], sq0[1], sq0[2]}, best_q1[3] = {sq1[0], sq1[1], sq1[2]};
  for (int i = 0; i < 16; ++i) best_idx |= ((active >> i & 1) ? 2u : 3u) << (2 * i);

  const bool flat = lo[0] == hi[0] && lo[1] == hi[1] && lo[2] == hi[2];
  if (!flat && best_err > 0) {
    // PCA (power iteration on the weighted covariance) and the extreme texels along the axis.
    float mean[3], cov[6] = {0, 0, 0, 0, 0, 0};
    for (int c = 0; c < 3; ++c) mean[c] = float(sum[c]) / float(n);
    for (int i = 0; i < 16; ++i) {
      const float m = px.act[i] ? 1.0f : 0.0f;
      const float d[3] = {(px.c[0][i] - mean[0]) * w[0] * m, (px.c[1][i] - mean[1]) * w[1] * m,
                          (px.c[2][i] - mean[2]) * w[2] * m};
      cov[0] += d[0] * d[0]; cov[1] += d[0] * d[1]; cov[2] += d[0] * d[2];
      cov[3] += d[1] * d[1]; cov[4] += d[1] * d[2]; cov[5] += d[2] * d[2];
    }
    float ax[3] = {float(hi[0] - lo[0]) * w[0], float(hi[1] - lo[1]) * w[1], float(hi[2] - lo[2]) * w[2]};
    // Start from the bounding-box diagonal with the covariance's signs.
    principal_axis(cov, ax);
    alignas(16) float proj[16];
    float pmin = 3.4e38f, pmax = -3.4e38f;
    const float k0 = ax[0] * w[0], k1 = ax[1] * w[1], k2 = ax[2] * w[2];
    for (int i = 0; i < 16; ++i) {
      proj[i] = px.c[0][i] * k0 + px.c[1][i] * k1 + px.c[2][i] * k2;
      pmin = px.act[i] ? std::min(pmin, proj[i]) : pmin;
      pmax = px.act[i] ? std::max(pmax, proj[i]) : pmax;
    }
    // First indices from the position along the axis (no palette needed): 0..3 from the low
    // end maps to BC1 indices 1, 3, 2, 0 (4-colour) or 1, 2, 0 (3-colour).
    Assignment as;
    {
      const int steps = four ? 3 : 2;
      const float scale = pmax > pmin ? float(steps) / (pmax - pmin) : 0.0f;
      static const int kMap4[4] = {1, 3, 2, 0}, kMap3[3] = {1, 2, 0};
      alignas(16) int sel[16];
      for (int i = 0; i < 16; ++i) {
        const int t = std::clamp(int((proj[i] - pmin) * scale + 0.5f), 0, steps);
        sel[i] = px.act[i] ? (four ? kMap4[t] : kMap3[t]) : 3;
      }
      for (int i = 0; i < 16; ++i) as.idx |= uint32_t(sel[i]) << (2 * i);
      for (int k = 0; k < (four ? 4 : 3); ++k) {
        int cnt = 0, s0 = 0, s1 = 0, s2 = 0, q0 = 0, q1 = 0, q2 = 0;
        for (int i = 0; i < 16; ++i) {
          const int m = -int(sel[i] == k) & px.act[i];
          cnt -= m;
          s0 += px.v[0][i] & m; s1 += px.v[1][i] & m; s2 += px.v[2][i] & m;
          q0 += px.v2[0][i] & m; q1 += px.v2[1][i] & m; q2 += px.v2[2][i] & m;
        }
        as.n[k] = cnt;
        as.s[0][k] = s0; as.s[1][k] = s1; as.s[2][k] = s2;
        as.q[0][k] = q0; as.q[1][k] = q1; as.q[2][k] = q2;
      }
    }
    const int entries = four ? 4 : 3;
    for (int iter = 0; iter < std::max(iterations, 1); ++iter) {
      // Exact per-channel endpoint choice for these indices (the error separates by channel),
      // then the nearest-entry indices for the new palette.
      int q0[3], q1[3];
      fit_endpoints(as.n, as.s, as.q, four, iterations > 1 ? 2 : 1, q0, q1);
      int pal[4][3];
      palette_of(q0, q1, four, pal);
      assign(px, pal, entries, w, iter + 1 < std::max(iterations, 1), as);
      if (!(as.werr < best_err)) break;
      best_err = as.werr;
      best_idx = as.idx;
      std::copy(q0, q0 + 3, best_q0);
      std::copy(q1, q1 + 3, best_q1);
      if (as.werr <= 0) break;
    }
  }

  uint16_t c0 = pack(best_q0), c1 = pack(best_q1);
  if (four) {
    if (c0 < c1) {
      std::swap(c0, c1);
      best_idx ^= 0x55555555u;  // 0<->1, 2<->3
    } else if (c0 == c1) {
      best_idx = 0;  // all four entries are the same colour; index 0 is opaque in either mode
    }
  } else if (c0 > c1) {
    std::swap(c0, c1);
    uint32_t swapped = 0;  // swap indices 0 and 1 only; 2 (midpoint) and 3 (transparent) stay
    for (int i = 0; i < 16; ++i) {
      uint32_t k = (best_idx >> (2 * i)) & 3;
      if (k < 2) k ^= 1;
      swapped |= k << (2 * i);
    }
    best_idx = swapped;
  }
  write16(out, c0);
  write16(out + 2, c1);
  write32(out + 4, best_idx);
}

#if defined(__SSE2__)
// ---- SSE2 path for opaque 4-colour blocks (the albedo hot path) ----------------------------
// Same algorithm as encode_colour, restated on moments so every pass is a few vector ops:
// for fixed per-texel weights a_i (1, 2/3, 1/3, 0 for indices 0, 2, 3, 1) the least-squares
// endpoints and the error of any candidate endpoint pair follow from sum a, sum a^2, sum x,
// sum x^2 and sum a*x per channel (the palette's +1/3 rounding is ignored when ranking the few
// candidates; the final index choice uses the exact decoded palette).

inline float hsum(__m128 v) {
  __m128 t = _mm_add_ps(v, _mm_movehl_ps(v, v));
  t = _mm_add_ss(t, _mm_shuffle_ps(t, t, 1));
  return _mm_cvtss_f32(t);
}
inline float hmin(__m128 v) {
  __m128 t = _mm_min_ps(v, _mm_movehl_ps(v, v));
  t = _mm_min_ss(t, _mm_shuffle_ps(t, t, 1));
  return _mm_cvtss_f32(t);
}
inline float hmax(__m128 v) {
  __m128 t = _mm_max_ps(v, _mm_movehl_ps(v, v));
  t = _mm_max_ss(t, _mm_shuffle_ps(t, t, 1));
  return _mm_cvtss_f32(t);
}

// Extra effort for blocks whose error stays high after the normal refits.
struct HardBlocks {
  int iterations = 0;     // total refits allowed for a hard block (0: no extra refits)
  float threshold = 0;    // squared error over the block above which a block counts as hard
  int ordering_sweeps = 0;        // coordinate sweeps of the ordering search (0: none)
  float ordering_threshold = 16;  // squared error over the block above which the ordering search runs
};

struct Moments {
  float sa = 0, saa = 0, sx[3] = {0, 0, 0}, sxx[3] = {0, 0, 0}, sax[3] = {0, 0, 0};
};

// Endpoints for weights with the given moments: least squares, then the best of the 4x4 nearest
// quantised pairs per channel (floor-1 .. floor+2, clamped), ranked by the moment form of the error,
// which separates as f0(v0) + f1(v1) + 2 ab v0 v1. The least-squares solve runs for the three
// channels in one vector (same IEEE operations as per channel, so the same result), the candidate
// expansion in integer lanes (5/6-bit replication by shifts), the 16 candidate errors as 4 vectors.
void fit_from_moments(const Moments& m, int q0[3], int q1[3]) {
  const float n = 16.0f;
  const float aa = m.saa, ab = m.sa - m.saa, bb = n - 2 * m.sa + m.saa;
  const float det = aa * bb - ab * ab;
  const __m128 ax = _mm_setr_ps(m.sax[0], m.sax[1], m.sax[2], 0.0f);
  const __m128 bx = _mm_sub_ps(_mm_setr_ps(m.sx[0], m.sx[1], m.sx[2], 0.0f), ax);
  __m128 e0, e1;
  if (std::fabs(det) > 1e-3f) {
    const __m128 vdet = _mm_set1_ps(det);
    e0 = _mm_div_ps(_mm_sub_ps(_mm_mul_ps(ax, _mm_set1_ps(bb)), _mm_mul_ps(bx, _mm_set1_ps(ab))), vdet);
    e1 = _mm_div_ps(_mm_sub_ps(_mm_mul_ps(bx, _mm_set1_ps(aa)), _mm_mul_ps(ax, _mm_set1_ps(ab))), vdet);
  } else {
    e0 = e1 = _mm_div_ps(_mm_setr_ps(m.sx[0], m.sx[1], m.sx[2], 0.0f), _mm_set1_ps(n));
  }
  const __m128 zero = _mm_setzero_ps(), top = _mm_set1_ps(255.0f);
  const __m128 scale = _mm_setr_ps(31.0f / 255.0f, 63.0f / 255.0f, 31.0f / 255.0f, 0.0f);
  alignas(16) int32_t base0[4], base1[4];
  _mm_store_si128(reinterpret_cast<__m128i*>(base0), _mm_cvttps_epi32(_mm_mul_ps(_mm_min_ps(_mm_max_ps(e0, zero), top), scale)));
  _mm_store_si128(reinterpret_cast<__m128i*>(base1), _mm_cvttps_epi32(_mm_mul_ps(_mm_min_ps(_mm_max_ps(e1, zero), top), scale)));
  alignas(16) float axs[4], bxs[4];
  _mm_store_ps(axs, ax);
  _mm_store_ps(bxs, bx);
  const __m128i offs = _mm_setr_epi32(-1, 0, 1, 2);
  const __m128 vaa = _mm_set1_ps(aa), vbb = _mm_set1_ps(bb), two_ab = _mm_set1_ps(2 * ab);
  for (int c = 0; c < 3; ++c) {
    const int six = c == 1;
    // Clamp in 16-bit lanes: values are small, and -1 reads as -1 in both halves.
    const __m128i lo = _mm_setzero_si128(), hi = _mm_set1_epi32(six ? 63 : 31);
    const __m128i qa = _mm_min_epi16(_mm_max_epi16(_mm_add_epi32(_mm_set1_epi32(base0[c]), offs), lo), hi);
    const __m128i qb = _mm_min_epi16(_mm_max_epi16(_mm_add_epi32(_mm_set1_epi32(base1[c]), offs), lo), hi);
    const __m128i ea = six ? _mm_or_si128(_mm_slli_epi32(qa, 2), _mm_srli_epi32(qa, 4))
                           : _mm_or_si128(_mm_slli_epi32(qa, 3), _mm_srli_epi32(qa, 2));
    const __m128i eb = six ? _mm_or_si128(_mm_slli_epi32(qb, 2), _mm_srli_epi32(qb, 4))
                           : _mm_or_si128(_mm_slli_epi32(qb, 3), _mm_srli_epi32(qb, 2));
    const __m128 va = _mm_cvtepi32_ps(ea), vb = _mm_cvtepi32_ps(eb);
    const __m128 fa = _mm_mul_ps(va, _mm_sub_ps(_mm_mul_ps(va, vaa), _mm_set1_ps(2 * axs[c])));
    const __m128 fb = _mm_mul_ps(vb, _mm_sub_ps(_mm_mul_ps(vb, vbb), _mm_set1_ps(2 * bxs[c])));
    const __m128 ka = _mm_mul_ps(two_ab, va);
    __m128 e[4];
    e[0] = _mm_add_ps(_mm_shuffle_ps(fa, fa, _MM_SHUFFLE(0, 0, 0, 0)), _mm_add_ps(fb, _mm_mul_ps(_mm_shuffle_ps(ka, ka, _MM_SHUFFLE(0, 0, 0, 0)), vb)));
    e[1] = _mm_add_ps(_mm_shuffle_ps(fa, fa, _MM_SHUFFLE(1, 1, 1, 1)), _mm_add_ps(fb, _mm_mul_ps(_mm_shuffle_ps(ka, ka, _MM_SHUFFLE(1, 1, 1, 1)), vb)));
    e[2] = _mm_add_ps(_mm_shuffle_ps(fa, fa, _MM_SHUFFLE(2, 2, 2, 2)), _mm_add_ps(fb, _mm_mul_ps(_mm_shuffle_ps(ka, ka, _MM_SHUFFLE(2, 2, 2, 2)), vb)));
    e[3] = _mm_add_ps(_mm_shuffle_ps(fa, fa, _MM_SHUFFLE(3, 3, 3, 3)), _mm_add_ps(fb, _mm_mul_ps(_mm_shuffle_ps(ka, ka, _MM_SHUFFLE(3, 3, 3, 3)), vb)));
    __m128 mn = _mm_min_ps(_mm_min_ps(e[0], e[1]), _mm_min_ps(e[2], e[3]));
    mn = _mm_min_ps(mn, _mm_shuffle_ps(mn, mn, _MM_SHUFFLE(2, 3, 0, 1)));
    mn = _mm_min_ps(mn, _mm_shuffle_ps(mn, mn, _MM_SHUFFLE(1, 0, 3, 2)));
    alignas(16) int32_t qas[4], qbs[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(qas), qa);
    _mm_store_si128(reinterpret_cast<__m128i*>(qbs), qb);
    int bq0 = qas[0], bq1 = qbs[0];
    for (int i = 0; i < 4; ++i) {
      const int hit = _mm_movemask_ps(_mm_cmpeq_ps(e[i], mn));
      if (hit) {
        bq0 = qas[i];
        bq1 = qbs[__builtin_ctz(unsigned(hit))];
        break;
      }
    }
    q0[c] = bq0;
    q1[c] = bq1;
  }
}

// 16 indices (0..3, one per 32-bit lane, texel order) -> the 2-bit fields of a BC1 block. Bytes
// b0..b3 of each group of four merge by shifts: in 16-bit lanes b0 | b1 << 2, in 32-bit lanes
// then | (b2 | b3 << 2) << 4.
inline uint32_t pack_indices(const __m128i sel[4]) {
  const __m128i bytes = _mm_packus_epi16(_mm_packs_epi32(sel[0], sel[1]), _mm_packs_epi32(sel[2], sel[3]));
  __m128i t = _mm_or_si128(bytes, _mm_srli_epi16(bytes, 6));
  t = _mm_or_si128(t, _mm_srli_epi32(t, 12));
  t = _mm_and_si128(t, _mm_set1_epi32(0xFF));
  t = _mm_packus_epi16(_mm_packs_epi32(t, t), t);
  return uint32_t(_mm_cvtsi128_si32(t));
}

// Nearest exact palette entry (uniform metric) for every texel: error and packed indices.
inline float assign_uniform(const __m128 ch[3][4], const int pal[4][3], uint32_t& packed, __m128i sel[4]) {
  __m128 err = _mm_setzero_ps();
  for (int v = 0; v < 4; ++v) {
    __m128 best = _mm_setzero_ps();
    for (int k = 0; k < 4; ++k) {
      const __m128 dr = _mm_sub_ps(ch[0][v], _mm_set1_ps(float(pal[k][0])));
      const __m128 dg = _mm_sub_ps(ch[1][v], _mm_set1_ps(float(pal[k][1])));
      const __m128 db = _mm_sub_ps(ch[2][v], _mm_set1_ps(float(pal[k][2])));
      const __m128 d = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dr, dr), _mm_mul_ps(dg, dg)), _mm_mul_ps(db, db));
      if (k == 0) {
        best = d;
        sel[v] = _mm_setzero_si128();
      } else {
        const __m128i better = _mm_castps_si128(_mm_cmplt_ps(d, best));
        best = _mm_min_ps(d, best);
        sel[v] = _mm_or_si128(_mm_andnot_si128(better, sel[v]), _mm_and_si128(better, _mm_set1_epi32(k)));
      }
    }
    err = _mm_add_ps(err, best);
  }
  packed = pack_indices(sel);
  return hsum(err);
}

// Ordering search (a cheap relative of libsquish's cluster fit), used by Bc1Method::own_cluster.
// Texels sorted along the principal axis form four contiguous groups with c0 weights 1, 2/3, 1/3, 0
// from the low end. With group boundaries i <= j <= k and P(r) the prefix sums of the sorted
// colours, sum a*x = (P(i) + P(j) + P(k)) / 3, sum a = (i + j + k) / 3 and sum a^2 = (5i + 3j + k) / 9,
// so the least-squares endpoints of a partition cost a few multiply-adds. Like libsquish, partitions
// are ranked by the error of those endpoints rounded to the 5:6:5 grid. libsquish scores all 969
// partitions; we run coordinate sweeps from the partition the current indices imply: each boundary
// in turn scans its whole free range with the other two fixed (4 candidates per vector op), then
// the winner is quantised exactly (4x4 window) and kept if its exact error is lower.
// Measured on Oetztal splat albedo (terrain-bc-bench --block-stats; default own 39.76 dB, squish
// cluster 40.08 dB): the winning partitions usually differ from the start in one boundary, by up
// to ~7 texels, so a +-1 neighbourhood hill-climb stalls at 39.93 dB (+-3: 40.04 dB); one sweep
// gives 40.06 dB, two 40.08 dB, the full 969-partition search 40.27 dB (at ~10x the time);
// ranking by the unrounded error instead loses 0.06-0.08 dB. The search only helps together with
// the hard-block refits (without them: 40.01 dB), and it is needed on nearly every block with
// error (only above 48 x 4 per channel: 40.03 dB), since the loss is spread over all such blocks.
struct OrderingSearch {
  alignas(16) float P[3][24];  // prefix sums per channel, padded with P(16)
  float X3[3];                 // 3 * sum x per channel

  // Rounded-endpoint residual (minus the constant sum x^2, times 9) of 4 partitions whose
  // boundaries are the lanes of fi, fj, fk; T: the lanes of P(i) + P(j) + P(k) per channel.
  // Lanes with a singular system (all texels in one group) or `invalid` get +inf.
  static __m128 score(__m128 fi, __m128 fj, __m128 fk, const __m128 T[3], __m128 invalid, const float X3[3]) {
    const __m128 s3 = _mm_add_ps(_mm_add_ps(fi, fj), fk);
    const __m128 a9 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(fi, _mm_set1_ps(5.0f)), _mm_mul_ps(fj, _mm_set1_ps(3.0f))), fk);
    const __m128 AA = a9, AB = _mm_sub_ps(_mm_mul_ps(s3, _mm_set1_ps(3.0f)), a9);
    const __m128 BB = _mm_add_ps(_mm_sub_ps(_mm_set1_ps(144.0f), _mm_mul_ps(s3, _mm_set1_ps(6.0f))), a9);
    const __m128 D = _mm_sub_ps(_mm_mul_ps(AA, BB), _mm_mul_ps(AB, AB));
    const __m128 bad = _mm_or_ps(invalid, _mm_cmple_ps(D, _mm_set1_ps(0.5f)));
    const __m128 inv = _mm_div_ps(_mm_set1_ps(3.0f), _mm_or_ps(_mm_andnot_ps(bad, D), _mm_and_ps(bad, _mm_set1_ps(1.0f))));
    const __m128 AB2 = _mm_add_ps(AB, AB), zero = _mm_setzero_ps(), top = _mm_set1_ps(255.0f);
    static const float kGrid[3] = {31.0f / 255.0f, 63.0f / 255.0f, 31.0f / 255.0f};
    static const float kGridInv[3] = {255.0f / 31.0f, 255.0f / 63.0f, 255.0f / 31.0f};
    __m128 e = zero;
    for (int c = 0; c < 3; ++c) {
      const __m128 t = T[c], u = _mm_sub_ps(_mm_set1_ps(X3[c]), t);
      __m128 a = _mm_mul_ps(_mm_sub_ps(_mm_mul_ps(t, BB), _mm_mul_ps(u, AB)), inv);
      __m128 b = _mm_mul_ps(_mm_sub_ps(_mm_mul_ps(u, AA), _mm_mul_ps(t, AB)), inv);
      const __m128 g = _mm_set1_ps(kGrid[c]), gi = _mm_set1_ps(kGridInv[c]);
      a = _mm_mul_ps(_mm_cvtepi32_ps(_mm_cvtps_epi32(_mm_mul_ps(_mm_min_ps(_mm_max_ps(a, zero), top), g))), gi);
      b = _mm_mul_ps(_mm_cvtepi32_ps(_mm_cvtps_epi32(_mm_mul_ps(_mm_min_ps(_mm_max_ps(b, zero), top), g))), gi);
      // AA a^2 + BB b^2 + 2 AB a b - 6 (a T + b U)   (9 x the residual minus sum x^2)
      const __m128 quad = _mm_add_ps(_mm_mul_ps(a, _mm_add_ps(_mm_mul_ps(a, AA), _mm_mul_ps(b, AB2))), _mm_mul_ps(_mm_mul_ps(b, b), BB));
      e = _mm_add_ps(e, _mm_sub_ps(quad, _mm_mul_ps(_mm_add_ps(_mm_mul_ps(a, t), _mm_mul_ps(b, u)), _mm_set1_ps(6.0f))));
    }
    return _mm_or_ps(_mm_andnot_ps(bad, e), _mm_and_ps(bad, _mm_set1_ps(3.4e38f)));
  }

  // Scans boundary `which` (0: i, 1: j, 2: k) over [lo, hi] with the others fixed; updates b[] and best.
  void scan(int which, int lo, int hi, int b[3], float& best) const {
    const __m128 lane = _mm_setr_ps(0, 1, 2, 3);
    int fixed0 = which == 0 ? 1 : 0, fixed1 = which == 2 ? 1 : 2;
    float base[3];
    for (int c = 0; c < 3; ++c) base[c] = P[c][b[fixed0]] + P[c][b[fixed1]];
    int arg = b[which];
    for (int x = lo; x <= hi; x += 4) {
      const __m128 fx = _mm_add_ps(_mm_set1_ps(float(x)), lane);
      const __m128 invalid = _mm_cmpgt_ps(fx, _mm_set1_ps(float(hi)));
      __m128 T[3];
      for (int c = 0; c < 3; ++c) T[c] = _mm_add_ps(_mm_set1_ps(base[c]), _mm_loadu_ps(P[c] + x));
      const __m128 fi = which == 0 ? fx : _mm_set1_ps(float(b[0]));
      const __m128 fj = which == 1 ? fx : _mm_set1_ps(float(b[1]));
      const __m128 fk = which == 2 ? fx : _mm_set1_ps(float(b[2]));
      const __m128 e = score(fi, fj, fk, T, invalid, X3);
      const float m = hmin(e);
      if (m < best) {
        best = m;
        arg = x + __builtin_ctz(unsigned(_mm_movemask_ps(_mm_cmpeq_ps(e, _mm_set1_ps(m)))));
      }
    }
    b[which] = arg;
  }
};

void ordering_search(const __m128 ch[3][4], const __m128 proj[4], const float axis[3], int sweeps, int best_q0[3],
                     int best_q1[3], uint32_t& best_idx, float& best_err) {
  alignas(16) float col[3][16];
  for (int v = 0; v < 4; ++v)
    for (int c = 0; c < 3; ++c) _mm_store_ps(col[c] + 4 * v, ch[c][v]);
  // Rank of texel t = number of keys below its key; the keys are the projections scaled to 24 bits
  // with the texel index in the low 4 bits, so they are distinct and the ranks a permutation.
  int order[16];
  {
    __m128 lo = _mm_min_ps(_mm_min_ps(proj[0], proj[1]), _mm_min_ps(proj[2], proj[3]));
    __m128 hi = _mm_max_ps(_mm_max_ps(proj[0], proj[1]), _mm_max_ps(proj[2], proj[3]));
    const float pmin = hmin(lo), pmax = hmax(hi);
    const __m128 base = _mm_set1_ps(pmin), scale = _mm_set1_ps(pmax > pmin ? float(1 << 20) / (pmax - pmin) : 0.0f);
    __m128i key[4];
    for (int v = 0; v < 4; ++v) {
      const __m128i q = _mm_cvttps_epi32(_mm_mul_ps(_mm_sub_ps(proj[v], base), scale));
      key[v] = _mm_or_si128(_mm_slli_epi32(q, 4), _mm_setr_epi32(4 * v, 4 * v + 1, 4 * v + 2, 4 * v + 3));
    }
    alignas(16) int32_t k[16];
    for (int v = 0; v < 4; ++v) _mm_store_si128(reinterpret_cast<__m128i*>(k + 4 * v), key[v]);
    for (int t = 0; t < 16; ++t) {
      const __m128i kt = _mm_set1_epi32(k[t]);
      __m128i cnt = _mm_add_epi32(_mm_cmplt_epi32(key[0], kt), _mm_cmplt_epi32(key[1], kt));
      cnt = _mm_add_epi32(cnt, _mm_add_epi32(_mm_cmplt_epi32(key[2], kt), _mm_cmplt_epi32(key[3], kt)));
      cnt = _mm_add_epi32(cnt, _mm_shuffle_epi32(cnt, _MM_SHUFFLE(1, 0, 3, 2)));
      cnt = _mm_add_epi32(cnt, _mm_shuffle_epi32(cnt, _MM_SHUFFLE(2, 3, 0, 1)));
      order[-_mm_cvtsi128_si32(cnt)] = t;
    }
  }
  OrderingSearch os;
  for (int c = 0; c < 3; ++c) {
    float acc = 0;
    os.P[c][0] = 0;
    for (int r = 0; r < 16; ++r) os.P[c][r + 1] = acc += col[c][order[r]];
    for (int r = 17; r < 24; ++r) os.P[c][r] = acc;
    os.X3[c] = 3 * acc;
  }
  // Start: the group sizes of the current indices, from the endpoint that projects lower.
  int cnt[4] = {0, 0, 0, 0};
  for (int t = 0; t < 16; ++t) ++cnt[(best_idx >> (2 * t)) & 3];
  const float d0 = axis[0] * float(expand5(best_q0[0])) + axis[1] * float(expand6(best_q0[1])) + axis[2] * float(expand5(best_q0[2]));
  const float d1 = axis[0] * float(expand5(best_q1[0])) + axis[1] * float(expand6(best_q1[1])) + axis[2] * float(expand5(best_q1[2]));
  const bool low0 = d0 <= d1;
  int b[3];
  b[0] = low0 ? cnt[0] : cnt[1];
  b[1] = b[0] + cnt[low0 ? 2 : 3];
  b[2] = b[1] + cnt[low0 ? 3 : 2];
  const int start[3] = {b[0], b[1], b[2]};
  float best;
  {
    __m128 T[3];
    for (int c = 0; c < 3; ++c) T[c] = _mm_set1_ps(os.P[c][b[0]] + os.P[c][b[1]] + os.P[c][b[2]]);
    const __m128 e = OrderingSearch::score(_mm_set1_ps(float(b[0])), _mm_set1_ps(float(b[1])), _mm_set1_ps(float(b[2])), T,
                                           _mm_setzero_ps(), os.X3);
    best = _mm_cvtss_f32(e);
  }
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    const int before[3] = {b[0], b[1], b[2]};
    os.scan(0, 0, b[1], b, best);
    os.scan(2, b[1], 16, b, best);
    os.scan(1, b[0], b[2], b, best);
    if (b[0] == before[0] && b[1] == before[1] && b[2] == before[2]) break;
  }
  if (b[0] == start[0] && b[1] == start[1] && b[2] == start[2]) return;
  // The winner's endpoints, quantised exactly (4x4 window), then the exact nearest indices.
  Moments m;
  m.sa = float(b[0] + b[1] + b[2]) / 3.0f;
  m.saa = float(5 * b[0] + 3 * b[1] + b[2]) / 9.0f;
  for (int c = 0; c < 3; ++c) {
    m.sax[c] = (os.P[c][b[0]] + os.P[c][b[1]] + os.P[c][b[2]]) / 3.0f;
    m.sx[c] = os.P[c][16];
  }
  int q0[3], q1[3], pal[4][3];
  fit_from_moments(m, q0, q1);
  palette_of(q0, q1, true, pal);
  uint32_t packed;
  __m128i sel[4];
  const float e = assign_uniform(ch, pal, packed, sel);
  if (e < best_err) {
    best_err = e;
    best_idx = packed;
    std::copy(q0, q0 + 3, best_q0);
    std::copy(q1, q1 + 3, best_q1);
  }
}

template <bool kUniform>  // all weights 1: the distance skips the weight multiplies
void encode_opaque_sse(const uint8_t rgba[64], const float w[3], int iterations, const HardBlocks& hard,
                       uint8_t out[8], float* err_out) {
  __m128 ch[3][4];
  const __m128i byte = _mm_set1_epi32(0xFF);
  for (int v = 0; v < 4; ++v) {
    const __m128i px = _mm_loadu_si128(reinterpret_cast<const __m128i*>(rgba + 16 * v));
    ch[0][v] = _mm_cvtepi32_ps(_mm_and_si128(px, byte));
    ch[1][v] = _mm_cvtepi32_ps(_mm_and_si128(_mm_srli_epi32(px, 8), byte));
    ch[2][v] = _mm_cvtepi32_ps(_mm_and_si128(_mm_srli_epi32(px, 16), byte));
  }
  // Sums, squares, cross products, min and max per channel.
  __m128 s[3], ss[6], lo[3], hi[3];
  for (int c = 0; c < 3; ++c) {
    s[c] = _mm_setzero_ps();
    lo[c] = hi[c] = ch[c][0];
  }
  for (int k = 0; k < 6; ++k) ss[k] = _mm_setzero_ps();
  for (int v = 0; v < 4; ++v) {
    const __m128 r = ch[0][v], g = ch[1][v], b = ch[2][v];
    s[0] = _mm_add_ps(s[0], r); s[1] = _mm_add_ps(s[1], g); s[2] = _mm_add_ps(s[2], b);
    ss[0] = _mm_add_ps(ss[0], _mm_mul_ps(r, r)); ss[1] = _mm_add_ps(ss[1], _mm_mul_ps(r, g));
    ss[2] = _mm_add_ps(ss[2], _mm_mul_ps(r, b)); ss[3] = _mm_add_ps(ss[3], _mm_mul_ps(g, g));
    ss[4] = _mm_add_ps(ss[4], _mm_mul_ps(g, b)); ss[5] = _mm_add_ps(ss[5], _mm_mul_ps(b, b));
    for (int c = 0; c < 3; ++c) {
      lo[c] = _mm_min_ps(lo[c], ch[c][v]);
      hi[c] = _mm_max_ps(hi[c], ch[c][v]);
    }
  }
  float sum[3], sq[6], mn[3], mx[3];
  for (int c = 0; c < 3; ++c) { sum[c] = hsum(s[c]); mn[c] = hmin(lo[c]); mx[c] = hmax(hi[c]); }
  for (int k = 0; k < 6; ++k) sq[k] = hsum(ss[k]);
  const float sqd[3] = {sq[0], sq[3], sq[5]};

  // Candidate 1: one colour (single-colour tables at the mean), error from the sums.
  const SingleColourTables& tab = single_colour_tables();
  int best_q0[3], best_q1[3];
  float best_err = 0;
  for (int c = 0; c < 3; ++c) {
    const int mean = int(sum[c] * (1.0f / 16.0f) + 0.5f);
    const int six = kBits[c] == 6;
    best_q0[c] = tab.q4[six][mean][0];
    best_q1[c] = tab.q4[six][mean][1];
    const int v0 = expand_bits(best_q0[c], kBits[c]), v1 = expand_bits(best_q1[c], kBits[c]);
    const float p = float((2 * v0 + v1 + 1) / 3);
    best_err += w[c] * (sqd[c] - 2 * p * sum[c] + 16 * p * p);
  }
  uint32_t best_idx = 0xAAAAAAAAu;  // index 2 everywhere

  const bool flat = mn[0] == mx[0] && mn[1] == mx[1] && mn[2] == mx[2];
  if (!flat && best_err > 0.5f) {
    // Principal axis of the weighted covariance (power iteration from the bounding box).
    const float inv16 = 1.0f / 16.0f;
    float cov[6] = {(sq[0] - sum[0] * sum[0] * inv16) * w[0] * w[0], (sq[1] - sum[0] * sum[1] * inv16) * w[0] * w[1],
                    (sq[2] - sum[0] * sum[2] * inv16) * w[0] * w[2], (sq[3] - sum[1] * sum[1] * inv16) * w[1] * w[1],
                    (sq[4] - sum[1] * sum[2] * inv16) * w[1] * w[2], (sq[5] - sum[2] * sum[2] * inv16) * w[2] * w[2]};
    float ax[3] = {(mx[0] - mn[0]) * w[0], (mx[1] - mn[1]) * w[1], (mx[2] - mn[2]) * w[2]};
    principal_axis(cov, ax);
    const __m128 k0 = _mm_set1_ps(ax[0] * w[0]), k1 = _mm_set1_ps(ax[1] * w[1]), k2 = _mm_set1_ps(ax[2] * w[2]);
    __m128 proj[4], pl, ph;
    for (int v = 0; v < 4; ++v) {
      proj[v] = _mm_add_ps(_mm_add_ps(_mm_mul_ps(ch[0][v], k0), _mm_mul_ps(ch[1][v], k1)), _mm_mul_ps(ch[2][v], k2));
      pl = v ? _mm_min_ps(pl, proj[v]) : proj[v];
      ph = v ? _mm_max_ps(ph, proj[v]) : proj[v];
    }
    const float pmin = hmin(pl), pmax = hmax(ph);
    // Weights a_i = t_i / 3 from the position along the axis (t = 0..3 from the low end).
    Moments m;
    {
      const __m128 base = _mm_set1_ps(pmin), scale = _mm_set1_ps(pmax > pmin ? 3.0f / (pmax - pmin) : 0.0f);
      const __m128 half = _mm_set1_ps(0.5f), third = _mm_set1_ps(1.0f / 3.0f);
      __m128 sa = _mm_setzero_ps(), saa = _mm_setzero_ps(), sax[3] = {sa, sa, sa};
      for (int v = 0; v < 4; ++v) {
        const __m128 t = _mm_cvtepi32_ps(_mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(_mm_sub_ps(proj[v], base), scale), half)));
        const __m128 a = _mm_mul_ps(t, third);
        sa = _mm_add_ps(sa, a);
        saa = _mm_add_ps(saa, _mm_mul_ps(a, a));
        for (int c = 0; c < 3; ++c) sax[c] = _mm_add_ps(sax[c], _mm_mul_ps(a, ch[c][v]));
      }
      m.sa = hsum(sa);
      m.saa = hsum(saa);
      for (int c = 0; c < 3; ++c) {
        m.sx[c] = sum[c];
        m.sxx[c] = sqd[c];
        m.sax[c] = hsum(sax[c]);
      }
    }
    int max_iter = std::max(iterations, 1);
    for (int iter = 0; iter < max_iter; ++iter) {
      int q0[3], q1[3];
      fit_from_moments(m, q0, q1);
      int pal[4][3];
      palette_of(q0, q1, true, pal);
      // Nearest exact palette entry per texel.
      __m128 best[4];
      __m128i sel[4];
      __m128 err = _mm_setzero_ps();
      const __m128 w0 = _mm_set1_ps(w[0]), w1 = _mm_set1_ps(w[1]), w2 = _mm_set1_ps(w[2]);
      for (int v = 0; v < 4; ++v) {
        for (int k = 0; k < 4; ++k) {
          const __m128 dr = _mm_sub_ps(ch[0][v], _mm_set1_ps(float(pal[k][0])));
          const __m128 dg = _mm_sub_ps(ch[1][v], _mm_set1_ps(float(pal[k][1])));
          const __m128 db = _mm_sub_ps(ch[2][v], _mm_set1_ps(float(pal[k][2])));
          __m128 d;
          if constexpr (kUniform) {
            d = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dr, dr), _mm_mul_ps(dg, dg)), _mm_mul_ps(db, db));
          } else {
            d = _mm_add_ps(_mm_add_ps(_mm_mul_ps(w0, _mm_mul_ps(dr, dr)), _mm_mul_ps(w1, _mm_mul_ps(dg, dg))),
                           _mm_mul_ps(w2, _mm_mul_ps(db, db)));
          }
          if (k == 0) {
            best[v] = d;
            sel[v] = _mm_setzero_si128();
          } else {
            const __m128i better = _mm_castps_si128(_mm_cmplt_ps(d, best[v]));
            best[v] = _mm_min_ps(d, best[v]);
            sel[v] = _mm_or_si128(_mm_andnot_si128(better, sel[v]), _mm_and_si128(better, _mm_set1_epi32(k)));
          }
        }
        err = _mm_add_ps(err, best[v]);
      }
      const float e = hsum(err);
      if (!(e < best_err)) break;
      const uint32_t packed = pack_indices(sel);
      best_err = e;
      best_idx = packed;
      std::copy(q0, q0 + 3, best_q0);
      std::copy(q1, q1 + 3, best_q1);
      // Another refit cannot gain much once the mean squared error is below 1 per texel.
      if (e <= 16.0f) break;
      // Hard blocks (several colour clusters, e.g. material borders) dominate the PSNR: they get
      // up to kHardIterations refits while each one still improves; smooth blocks stop early.
      if (iter + 1 >= max_iter) {
        if (hard.iterations > max_iter && e > hard.threshold) max_iter = hard.iterations;
        else break;
      }
      // Moments of the exact indices for the next refit: weight of c0 per index is 1, 0, 2/3,
      // 1/3 = (k < 2 ? 1 - k : (4 - k) / 3), computed in the vector lanes.
      {
        __m128 sa = _mm_setzero_ps(), saa = _mm_setzero_ps(), sax[3] = {sa, sa, sa};
        const __m128 one = _mm_set1_ps(1.0f), four = _mm_set1_ps(4.0f), two = _mm_set1_ps(2.0f),
                     third = _mm_set1_ps(1.0f / 3.0f);
        for (int v = 0; v < 4; ++v) {
          const __m128 k = _mm_cvtepi32_ps(sel[v]);
          const __m128 upper = _mm_cmpge_ps(k, two);
          const __m128 a = _mm_or_ps(_mm_and_ps(upper, _mm_mul_ps(_mm_sub_ps(four, k), third)),
                                     _mm_andnot_ps(upper, _mm_sub_ps(one, k)));
          sa = _mm_add_ps(sa, a);
          saa = _mm_add_ps(saa, _mm_mul_ps(a, a));
          for (int c = 0; c < 3; ++c) sax[c] = _mm_add_ps(sax[c], _mm_mul_ps(a, ch[c][v]));
        }
        m.sa = hsum(sa);
        m.saa = hsum(saa);
        for (int c = 0; c < 3; ++c) m.sax[c] = hsum(sax[c]);
      }
    }
    if constexpr (kUniform) {
      if (hard.ordering_sweeps > 0 && best_err > hard.ordering_threshold)
        ordering_search(ch, proj, ax, hard.ordering_sweeps, best_q0, best_q1, best_idx, best_err);
    }
  }
  uint16_t c0 = pack(best_q0), c1 = pack(best_q1);
  if (c0 < c1) {
    std::swap(c0, c1);
    best_idx ^= 0x55555555u;
  } else if (c0 == c1) {
    best_idx = 0;
  }
  write16(out, c0);
  write16(out + 2, c1);
  write32(out + 4, best_idx);
  if (err_out) *err_out = best_err;
}
#endif

void write_bc4(int a0, int a1, const uint8_t sel[16], uint8_t out[8]) {
  out[0] = uint8_t(a0);
  out[1] = uint8_t(a1);
  uint64_t bits = 0;
  for (int i = 0; i < 16; ++i) bits |= uint64_t(sel[i]) << (3 * i);
  for (int i = 0; i < 6; ++i) out[2 + i] = uint8_t(bits >> (8 * i));
}

// Palette exactly as decode_bc4_block computes it.
void bc4_palette(int a0, int a1, int pal[8]) {
  pal[0] = a0;
  pal[1] = a1;
  if (a0 > a1) {
    for (int i = 1; i < 7; ++i) pal[i + 1] = ((7 - i) * a0 + i * a1 + 3) / 7;
  } else {
    for (int i = 1; i < 5; ++i) pal[i + 1] = ((5 - i) * a0 + i * a1 + 2) / 5;
    pal[6] = 0;
    pal[7] = 255;
  }
}

int64_t bc4_assign(const uint8_t v[16], int a0, int a1, uint8_t sel[16]) {
  int pal[8];
  bc4_palette(a0, a1, pal);
  int64_t err = 0;
  for (int i = 0; i < 16; ++i) {
    int best = INT32_MAX;
    for (int k = 0; k < 8; ++k) {
      const int d = v[i] - pal[k];
      if (d * d < best) { best = d * d; sel[i] = uint8_t(k); }
    }
    err += best;
  }
  return err;
}

// Exact squared RGB error of a BC1 block against 16 texels (the decoder's arithmetic).
int block_sq_err(const uint8_t rgba[64], const uint8_t block[8]) {
  uint8_t dec[64];
  decode_bc1_block(block, dec);
  int e = 0;
  for (int i = 0; i < 16; ++i)
    for (int c = 0; c < 3; ++c) {
      const int d = int(rgba[4 * i + c]) - dec[4 * i + c];
      e += d * d;
    }
  return e;
}

// Hard-block effort of own_encode_bc1_opaque(refine_hard): the thresholds are squared RGB error
// summed over the block (16 texels x 3 channels), i.e. 48 x the mean squared error per channel.
// Measured on the splat albedo of real nodes (terrain-bc-bench): up to 4 refits above a mean
// squared error of 8 per channel gain 0.07-0.15 dB for ~10 % more time (threshold 16 lost
// 0.04 dB on Kilauea, 4 cost 5 % more time for nothing); the 3-colour try gains up to 0.1 dB more
// but doubles the time, so only the best setting uses it (from 4 per channel).
constexpr int kHardIterations = 4;
constexpr float kHardThreshold = 48.0f * 8.0f;
constexpr float kThreeColourThreshold = 48.0f * 4.0f;

}  // namespace

void own_encode_bc1_opaque(const uint8_t rgba[64], uint8_t out[8], int iterations, bool refine_hard,
                           bool try_three_colour, int ordering_sweeps) {
  Bc1OpaqueEffort effort;
  effort.iterations = iterations;
  effort.refine_hard = refine_hard;
  effort.ordering_sweeps = ordering_sweeps;
  effort.three_colour_threshold = try_three_colour ? kThreeColourThreshold : -1.0f;
  own_encode_bc1_opaque(rgba, out, effort);
}

void own_encode_bc1_opaque(const uint8_t rgba[64], uint8_t out[8], const Bc1OpaqueEffort& effort) {
  static const float kUniform[3] = {1, 1, 1};
  // Constant blocks (common in smooth albedo): straight from the single-colour tables.
  uint32_t first, px;
  std::memcpy(&first, rgba, 4);
  first &= 0x00FFFFFFu;
  bool constant = true;
  for (int i = 1; i < 16 && constant; ++i) {
    std::memcpy(&px, rgba + 4 * i, 4);
    constant = (px & 0x00FFFFFFu) == first;
  }
  if (constant) {
    const SingleColourTables& tab = single_colour_tables();
    int q0[3], q1[3];
    for (int c = 0; c < 3; ++c) {
      const int six = kBits[c] == 6;
      q0[c] = tab.q4[six][rgba[c]][0];
      q1[c] = tab.q4[six][rgba[c]][1];
    }
    uint16_t c0 = pack(q0), c1 = pack(q1);
    uint32_t idx = 0xAAAAAAAAu;  // the 2/3 interpolant everywhere
    if (c0 < c1) {
      std::swap(c0, c1);
      idx = 0xFFFFFFFFu;
    } else if (c0 == c1) {
      idx = 0;
    }
    write16(out, c0);
    write16(out + 2, c1);
    write32(out + 4, idx);
    return;
  }
#if defined(__SSE2__)
  HardBlocks hard;
  if (effort.refine_hard) {
    hard.iterations = kHardIterations;
    hard.threshold = kHardThreshold;
  }
  hard.ordering_sweeps = effort.ordering_sweeps;
  hard.ordering_threshold = effort.ordering_threshold;
  float err = 0;
  encode_opaque_sse<true>(rgba, kUniform, effort.iterations, hard, out, &err);
  if (effort.three_colour_threshold >= 0 && err > effort.three_colour_threshold) {
    // Two clusters and their midpoint fit the 3-colour mode better (index 3 is not used).
    uint8_t three[8];
    encode_colour(rgba, 0xFFFF, false, kUniform, 2, three);
    if (block_sq_err(rgba, three) < block_sq_err(rgba, out)) std::memcpy(out, three, 8);
  }
#else
  encode_colour(rgba, 0xFFFF, true, kUniform, effort.iterations, out);
#endif
}

void own_encode_bc1_holes(const uint8_t rgba[64], uint16_t holes, uint8_t out[8], int iterations) {
  static const float kUniform[3] = {1, 1, 1};
  encode_colour(rgba, uint16_t(~holes), false, kUniform, iterations, out);
}

void own_encode_bc1_weighted(const uint8_t rgba[64], const float weights[3], uint8_t out[8]) {
#if defined(__SSE2__)
  encode_opaque_sse<false>(rgba, weights, 2, HardBlocks{}, out, nullptr);
#else
  encode_colour(rgba, 0xFFFF, true, weights, 2, out);
#endif
}

bool own_encode_bc1_g_only(const uint8_t rgba[64], uint8_t out[8], int iterations) {
  // Applies when R and B are constant over the block and exactly representable in 5 bits (the
  // normal map's layout): the colour block is then a 1D fit of G (6-bit endpoints, 4 levels).
  const int r = rgba[0], b = rgba[2];
  for (int i = 1; i < 16; ++i)
    if (rgba[4 * i] != r || rgba[4 * i + 2] != b) return false;
  const int qr = (r * 31 + 127) / 255, qb = (b * 31 + 127) / 255;
  if (expand5(qr) != r || expand5(qb) != b) return false;
  int g[16], lo = 255, hi = 0, sum = 0, sq = 0;
  for (int i = 0; i < 16; ++i) {
    g[i] = rgba[4 * i + 1];
    lo = std::min(lo, g[i]);
    hi = std::max(hi, g[i]);
    sum += g[i];
    sq += g[i] * g[i];
  }
  const ExpandTables& ex = expand_tables();
  // Candidate: one colour from the single-colour table (index 2 everywhere).
  const SingleColourTables& tab = single_colour_tables();
  const int mean = (sum + 8) / 16;
  int best_g0 = tab.q4[1][mean][0], best_g1 = tab.q4[1][mean][1];
  uint32_t best_idx = 0xAAAAAAAAu;
  int best_err;
  {
    const int p = (2 * ex.e6[best_g0] + ex.e6[best_g1] + 1) / 3;
    best_err = sq - 2 * p * sum + 16 * p * p;
  }
  if (lo != hi && best_err > 0) {
    // Start: positions along [lo, hi] in 4 steps; then least squares + exact nearest, twice.
    float a[16];
    const float scale = 3.0f / float(hi - lo);
    for (int i = 0; i < 16; ++i) a[i] = float(std::clamp(int(float(g[i] - lo) * scale + 0.5f), 0, 3)) / 3.0f;
    for (int iter = 0; iter < std::max(iterations, 1); ++iter) {
      float sa = 0, saa = 0, sax = 0;
      for (int i = 0; i < 16; ++i) { sa += a[i]; saa += a[i] * a[i]; sax += a[i] * float(g[i]); }
      const float aa = saa, ab = sa - saa, bb = 16.0f - 2 * sa + saa, ax = sax, bx = float(sum) - sax;
      const float det = aa * bb - ab * ab;
      if (!(std::fabs(det) > 1e-3f)) break;
      const float e0 = (ax * bb - bx * ab) / det, e1 = (bx * aa - ax * ab) / det;
      const int b0 = int(std::clamp(e0, 0.0f, 255.0f) * (63.0f / 255.0f));
      const int b1 = int(std::clamp(e1, 0.0f, 255.0f) * (63.0f / 255.0f));
      // Rank the 4x4 nearest quantised pairs on the moments, then index the winner exactly.
      int g0 = b0, g1 = b1;
      float rank = 3.4e38f;
      for (int d0 = -1; d0 <= 2; ++d0)
        for (int d1 = -1; d1 <= 2; ++d1) {
          const int c0 = b0 + d0, c1 = b1 + d1;
          if (c0 < 0 || c0 > 63 || c1 < 0 || c1 > 63) continue;
          const float v0 = float(ex.e6[c0]), v1 = float(ex.e6[c1]);
          const float e = -2 * v0 * ax - 2 * v1 * bx + v0 * v0 * aa + 2 * v0 * v1 * ab + v1 * v1 * bb;
          if (e < rank) { rank = e; g0 = c0; g1 = c1; }
        }
      const int v0 = ex.e6[g0], v1 = ex.e6[g1];
      // The four entries in ascending order with their indices (p2 and p3 lie between the ends);
      // the nearest entry is the number of midpoints below 2g (a tie picks the lower entry, at
      // the same error). Branch-free and nested (c3 => c2 => c1), so sums and XORs telescope.
      const int p2 = (2 * v0 + v1 + 1) / 3, p3 = (v0 + 2 * v1 + 1) / 3;
      const bool up = v0 >= v1;
      const int sv[4] = {up ? v1 : v0, up ? p3 : p2, up ? p2 : p3, up ? v0 : v1};
      const int si[4] = {up ? 1 : 0, up ? 3 : 2, up ? 2 : 3, up ? 0 : 1};
      const int m1 = sv[0] + sv[1], m2 = sv[1] + sv[2], m3 = sv[2] + sv[3];
      int cand_err = 0;
      uint32_t cand_idx = 0;
      for (int i = 0; i < 16; ++i) {
        const int g2 = 2 * g[i];
        const int c1 = g2 > m1, c2 = g2 > m2, c3 = g2 > m3;
        const int v = sv[0] + c1 * (sv[1] - sv[0]) + c2 * (sv[2] - sv[1]) + c3 * (sv[3] - sv[2]);
        const int k = si[0] ^ (c1 * (si[0] ^ si[1])) ^ (c2 * (si[1] ^ si[2])) ^ (c3 * (si[2] ^ si[3]));
        cand_err += (g[i] - v) * (g[i] - v);
        cand_idx |= uint32_t(k) << (2 * i);
      }
      if (cand_err >= best_err) break;
      best_err = cand_err;
      best_g0 = g0;
      best_g1 = g1;
      best_idx = cand_idx;
      static const float kWeight[4] = {1.0f, 0.0f, 2.0f / 3.0f, 1.0f / 3.0f};
      for (int i = 0; i < 16; ++i) a[i] = kWeight[(best_idx >> (2 * i)) & 3];
    }
  }
  uint16_t c0 = uint16_t((qr << 11) | (best_g0 << 5) | qb), c1 = uint16_t((qr << 11) | (best_g1 << 5) | qb);
  if (c0 < c1) {
    std::swap(c0, c1);
    best_idx ^= 0x55555555u;
  } else if (c0 == c1) {
    best_idx = 0;
  }
  write16(out, c0);
  write16(out + 2, c1);
  write32(out + 4, best_idx);
  return true;
}

namespace {
// 8-value mode: exact nearest entry per value (direct position plus a neighbour check). u = 0..7
// is the position from a1 (u = 0) to a0 (u = 7); selector = 1 for u 0, 0 for u 7, else 8 - u.
int bc4_assign8(const uint8_t v[16], int a0, int a1, uint8_t sel[16], int u_out[16]) {
  int pal[8];
  bc4_palette(a0, a1, pal);
  int by_u[8];
  for (int u = 0; u < 8; ++u) by_u[u] = pal[u == 7 ? 0 : u == 0 ? 1 : 8 - u];
  const float scale = 7.0f / float(a0 - a1);
  int err = 0;
  for (int i = 0; i < 16; ++i) {
    const int x = v[i];
    int u = std::clamp(int(float(x - a1) * scale + 0.5f), 0, 7);
    int d = std::abs(x - by_u[u]);
    if (u > 0 && std::abs(x - by_u[u - 1]) < d) { --u; d = std::abs(x - by_u[u]); }
    if (u < 7 && std::abs(x - by_u[u + 1]) < d) { ++u; d = std::abs(x - by_u[u]); }
    u_out[i] = u;
    sel[i] = uint8_t(u == 7 ? 0 : u == 0 ? 1 : 8 - u);
    err += d * d;
  }
  return err;
}
}  // namespace

void own_encode_bc4(const uint8_t values[16], uint8_t out[8]) {
  int lo = 255, hi = 0;
  for (int i = 0; i < 16; ++i) {
    lo = std::min(lo, int(values[i]));
    hi = std::max(hi, int(values[i]));
  }
  uint8_t sel[16], best_sel[16];
  if (lo == hi) {
    std::memset(sel, 0, 16);
    write_bc4(lo, lo, sel, out);
    return;
  }
  // 8-value mode from min/max, then one least-squares refit ranked on the moments.
  int u[16];
  int best = bc4_assign8(values, hi, lo, best_sel, u);
  int best_a0 = hi, best_a1 = lo;
  if (best > 0) {
    float su = 0, suu = 0, sv = 0, suv = 0;
    for (int i = 0; i < 16; ++i) {
      const float a = float(u[i]) * (1.0f / 7.0f);
      su += a; suu += a * a; sv += float(values[i]); suv += a * float(values[i]);
    }
    const float aa = suu, ab = su - suu, bb = 16.0f - 2 * su + suu, ax = suv, bx = sv - suv;
    const float det = aa * bb - ab * ab;
    if (std::fabs(det) > 1e-3f) {
      const int e0 = int(std::lround((ax * bb - bx * ab) / det)), e1 = int(std::lround((bx * aa - ax * ab) / det));
      float rank = 3.4e38f;
      int c0 = hi, c1 = lo;
      for (int d0 = -1; d0 <= 1; ++d0)
        for (int d1 = -1; d1 <= 1; ++d1) {
          const int t0 = std::clamp(e0 + d0, 0, 255), t1 = std::clamp(e1 + d1, 0, 255);
          if (t0 <= t1) continue;
          const float v0 = float(t0), v1 = float(t1);
          const float e = -2 * v0 * ax - 2 * v1 * bx + v0 * v0 * aa + 2 * v0 * v1 * ab + v1 * v1 * bb;
          if (e < rank) { rank = e; c0 = t0; c1 = t1; }
        }
      const int err = bc4_assign8(values, c0, c1, sel, u);
      if (err < best) {
        best = err;
        best_a0 = c0;
        best_a1 = c1;
        std::memcpy(best_sel, sel, 16);
      }
    }
  }
  // 6-value mode with explicit 0 and 255, useful when the block touches the ends of the range.
  if (lo == 0 || hi == 255) {
    int lo2 = 255, hi2 = 0;
    for (int i = 0; i < 16; ++i)
      if (values[i] != 0 && values[i] != 255) {
        lo2 = std::min(lo2, int(values[i]));
        hi2 = std::max(hi2, int(values[i]));
      }
    if (lo2 > hi2) lo2 = hi2 = lo;
    const int64_t err = bc4_assign(values, lo2, hi2, sel);
    if (err < best) {
      best = int(err);
      best_a0 = lo2;
      best_a1 = hi2;
      std::memcpy(best_sel, sel, 16);
    }
  }
  write_bc4(best_a0, best_a1, best_sel, out);
}

void own_encode_bc4_upper(const uint8_t targets[16], uint8_t out[8]) {
  int hi = 0, hi_below_255 = -1;
  for (int i = 0; i < 16; ++i) {
    hi = std::max(hi, int(targets[i]));
    if (targets[i] < 255) hi_below_255 = std::max(hi_below_255, int(targets[i]));
  }
  int64_t best = INT64_MAX;
  int best_a0 = 255, best_a1 = 255;
  // Sum over texels of (smallest palette entry >= target) - target; INT64_MAX if one has none.
  auto cost = [&](int a0, int a1) {
    int pal[8];
    bc4_palette(a0, a1, pal);
    std::sort(pal, pal + 8);
    int64_t total = 0;
    for (int i = 0; i < 16; ++i) {
      const int t = targets[i];
      const int* e = std::lower_bound(pal, pal + 8, t);
      if (e == pal + 8) return INT64_MAX;
      total += *e - t;
    }
    return total;
  };
  // 8-value mode: a0 = max target (needed exactly), a1 free below it; 6-value mode: 255 comes
  // free, so the range only covers the targets below 255. Coarse scan (step 8), then the
  // neighbourhood of the best coarse value.
  const int top = hi_below_255 < 0 ? 0 : hi_below_255;
  auto scan = [&](int from, int to, int step) {
    for (int a1 = std::max(0, from); a1 < std::min(hi, to + 1); a1 += step) {
      const int64_t c = cost(hi, a1);
      if (c < best) { best = c; best_a0 = hi; best_a1 = a1; }
    }
    for (int a0 = std::max(0, from); a0 <= std::min(top, to); a0 += step) {
      const int64_t c = cost(a0, top);
      if (c < best) { best = c; best_a0 = a0; best_a1 = top; }
    }
  };
  scan(0, 255, 8);
  const int centre = best_a0 == hi && best_a0 > best_a1 ? best_a1 : best_a0;
  scan(centre - 7, centre + 7, 1);
  if (best == INT64_MAX) { best_a0 = 0; best_a1 = 0; }  // all targets 255: 6-value mode, index 7
  int pal[8];
  bc4_palette(best_a0, best_a1, pal);
  uint8_t sel[16];
  for (int i = 0; i < 16; ++i) {
    int e = INT32_MAX;
    for (int k = 0; k < 8; ++k)
      if (pal[k] >= targets[i] && pal[k] - targets[i] < e) {
        e = pal[k] - targets[i];
        sel[i] = uint8_t(k);
      }
  }
  write_bc4(best_a0, best_a1, sel, out);
}

}  // namespace terrain::cook
