// Normal texels from the window heights. Everything is a function of the window (canonical heights
// shared with the neighbours), so apron texels equal the neighbours' interior texels bit for bit
// before compression.
#include "normals.h"

#include "avx2_clones.h"
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

// The ring (8 spacings wide) and centre (4 wide) height sums of one AO block whose south-west
// vertex is (i0, j0), for it and the 3 blocks east of it (one per lane): each lane adds its
// block's values in the order of the per-block loop (rows south to north, west to east), a
// missing height as +0.0 (the sums start at +0.0 and can never be -0.0, so that equals leaving
// it out).
TERRAIN_AVX2_CLONES void block_ao_lanes(const float* h, int i0, int j0, double s, float ao[4]) {
  typedef double V4d __attribute__((vector_size(32)));
  typedef int64_t V4l __attribute__((vector_size(32)));
  V4d ring = {}, inner = {};
  V4l nr = {}, ni = {};
  const V4d zero = {};
  const auto add = [&](const float* p, V4d& sum, V4l& n) {
    const V4d v = {p[0], p[4], p[8], p[12]};
    const V4l ok = v == v;
    sum += ok ? v : zero;
    n -= ok;
  };
  for (int b = -2; b <= 6; ++b) {
    const float* row = &h[size_t((j0 + b + kWindowMargin) * kWindowSize + (i0 - 2 + kWindowMargin))];  // a = -2
    if (b == -2 || b == 6) {
      for (int a = 0; a <= 8; ++a) add(row + a, ring, nr);
      continue;
    }
    add(row, ring, nr);
    if (b >= 0 && b <= 4)
      for (int a = 2; a <= 6; ++a) add(row + a, inner, ni);
    add(row + 8, ring, nr);
  }
  for (int l = 0; l < 4; ++l) {
    ao[l] = 1.0f;
    if (ni[l] && nr[l]) {
      const double depth = std::max(0.0, ring[l] / double(nr[l]) - inner[l] / double(ni[l]));
      const double r = depth / (4.0 * s);
      ao[l] = float(1.0 / (1.0 + r * r));
    }
  }
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
  // Block ambient occlusion (see normals.h), 4 blocks of a block row at a time.
  static_assert(((kTexelBlocks + 3) / 4 * 4 - 1) * 4 - kApron + 6 + kWindowMargin < kWindowSize);  // padding lanes read inside
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; bx += 4) {
      float ao[4];
      block_ao_lanes(h, bx * 4 - kApron, by * 4 - kApron, s, ao);
      for (int l = 0; l < 4 && bx + l < kTexelBlocks; ++l) out.ao[size_t(by * kTexelBlocks + bx + l)] = ao[l];
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

namespace {

typedef float V4f __attribute__((vector_size(16)));
typedef int32_t V4i __attribute__((vector_size(16)));
typedef double V4d __attribute__((vector_size(32)));
typedef int64_t V4l __attribute__((vector_size(32)));

// normal_of_texel of every byte.
struct TexelComponents {
  float c[256];
  TexelComponents() {
    for (int v = 0; v < 256; ++v) c[v] = normal_of_texel(uint8_t(v));
  }
};
const TexelComponents& texel_components() {
  static const TexelComponents t;
  return t;
}

// Degrees between reference normals (ax, ay, az) and decoded ones whose x and y components are
// (bx, by) before unpack_normal, 4 at a time (n a multiple of 4). Each lane does unpack_normal's
// float operations and normal_error_per_texel's double ones in their order; both sides of a
// branch are computed and selected (a branch that computes a value would stop GCC vectorising),
// the rarely taken ones only when a lane takes them.
TERRAIN_AVX2_CLONES void normal_angles_deg(const float* __restrict ax, const float* __restrict ay,
                                           const float* __restrict az, const float* __restrict bx,
                                           const float* __restrict by, size_t n, double* __restrict degs) {
  const V4f one_f = {1, 1, 1, 1}, zero_f = {};
  const V4d zero = {}, half_pi = {1.5707963267948966, 1.5707963267948966, 1.5707963267948966, 1.5707963267948966};
  const V4d pi = half_pi + half_pi, one = {1, 1, 1, 1};
  const V4l abs_mask = {INT64_MAX, INT64_MAX, INT64_MAX, INT64_MAX};
  for (size_t v = 0; v < n; v += 4) {
    V4f x, y, fa0, fa1, fa2;
    std::memcpy(&x, bx + v, sizeof x);
    std::memcpy(&y, by + v, sizeof y);
    std::memcpy(&fa0, ax + v, sizeof fa0);
    std::memcpy(&fa1, ay + v, sizeof fa1);
    std::memcpy(&fa2, az + v, sizeof fa2);
    // unpack_normal.
    const V4f rr = x * x + y * y;
    V4f zi = one_f - rr;
    for (int l = 0; l < 4; ++l) zi[l] = std::sqrt(zi[l]);
    const V4i inside = rr < one_f;
    V4f b0f = x, b1f = y;
    if (!(inside[0] & inside[1] & inside[2] & inside[3])) {  // some outside the unit disc: rescaled
      V4f root = rr;
      for (int l = 0; l < 4; ++l) root[l] = std::sqrt(root[l]);
      const V4f inv = one_f / root;
      b0f = inside ? x : x * inv;
      b1f = inside ? y : y * inv;
    }
    const V4f b2f = inside ? zi : zero_f;
    // The angle: cross and dot products, then fast_atan2_pos_select.
    const V4d a0 = __builtin_convertvector(fa0, V4d), a1 = __builtin_convertvector(fa1, V4d);
    const V4d a2 = __builtin_convertvector(fa2, V4d), b0 = __builtin_convertvector(b0f, V4d);
    const V4d b1 = __builtin_convertvector(b1f, V4d), b2 = __builtin_convertvector(b2f, V4d);
    const V4d cx = a1 * b2 - a2 * b1, cy = a2 * b0 - a0 * b2, cz = a0 * b1 - a1 * b0;
    V4d sy = cx * cx + cy * cy + cz * cz;
    for (int l = 0; l < 4; ++l) sy[l] = std::sqrt(sy[l]);
    const V4d sx = a0 * b0 + a1 * b1 + a2 * b2;
    const V4d q = sy / V4d(V4l(sx) & abs_mask);
    const V4l big = q > one;
    V4d t = q;
    if (big[0] | big[1] | big[2] | big[3]) t = big ? one / q : q;  // angles over 45 degrees
    const V4d t2 = t * t;
    const V4d p =
        t * (0.99997726 + t2 * (-0.33262347 + t2 * (0.19354346 + t2 * (-0.11643287 + t2 * (0.05265332 + t2 * -0.01172120)))));
    const V4d a = big ? half_pi - p : p;
    const V4d angle = sx == zero ? (sy == zero ? zero : half_pi) : (sx > zero ? a : pi - a);
    const V4d deg = angle * kRadToDeg;
    std::memcpy(degs + v, &deg, sizeof deg);
  }
}

}  // namespace

AngleStats normal_error(const NormalTexels& ref, const uint8_t* bc3_blocks) {
  // Decode in block order into arrays, the angles 4 lanes at a time, then the sums in block order
  // (normal_error_per_texel's order).
  static_assert(kTexelCount % 4 == 0);
  struct Scratch {
    alignas(32) float ax[kTexelCount], ay[kTexelCount], az[kTexelCount], bx[kTexelCount], by[kTexelCount];
    alignas(32) double degs[kTexelCount];
  };
  static thread_local Scratch sc;
  const float* comp = texel_components().c;
  size_t m = 0;
  const auto decode = [](const uint8_t* block, uint8_t* out) { decode_bc3_block(block, out); };
  for_each_decoded_texel(bc3_blocks, 16, decode, [&](size_t k, const uint8_t* texel) {
    sc.ax[m] = ref.n[k * 3];
    sc.ay[m] = ref.n[k * 3 + 1];
    sc.az[m] = ref.n[k * 3 + 2];
    sc.bx[m] = comp[texel[3]];
    sc.by[m] = comp[texel[1]];
    ++m;
  });
  normal_angles_deg(sc.ax, sc.ay, sc.az, sc.bx, sc.by, m, sc.degs);
  AngleStats st;
  for (size_t v = 0; v < m; ++v) {
    st.sum_deg += sc.degs[v];
    st.max_deg = std::max(st.max_deg, sc.degs[v]);
  }
  st.count = m;
  return st;
}

AngleStats normal_error_per_texel(const NormalTexels& ref, const uint8_t* bc3_blocks) {
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
