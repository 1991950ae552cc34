#include "terrain/derived_normals.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "terrain/surface_contract.h"

namespace terrain {
namespace {


int expand6(int g) { return (g << 2) | (g >> 4); }
int nearest6(int v) { return (v * 63 + 127) / 255; }

// The 8 alpha entries by position from the maximum (bc_decode.h, nearest rounding): position p
// holds index 0 (p = 0), 1 (p = 7), p + 1 otherwise.
void alpha_entries(int hi, int lo, int value[8]) {
  for (int p = 0; p < 8; ++p) value[p] = ((7 - p) * hi + p * lo + 3) / 7;
  value[0] = hi;
  value[7] = lo;
}

// Alpha half: endpoints hi, lo and the 3-bit indices of the 16 positions (all 0 when hi == lo).
void store_alpha_block(int hi, int lo, const int16_t pos[16], uint8_t out[8]) {
  static constexpr uint64_t kIndex[8] = {0, 2, 3, 4, 5, 6, 7, 1};
  uint64_t bits = 0;
  if (hi > lo)
    for (int i = 0; i < 16; ++i) bits |= kIndex[pos[i]] << (3 * i);
  out[0] = uint8_t(hi);
  out[1] = uint8_t(lo);
  for (int b = 0; b < 6; ++b) out[2 + b] = uint8_t(bits >> (8 * b));
}

// The tightest six-bit G pair whose expanded values cover [lo, hi], from the nearest pair g0, g1.
void covering_pair(int g0, int g1, int hi, int lo, int& c0, int& c1) {
  c0 = g0;
  c1 = g1;
  while (c0 < 63 && expand6(c0) < hi) ++c0;
  while (c1 > 0 && expand6(c1) > lo) --c1;
}

// Colour half: endpoints (R = q, G = g0 / g1, B = 0) and the 2-bit indices of the 16 positions.
void store_colour_block(int q, int g0, int g1, const int16_t pos[16], uint8_t out[8]) {
  static constexpr uint32_t kIndex[4] = {0, 2, 3, 1};
  uint32_t bits = 0;
  for (int i = 0; i < 16; ++i) bits |= kIndex[pos[i]] << (2 * i);
  const uint16_t e0 = uint16_t((q << 11) | (g0 << 5)), e1 = uint16_t((q << 11) | (g1 << 5));
  out[0] = uint8_t(e0);
  out[1] = uint8_t(e0 >> 8);
  out[2] = uint8_t(e1);
  out[3] = uint8_t(e1 >> 8);
  for (int b = 0; b < 4; ++b) out[4 + b] = uint8_t(bits >> (8 * b));
}

// Loops over the 16 texels of a block are written lane by lane, without branches, so that they
// vectorise; the results are those of the plain per-texel definitions in the comments.

// The alpha half: endpoints max/min of the 16 values (8-value mode when they differ); each value
// takes the nearest palette entry, ties to the one nearer the maximum.
void encode_alpha(const uint8_t v[16], uint8_t out[8]) {
  int lo = 255, hi = 0;
  for (int i = 0; i < 16; ++i) {
    lo = std::min<int>(lo, v[i]);
    hi = std::max<int>(hi, v[i]);
  }
  int16_t pos[16] = {};
  if (hi > lo) {
    int value[8];
    alpha_entries(hi, lo, value);
    // Position = how many of the 7 midpoints between neighbouring entries lie above the value
    // (a value on a midpoint stays with the entry nearer the maximum).
    int16_t v2[16];
    for (int i = 0; i < 16; ++i) v2[i] = int16_t(2 * v[i]);
    for (int k = 0; k < 7; ++k) {
      const int16_t mid = int16_t(value[k] + value[k + 1]);
      for (int i = 0; i < 16; ++i) pos[i] = int16_t(pos[i] + (v2[i] < mid));
    }
  }
  store_alpha_block(hi, lo, pos, out);
}

// Positions (0 = g0's entry .. 3 = g1's) and squared error of the 16 values against the 4-colour G
// palette of endpoints g0 >= g1 (six bits): nearest entry, ties to the one nearer g0.
int colour_fit(const uint8_t g[16], int g0, int g1, int16_t pos[16]) {
  const int e0 = expand6(g0), e1 = expand6(g1);
  const int p2 = (2 * e0 + e1 + 1) / 3, p3 = (e0 + 2 * e1 + 1) / 3;  // bc_decode.h, nearest rounding
  const int16_t m01 = int16_t(e0 + p2), m12 = int16_t(p2 + p3), m23 = int16_t(p3 + e1);
  int err = 0;
  for (int i = 0; i < 16; ++i) {
    const int16_t v2 = int16_t(2 * g[i]);
    pos[i] = int16_t((v2 < m01) + (v2 < m12) + (v2 < m23));
    const int16_t value = pos[i] == 0 ? int16_t(e0) : pos[i] == 1 ? int16_t(p2) : pos[i] == 2 ? int16_t(p3) : int16_t(e1);
    const int d = g[i] - value;
    err += d * d;
  }
  return err;
}

// The colour half: R = q (5 bits, exact), B = 0; G's endpoints are the better (first on a tie) of
// the nearest six-bit values of the block's max and min and the tightest pair that covers them.
void encode_colour(int q, const uint8_t g[16], uint8_t out[8]) {
  int lo = 255, hi = 0;
  for (int i = 0; i < 16; ++i) {
    lo = std::min<int>(lo, g[i]);
    hi = std::max<int>(hi, g[i]);
  }
  int g0 = nearest6(hi), g1 = nearest6(lo);
  int16_t pos[16];
  const int err = colour_fit(g, g0, g1, pos);
  int c0, c1;
  covering_pair(g0, g1, hi, lo, c0, c1);
  if (err > 0 && (c0 != g0 || c1 != g1)) {
    int16_t cover_pos[16];
    if (colour_fit(g, c0, c1, cover_pos) < err) {
      g0 = c0;
      g1 = c1;
      std::memcpy(pos, cover_pos, sizeof(pos));
    }
  }
  store_colour_block(q, g0, g1, pos, out);
}

// Mean difference along the two parallel cell edges (a0 -> a1, b0 -> b1) that have both corners.
float edge_gradient(int a0, int a1, bool a_ok, int b0, int b1, bool b_ok) {
  if (a_ok && b_ok) return float((a1 - a0) + (b1 - b0)) * 0.5f;
  if (a_ok) return float(a1 - a0);
  if (b_ok) return float(b1 - b0);
  return 0.0f;
}

}  // namespace

void store_normals_derivation(const NormalsDerivation& d, uint8_t out[kNormalsDerivationBytes]) {
  uint32_t bits;
  std::memcpy(&bits, &d.rise_per_unit, 4);
  for (int b = 0; b < 4; ++b) out[b] = uint8_t(bits >> (8 * b));
  std::memcpy(out + 4, d.apron.data(), d.apron.size());
  std::memcpy(out + 4 + d.apron.size(), d.ao.data(), d.ao.size());
}

bool load_normals_derivation(const uint8_t* bytes, size_t size, NormalsDerivation& out) {
  if (size != kNormalsDerivationBytes) return false;
  const uint32_t bits = uint32_t(bytes[0]) | (uint32_t(bytes[1]) << 8) | (uint32_t(bytes[2]) << 16) | (uint32_t(bytes[3]) << 24);
  std::memcpy(&out.rise_per_unit, &bits, 4);
  // At most kMaxRisePerUnit, so no gradient of u16 heights overflows a float (the texels stay finite).
  if (!(out.rise_per_unit > 0 && out.rise_per_unit <= kMaxRisePerUnit)) return false;
  std::memcpy(out.apron.data(), bytes + 4, out.apron.size());
  std::memcpy(out.ao.data(), bytes + 4 + out.apron.size(), out.ao.size());
  for (uint8_t q : out.ao)
    if (q > 31) return false;
  return true;
}

void derive_normal_texels(const uint16_t* heights, const uint8_t* holes, const NormalsDerivation& d,
                          uint8_t rgba[kTexels * kTexels * 4]) {
  const float half_rise = 0.5f * d.rise_per_unit;
  // Texels are written as little-endian words R | G << 8 | B << 16 | A << 24 (R = block AO, B = 0).
  auto store = [rgba](int t, int u, uint32_t word) { std::memcpy(rgba + 4 * size_t(u * kTexels + t), &word, 4); };
  uint32_t red[kTexels];  // the R byte of each texel of the current row
  auto fill_red = [&](int u) {
    for (int t = 0; t < kTexels; ++t) {
      const uint32_t q = d.ao[size_t((u / 4) * kTexelBlocks + t / 4)];
      red[t] = (q << 3) | (q >> 2);
    }
  };
  // The apron's x8 and y8 in record order.
  size_t apron_at = 0;
  auto apron = [&](int t, int u) {
    const uint32_t x8 = d.apron[apron_at], y8 = d.apron[apron_at + 1];
    apron_at += 2;
    store(t, u, red[t] | (y8 << 8) | (x8 << 24));
  };
  float gx[128], gy[128];
  uint32_t words[128];
  for (int u = 0; u < kTexels; ++u) {
    fill_red(u);
    if (u < kApron || u >= kTexels - kApron) {
      for (int t = 0; t < kTexels; ++t) apron(t, u);
      continue;
    }
    apron(0, u);
    apron(1, u);
    // Interior cells of row j: the plain gradient in a loop without branches, then the cells with a
    // hole corner with the edge rule.
    const int j = u - kApron;
    const uint16_t* south = heights + size_t(j * kHeightSamples);
    const uint16_t* north = south + kHeightSamples;
    for (int i = 0; i < 128; ++i) {
      gx[i] = float((int(south[i + 1]) - int(south[i])) + (int(north[i + 1]) - int(north[i]))) * half_rise;
      gy[i] = float((int(north[i]) - int(south[i])) + (int(north[i + 1]) - int(south[i + 1]))) * half_rise;
    }
    if (holes) {
      const uint8_t* hs = holes + size_t(j * kHeightSamples);
      const uint8_t* hn = hs + kHeightSamples;
      for (int i = 0; i < 128; ++i) {
        if (!(hs[i] | hs[i + 1] | hn[i] | hn[i + 1])) continue;
        const bool ok00 = !hs[i], ok10 = !hs[i + 1], ok01 = !hn[i], ok11 = !hn[i + 1];
        gx[i] = edge_gradient(south[i], south[i + 1], ok00 && ok10, north[i], north[i + 1], ok01 && ok11) * d.rise_per_unit;
        gy[i] = edge_gradient(south[i], north[i], ok00 && ok01, south[i + 1], north[i + 1], ok10 && ok11) * d.rise_per_unit;
      }
    }
    for (int i = 0; i < 128; ++i) {
      const float inv = 1.0f / std::sqrt(gx[i] * gx[i] + gy[i] * gy[i] + 1.0f);
      gx[i] = -gx[i] * inv;
      gy[i] = -gy[i] * inv;
    }
    for (int i = 0; i < 128; ++i) {
      // normal_texel_of() (surface_contract.h) spelled out, so that the loop vectorises.
      const int x8 = std::clamp(int(128.5f + 127.0f * gx[i]), 1, 255), y8 = std::clamp(int(128.5f + 127.0f * gy[i]), 1, 255);
      words[i] = red[i + kApron] | (uint32_t(y8) << 8) | (uint32_t(x8) << 24);
    }
    std::memcpy(rgba + 4 * size_t(u * kTexels + kApron), words, sizeof(words));
    apron(kTexels - 2, u);
    apron(kTexels - 1, u);
  }
}

void encode_derived_normals_bc3_reference(const uint8_t rgba[kTexels * kTexels * 4], uint8_t bc3[kNormalsBytes]) {
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      uint8_t x8[16], y8[16];
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) {
          const uint8_t* px = rgba + 4 * size_t((by * 4 + r) * kTexels + bx * 4 + c);
          x8[4 * r + c] = px[3];
          y8[4 * r + c] = px[1];
        }
      const int q = rgba[4 * size_t((by * 4) * kTexels + bx * 4)] >> 3;
      uint8_t* out = bc3 + 16 * size_t(by * kTexelBlocks + bx);
      encode_alpha(x8, out);
      encode_colour(q, y8, out + 8);
    }
}

#if defined(__SSE2__)
namespace {

// Horizontal min and max of 16 int16 lanes held in two registers.
inline void min_max16(__m128i a, __m128i b, int& lo, int& hi) {
  __m128i mn = _mm_min_epi16(a, b), mx = _mm_max_epi16(a, b);
  mn = _mm_min_epi16(mn, _mm_shuffle_epi32(mn, _MM_SHUFFLE(1, 0, 3, 2)));
  mx = _mm_max_epi16(mx, _mm_shuffle_epi32(mx, _MM_SHUFFLE(1, 0, 3, 2)));
  mn = _mm_min_epi16(mn, _mm_shuffle_epi32(mn, _MM_SHUFFLE(2, 3, 0, 1)));
  mx = _mm_max_epi16(mx, _mm_shuffle_epi32(mx, _MM_SHUFFLE(2, 3, 0, 1)));
  mn = _mm_min_epi16(mn, _mm_srli_epi32(mn, 16));
  mx = _mm_max_epi16(mx, _mm_srli_epi32(mx, 16));
  lo = int16_t(_mm_cvtsi128_si32(mn));
  hi = int16_t(_mm_cvtsi128_si32(mx));
}

// Squared error and entry positions (0..3 from g0) of 16 G values (2 x 8 int16) against the palette
// of colour_fit(): the same nearest rule, with the nested compares of monotone midpoints.
inline int colour_fit_sse2(const __m128i g[2], int g0, int g1, __m128i pos[2]) {
  const int e0 = expand6(g0), e1 = expand6(g1);
  const int p2 = (2 * e0 + e1 + 1) / 3, p3 = (e0 + 2 * e1 + 1) / 3;
  const __m128i m01 = _mm_set1_epi16(int16_t(e0 + p2)), m12 = _mm_set1_epi16(int16_t(p2 + p3)),
                m23 = _mm_set1_epi16(int16_t(p3 + e1));
  const __m128i d1 = _mm_set1_epi16(int16_t(p2 - e0)), d2 = _mm_set1_epi16(int16_t(p3 - p2)),
                d3 = _mm_set1_epi16(int16_t(e1 - p3)), base = _mm_set1_epi16(int16_t(e0));
  __m128i sum = _mm_setzero_si128();
  for (int h = 0; h < 2; ++h) {
    const __m128i v2 = _mm_add_epi16(g[h], g[h]);
    const __m128i c1 = _mm_cmplt_epi16(v2, m01), c2 = _mm_cmplt_epi16(v2, m12), c3 = _mm_cmplt_epi16(v2, m23);
    pos[h] = _mm_sub_epi16(_mm_sub_epi16(_mm_sub_epi16(_mm_setzero_si128(), c1), c2), c3);
    const __m128i value = _mm_add_epi16(
        _mm_add_epi16(base, _mm_and_si128(c1, d1)), _mm_add_epi16(_mm_and_si128(c2, d2), _mm_and_si128(c3, d3)));
    const __m128i d = _mm_sub_epi16(g[h], value);
    sum = _mm_add_epi32(sum, _mm_madd_epi16(d, d));
  }
  sum = _mm_add_epi32(sum, _mm_shuffle_epi32(sum, _MM_SHUFFLE(1, 0, 3, 2)));
  sum = _mm_add_epi32(sum, _mm_shuffle_epi32(sum, _MM_SHUFFLE(2, 3, 0, 1)));
  return _mm_cvtsi128_si32(sum);
}

}  // namespace

void encode_derived_normals_bc3(const uint8_t rgba[kTexels * kTexels * 4], uint8_t bc3[kNormalsBytes]) {
  const __m128i byte_mask = _mm_set1_epi32(0xFF);
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      // x8 (A) and y8 (G) of the block's texels as 2 x 8 int16, texel 4 r + c in lane order.
      __m128i x[2], g[2];
      for (int h = 0; h < 2; ++h) {
        const uint8_t* row0 = rgba + 4 * size_t((by * 4 + 2 * h) * kTexels + bx * 4);
        const __m128i r0 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row0));
        const __m128i r1 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row0 + 4 * kTexels));
        x[h] = _mm_packs_epi32(_mm_srli_epi32(r0, 24), _mm_srli_epi32(r1, 24));
        g[h] = _mm_packs_epi32(_mm_and_si128(_mm_srli_epi32(r0, 8), byte_mask), _mm_and_si128(_mm_srli_epi32(r1, 8), byte_mask));
      }
      uint8_t* out = bc3 + 16 * size_t(by * kTexelBlocks + bx);
      // Alpha: as encode_alpha().
      int lo, hi;
      min_max16(x[0], x[1], lo, hi);
      alignas(16) int16_t lane[16] = {};
      if (hi > lo) {
        int value[8];
        alpha_entries(hi, lo, value);
        __m128i pos[2] = {_mm_setzero_si128(), _mm_setzero_si128()};
        const __m128i v2[2] = {_mm_add_epi16(x[0], x[0]), _mm_add_epi16(x[1], x[1])};
        for (int k = 0; k < 7; ++k) {
          const __m128i mid = _mm_set1_epi16(int16_t(value[k] + value[k + 1]));
          pos[0] = _mm_sub_epi16(pos[0], _mm_cmplt_epi16(v2[0], mid));
          pos[1] = _mm_sub_epi16(pos[1], _mm_cmplt_epi16(v2[1], mid));
        }
        _mm_store_si128(reinterpret_cast<__m128i*>(lane), pos[0]);
        _mm_store_si128(reinterpret_cast<__m128i*>(lane + 8), pos[1]);
      }
      store_alpha_block(hi, lo, lane, out);
      // Colour: as encode_colour().
      const int q = rgba[4 * size_t((by * 4) * kTexels + bx * 4)] >> 3;
      min_max16(g[0], g[1], lo, hi);
      int g0 = nearest6(hi), g1 = nearest6(lo);
      __m128i pos[2];
      const int err = colour_fit_sse2(g, g0, g1, pos);
      int c0, c1;
      covering_pair(g0, g1, hi, lo, c0, c1);
      if (err > 0 && (c0 != g0 || c1 != g1)) {
        __m128i cover[2];
        if (colour_fit_sse2(g, c0, c1, cover) < err) {
          g0 = c0;
          g1 = c1;
          pos[0] = cover[0];
          pos[1] = cover[1];
        }
      }
      _mm_store_si128(reinterpret_cast<__m128i*>(lane), pos[0]);
      _mm_store_si128(reinterpret_cast<__m128i*>(lane + 8), pos[1]);
      store_colour_block(q, g0, g1, lane, out + 8);
    }
}
#else
void encode_derived_normals_bc3(const uint8_t rgba[kTexels * kTexels * 4], uint8_t bc3[kNormalsBytes]) {
  encode_derived_normals_bc3_reference(rgba, bc3);
}
#endif

}  // namespace terrain
