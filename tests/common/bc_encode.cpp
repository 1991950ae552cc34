#include "bc_encode.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>

#include "terrain/bc_decode.h"

namespace terrain::synthetic {
namespace {

uint16_t pack565(int r, int g, int b) { return uint16_t((r >> 3) << 11 | (g >> 2) << 5 | (b >> 3)); }

}  // namespace

// BC1 with exact punch-through: a block with a hole texel uses the 3-colour mode, index 3 = hole.
void encode_bc1(const uint8_t rgba[16][4], uint8_t out[8]) {
  bool any_hole = false;
  int lo = 0, hi = 0;
  auto luma = [&](int t) { return rgba[t][0] * 2 + rgba[t][1] * 4 + rgba[t][2]; };
  for (int t = 0; t < 16; ++t) {
    if (rgba[t][3] < 128) {
      any_hole = true;
      continue;
    }
    if (luma(t) < luma(lo) || rgba[lo][3] < 128) lo = t;
    if (luma(t) > luma(hi) || rgba[hi][3] < 128) hi = t;
  }
  uint16_t a = pack565(rgba[hi][0], rgba[hi][1], rgba[hi][2]), b = pack565(rgba[lo][0], rgba[lo][1], rgba[lo][2]);
  uint16_t c0, c1;
  if (any_hole) {  // 3-colour mode: c0 <= c1
    c0 = std::min(a, b);
    c1 = std::max(a, b);
  } else {
    if (a == b) {
      if (a > 0) b = uint16_t(a - 1); else a = 1;  // keep c0 > c1 for the 4-colour mode
    }
    c0 = std::max(a, b);
    c1 = std::min(a, b);
  }
  uint8_t block[8] = {uint8_t(c0), uint8_t(c0 >> 8), uint8_t(c1), uint8_t(c1 >> 8), 0, 0, 0, 0};
  uint8_t pal[8][4];  // entries 4..7: the palette (decoded from probe blocks with fixed indices)
  for (int idx = 0; idx < 4; ++idx) {
    uint8_t probe[8], dec[64];
    std::memcpy(probe, block, 4);
    const uint8_t bits = uint8_t(idx | idx << 2 | idx << 4 | idx << 6);
    probe[4] = probe[5] = probe[6] = probe[7] = bits;
    decode_bc1_block(probe, dec, BcRounding::truncate);
    std::memcpy(pal[idx + 4], dec, 4);
  }
  uint32_t indices = 0;
  for (int t = 0; t < 16; ++t) {
    int best = 0;
    if (any_hole && rgba[t][3] < 128) {
      best = 3;
    } else {
      int best_d = 1 << 30;
      for (int idx = 0; idx < (any_hole ? 3 : 4); ++idx) {
        int d = 0;
        for (int k = 0; k < 3; ++k) d += (pal[idx + 4][k] - rgba[t][k]) * (pal[idx + 4][k] - rgba[t][k]);
        if (d < best_d) {
          best_d = d;
          best = idx;
        }
      }
    }
    indices |= uint32_t(best) << (2 * t);
  }
  for (int k = 0; k < 4; ++k) block[4 + k] = uint8_t(indices >> (8 * k));
  std::memcpy(out, block, 8);
}

// BC3 alpha: 8-value mode between the block's max and min; `conservative` picks, per texel, the
// smallest decoded value >= target + 1 (or the exact max endpoint), so GPU rounding of the
// interpolants can never lower a stored cone angle below its target.
void encode_bc3_alpha(const uint8_t target[16], bool conservative, uint8_t out[8]) {
  int a0 = 0, a1 = 255;
  for (int t = 0; t < 16; ++t) {
    a0 = std::max(a0, int(target[t]));
    a1 = std::min(a1, int(target[t]));
  }
  int pal[8] = {a0, a1};
  if (a0 > a1)
    for (int k = 1; k < 7; ++k) pal[k + 1] = ((7 - k) * a0 + k * a1) / 7;
  else
    for (int k = 2; k < 8; ++k) pal[k] = a0;
  uint64_t bits = 0;
  for (int t = 0; t < 16; ++t) {
    int best = 0, best_v = 1 << 30;
    for (int idx = 0; idx < 8; ++idx) {
      const int v = pal[idx];
      if (conservative) {
        const bool exact = idx < 2;
        if (v < target[t] + (exact ? 0 : 1)) continue;
        if (v < best_v) {
          best_v = v;
          best = idx;
        }
      } else {
        const int d = std::abs(v - int(target[t]));
        if (d < best_v) {
          best_v = d;
          best = idx;
        }
      }
    }
    bits |= uint64_t(best) << (3 * t);
  }
  out[0] = uint8_t(a0);
  out[1] = uint8_t(a1);
  for (int k = 0; k < 6; ++k) out[2 + k] = uint8_t(bits >> (8 * k));
}

// BC3 colour block (always 4-colour): endpoints = per-channel max and min.
void encode_bc3_colour(const uint8_t rgba[16][4], uint8_t out[8]) {
  int mx[3] = {0, 0, 0}, mn[3] = {255, 255, 255};
  for (int t = 0; t < 16; ++t)
    for (int k = 0; k < 3; ++k) {
      mx[k] = std::max(mx[k], int(rgba[t][k]));
      mn[k] = std::min(mn[k], int(rgba[t][k]));
    }
  const uint16_t c0 = pack565(mx[0], mx[1], mx[2]), c1 = pack565(mn[0], mn[1], mn[2]);
  uint8_t probe[16] = {};
  probe[8] = uint8_t(c0);
  probe[9] = uint8_t(c0 >> 8);
  probe[10] = uint8_t(c1);
  probe[11] = uint8_t(c1 >> 8);
  uint8_t pal[4][4];
  for (int idx = 0; idx < 4; ++idx) {
    uint8_t dec[64];
    const uint8_t bits = uint8_t(idx | idx << 2 | idx << 4 | idx << 6);
    probe[12] = probe[13] = probe[14] = probe[15] = bits;
    decode_bc3_block(probe, dec, BcRounding::truncate);
    std::memcpy(pal[idx], dec, 4);
  }
  uint32_t indices = 0;
  for (int t = 0; t < 16; ++t) {
    int best = 0, best_d = 1 << 30;
    for (int idx = 0; idx < 4; ++idx) {
      int d = 0;
      for (int k = 0; k < 3; ++k) d += (pal[idx][k] - rgba[t][k]) * (pal[idx][k] - rgba[t][k]);
      if (d < best_d) {
        best_d = d;
        best = idx;
      }
    }
    indices |= uint32_t(best) << (2 * t);
  }
  out[0] = uint8_t(c0);
  out[1] = uint8_t(c0 >> 8);
  out[2] = uint8_t(c1);
  out[3] = uint8_t(c1 >> 8);
  for (int k = 0; k < 4; ++k) out[4 + k] = uint8_t(indices >> (8 * k));
}

}  // namespace terrain::synthetic
