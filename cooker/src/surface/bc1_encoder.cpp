// BC1 block encoders (colour blocks of the albedo and the normals; BC4 is bc4_encoder.cpp).
//
// Colour (encode_bc1_opaque / encode_bc1_weighted / encode_bc1_holes): PCA extremes, then alternate
//  (a) nearest-palette index assignment and (b) endpoint optimisation for the fixed indices.
//  encode_colour (holes, 3-colour tries) does (b) exactly over a small window of quantised 5/6-bit
//  endpoint pairs around the least-squares solution: for fixed indices the squared error separates
//  by channel, and each candidate pair costs four multiply-adds from per-index sums (n_k, S_k, Q_k).
//  This is where the quality over stb_dxt comes from (stb rounds its least-squares endpoints once).
//  The opaque 4-colour path (encode_opaque_scalar, restated in SSE2 as encode_opaque_sse) ranks the
//  candidates on moments instead; see its section below.
// Ordering search (Bc1Method::ordering_search): see ordering_search_scalar() below; a sorted-order
//  partition search like libsquish's cluster fit, restricted to coordinate sweeps over the group
//  boundaries.
// G-only blocks (encode_bc1_g_only): normal maps whose R and B are constant.
#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "bc_blocks.h"
#include "pair_ranks_sse2.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

// The scalar definition rounds every float operation to float (as SSE2 does); x87 excess
// precision would give other bytes.
#if defined(FLT_EVAL_METHOD) && FLT_EVAL_METHOD != 0
#error "bc1_encoder.cpp needs FLT_EVAL_METHOD == 0 (e.g. -mfpmath=sse on 32-bit x86)"
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

// ---- Opaque 4-colour blocks (the albedo hot path): one definition, two statements --------------
// Same algorithm as encode_colour, restated on moments: for fixed per-texel weights a_i (1, 2/3,
// 1/3, 0 for indices 0, 2, 3, 1) the least-squares endpoints and the error of any candidate
// endpoint pair follow from sum a, sum a^2, sum x, sum x^2 and sum a*x per channel (the palette's
// +1/3 rounding is ignored when ranking the few candidates; the final index choice uses the exact
// decoded palette).
//
// The definition is the plain scalar code below (encode_opaque_scalar); the SSE2 code after it
// (encode_opaque_sse) is a restatement that writes the same bytes, like meshoptimizer's vertex
// codec. Float results must be bit-identical, so the scalar code keeps the vector code's
// operation order: a texel i lives in lane i % 4 of vector i / 4, sums over texels add per lane
// first and then across lanes as (l0 + l2) + (l1 + l3) (sum_lanes), min / max have the minps /
// maxps semantics (a < b ? a : b) and the same reduction trees. The file is built with
// -ffp-contract=off so no compiler fuses a multiply-add in one statement and not the other.
// tests/surface/test_bc1_paths.cpp encodes real, random and hard blocks both ways.

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

// minps / maxps: the second operand unless the first is strictly smaller / larger.
inline float min_ps(float a, float b) { return a < b ? a : b; }
inline float max_ps(float a, float b) { return a > b ? a : b; }
// Horizontal reductions of four lanes in the SSE2 order (hsum / hmin / hmax below).
// cvttps2dq: truncation, and INT32_MIN for NaN or out of range (a plain cast would be undefined).
inline int32_t truncate_like_cvttps(float x) {
  return x >= -2147483648.0f && x < 2147483648.0f ? int32_t(x) : INT32_MIN;
}
inline float sum_lanes(const float l[4]) { return (l[0] + l[2]) + (l[1] + l[3]); }
inline float min_lanes(const float l[4]) { return min_ps(min_ps(l[0], l[2]), min_ps(l[1], l[3])); }
inline float max_lanes(const float l[4]) { return max_ps(max_ps(l[0], l[2]), max_ps(l[1], l[3])); }
// Sum over the 16 texels: per lane from 0 in texel order, then across the lanes.
inline float sum16(const float x[16]) {
  float l[4] = {0, 0, 0, 0};
  for (int v = 0; v < 4; ++v)
    for (int i = 0; i < 4; ++i) l[i] += x[4 * v + i];
  return sum_lanes(l);
}

// Endpoints for weights with the given moments: least squares, then the best of the 4x4 nearest
// quantised pairs per channel (floor-1 .. floor+2, clamped), ranked by the moment form of the error,
// which separates as f0(v0) + f1(v1) + 2 ab v0 v1; the first minimum in (v0, v1) order wins.
void fit_from_moments_scalar(const Moments& m, int q0[3], int q1[3]) {
  const float n = 16.0f;
  const float aa = m.saa, ab = m.sa - m.saa, bb = n - 2 * m.sa + m.saa;
  const float det = aa * bb - ab * ab;
  const float scale[3] = {31.0f / 255.0f, 63.0f / 255.0f, 31.0f / 255.0f};
  for (int c = 0; c < 3; ++c) {
    const float ax = m.sax[c], bx = m.sx[c] - ax;
    float e0, e1;
    if (std::fabs(det) > 1e-3f) {
      e0 = (ax * bb - bx * ab) / det;
      e1 = (bx * aa - ax * ab) / det;
    } else {
      e0 = e1 = m.sx[c] / n;
    }
    const int base0 = int(min_ps(max_ps(e0, 0.0f), 255.0f) * scale[c]);
    const int base1 = int(min_ps(max_ps(e1, 0.0f), 255.0f) * scale[c]);
    const int six = c == 1, qmax = six ? 63 : 31;
    int qa[4], qb[4];
    float va[4], vb[4], fa[4], fb[4], ka[4];
    for (int i = 0; i < 4; ++i) {
      qa[i] = std::clamp(base0 + i - 1, 0, qmax);
      qb[i] = std::clamp(base1 + i - 1, 0, qmax);
      va[i] = float(six ? expand6(qa[i]) : expand5(qa[i]));
      vb[i] = float(six ? expand6(qb[i]) : expand5(qb[i]));
      fa[i] = va[i] * (va[i] * aa - 2 * ax);
      fb[i] = vb[i] * (vb[i] * bb - 2 * bx);
      ka[i] = (2 * ab) * va[i];
    }
    float e[4][4];
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) e[i][j] = fa[i] + (fb[j] + ka[i] * vb[j]);
    // The vector reduction: rows lane-wise, then lanes 1 and 2 apart.
    float mn[4], m1[4], m2[4];
    for (int j = 0; j < 4; ++j) mn[j] = min_ps(min_ps(e[0][j], e[1][j]), min_ps(e[2][j], e[3][j]));
    for (int j = 0; j < 4; ++j) m1[j] = min_ps(mn[j], mn[j ^ 1]);
    for (int j = 0; j < 4; ++j) m2[j] = min_ps(m1[j], m1[j ^ 2]);
    int bq0 = qa[0], bq1 = qb[0];
    bool found = false;
    for (int i = 0; i < 4 && !found; ++i)
      for (int j = 0; j < 4 && !found; ++j)
        if (e[i][j] == m2[j]) {
          bq0 = qa[i];
          bq1 = qb[j];
          found = true;
        }
    q0[c] = bq0;
    q1[c] = bq1;
  }
}

inline uint32_t pack_indices_scalar(const int sel[16]) {
  uint32_t idx = 0;
  for (int i = 0; i < 16; ++i) idx |= uint32_t(sel[i]) << (2 * i);
  return idx;
}

// Nearest exact palette entry per texel (the first of equal ones) and the summed error.
template <bool kUniform>
float assign_scalar(const float ch[3][16], const int pal[4][3], const float w[3], int sel[16]) {
  float best[16];
  for (int i = 0; i < 16; ++i) {
    for (int k = 0; k < 4; ++k) {
      const float dr = ch[0][i] - float(pal[k][0]), dg = ch[1][i] - float(pal[k][1]), db = ch[2][i] - float(pal[k][2]);
      float d;
      if constexpr (kUniform) {
        d = (dr * dr + dg * dg) + db * db;
      } else {
        d = (w[0] * (dr * dr) + w[1] * (dg * dg)) + w[2] * (db * db);
      }
      if (k == 0) {
        best[i] = d;
        sel[i] = 0;
      } else {
        if (d < best[i]) sel[i] = k;
        best[i] = min_ps(d, best[i]);
      }
    }
  }
  return sum16(best);
}

// Ordering search, both paths: prefix sums of each channel in the search's order (P[c][r]: the
// first r texels; padded to 24 with the total) and three times each channel's total.
inline void prefix_sums_in_order(const float ch[3][16], const int order[16], float P[3][24], float X3[3]) {
  for (int c = 0; c < 3; ++c) {
    float acc = 0;
    P[c][0] = 0;
    for (int r = 0; r < 16; ++r) P[c][r + 1] = acc += ch[c][order[r]];
    for (int r = 17; r < 24; ++r) P[c][r] = acc;
    X3[c] = 3 * acc;
  }
}

// Ordering search, both paths: the start partition, the group boundaries of the block's current
// indices counted from the endpoint that projects lower on the axis.
inline void start_boundaries(uint32_t idx, const float axis[3], const int q0[3], const int q1[3], int b[3]) {
  int cnt[4] = {0, 0, 0, 0};
  for (int t = 0; t < 16; ++t) ++cnt[(idx >> (2 * t)) & 3];
  const float d0 = axis[0] * float(expand5(q0[0])) + axis[1] * float(expand6(q0[1])) + axis[2] * float(expand5(q0[2]));
  const float d1 = axis[0] * float(expand5(q1[0])) + axis[1] * float(expand6(q1[1])) + axis[2] * float(expand5(q1[2]));
  const bool low0 = d0 <= d1;
  b[0] = low0 ? cnt[0] : cnt[1];
  b[1] = b[0] + cnt[low0 ? 2 : 3];
  b[2] = b[1] + cnt[low0 ? 3 : 2];
}

// Ordering search, both paths: coordinate sweeps over the three boundaries b (os.scan keeps the
// best score), then the moments of the winning partition. False when the winner is the start.
template <class Search>
bool sweep_to_winner(Search& os, int sweeps, const int start[3], int b[3], float& best, Moments& m) {
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    const int before[3] = {b[0], b[1], b[2]};
    os.scan(0, 0, b[1], b, best);
    os.scan(2, b[1], 16, b, best);
    os.scan(1, b[0], b[2], b, best);
    if (b[0] == before[0] && b[1] == before[1] && b[2] == before[2]) break;
  }
  if (b[0] == start[0] && b[1] == start[1] && b[2] == start[2]) return false;
  m.sa = float(b[0] + b[1] + b[2]) / 3.0f;
  m.saa = float(5 * b[0] + 3 * b[1] + b[2]) / 9.0f;
  for (int c = 0; c < 3; ++c) {
    m.sax[c] = (os.P[c][b[0]] + os.P[c][b[1]] + os.P[c][b[2]]) / 3.0f;
    m.sx[c] = os.P[c][16];
  }
  return true;
}

// Ordering search (a cheap relative of libsquish's cluster fit), used by Bc1Method::ordering_search.
// Texels sorted along the principal axis form four contiguous groups with c0 weights 1, 2/3, 1/3, 0
// from the low end. With group boundaries i <= j <= k and P(r) the prefix sums of the sorted
// colours, sum a*x = (P(i) + P(j) + P(k)) / 3, sum a = (i + j + k) / 3 and sum a^2 = (5i + 3j + k) / 9,
// so the least-squares endpoints of a partition cost a few multiply-adds. Like libsquish, partitions
// are ranked by the error of those endpoints rounded to the 5:6:5 grid. libsquish scores all 969
// partitions; we run coordinate sweeps from the partition the current indices imply: each boundary
// in turn scans its whole free range with the other two fixed (4 candidates per step), then
// the winner is quantised exactly (4x4 window) and kept if its exact error is lower.
// Measured on Oetztal splat albedo (terrain-bc-bench --block-stats; default axis-fit-hard 39.76 dB, squish
// cluster 40.08 dB): the winning partitions usually differ from the start in one boundary, by up
// to ~7 texels, so a +-1 neighbourhood hill-climb stalls at 39.93 dB (+-3: 40.04 dB); one sweep
// gives 40.06 dB, two 40.08 dB, the full 969-partition search 40.27 dB (at ~10x the time);
// ranking by the unrounded error instead loses 0.06-0.08 dB. The search only helps together with
// the hard-block refits (without them: 40.01 dB), and it is needed on nearly every block with
// error (only above 48 x 4 per channel: 40.03 dB), since the loss is spread over all such blocks.
struct OrderingSearchScalar {
  float P[3][24];  // prefix sums per channel, padded with P(16)
  float X3[3];     // 3 * sum x per channel

  // Rounded-endpoint residual (minus the constant sum x^2, times 9) of the partition with
  // boundaries fi <= fj <= fk; T: P(i) + P(j) + P(k) per channel. A singular system (all texels
  // in one group) or `invalid` scores 3.4e38.
  static float score(float fi, float fj, float fk, const float T[3], bool invalid, const float X3[3]) {
    const float s3 = (fi + fj) + fk;
    const float a9 = (fi * 5.0f + fj * 3.0f) + fk;
    const float AA = a9, AB = s3 * 3.0f - a9;
    const float BB = (144.0f - s3 * 6.0f) + a9;
    const float D = AA * BB - AB * AB;
    if (invalid || D <= 0.5f) return 3.4e38f;
    const float inv = 3.0f / D;
    const float AB2 = AB + AB;
    static const float kGrid[3] = {31.0f / 255.0f, 63.0f / 255.0f, 31.0f / 255.0f};
    static const float kGridInv[3] = {255.0f / 31.0f, 255.0f / 63.0f, 255.0f / 31.0f};
    float e = 0.0f;
    for (int c = 0; c < 3; ++c) {
      const float t = T[c], u = X3[c] - t;
      float a = (t * BB - u * AB) * inv;
      float b = (u * AA - t * AB) * inv;
      // Round to the grid, half to even (cvtps2dq in the default rounding mode).
      a = float(std::lrint(min_ps(max_ps(a, 0.0f), 255.0f) * kGrid[c])) * kGridInv[c];
      b = float(std::lrint(min_ps(max_ps(b, 0.0f), 255.0f) * kGrid[c])) * kGridInv[c];
      // AA a^2 + BB b^2 + 2 AB a b - 6 (a T + b U)   (9 x the residual minus sum x^2)
      const float quad = a * (a * AA + b * AB2) + (b * b) * BB;
      e = e + (quad - (a * t + b * u) * 6.0f);
    }
    return e;
  }

  // Scans boundary `which` (0: i, 1: j, 2: k) over [lo, hi] with the others fixed, four candidates
  // per step like the vector code (the step's minimum, its first lane); updates b[] and best.
  void scan(int which, int lo, int hi, int b[3], float& best) const {
    const int fixed0 = which == 0 ? 1 : 0, fixed1 = which == 2 ? 1 : 2;
    float base[3];
    for (int c = 0; c < 3; ++c) base[c] = P[c][b[fixed0]] + P[c][b[fixed1]];
    int arg = b[which];
    for (int x = lo; x <= hi; x += 4) {
      float e[4];
      for (int l = 0; l < 4; ++l) {
        const float fx = float(x) + float(l);
        float T[3];
        for (int c = 0; c < 3; ++c) T[c] = base[c] + P[c][x + l];
        const float fi = which == 0 ? fx : float(b[0]);
        const float fj = which == 1 ? fx : float(b[1]);
        const float fk = which == 2 ? fx : float(b[2]);
        e[l] = score(fi, fj, fk, T, fx > float(hi), X3);
      }
      const float m = min_lanes(e);
      if (m < best) {
        best = m;
        int l = 0;
        while (e[l] != m) ++l;
        arg = x + l;
      }
    }
    b[which] = arg;
  }
};

void ordering_search_scalar(const float ch[3][16], const float proj[16], const float axis[3], int sweeps,
                            int best_q0[3], int best_q1[3], uint32_t& best_idx, float& best_err) {
  // Rank of texel t = number of keys below its key; the keys are the projections scaled to 24 bits
  // with the texel index in the low 4 bits, so they are distinct and the ranks a permutation.
  int order[16];
  {
    float lo[4], hi[4];
    for (int l = 0; l < 4; ++l) {
      lo[l] = min_ps(min_ps(proj[l], proj[4 + l]), min_ps(proj[8 + l], proj[12 + l]));
      hi[l] = max_ps(max_ps(proj[l], proj[4 + l]), max_ps(proj[8 + l], proj[12 + l]));
    }
    const float pmin = min_lanes(lo), pmax = max_lanes(hi);
    const float scale = pmax > pmin ? float(1 << 20) / (pmax - pmin) : 0.0f;
    int32_t key[16];
    for (int t = 0; t < 16; ++t) key[t] = int32_t(uint32_t(truncate_like_cvttps((proj[t] - pmin) * scale)) << 4) | t;
    for (int t = 0; t < 16; ++t) {
      int rank = 0;
      for (int s = 0; s < 16; ++s) rank += key[s] < key[t];
      order[rank] = t;
    }
  }
  OrderingSearchScalar os;
  prefix_sums_in_order(ch, order, os.P, os.X3);
  int b[3];
  start_boundaries(best_idx, axis, best_q0, best_q1, b);
  const int start[3] = {b[0], b[1], b[2]};
  float best;
  {
    float T[3];
    for (int c = 0; c < 3; ++c) T[c] = os.P[c][b[0]] + os.P[c][b[1]] + os.P[c][b[2]];
    best = OrderingSearchScalar::score(float(b[0]), float(b[1]), float(b[2]), T, false, os.X3);
  }
  Moments m;
  if (!sweep_to_winner(os, sweeps, start, b, best, m)) return;
  // The winner's endpoints, quantised exactly (4x4 window), then the exact nearest indices.
  int q0[3], q1[3], pal[4][3], sel[16];
  fit_from_moments_scalar(m, q0, q1);
  palette_of(q0, q1, true, pal);
  static const float kUnit[3] = {1, 1, 1};
  const float e = assign_scalar<true>(ch, pal, kUnit, sel);
  if (e < best_err) {
    best_err = e;
    best_idx = pack_indices_scalar(sel);
    std::copy(q0, q0 + 3, best_q0);
    std::copy(q1, q1 + 3, best_q1);
  }
}

// Writes the 4-colour block (c0 > c1; equal endpoints: index 0 everywhere).
void write_four_colour(int q0[3], int q1[3], uint32_t idx, uint8_t out[8]) {
  uint16_t c0 = pack(q0), c1 = pack(q1);
  if (c0 < c1) {
    std::swap(c0, c1);
    idx ^= 0x55555555u;
  } else if (c0 == c1) {
    idx = 0;
  }
  write16(out, c0);
  write16(out + 2, c1);
  write32(out + 4, idx);
}

// The definition of the opaque encoder (see the section comment).
// ---- Shared by the scalar definition and its SSE2 restatement (same float operations) ----------

// Candidate 1: one colour for every texel, the single-colour tables' endpoints at the mean; its
// weighted squared error from the block's sums (sum) and sums of squares (sqd) per channel.
inline float single_colour_candidate(const float sum[3], const float sqd[3], const float w[3], int q0[3], int q1[3]) {
  const SingleColourTables& tab = single_colour_tables();
  float err = 0;
  for (int c = 0; c < 3; ++c) {
    const int mean = int(sum[c] * (1.0f / 16.0f) + 0.5f);
    const int six = kBits[c] == 6;
    q0[c] = tab.q4[six][mean][0];
    q1[c] = tab.q4[six][mean][1];
    const int v0 = expand_bits(q0[c], kBits[c]), v1 = expand_bits(q1[c], kBits[c]);
    const float p = float((2 * v0 + v1 + 1) / 3);
    err += w[c] * (sqd[c] - 2 * p * sum[c] + 16 * p * p);
  }
  return err;
}

// Principal axis of the weighted covariance (sq: xx, xy, xz, yy, yz, zz sums), by power iteration
// started from the weighted bounding box diagonal.
inline void weighted_principal_axis(const float sum[3], const float sq[6], const float mn[3], const float mx[3],
                                    const float w[3], float ax[3]) {
  const float inv16 = 1.0f / 16.0f;
  float cov[6] = {(sq[0] - sum[0] * sum[0] * inv16) * w[0] * w[0], (sq[1] - sum[0] * sum[1] * inv16) * w[0] * w[1],
                  (sq[2] - sum[0] * sum[2] * inv16) * w[0] * w[2], (sq[3] - sum[1] * sum[1] * inv16) * w[1] * w[1],
                  (sq[4] - sum[1] * sum[2] * inv16) * w[1] * w[2], (sq[5] - sum[2] * sum[2] * inv16) * w[2] * w[2]};
  ax[0] = (mx[0] - mn[0]) * w[0];
  ax[1] = (mx[1] - mn[1]) * w[1];
  ax[2] = (mx[2] - mn[2]) * w[2];
  principal_axis(cov, ax);
}

template <bool kUniform>  // all weights 1: the distance skips the weight multiplies
void encode_opaque_scalar(const uint8_t rgba[64], const float w[3], int iterations, const HardBlocks& hard,
                          uint8_t out[8], float* err_out) {
  float ch[3][16];
  for (int i = 0; i < 16; ++i)
    for (int c = 0; c < 3; ++c) ch[c][i] = float(rgba[4 * i + c]);
  // Sums, squares, cross products, min and max per channel.
  float sum[3], sq[6], mn[3], mx[3];
  {
    static const int kPair[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
    for (int k = 0; k < 6; ++k) {
      float p[16];
      for (int i = 0; i < 16; ++i) p[i] = ch[kPair[k][0]][i] * ch[kPair[k][1]][i];
      sq[k] = sum16(p);
    }
    for (int c = 0; c < 3; ++c) {
      sum[c] = sum16(ch[c]);
      float lo[4], hi[4];
      for (int l = 0; l < 4; ++l) {
        lo[l] = hi[l] = ch[c][l];
        for (int v = 0; v < 4; ++v) {
          lo[l] = min_ps(lo[l], ch[c][4 * v + l]);
          hi[l] = max_ps(hi[l], ch[c][4 * v + l]);
        }
      }
      mn[c] = min_lanes(lo);
      mx[c] = max_lanes(hi);
    }
  }
  const float sqd[3] = {sq[0], sq[3], sq[5]};

  // Candidate 1: one colour (single-colour tables at the mean), error from the sums.
  int best_q0[3], best_q1[3];
  float best_err = single_colour_candidate(sum, sqd, w, best_q0, best_q1);
  uint32_t best_idx = 0xAAAAAAAAu;  // index 2 everywhere

  const bool flat = mn[0] == mx[0] && mn[1] == mx[1] && mn[2] == mx[2];
  if (!flat && best_err > 0.5f) {
    // Principal axis of the weighted covariance (power iteration from the bounding box).
    float ax[3];
    weighted_principal_axis(sum, sq, mn, mx, w, ax);
    const float k0 = ax[0] * w[0], k1 = ax[1] * w[1], k2 = ax[2] * w[2];
    float proj[16], pl[4], ph[4];
    for (int i = 0; i < 16; ++i) proj[i] = (ch[0][i] * k0 + ch[1][i] * k1) + ch[2][i] * k2;
    for (int l = 0; l < 4; ++l) {
      pl[l] = ph[l] = proj[l];
      for (int v = 1; v < 4; ++v) {
        pl[l] = min_ps(pl[l], proj[4 * v + l]);
        ph[l] = max_ps(ph[l], proj[4 * v + l]);
      }
    }
    const float pmin = min_lanes(pl), pmax = max_lanes(ph);
    // Moments of weights a_i = t_i / 3 and of the exact indices' weights (c0 weight per index:
    // 1, 0, 2/3, 1/3 = k < 2 ? 1 - k : (4 - k) / 3).
    Moments m;
    auto set_moments = [&](const float a[16]) {
      float aa[16], ax3[3][16];
      for (int i = 0; i < 16; ++i) {
        aa[i] = a[i] * a[i];
        for (int c = 0; c < 3; ++c) ax3[c][i] = a[i] * ch[c][i];
      }
      m.sa = sum16(a);
      m.saa = sum16(aa);
      for (int c = 0; c < 3; ++c) m.sax[c] = sum16(ax3[c]);
    };
    {
      const float scale = pmax > pmin ? 3.0f / (pmax - pmin) : 0.0f;
      float a[16];
      for (int i = 0; i < 16; ++i) a[i] = float(truncate_like_cvttps((proj[i] - pmin) * scale + 0.5f)) * (1.0f / 3.0f);
      set_moments(a);
      for (int c = 0; c < 3; ++c) {
        m.sx[c] = sum[c];
        m.sxx[c] = sqd[c];
      }
    }
    int max_iter = std::max(iterations, 1);
    for (int iter = 0; iter < max_iter; ++iter) {
      int q0[3], q1[3];
      fit_from_moments_scalar(m, q0, q1);
      int pal[4][3];
      palette_of(q0, q1, true, pal);
      int sel[16];
      const float e = assign_scalar<kUniform>(ch, pal, w, sel);
      if (!(e < best_err)) break;
      best_err = e;
      best_idx = pack_indices_scalar(sel);
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
      float a[16];
      for (int i = 0; i < 16; ++i) {
        const float k = float(sel[i]);
        a[i] = k >= 2.0f ? (4.0f - k) * (1.0f / 3.0f) : 1.0f - k;
      }
      set_moments(a);
    }
    if constexpr (kUniform) {
      if (hard.ordering_sweeps > 0 && best_err > hard.ordering_threshold)
        ordering_search_scalar(ch, proj, ax, hard.ordering_sweeps, best_q0, best_q1, best_idx, best_err);
    }
  }
  write_four_colour(best_q0, best_q1, best_idx, out);
  if (err_out) *err_out = best_err;
}

#if defined(__SSE2__)
// ---- SSE2 restatement of encode_opaque_scalar (same bytes, see the section comment) ---------------

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

// Endpoints for weights with the given moments: least squares, then the best of the 4x4 nearest
// quantised pairs per channel (floor-1 .. floor+2, clamped), ranked by the moment form of the error,
// which separates as f0(v0) + f1(v1) + 2 ab v0 v1. The least-squares solve runs for the three
// channels in one vector (same IEEE operations as per channel, so the same result), the candidate
// expansion in integer lanes (5/6-bit replication by shifts), the 16 candidate errors as 4 vectors.
void fit_from_moments_sse(const Moments& m, int q0[3], int q1[3]) {
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

// The ordering search of ordering_search_scalar, four candidates per vector op.
struct OrderingSearchSse {
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

void ordering_search_sse(const __m128 ch[3][4], const __m128 proj[4], const float axis[3], int sweeps, int best_q0[3],
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
  OrderingSearchSse os;
  prefix_sums_in_order(col, order, os.P, os.X3);
  int b[3];
  start_boundaries(best_idx, axis, best_q0, best_q1, b);
  const int start[3] = {b[0], b[1], b[2]};
  float best;
  {
    __m128 T[3];
    for (int c = 0; c < 3; ++c) T[c] = _mm_set1_ps(os.P[c][b[0]] + os.P[c][b[1]] + os.P[c][b[2]]);
    const __m128 e = OrderingSearchSse::score(_mm_set1_ps(float(b[0])), _mm_set1_ps(float(b[1])), _mm_set1_ps(float(b[2])), T,
                                           _mm_setzero_ps(), os.X3);
    best = _mm_cvtss_f32(e);
  }
  Moments m;
  if (!sweep_to_winner(os, sweeps, start, b, best, m)) return;
  // The winner's endpoints, quantised exactly (4x4 window), then the exact nearest indices.
  int q0[3], q1[3], pal[4][3];
  fit_from_moments_sse(m, q0, q1);
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
  int best_q0[3], best_q1[3];
  float best_err = single_colour_candidate(sum, sqd, w, best_q0, best_q1);
  uint32_t best_idx = 0xAAAAAAAAu;  // index 2 everywhere

  const bool flat = mn[0] == mx[0] && mn[1] == mx[1] && mn[2] == mx[2];
  if (!flat && best_err > 0.5f) {
    // Principal axis of the weighted covariance (power iteration from the bounding box).
    float ax[3];
    weighted_principal_axis(sum, sq, mn, mx, w, ax);
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
      fit_from_moments_sse(m, q0, q1);
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
        ordering_search_sse(ch, proj, ax, hard.ordering_sweeps, best_q0, best_q1, best_idx, best_err);
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

// Hard-block effort of encode_bc1_opaque(refine_hard): the thresholds are squared RGB error
// summed over the block (16 texels x 3 channels), i.e. 48 x the mean squared error per channel.
// Measured on the splat albedo of real nodes (terrain-bc-bench): up to 4 refits above a mean
// squared error of 8 per channel gain 0.07-0.15 dB for ~10 % more time (threshold 16 lost
// 0.04 dB on Kilauea, 4 cost 5 % more time for nothing). The 3-colour try's threshold is
// kBc1ThreeColourThreshold (bc_blocks.h).
constexpr int kHardIterations = 4;
constexpr float kHardThreshold = 48.0f * 8.0f;

// The opaque encoder through the SSE2 restatement when it is compiled in and `simd` asks for it,
// else through the scalar definition; both write the same bytes.
template <bool kUniform>
void encode_opaque(const uint8_t rgba[64], const float w[3], int iterations, const HardBlocks& hard, uint8_t out[8],
                   float* err_out, bool simd) {
#if defined(__SSE2__)
  if (simd) {
    encode_opaque_sse<kUniform>(rgba, w, iterations, hard, out, err_out);
    return;
  }
#endif
  (void)simd;
  encode_opaque_scalar<kUniform>(rgba, w, iterations, hard, out, err_out);
}

void encode_bc1_opaque_path(const uint8_t rgba[64], uint8_t out[8], const Bc1OpaqueEffort& effort, bool simd) {
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
  HardBlocks hard;
  if (effort.refine_hard) {
    hard.iterations = kHardIterations;
    hard.threshold = kHardThreshold;
  }
  hard.ordering_sweeps = effort.ordering_sweeps;
  hard.ordering_threshold = effort.ordering_threshold;
  float err = 0;
  encode_opaque<true>(rgba, kUniform, effort.iterations, hard, out, &err, simd);
  if (effort.three_colour_threshold >= 0 && err > effort.three_colour_threshold) {
    // Two clusters and their midpoint fit the 3-colour mode better (index 3 is not used).
    uint8_t three[8];
    encode_colour(rgba, 0xFFFF, false, kUniform, 2, three);
    if (block_sq_err(rgba, three) < block_sq_err(rgba, out)) std::memcpy(out, three, 8);
  }
}

}  // namespace

bool bc1_simd_compiled() {
#if defined(__SSE2__)
  return true;
#else
  return false;
#endif
}

void encode_bc1_opaque(const uint8_t rgba[64], uint8_t out[8], const Bc1OpaqueEffort& effort) {
  encode_bc1_opaque_path(rgba, out, effort, true);
}

void encode_bc1_opaque_scalar(const uint8_t rgba[64], uint8_t out[8], const Bc1OpaqueEffort& effort) {
  encode_bc1_opaque_path(rgba, out, effort, false);
}

void encode_bc1_holes(const uint8_t rgba[64], uint16_t holes, uint8_t out[8], int iterations) {
  static const float kUniform[3] = {1, 1, 1};
  encode_colour(rgba, uint16_t(~holes), false, kUniform, iterations, out);
}

void encode_bc1_weighted(const uint8_t rgba[64], const float weights[3], uint8_t out[8]) {
  encode_opaque<false>(rgba, weights, 2, HardBlocks{}, out, nullptr, true);
}

void encode_bc1_weighted_scalar(const uint8_t rgba[64], const float weights[3], uint8_t out[8]) {
  encode_opaque<false>(rgba, weights, 2, HardBlocks{}, out, nullptr, false);
}

namespace {

#if defined(__SSE2__)
// Bit i of x moved to bit 2i (x < 2^16).
inline uint32_t spread_bits(uint32_t x) {
  x = (x | (x << 8)) & 0x00FF00FFu;
  x = (x | (x << 4)) & 0x0F0F0F0Fu;
  x = (x | (x << 2)) & 0x33333333u;
  return (x | (x << 1)) & 0x55555555u;
}
#endif

// The G-only block's nearest entries, indices and squared error (see encode_bc1_g_only): sv the
// four entries ascending, si their indices, m1..m3 the doubled midpoints.
void g_only_indices(const int g[16], const int sv[4], const int si[4], bool simd, int& err_out, uint32_t& idx_out) {
  const int m1 = sv[0] + sv[1], m2 = sv[1] + sv[2], m3 = sv[2] + sv[3];
#if defined(__SSE2__)
  if (simd) {
    // The same sums, 8 values per register: masks instead of the 0/1 comparisons, and the 2-bit
    // indices gathered from the two bit planes' byte masks.
    const auto set = [](int v) { return _mm_set1_epi16(int16_t(v)); };
    const __m128i m1v = set(m1), m2v = set(m2), m3v = set(m3);
    const __m128i d01 = set(sv[1] - sv[0]), d12 = set(sv[2] - sv[1]), d23 = set(sv[3] - sv[2]);
    const __m128i x01 = set(si[0] ^ si[1]), x12 = set(si[1] ^ si[2]), x23 = set(si[2] ^ si[3]);
    __m128i errv = _mm_setzero_si128(), ks[2];
    for (int h = 0; h < 2; ++h) {
      const __m128i gv = _mm_packs_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(g + 8 * h)),
                                         _mm_loadu_si128(reinterpret_cast<const __m128i*>(g + 8 * h + 4)));
      const __m128i g2 = _mm_add_epi16(gv, gv);
      const __m128i c1 = _mm_cmpgt_epi16(g2, m1v), c2 = _mm_cmpgt_epi16(g2, m2v), c3 = _mm_cmpgt_epi16(g2, m3v);
      const __m128i v = _mm_add_epi16(_mm_add_epi16(set(sv[0]), _mm_and_si128(c1, d01)),
                                      _mm_add_epi16(_mm_and_si128(c2, d12), _mm_and_si128(c3, d23)));
      ks[h] = _mm_xor_si128(_mm_xor_si128(set(si[0]), _mm_and_si128(c1, x01)),
                            _mm_xor_si128(_mm_and_si128(c2, x12), _mm_and_si128(c3, x23)));
      const __m128i e = _mm_sub_epi16(gv, v);
      errv = _mm_add_epi32(errv, _mm_madd_epi16(e, e));
    }
    const __m128i k8 = _mm_packus_epi16(ks[0], ks[1]);
    const uint32_t bit0 = uint32_t(_mm_movemask_epi8(_mm_slli_epi16(k8, 7)));
    const uint32_t bit1 = uint32_t(_mm_movemask_epi8(_mm_slli_epi16(k8, 6)));
    idx_out = spread_bits(bit0) | (spread_bits(bit1) << 1);
    errv = _mm_add_epi32(errv, _mm_shuffle_epi32(errv, _MM_SHUFFLE(1, 0, 3, 2)));
    errv = _mm_add_epi32(errv, _mm_shuffle_epi32(errv, _MM_SHUFFLE(2, 3, 0, 1)));
    err_out = _mm_cvtsi128_si32(errv);
    return;
  }
#endif
  (void)simd;
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
  err_out = cand_err;
  idx_out = cand_idx;
}

bool encode_bc1_g_only_path(const uint8_t rgba[64], uint8_t out[8], int iterations, bool simd) {
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
#if defined(__SSE2__)
      if (simd) {
        // The same 16 ranks, a row of d1 = -1..2 per register: each lane the expression below in
        // its order of operations, out-of-range pairs +inf (never below the start); then the first
        // smallest in the same order (d0, then d1).
        alignas(16) float v1s[4], bad1[4], e[16];
        for (int d1 = -1; d1 <= 2; ++d1) {
          const int c1 = b1 + d1;
          const bool in = c1 >= 0 && c1 <= 63;
          v1s[d1 + 1] = in ? float(ex.e6[c1]) : 0.0f;
          bad1[d1 + 1] = in ? 0.0f : FLT_MAX * 2.0f;  // +inf
        }
        const __m128 inf1 = _mm_load_ps(bad1);
        const __m128 bad = _mm_cmpneq_ps(inf1, _mm_setzero_ps());
        const PairRanks pairs(ax, bx, aa, ab, bb, _mm_load_ps(v1s));
        for (int d0 = -1; d0 <= 2; ++d0) {
          const int c0 = b0 + d0;
          if (c0 < 0 || c0 > 63) {
            _mm_store_ps(e + 4 * (d0 + 1), _mm_set1_ps(FLT_MAX * 2.0f));
            continue;
          }
          const __m128 ranks = pairs.row(float(ex.e6[c0]));
          _mm_store_ps(e + 4 * (d0 + 1), _mm_or_ps(_mm_and_ps(bad, inf1), _mm_andnot_ps(bad, ranks)));
        }
        const int best = first_smallest(e, 16, rank);
        if (best >= 0) {
          g0 = b0 + best / 4 - 1;
          g1 = b1 + best % 4 - 1;
        }
      } else
#endif
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
      int cand_err = 0;
      uint32_t cand_idx = 0;
      g_only_indices(g, sv, si, simd, cand_err, cand_idx);
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

}  // namespace

bool encode_bc1_g_only(const uint8_t rgba[64], uint8_t out[8], int iterations) {
  return encode_bc1_g_only_path(rgba, out, iterations, true);
}

bool encode_bc1_g_only_scalar(const uint8_t rgba[64], uint8_t out[8], int iterations) {
  return encode_bc1_g_only_path(rgba, out, iterations, false);
}

}  // namespace terrain::cook
