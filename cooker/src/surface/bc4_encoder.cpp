// BC4 block encoders (one channel: the normals' alpha block, the cones' angle blocks).
//
// encode_bc4: min/max start, then one least-squares refit of the 8-value mode ranked on the
//  moments; the 6-value mode (explicit 0 and 255) is tried when the block touches 0 or 255.
// encode_bc4_upper (conservative): every decoded value >= its target, minimising the sum of
//  excesses over one free endpoint (exhaustive, 256 candidates).
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "bc_blocks.h"
#include "pair_ranks_sse2.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace terrain::cook {

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

namespace {

void write_bc4(int a0, int a1, const uint8_t sel[16], uint8_t out[8]) {
  out[0] = uint8_t(a0);
  out[1] = uint8_t(a1);
  uint64_t bits = 0;
  for (int i = 0; i < 16; ++i) bits |= uint64_t(sel[i]) << (3 * i);
  for (int i = 0; i < 6; ++i) out[2 + i] = uint8_t(bits >> (8 * i));
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

}  // namespace

// 8-value mode: exact nearest entry per value (direct position plus a neighbour check). u = 0..7
// is the position from a1 (u = 0) to a0 (u = 7); selector = 1 for u 0, 0 for u 7, else 8 - u.
int bc4_assign8_scalar(const uint8_t v[16], int a0, int a1, uint8_t sel[16], int u_out[16]) {
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

#if defined(__SSE2__)
namespace {
// The same in SSE2, 8 values per register: the start position in float as above (truncation, no
// fused multiply-add), the palette entry at position u as (u*a0 + (7-u)*a1 + 3) / 7 (bc4_palette's
// rounding; x / 7 = (x * 9363) >> 16 exactly for x <= 7 * 255 + 3), the two neighbour checks in
// the same order. Same selectors, positions and error as bc4_assign8_scalar for every a0 > a1.
int bc4_assign8_sse2(const uint8_t v[16], int a0, int a1, uint8_t sel[16], int u_out[16]) {
  const __m128i zero = _mm_setzero_si128();
  const __m128i bytes = _mm_loadu_si128(reinterpret_cast<const __m128i*>(v));
  const __m128 scale = _mm_set1_ps(7.0f / float(a0 - a1)), half = _mm_set1_ps(0.5f);
  const __m128i base32 = _mm_set1_epi32(a1);
  const __m128i span = _mm_set1_epi16(int16_t(a0 - a1)), offset = _mm_set1_epi16(int16_t(7 * a1 + 3));
  const __m128i div7 = _mm_set1_epi16(int16_t(9363)), one = _mm_set1_epi16(1), seven = _mm_set1_epi16(7);
  const __m128i eight = _mm_set1_epi16(8);
  const auto entry = [&](__m128i u) { return _mm_mulhi_epu16(_mm_add_epi16(_mm_mullo_epi16(u, span), offset), div7); };
  const auto dist = [](__m128i x, __m128i e) { return _mm_max_epi16(_mm_sub_epi16(x, e), _mm_sub_epi16(e, x)); };
  const auto pick = [](__m128i m, __m128i a, __m128i b) { return _mm_or_si128(_mm_and_si128(m, a), _mm_andnot_si128(m, b)); };
  __m128i err = zero, sels[2];
  for (int h = 0; h < 2; ++h) {
    const __m128i x = h == 0 ? _mm_unpacklo_epi8(bytes, zero) : _mm_unpackhi_epi8(bytes, zero);
    const auto start = [&](__m128i x32) {
      return _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(_mm_cvtepi32_ps(_mm_sub_epi32(x32, base32)), scale), half));
    };
    __m128i u = _mm_packs_epi32(start(_mm_unpacklo_epi16(x, zero)), start(_mm_unpackhi_epi16(x, zero)));
    u = _mm_min_epi16(_mm_max_epi16(u, zero), seven);
    __m128i d = dist(x, entry(u));
    const __m128i dm = dist(x, entry(_mm_max_epi16(_mm_sub_epi16(u, one), zero)));
    const __m128i down = _mm_and_si128(_mm_cmpgt_epi16(u, zero), _mm_cmplt_epi16(dm, d));
    u = _mm_add_epi16(u, down);  // -1 where taken
    d = pick(down, dm, d);
    const __m128i dp = dist(x, entry(_mm_min_epi16(_mm_add_epi16(u, one), seven)));
    const __m128i up = _mm_and_si128(_mm_cmplt_epi16(u, seven), _mm_cmplt_epi16(dp, d));
    u = _mm_sub_epi16(u, up);
    d = pick(up, dp, d);
    err = _mm_add_epi32(err, _mm_madd_epi16(d, d));
    __m128i s = _mm_sub_epi16(eight, u);
    s = pick(_mm_cmpeq_epi16(u, zero), one, s);
    s = _mm_andnot_si128(_mm_cmpeq_epi16(u, seven), s);
    sels[h] = s;
    _mm_storeu_si128(reinterpret_cast<__m128i*>(u_out + 8 * h), _mm_unpacklo_epi16(u, zero));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(u_out + 8 * h + 4), _mm_unpackhi_epi16(u, zero));
  }
  _mm_storeu_si128(reinterpret_cast<__m128i*>(sel), _mm_packus_epi16(sels[0], sels[1]));
  err = _mm_add_epi32(err, _mm_shuffle_epi32(err, _MM_SHUFFLE(1, 0, 3, 2)));
  err = _mm_add_epi32(err, _mm_shuffle_epi32(err, _MM_SHUFFLE(2, 3, 0, 1)));
  return _mm_cvtsi128_si32(err);
}
}  // namespace
#endif

int bc4_assign8(const uint8_t v[16], int a0, int a1, uint8_t sel[16], int u_out[16]) {
#if defined(__SSE2__)
  return bc4_assign8_sse2(v, a0, a1, sel, u_out);
#else
  return bc4_assign8_scalar(v, a0, a1, sel, u_out);
#endif
}

namespace {
void encode_bc4_path(const uint8_t values[16], uint8_t out[8], bool simd) {
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
#if defined(__SSE2__)
      if (simd) {
        // The same 9 ranks, a row of d1 = -1..1 (and a padding lane) per register: each lane the
        // expression below in its order of operations, pairs with t0 <= t1 +inf; then the first
        // smallest in the same order (d0, then d1).
        alignas(16) int32_t t1s[4];
        alignas(16) float v1s[4], e[12];
        for (int d1 = -1; d1 <= 1; ++d1) {
          t1s[d1 + 1] = std::clamp(e1 + d1, 0, 255);
          v1s[d1 + 1] = float(t1s[d1 + 1]);
        }
        t1s[3] = 256;  // never below t0
        v1s[3] = 0.0f;
        const __m128 inf = _mm_set1_ps(FLT_MAX * 2.0f);
        const __m128i t1v = _mm_load_si128(reinterpret_cast<const __m128i*>(t1s));
        const PairRanks pairs(ax, bx, aa, ab, bb, _mm_load_ps(v1s));
        for (int d0 = -1; d0 <= 1; ++d0) {
          const int t0 = std::clamp(e0 + d0, 0, 255);
          const __m128 ranks = pairs.row(float(t0));
          const __m128 valid = _mm_castsi128_ps(_mm_cmpgt_epi32(_mm_set1_epi32(t0), t1v));
          _mm_store_ps(e + 4 * (d0 + 1), _mm_or_ps(_mm_and_ps(valid, ranks), _mm_andnot_ps(valid, inf)));
        }
        const int first = first_smallest(e, 12, rank);
        if (first >= 0) {
          c0 = std::clamp(e0 + first / 4 - 1, 0, 255);
          c1 = std::clamp(e1 + first % 4 - 1, 0, 255);
        }
      } else
#endif
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
}  // namespace

void encode_bc4(const uint8_t values[16], uint8_t out[8]) { encode_bc4_path(values, out, true); }
void encode_bc4_scalar(const uint8_t values[16], uint8_t out[8]) { encode_bc4_path(values, out, false); }

void encode_bc4_upper(const uint8_t targets[16], uint8_t out[8]) {
  int hi = 0, hi_below_255 = -1;
  for (int i = 0; i < 16; ++i) {
    hi = std::max(hi, int(targets[i]));
    if (targets[i] < 255) hi_below_255 = std::max(hi_below_255, int(targets[i]));
  }
  int64_t best = INT64_MAX;
  int best_a0 = 255, best_a1 = 255;
  // Sum over texels of (smallest palette entry >= target) - target; INT64_MAX if one has none.
  // The targets are sorted once and each candidate's palette is listed in ascending order, so one
  // merge walk finds every texel's entry (the same entries as a search per texel).
  uint8_t sorted[16];
  std::memcpy(sorted, targets, 16);
  std::sort(sorted, sorted + 16);
  int64_t target_sum = 0;
  for (int i = 0; i < 16; ++i) target_sum += sorted[i];
  auto cost = [&](int a0, int a1) {
    int pal[8], asc[8];
    bc4_palette(a0, a1, pal);
    if (a0 > a1) {  // a1, the six interpolants from a1 towards a0, a0
      asc[0] = a1;
      for (int u = 1; u < 7; ++u) asc[u] = pal[8 - u];
      asc[7] = a0;
    } else {  // 0, a0, the four interpolants from a0 towards a1, a1, 255
      asc[0] = 0;
      asc[1] = a0;
      for (int i = 2; i < 6; ++i) asc[i] = pal[i];
      asc[6] = a1;
      asc[7] = 255;
    }
    int64_t total = 0;
    int k = 0;
    for (int i = 0; i < 16; ++i) {
      while (k < 8 && asc[k] < sorted[i]) ++k;
      if (k == 8) return INT64_MAX;
      total += asc[k];
    }
    return total - target_sum;
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
