// Normal texels from the window heights. Everything is a function of the window (canonical heights
// shared with the neighbours), so apron texels equal the neighbours' interior texels bit for bit
// before compression.
#include "normals.h"

#include "fast_math.h"
#include "terrain/surface_contract.h"

#include <algorithm>
#include <cstring>
#include <cmath>
#include <cstdint>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace terrain::cook {
namespace {

constexpr double kRadToDeg = 57.29577951308232;

// Window element of node vertex (i, j) (i, j from -4 to 132).
inline float wh(const float* h, int i, int j) {
  return h[size_t((j + kWindowMargin) * kWindowSize + (i + kWindowMargin))];
}

// Mean of the two differences across a cell edge pair, using only pairs with data; false if none.
inline bool mean_diff(float a0, float a1, float b0, float b1, double& out) {
  int n = 0;
  double s = 0;
  if (!std::isnan(a0) && !std::isnan(a1)) { s += double(a1) - a0; ++n; }
  if (!std::isnan(b0) && !std::isnan(b1)) { s += double(b1) - b0; ++n; }
  if (!n) return false;
  out = s / n;
  return true;
}

}  // namespace

void compute_normal_texels(const SurfaceInput& in, NormalTexels& out) {
  const float* h = in.heights_m;
  const double s = in.spacing_m;
  const float half_inv_s = float(0.5 / s);
  // Per row of texels: the cell gradient of every texel in a loop without branches (it vectorises),
  // then the few cells with a missing corner (their sum is NaN) redone with the edge fallback.
  float gx[kTexels], gy[kTexels], corners[kTexels];
  for (int u = 0; u < kTexels; ++u) {
    const int j = u - kApron;  // south row of the cells' corners
    const float* south = h + size_t((j + kWindowMargin) * kWindowSize + kWindowMargin - kApron);  // vertex (-kApron, j)
    const float* north = south + kWindowSize;
    for (int t = 0; t < kTexels; ++t) {
      const float h00 = south[t], h10 = south[t + 1], h01 = north[t], h11 = north[t + 1];
      corners[t] = h00 + h10 + h01 + h11;
      gx[t] = ((h10 - h00) + (h11 - h01)) * half_inv_s;
      gy[t] = ((h01 - h00) + (h11 - h10)) * half_inv_s;
    }
    for (int t = 0; t < kTexels; ++t) {
      if (!std::isnan(corners[t])) continue;
      // At the edge of the data (NaN corners) use the cell edges that have data; else flat.
      const float h00 = south[t], h10 = south[t + 1], h01 = north[t], h11 = north[t + 1];
      double dx = 0, dy = 0;
      if (!mean_diff(h00, h10, h01, h11, dx)) dx = 0;
      if (!mean_diff(h00, h01, h10, h11, dy)) dy = 0;
      gx[t] = float(dx / s);
      gy[t] = float(dy / s);
    }
    float* n = &out.n[size_t(u * kTexels) * 3];
    for (int t = 0; t < kTexels; ++t) {
      const float inv = 1.0f / std::sqrt(gx[t] * gx[t] + gy[t] * gy[t] + 1.0f);
      n[t * 3 + 0] = -gx[t] * inv;
      n[t * 3 + 1] = -gy[t] * inv;
      n[t * 3 + 2] = inv;
    }
  }
  // Block ambient occlusion (see normals.h).
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      const int i0 = bx * 4 - kApron, j0 = by * 4 - kApron;  // south-west vertex of the block
      double inner = 0, ring = 0;
      int ni = 0, nr = 0;
      for (int b = -2; b <= 6; ++b)
        for (int a = -2; a <= 6; ++a) {
          const bool border = a == -2 || a == 6 || b == -2 || b == 6;
          const bool centre = a >= 0 && a <= 4 && b >= 0 && b <= 4;
          if (!border && !centre) continue;
          const float v = wh(h, i0 + a, j0 + b);
          if (std::isnan(v)) continue;
          if (border) { ring += v; ++nr; } else { inner += v; ++ni; }
        }
      float ao = 1.0f;
      if (ni && nr) {
        const double depth = std::max(0.0, ring / nr - inner / ni);
        const double r = depth / (4.0 * s);
        ao = float(1.0 / (1.0 + r * r));
      }
      out.ao[size_t(by * kTexelBlocks + bx)] = ao;
    }
}

void pack_normal_texels(const NormalTexels& in, std::array<uint8_t, kTexelCount * 4>& rgba, bool ao_in_red) {
#if defined(__SSE2__)
  // A block row of 4 texels at a time (a block's AO byte in red): normal_texel_of's float
  // operations, its int conversion (cvttps2dq) and its clamp to 1..255 (saturating packs, then
  // at least 1), then the bytes interleaved as R, G = y, B = 0, A = x.
  const __m128 half = _mm_set1_ps(128.5f), scale = _mm_set1_ps(127.0f);
  const __m128i one = _mm_set1_epi8(1);
  for (int u = 0; u < kTexels; ++u)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      const size_t k = size_t(u * kTexels + bx * 4);
      const int q5 = int(std::clamp(in.ao[size_t((u / 4) * kTexelBlocks + bx)], 0.0f, 1.0f) * 31.0f + 0.5f);
      const uint8_t red = ao_in_red ? uint8_t((q5 << 3) | (q5 >> 2)) : uint8_t(255);
      const float* n = &in.n[k * 3];
      const __m128 x = _mm_setr_ps(n[0], n[3], n[6], n[9]), y = _mm_setr_ps(n[1], n[4], n[7], n[10]);
      const __m128i ix = _mm_cvttps_epi32(_mm_add_ps(half, _mm_mul_ps(scale, x)));
      const __m128i iy = _mm_cvttps_epi32(_mm_add_ps(half, _mm_mul_ps(scale, y)));
      const __m128i b = _mm_max_epu8(_mm_packus_epi16(_mm_packs_epi32(ix, iy), _mm_setzero_si128()), one);  // x0..3 y0..3
      const __m128i rg = _mm_unpacklo_epi8(_mm_set1_epi8(char(red)), _mm_srli_si128(b, 4));  // R y0 R y1 ..
      const __m128i ba = _mm_unpacklo_epi8(_mm_setzero_si128(), b);                           // 0 x0 0 x1 ..
      _mm_storeu_si128(reinterpret_cast<__m128i*>(&rgba[k * 4]), _mm_unpacklo_epi16(rg, ba));
    }
#else
  pack_normal_texels_per_texel(in, rgba, ao_in_red);
#endif
}

void pack_normal_texels_per_texel(const NormalTexels& in, std::array<uint8_t, kTexelCount * 4>& rgba, bool ao_in_red) {
  for (int u = 0; u < kTexels; ++u)
    for (int t = 0; t < kTexels; ++t) {
      const size_t k = size_t(u * kTexels + t);
      const int q5 = int(std::clamp(in.ao[size_t((u / 4) * kTexelBlocks + t / 4)], 0.0f, 1.0f) * 31.0f + 0.5f);
      rgba[k * 4 + 0] = ao_in_red ? uint8_t((q5 << 3) | (q5 >> 2)) : 255;
      rgba[k * 4 + 1] = normal_texel_of(in.n[k * 3 + 1]);
      rgba[k * 4 + 2] = 0;
      rgba[k * 4 + 3] = normal_texel_of(in.n[k * 3 + 0]);
    }
}

void unpack_normal(const uint8_t rgba[4], float n[3]) {
  float x = normal_of_texel(rgba[3]), y = normal_of_texel(rgba[1]);
  const float rr = x * x + y * y;
  float z = 0;
  if (rr < 1.0f) {
    z = std::sqrt(1.0f - rr);
  } else {
    const float inv = 1.0f / std::sqrt(rr);
    x *= inv;
    y *= inv;
  }
  n[0] = x;
  n[1] = y;
  n[2] = z;
}

void encode_bc3_image(const uint8_t* rgba, Bc3Method method, uint8_t* out_blocks) {
  encode_image_blocks(rgba, 16, out_blocks,
                      [method](const uint8_t* block, uint8_t* out) { encode_bc3_block(block, method, out); });
}

AngleStats normal_error(const NormalTexels& ref, const uint8_t* bc3_blocks) {
  // Decode in block order, then the angles as one branch-free loop (the same operations as
  // fast_angle(), selects instead of branches, so SIMD lanes give the same doubles), then the sums
  // in block order as before.
  static thread_local std::array<float, kTexelCount * 6> pairs;  // per visit: ref xyz, decoded xyz
  static thread_local std::array<double, kTexelCount> degs;
  size_t m = 0;
  const auto decode = [](const uint8_t* block, uint8_t* out) { decode_bc3_block(block, out); };
  for_each_decoded_texel(bc3_blocks, 16, decode, [&](size_t k, const uint8_t* texel) {
    float* p = &pairs[m * 6];
    p[0] = ref.n[k * 3];
    p[1] = ref.n[k * 3 + 1];
    p[2] = ref.n[k * 3 + 2];
    unpack_normal(texel, p + 3);
    ++m;
  });
  for (size_t v = 0; v < m; ++v) {
    const float* p = &pairs[v * 6];
    const double a0 = p[0], a1 = p[1], a2 = p[2], b0 = p[3], b1 = p[4], b2 = p[5];
    const double cx = a1 * b2 - a2 * b1, cy = a2 * b0 - a0 * b2, cz = a0 * b1 - a1 * b0;
    const double y = std::sqrt(cx * cx + cy * cy + cz * cz), x = a0 * b0 + a1 * b1 + a2 * b2;
    degs[v] = fast_atan2_pos_select(y, x) * kRadToDeg;  // statistics: 1e-3 degree is plenty
  }
  AngleStats st;
  for (size_t v = 0; v < m; ++v) {
    st.sum_deg += degs[v];
    st.max_deg = std::max(st.max_deg, degs[v]);
  }
  st.count = m;
  return st;
}

}  // namespace terrain::cook
