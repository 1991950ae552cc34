// Library encoder wrappers and the punch-through guarantee for BC1.
#include "bc_blocks.h"

#include "terrain/bc_decode.h"

#include <algorithm>
#include <cstring>

#include <squish.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#define STB_DXT_STATIC
#define STB_DXT_IMPLEMENTATION
#include <stb/stb_dxt.h>

namespace terrain::cook {
namespace {

void unpack565(uint16_t c, uint8_t out[3]) {
  const int r = (c >> 11) & 31, g = (c >> 5) & 63, b = c & 31;
  out[0] = uint8_t((r << 3) | (r >> 2));
  out[1] = uint8_t((g << 2) | (g >> 4));
  out[2] = uint8_t((b << 3) | (b >> 2));
}

uint16_t read16(const uint8_t* p) { return uint16_t(p[0] | (p[1] << 8)); }
void write16(uint8_t* p, uint16_t v) { p[0] = uint8_t(v); p[1] = uint8_t(v >> 8); }
void write32(uint8_t* p, uint32_t v) {
  p[0] = uint8_t(v); p[1] = uint8_t(v >> 8); p[2] = uint8_t(v >> 16); p[3] = uint8_t(v >> 24);
}

uint16_t pack565(const uint8_t rgb[3]) {
  // Round to the nearest 5/6-bit value (exact inverse of the bit-replicating expansion at the ends).
  const int r = (rgb[0] * 31 + 127) / 255, g = (rgb[1] * 63 + 127) / 255, b = (rgb[2] * 31 + 127) / 255;
  return uint16_t((r << 11) | (g << 5) | b);
}

uint16_t hole_mask_of(const uint8_t rgba[64]) {
#if defined(__SSE2__)
  // alpha < 128 <=> its top bit is clear: one movemask per 4 texels, bits 3, 7, 11, 15.
  uint32_t m = 0;
  for (int v = 0; v < 4; ++v) {
    const uint32_t top = uint32_t(_mm_movemask_epi8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(rgba + 16 * v))));
    const uint32_t clear = ~top;
    m |= (((clear >> 3) & 1) | ((clear >> 6) & 2) | ((clear >> 9) & 4) | ((clear >> 12) & 8)) << (4 * v);
  }
  return uint16_t(m);
#else
  uint16_t m = 0;
  for (int i = 0; i < 16; ++i)
    if (rgba[4 * i + 3] < 128) m = uint16_t(m | (1u << i));
  return m;
#endif
}

// Exact 3-colour fallback for blocks with holes: endpoints = bounding box of the opaque texels
// along their longest axis, each opaque texel takes the nearest of {c0, c1, midpoint}.
void encode_bc1_holes_fallback(const uint8_t rgba[64], uint16_t holes, uint8_t out[8]) {
  int lo[3] = {255, 255, 255}, hi[3] = {0, 0, 0};
  int best_axis = 0, lo_i = -1, hi_i = -1;
  for (int i = 0; i < 16; ++i)
    if (!(holes >> i & 1))
      for (int c = 0; c < 3; ++c) {
        lo[c] = std::min(lo[c], int(rgba[4 * i + c]));
        hi[c] = std::max(hi[c], int(rgba[4 * i + c]));
      }
  for (int c = 1; c < 3; ++c)
    if (hi[c] - lo[c] > hi[best_axis] - lo[best_axis]) best_axis = c;
  for (int i = 0; i < 16; ++i) {
    if (holes >> i & 1) continue;
    if (lo_i < 0 || rgba[4 * i + best_axis] < rgba[4 * lo_i + best_axis]) lo_i = i;
    if (hi_i < 0 || rgba[4 * i + best_axis] > rgba[4 * hi_i + best_axis]) hi_i = i;
  }
  uint16_t c0 = 0, c1 = 0;
  if (lo_i >= 0) {
    c0 = pack565(&rgba[4 * lo_i]);
    c1 = pack565(&rgba[4 * hi_i]);
  }
  if (c0 > c1) std::swap(c0, c1);  // c0 <= c1 selects the 3-colour (punch-through) mode
  uint8_t pal[3][3];
  unpack565(c0, pal[0]);
  unpack565(c1, pal[1]);
  for (int c = 0; c < 3; ++c) pal[2][c] = uint8_t((pal[0][c] + pal[1][c] + 1) / 2);
  uint32_t idx = 0;
  for (int i = 0; i < 16; ++i) {
    uint32_t sel = 3;
    if (!(holes >> i & 1)) {
      int best = 1 << 30;
      for (uint32_t k = 0; k < 3; ++k) {
        int e = 0;
        for (int c = 0; c < 3; ++c) {
          const int d = int(rgba[4 * i + c]) - pal[k][c];
          e += d * d;
        }
        if (e < best) {
          best = e;
          sel = k;
        }
      }
    }
    idx |= sel << (2 * i);
  }
  write16(out, c0);
  write16(out + 2, c1);
  write32(out + 4, idx);
}

// Squared colour error of a BC1 block over the non-hole texels of `rgba`.
int colour_sq_err(const uint8_t rgba[64], const uint8_t block[8]) {
  uint8_t dec[64];
  decode_bc1_block(block, dec);
  int e = 0;
  for (int i = 0; i < 16; ++i) {
    if (rgba[4 * i + 3] < 128) continue;
    for (int c = 0; c < 3; ++c) {
      const int d = int(rgba[4 * i + c]) - dec[4 * i + c];
      e += d * d;
    }
  }
  return e;
}

int squish_colour_flags(Bc1Method m) {
  switch (m) {
    case Bc1Method::squish_range: return squish::kColourRangeFit;
    case Bc1Method::squish_iterative: return squish::kColourIterativeClusterFit;
    default: return squish::kColourClusterFit;
  }
}

}  // namespace

const char* bc1_method_name(Bc1Method m) {
  switch (m) {
    case Bc1Method::stb: return "stb_dxt";
    case Bc1Method::stb_hq: return "stb_dxt-hq";
    case Bc1Method::squish_range: return "squish-range";
    case Bc1Method::squish_cluster: return "squish-cluster";
    case Bc1Method::squish_iterative: return "squish-iter";
    case Bc1Method::axis_fit: return "axis-fit";
    case Bc1Method::axis_fit_hard: return "axis-fit-hard";
    case Bc1Method::best_of_axis_fit_and_squish: return "axis-fit+squish";
    case Bc1Method::ordering_search: return "ordering-search";
  }
  return "?";
}

const char* bc3_method_name(Bc3Method m) {
  switch (m) {
    case Bc3Method::stb: return "stb_dxt";
    case Bc3Method::stb_hq: return "stb_dxt-hq";
    case Bc3Method::squish_cluster: return "squish-cluster";
    case Bc3Method::g_axis_fit: return "g-axis-fit";
    case Bc3Method::g_axis_fit_hq: return "g-axis-fit-hq";
  }
  return "?";
}

namespace {
// Effort of our opaque encoder for each of our settings (see Bc1Method).
Bc1OpaqueEffort opaque_effort(Bc1Method method) {
  Bc1OpaqueEffort e;
  e.refine_hard = method != Bc1Method::axis_fit;
  if (method == Bc1Method::ordering_search) e.ordering_sweeps = 2;
  if (method == Bc1Method::best_of_axis_fit_and_squish) {
    e.iterations = 2;
    e.three_colour_threshold = kBc1ThreeColourThreshold;
  }
  return e;
}
}  // namespace

void encode_bc1_block(const uint8_t rgba[64], Bc1Method method, uint8_t out[8]) {
  const uint16_t holes = hole_mask_of(rgba);
  if (holes == 0 && (method == Bc1Method::axis_fit || method == Bc1Method::axis_fit_hard)) {
    // Hot path of the default setting: our opaque encoder ignores alpha and only writes
    // 4-colour blocks (or equal endpoints with index 0), so no copy and no re-check are needed.
    encode_bc1_opaque(rgba, out, opaque_effort(method));
    return;
  }
  if (holes == 0xFFFF) {  // all holes: 3-colour black block, every index transparent
    write16(out, 0);
    write16(out + 2, 0);
    write32(out + 4, 0xFFFFFFFFu);
    return;
  }
  if (holes != 0) {
    uint8_t tmp[64];
    std::memcpy(tmp, rgba, 64);
    for (int i = 0; i < 16; ++i) tmp[4 * i + 3] = (holes >> i & 1) ? 0 : 255;
    if (method == Bc1Method::axis_fit_hard || method == Bc1Method::axis_fit || method == Bc1Method::ordering_search) {
      encode_bc1_holes(rgba, holes, out);
    } else if (method == Bc1Method::best_of_axis_fit_and_squish) {
      uint8_t a[8], b[8];
      encode_bc1_holes(rgba, holes, a);
      squish::Compress(tmp, b, squish::kDxt1 | squish::kColourClusterFit);
      const bool b_ok = bc1_transparent_mask(b) == holes;
      std::memcpy(out, b_ok && colour_sq_err(rgba, b) < colour_sq_err(rgba, a) ? b : a, 8);
    } else {
      // stb_dxt has no 3-colour mode: its rows use libsquish cluster fit for blocks with holes.
      const Bc1Method hm = method == Bc1Method::squish_range || method == Bc1Method::squish_iterative
                               ? method
                               : Bc1Method::squish_cluster;
      squish::Compress(tmp, out, squish::kDxt1 | squish_colour_flags(hm));
    }
    if (bc1_transparent_mask(out) != holes) encode_bc1_holes_fallback(rgba, holes, out);
    return;
  }
  uint8_t opaque[64];
  std::memcpy(opaque, rgba, 64);
  for (int i = 0; i < 16; ++i) opaque[4 * i + 3] = 255;
  switch (method) {
    case Bc1Method::stb: stb_compress_dxt_block(out, opaque, 0, STB_DXT_NORMAL); break;
    case Bc1Method::stb_hq: stb_compress_dxt_block(out, opaque, 0, STB_DXT_HIGHQUAL); break;
    case Bc1Method::axis_fit:
    case Bc1Method::axis_fit_hard:
    case Bc1Method::ordering_search: encode_bc1_opaque(opaque, out, opaque_effort(method)); break;
    case Bc1Method::best_of_axis_fit_and_squish: {
      uint8_t a[8], b[8];
      encode_bc1_opaque(opaque, a, opaque_effort(method));
      squish::Compress(opaque, b, squish::kDxt1 | squish::kColourClusterFit);
      const bool b_ok = bc1_transparent_mask(b) == 0;
      std::memcpy(out, b_ok && colour_sq_err(rgba, b) < colour_sq_err(rgba, a) ? b : a, 8);
      break;
    }
    default: squish::Compress(opaque, out, squish::kDxt1 | squish_colour_flags(method)); break;
  }
  if (bc1_transparent_mask(out) != 0) {
    // A 3-colour block that uses index 3 would punch a false hole. With equal endpoints every
    // other index decodes to the same colour, so remap; otherwise re-encode in 4-colour mode.
    if (read16(out) == read16(out + 2)) {
      write32(out + 4, 0);
    } else {
      encode_bc1_opaque(opaque, out, Bc1OpaqueEffort{});
    }
  }
}

void encode_bc3_block(const uint8_t rgba[64], Bc3Method method, uint8_t out[16]) {
  switch (method) {
    case Bc3Method::stb: stb_compress_dxt_block(out, rgba, 1, STB_DXT_NORMAL); break;
    case Bc3Method::stb_hq: stb_compress_dxt_block(out, rgba, 1, STB_DXT_HIGHQUAL); break;
    case Bc3Method::squish_cluster: {
      float metric[3] = {0.25f, 1.0f, 0.05f};
      squish::Compress(rgba, out, squish::kDxt5 | squish::kColourClusterFit, metric);
      break;
    }
    case Bc3Method::g_axis_fit:
    case Bc3Method::g_axis_fit_hq: {
      uint8_t a[16];
      for (int i = 0; i < 16; ++i) a[i] = rgba[4 * i + 3];
      encode_bc4(a, out);
      const float weights[3] = {0.25f, 1.0f, 0.05f};
      const int iterations = method == Bc3Method::g_axis_fit_hq ? 2 : 1;
      if (!encode_bc1_g_only(rgba, out + 8, iterations)) encode_bc1_weighted(rgba, weights, out + 8);
      break;
    }
  }
}

}  // namespace terrain::cook
