// BC4 block encoders (one channel: the normals' alpha block, the cones' angle blocks).
//
// encode_bc4: min/max start, then one least-squares refit of the 8-value mode ranked on the
//  moments; the 6-value mode (explicit 0 and 255) is tried when the block touches 0 or 255.
// encode_bc4_upper (conservative): every decoded value >= its target, minimising the sum of
//  excesses over one free endpoint (exhaustive, 256 candidates).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "bc_blocks.h"

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

void encode_bc4(const uint8_t values[16], uint8_t out[8]) {
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

void encode_bc4_upper(const uint8_t targets[16], uint8_t out[8]) {
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
