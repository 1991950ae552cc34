// Rate-distortion pass over encoded BC blocks (see bc_rdo.h).
//
// Blocks are visited in stream order. For each block half the candidates are the final halves of
// the blocks of the last four block rows: zstd finds those bytes within its window and stores a
// match of a few bytes instead of 8 literals. The source nearest by absolute difference (one SAD
// instruction per 16 values) is the one tried; its squared error decides. An alpha half may also
// take an earlier block's index bits with endpoints refitted to them (least squares), so only the
// 2 endpoint bytes stay literals.
// The choice minimises squared error + lambda * expected stored bytes, with literals counted at 1
// byte each and a match at kMatchBytes. The decoders here follow terrain/bc_decode.h (nearest
// rounding) exactly; all decisions are integer or exactly rounded, so the AVX2, SSE2 and scalar
// searches choose the same sources.
#include "bc_rdo.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#endif

#include "bc_blocks.h"
#include "surface_layers.h"
#include "terrain/bc_decode.h"

namespace terrain::cook {
namespace {

constexpr int kBlocksX = kTexelBlocks;
constexpr int kBlockBytes = 16;
// Expected stored bytes of a match (offset and length codes): an estimate, not a measurement.
constexpr float kMatchBytes = 3.0f;
// Normal sources: the 132 blocks before this one (four block rows). On the 1 m lidar-like 8 km
// square, default tolerance, normal + albedo bytes at +0.5 degrees mean normal error
// (interpolated between lambdas 32..36): 66 blocks 0.697x, 99 0.691x, 132 0.687x, 264 0.680x.
constexpr int kWindowBlocks = 4 * kBlocksX;
// Albedo sources: two block rows (33 blocks stored 611.7 KB, 66 606.0, 132 604.9 on that square).
constexpr int kAlbedoWindowBlocks = 2 * kBlocksX;
// Albedo: the share by which the pass may raise a node's squared colour error (0.41 dB of PSNR).
constexpr double kAlbedoBudget = 0.1;

inline uint64_t load48(const uint8_t* b) {
  uint64_t bits = 0;
  for (int i = 0; i < 6; ++i) bits |= uint64_t(b[i]) << (8 * i);
  return bits;
}

inline int bc4_sse(int a0, int a1, uint64_t bits, const uint8_t ref[16]) {
  int p[8];
  bc4_palette(a0, a1, p);
  int sse = 0;
  for (int i = 0; i < 16; ++i) {
    const int d = p[(bits >> (3 * i)) & 7] - ref[i];
    sse += d * d;
  }
  return sse;
}

// G channel of a BC3 colour half (always 4 colours), as decode_bc3_block with nearest rounding.
inline int expand_g(uint16_t c) {
  const int g = (c >> 5) & 63;
  return (g << 2) | (g >> 4);
}
// R and B bits of both endpoints (AO and the zero B of a normal block).
inline uint32_t colour_rb_bits(const uint8_t* half) {
  const uint16_t c0 = uint16_t(half[0] | (half[1] << 8)), c1 = uint16_t(half[2] | (half[3] << 8));
  return (uint32_t(c0 & 0xF81Fu) << 16) | (c1 & 0xF81Fu);
}

// Least-squares BC4 endpoints in the 8-value mode for texels at positions pos (0..7 along a0 -> a1:
// value = ((7 - pos) a0 + pos a1) / 7), in exact integers; false when the fit does not give
// a0 > a1 (the index bits would then mean something else).
bool bc4_refit(const uint8_t pos[16], const uint8_t ref[16], int& a0, int& a1) {
  int64_t saa = 0, sab = 0, sbb = 0, sax = 0, sbx = 0;
  for (int i = 0; i < 16; ++i) {
    const int w = pos[i], u = 7 - w, x = ref[i];
    saa += u * u;
    sab += u * w;
    sbb += w * w;
    sax += u * x;
    sbx += w * x;
  }
  const int64_t det = saa * sbb - sab * sab;
  if (det <= 0) return false;
  const double f0 = 7.0 * double(sax * sbb - sbx * sab) / double(det);
  const double f1 = 7.0 * double(sbx * saa - sax * sab) / double(det);
  a0 = int(std::floor(std::clamp(f0, 0.0, 255.0) + 0.5));
  a1 = int(std::floor(std::clamp(f1, 0.0, 255.0) + 0.5));
  return a0 > a1;
}

// Sum of absolute and of squared differences of 16 bytes (the same integers with or without SSE2).
#if defined(__SSE2__)
inline int sad16(const uint8_t* a, const uint8_t* b) {
  const __m128i s = _mm_sad_epu8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(a)),
                                 _mm_loadu_si128(reinterpret_cast<const __m128i*>(b)));
  return _mm_cvtsi128_si32(s) + _mm_extract_epi16(s, 4);
}
inline int sse16(const uint8_t* a, const uint8_t* b) {
  const __m128i va = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a));
  const __m128i vb = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b));
  const __m128i z = _mm_setzero_si128();
  const __m128i lo = _mm_sub_epi16(_mm_unpacklo_epi8(va, z), _mm_unpacklo_epi8(vb, z));
  const __m128i hi = _mm_sub_epi16(_mm_unpackhi_epi8(va, z), _mm_unpackhi_epi8(vb, z));
  __m128i acc = _mm_add_epi32(_mm_madd_epi16(lo, lo), _mm_madd_epi16(hi, hi));
  acc = _mm_add_epi32(acc, _mm_shuffle_epi32(acc, 0x4E));
  acc = _mm_add_epi32(acc, _mm_shuffle_epi32(acc, 0xB1));
  return _mm_cvtsi128_si32(acc);
}
#else
inline int sad16(const uint8_t* a, const uint8_t* b) {
  int s = 0;
  for (int i = 0; i < 16; ++i) s += a[i] > b[i] ? a[i] - b[i] : b[i] - a[i];
  return s;
}
inline int sse16(const uint8_t* a, const uint8_t* b) {
  int s = 0;
  for (int i = 0; i < 16; ++i) s += (int(a[i]) - b[i]) * (int(a[i]) - b[i]);
  return s;
}
#endif

// What the pass keeps of each final block: its decoded x (alpha) and y (G) values and, for an
// 8-value alpha block, each texel's position along a0 -> a1 (0..7; 255 in the other mode).
// A node's blocks as decoded so far, one array per field so that the source scan reads
// consecutive blocks with one load.
struct DecodedNormals {
  static constexpr int kCount = kBlocksX * kBlocksX;
  alignas(32) uint8_t x[kCount][16];
  alignas(32) uint8_t y[kCount][16];
  alignas(32) uint8_t pos[kCount][16];
  int32_t rb[kCount];     // colour_rb_bits of the colour half
  int32_t eight[kCount];  // -1 for an 8-value alpha block, else 0
};

// The definition; decode_for_rdo takes the AVX2 form where the CPU has it (the same bytes).
void decode_for_rdo_scalar(const uint8_t* block, DecodedNormals& image, int b) {
  uint8_t* const dx = image.x[b];
  uint8_t* const dy = image.y[b];
  uint8_t* const dpos = image.pos[b];
  int p[8];
  bc4_palette(block[0], block[1], p);
  const uint64_t bits = load48(block + 2);
  const bool eight = block[0] > block[1];
  for (int i = 0; i < 16; ++i) {
    const int idx = int((bits >> (3 * i)) & 7);
    dx[i] = uint8_t(p[idx]);
    dpos[i] = eight ? uint8_t(idx == 0 ? 0 : idx == 1 ? 7 : idx - 1) : uint8_t(255);
  }
  const uint16_t c0 = uint16_t(block[8] | (block[9] << 8)), c1 = uint16_t(block[10] | (block[11] << 8));
  const int e0 = expand_g(c0), e1 = expand_g(c1);
  const int g[4] = {e0, e1, (2 * e0 + e1 + 1) / 3, (e0 + 2 * e1 + 1) / 3};
  uint32_t sel;
  std::memcpy(&sel, block + 12, 4);
  for (int i = 0; i < 16; ++i) dy[i] = uint8_t(g[(sel >> (2 * i)) & 3]);
  image.rb[b] = int32_t(colour_rb_bits(block + 8));
  image.eight[b] = eight ? -1 : 0;
}

// The sources a block half may take, found among the kWindowBlocks blocks before block b: the
// nearest x and y halves by absolute difference (a y half only from a block with the same R and B
// bits) and, for an 8-value alpha block, the two blocks whose index positions are nearest. Each
// search orders candidates by (distance, how far back), so ties go to the most recent block; a
// key (distance << 11 | back) makes that one integer minimum, 4 candidates at a time with SSE2.
struct SourceScan {
  int whole_x = -1, whole_y = -1;
  int near[2] = {-1, -1};
};
constexpr int kBackBits = 11;  // back <= 33 * 33
static_assert((kBlocksX * kBlocksX) < (1 << kBackBits));
constexpr int32_t kNoKey = INT32_MAX;

// Whether rdo_normal_blocks takes the previous block without a scan where it decodes exactly to a
// block's values (rdo_neighbour_shortcut; tests compare the two).
bool neighbour_shortcut_enabled = true;

inline void keep_two_least(int32_t key, int32_t& k0, int32_t& k1) {
  if (key < k1) {
    if (key < k0)
      k1 = k0, k0 = key;
    else
      k1 = key;
  }
}

// The least keys found so far: x and y halves, the two nearest index positions.
struct ScanKeys {
  int32_t x = kNoKey, y = kNoKey, p0 = kNoKey, p1 = kNoKey;
  // Folds in the per-lane keys of a vector search (lanes[0..3] = x, y, p0, p1); the two least
  // overall are among each lane's two least.
  void fold(const int32_t (*lanes)[8], int count) {
    for (int i = 0; i < count; ++i) {
      x = std::min(x, lanes[0][i]);
      y = std::min(y, lanes[1][i]);
      keep_two_least(lanes[2][i], p0, p1);
      keep_two_least(lanes[3][i], p0, p1);
    }
  }
};

#if defined(__SSE2__)
inline __m128i min32(__m128i a, __m128i c) {
  const __m128i m = _mm_cmpgt_epi32(a, c);
  return _mm_or_si128(_mm_and_si128(m, c), _mm_andnot_si128(m, a));
}
inline __m128i max32(__m128i a, __m128i c) {
  const __m128i m = _mm_cmpgt_epi32(a, c);
  return _mm_or_si128(_mm_and_si128(m, a), _mm_andnot_si128(m, c));
}
// Sums of absolute differences of 16 bytes at `first`, first + stride, + 2 stride and + 3 stride
// against `own`, one per 32-bit lane.
inline __m128i sad4(const uint8_t* first, size_t stride, __m128i own) {
  __m128i t[4];
  for (size_t i = 0; i < 4; ++i)
    t[i] = _mm_sad_epu8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(first + i * stride)), own);
  const __m128i u01 = _mm_add_epi32(_mm_unpacklo_epi64(t[0], t[1]), _mm_unpackhi_epi64(t[0], t[1]));
  const __m128i u23 = _mm_add_epi32(_mm_unpacklo_epi64(t[2], t[3]), _mm_unpackhi_epi64(t[2], t[3]));
  return _mm_castps_si128(_mm_shuffle_ps(_mm_castsi128_ps(u01), _mm_castsi128_ps(u23), _MM_SHUFFLE(2, 0, 2, 0)));
}
// Candidate keys (sums << kBackBits | backs) where `valid`, kNoKey elsewhere.
inline __m128i keys4(__m128i sums, __m128i backs, __m128i valid) {
  const __m128i key = _mm_or_si128(_mm_slli_epi32(sums, kBackBits), backs);
  return _mm_or_si128(_mm_and_si128(valid, key), _mm_andnot_si128(valid, _mm_set1_epi32(kNoKey)));
}
#endif

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define TERRAIN_RDO_AVX2 1
// Whether scan_sources may take 8 candidates at a time with AVX2 (the CPU has it, and tests did
// not switch it off): the same keys, so the same sources either way.
bool cpu_has_avx2() {
  __builtin_cpu_init();  // may run before the runtime's own constructor
  return __builtin_cpu_supports("avx2");
}
bool avx2_scan_enabled = cpu_has_avx2();

#define TERRAIN_TARGET_AVX2 __attribute__((target("avx2")))

// Sums of absolute differences of the 16-byte fields of 8 consecutive blocks against `own`, in
// lane order c0 c2 c4 c6 c1 c3 c5 c7 (ci = the i-th block from `first`).
TERRAIN_TARGET_AVX2 inline __m256i sad8(const uint8_t* first, __m256i own) {
  __m256i t[4];
  for (int i = 0; i < 4; ++i)
    t[i] = _mm256_sad_epu8(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(first + 32 * i)), own);
  const __m256i u01 = _mm256_add_epi32(_mm256_unpacklo_epi64(t[0], t[1]), _mm256_unpackhi_epi64(t[0], t[1]));
  const __m256i u23 = _mm256_add_epi32(_mm256_unpacklo_epi64(t[2], t[3]), _mm256_unpackhi_epi64(t[2], t[3]));
  return _mm256_castps_si256(
      _mm256_shuffle_ps(_mm256_castsi256_ps(u01), _mm256_castsi256_ps(u23), _MM_SHUFFLE(2, 0, 2, 0)));
}
TERRAIN_TARGET_AVX2 inline __m256i keys8(__m256i sums, __m256i backs, __m256i valid) {
  const __m256i key = _mm256_or_si256(_mm256_slli_epi32(sums, kBackBits), backs);
  return _mm256_or_si256(_mm256_and_si256(valid, key), _mm256_andnot_si256(valid, _mm256_set1_epi32(kNoKey)));
}
TERRAIN_TARGET_AVX2 inline __m256i own16(const uint8_t* p) {
  return _mm256_broadcastsi128_si256(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)));
}

// The 3-bit fields of a 24-bit word one per byte (field j in byte j), and the 2-bit fields of a
// 16-bit word likewise: bit spreading in three shift-and-mask steps.
inline uint64_t spread3(uint64_t v) {
  v = (v | (v << 20)) & 0x00000FFF00000FFFull;
  v = (v | (v << 10)) & 0x003F003F003F003Full;
  return (v | (v << 5)) & 0x0707070707070707ull;
}
inline uint64_t spread2(uint64_t v) {
  v = (v | (v << 24)) & 0x000000FF000000FFull;
  v = (v | (v << 12)) & 0x000F000F000F000Full;
  return (v | (v << 6)) & 0x0303030303030303ull;
}
// The 16 2-bit selectors of a BC1 index word, one per byte.
inline __m128i bc1_selectors(const uint8_t* indices) {
  uint32_t sel;
  std::memcpy(&sel, indices, 4);
  return _mm_set_epi64x(int64_t(spread2(sel >> 16)), int64_t(spread2(sel & 0xFFFFu)));
}

// decode_for_rdo_scalar with byte shuffles for the palette lookups (SSSE3, part of AVX2).
TERRAIN_TARGET_AVX2 void decode_for_rdo_avx2(const uint8_t* block, DecodedNormals& image, int b) {
  int p[8];
  bc4_palette(block[0], block[1], p);
  const __m128i palette = _mm_setr_epi8(char(p[0]), char(p[1]), char(p[2]), char(p[3]), char(p[4]), char(p[5]), char(p[6]),
                                        char(p[7]), 0, 0, 0, 0, 0, 0, 0, 0);
  const uint64_t bits = load48(block + 2);
  const __m128i idx = _mm_set_epi64x(int64_t(spread3(bits >> 24)), int64_t(spread3(bits & 0xFFFFFFu)));
  _mm_store_si128(reinterpret_cast<__m128i*>(image.x[b]), _mm_shuffle_epi8(palette, idx));
  const bool eight = block[0] > block[1];
  const __m128i pos = eight ? _mm_shuffle_epi8(_mm_setr_epi8(0, 7, 1, 2, 3, 4, 5, 6, 0, 0, 0, 0, 0, 0, 0, 0), idx)
                            : _mm_set1_epi8(char(255));
  _mm_store_si128(reinterpret_cast<__m128i*>(image.pos[b]), pos);
  const uint16_t c0 = uint16_t(block[8] | (block[9] << 8)), c1 = uint16_t(block[10] | (block[11] << 8));
  const int e0 = expand_g(c0), e1 = expand_g(c1);
  const __m128i g = _mm_setr_epi8(char(e0), char(e1), char((2 * e0 + e1 + 1) / 3), char((e0 + 2 * e1 + 1) / 3), 0, 0, 0,
                                  0, 0, 0, 0, 0, 0, 0, 0, 0);
  _mm_store_si128(reinterpret_cast<__m128i*>(image.y[b]), _mm_shuffle_epi8(g, bc1_selectors(block + 12)));
  image.rb[b] = int32_t(colour_rb_bits(block + 8));
  image.eight[b] = eight ? -1 : 0;
}
#endif

void decode_for_rdo(const uint8_t* block, DecodedNormals& image, int b) {
#if defined(TERRAIN_RDO_AVX2)
  if (avx2_scan_enabled) return decode_for_rdo_avx2(block, image, b);
#endif
  decode_for_rdo_scalar(block, image, b);
}
#if defined(TERRAIN_RDO_AVX2)

// The keys of scan_sources for the candidates back .. (while 8 fit in the window), 8 at a time;
// advances back past them and folds its lanes into the running keys.
TERRAIN_TARGET_AVX2 void scan_sources_avx2(const DecodedNormals& image, int b, const uint8_t x[16],
                                           const uint8_t y[16], uint32_t own_rb, bool own_eight, int window,
                                           int& back, ScanKeys& keys) {
  const __m256i none = _mm256_set1_epi32(kNoKey);
  const __m256i ox = own16(x), oy = own16(y), op = own16(image.pos[b]);
  const __m256i rb = _mm256_set1_epi32(int32_t(own_rb));
  const __m256i order = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
  __m256i vx = none, vy = none, vp0 = none, vp1 = none;
  for (; back + 7 <= window; back += 8) {
    const int base = b - back - 7;  // block base + i is back + 7 - i blocks before b
    const __m256i backs = _mm256_setr_epi32(back + 7, back + 5, back + 3, back + 1, back + 6, back + 4, back + 2, back);
    vx = _mm256_min_epi32(vx, _mm256_or_si256(_mm256_slli_epi32(sad8(image.x[base], ox), kBackBits), backs));
    const __m256i rbs = _mm256_permutevar8x32_epi32(
        _mm256_loadu_si256(reinterpret_cast<const __m256i*>(image.rb + base)), order);
    vy = _mm256_min_epi32(vy, keys8(sad8(image.y[base], oy), backs, _mm256_cmpeq_epi32(rbs, rb)));
    if (own_eight) {
      const __m256i eight = _mm256_permutevar8x32_epi32(
          _mm256_loadu_si256(reinterpret_cast<const __m256i*>(image.eight + base)), order);
      const __m256i kp = keys8(sad8(image.pos[base], op), backs, eight);
      vp1 = _mm256_min_epi32(vp1, _mm256_max_epi32(vp0, kp));
      vp0 = _mm256_min_epi32(vp0, kp);
    }
  }
  alignas(32) int32_t lanes[4][8];
  const __m256i v[4] = {vx, vy, vp0, vp1};
  for (int k = 0; k < 4; ++k) _mm256_store_si256(reinterpret_cast<__m256i*>(lanes[k]), v[k]);
  keys.fold(lanes, 8);
}
#endif

SourceScan scan_sources(const DecodedNormals& image, int b, const uint8_t x[16], const uint8_t y[16],
                        uint32_t own_rb, bool own_eight) {
  ScanKeys keys;
  const int window = std::min(kWindowBlocks, b);
  int back = 1;
#if defined(TERRAIN_RDO_AVX2)
  if (avx2_scan_enabled) scan_sources_avx2(image, b, x, y, own_rb, own_eight, window, back, keys);
#endif
#if defined(__SSE2__)
  const __m128i ox = _mm_loadu_si128(reinterpret_cast<const __m128i*>(x));
  const __m128i oy = _mm_loadu_si128(reinterpret_cast<const __m128i*>(y));
  const __m128i op = _mm_loadu_si128(reinterpret_cast<const __m128i*>(image.pos[b]));
  const __m128i none = _mm_set1_epi32(kNoKey), rb = _mm_set1_epi32(int32_t(own_rb));
  __m128i vx = none, vy = none, vp0 = none, vp1 = none;
  // Lane i of a group holds block b - back - 3 + i, i.e. back + 3 - i.
  for (; back + 3 <= window; back += 4) {
    const int base = b - back - 3;
    const __m128i backs = _mm_setr_epi32(back + 3, back + 2, back + 1, back);
    vx = min32(vx, _mm_or_si128(_mm_slli_epi32(sad4(image.x[base], 16, ox), kBackBits), backs));
    const __m128i same_rb = _mm_cmpeq_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(image.rb + base)), rb);
    vy = min32(vy, keys4(sad4(image.y[base], 16, oy), backs, same_rb));
    if (own_eight) {
      const __m128i eight = _mm_loadu_si128(reinterpret_cast<const __m128i*>(image.eight + base));
      const __m128i kp = keys4(sad4(image.pos[base], 16, op), backs, eight);
      vp1 = min32(vp1, max32(vp0, kp));
      vp0 = min32(vp0, kp);
    }
  }
  alignas(16) int32_t lanes[4][8];
  const __m128i v[4] = {vx, vy, vp0, vp1};
  for (int k = 0; k < 4; ++k) _mm_store_si128(reinterpret_cast<__m128i*>(lanes[k]), v[k]);
  keys.fold(lanes, 4);
#endif
  for (; back <= window; ++back) {
    const int c = b - back;
    keys.x = std::min(keys.x, int32_t((sad16(image.x[c], x) << kBackBits) | back));
    if (image.rb[c] == int32_t(own_rb)) keys.y = std::min(keys.y, int32_t((sad16(image.y[c], y) << kBackBits) | back));
    if (own_eight && image.eight[c])
      keep_two_least(int32_t((sad16(image.pos[c], image.pos[b]) << kBackBits) | back), keys.p0, keys.p1);
  }
  const auto source = [b](int32_t key) { return key == kNoKey ? -1 : b - int(key & ((1 << kBackBits) - 1)); };
  SourceScan s;
  s.whole_x = source(keys.x);
  s.whole_y = source(keys.y);
  s.near[0] = source(keys.p0);
  s.near[1] = source(keys.p1);
  return s;
}

}  // namespace

bool rdo_neighbour_shortcut(bool enabled) {
  const bool was = neighbour_shortcut_enabled;
  neighbour_shortcut_enabled = enabled;
  return was;
}

bool rdo_avx2_scan(bool enabled) {
#if defined(TERRAIN_RDO_AVX2)
  const bool was = avx2_scan_enabled;
  avx2_scan_enabled = enabled && cpu_has_avx2();
  return was;
#else
  (void)enabled;
  return false;
#endif
}

void rdo_normal_blocks(const uint8_t* rgba, float lambda, uint8_t* blocks, RdoCounts* counts) {
  if (!(lambda > 0)) return;
  RdoCounts n;
  static thread_local DecodedNormals image;
  for (int by = 0; by < kBlocksX; ++by)
    for (int bx = 0; bx < kBlocksX; ++bx) {
      const int b = by * kBlocksX + bx;
      uint8_t* own = blocks + size_t(b) * kBlockBytes;
      uint8_t x[16], y[16];
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) {
          const uint8_t* t = rgba + (size_t(by * 4 + r) * kTexels + size_t(bx * 4 + c)) * 4;
          x[r * 4 + c] = t[3];
          y[r * 4 + c] = t[1];
        }
      decode_for_rdo(own, image, b);
      // The outer ring of blocks is also the neighbours' (texels 128..131 of a node are texels
      // 0..3 of the next, SPEC 16.2): it stays as encoded so both nodes keep the same bytes there.
      if (bx == 0 || by == 0 || bx == kBlocksX - 1 || by == kBlocksX - 1) continue;
      ++n.blocks;
      // Costs J = squared error + lambda * expected stored bytes; the own halves are 8 literals each.
      const uint32_t own_rb = colour_rb_bits(own + 8);
      // Where the previous block decodes to exactly this block's x and y (with the same R and B
      // bits), it is what the scan below would choose for both halves: its key (distance 0, one
      // block back) is the least possible, a match without error costs lambda * kMatchBytes, less
      // than own literals, and an index copy costs more. Flat ground (the sea) takes this path.
      const int prev = b - 1;
      if (neighbour_shortcut_enabled && image.rb[prev] == int32_t(own_rb) && std::memcmp(image.x[prev], x, 16) == 0 &&
          std::memcmp(image.y[prev], y, 16) == 0) {
        std::memcpy(own, blocks + size_t(prev) * kBlockBytes, kBlockBytes);
        decode_for_rdo(own, image, b);
        n.half_copies += 2;
        continue;
      }
      const int own_ea = sse16(image.x[b], x), own_ec = sse16(image.y[b], y);
      const bool own_eight = own[0] > own[1];
      const SourceScan scan = scan_sources(image, b, x, y, own_rb, own_eight);
      const int from_a = scan.whole_x, from_c = scan.whole_y;
      // Index sources: the two whose positions are nearest own (L1), refitted below.
      const int near[2] = {scan.near[0], scan.near[1]};
      // Alpha half: own, the nearest whole earlier half, or own refitted endpoints with an earlier
      // block's index bits.
      float best_ja = float(own_ea) + lambda * 8.0f;
      int src_a = -1;
      if (from_a >= 0) {
        const float j = float(sse16(image.x[from_a], x)) + lambda * kMatchBytes;
        if (j < best_ja) best_ja = j, src_a = from_a;
      }
      uint8_t best_a[8];
      std::memcpy(best_a, src_a >= 0 ? blocks + size_t(src_a) * kBlockBytes : own, 8);
      int index_src = -1;
      // An index copy costs at least lambda * (2 + kMatchBytes): no use trying once the best costs less.
      const float index_bytes = lambda * (2.0f + kMatchBytes);
      for (int c : near) {
        if (c < 0 || !(index_bytes < best_ja)) continue;
        const uint8_t* cand = blocks + size_t(c) * kBlockBytes;
        const uint64_t bits = load48(cand + 2);
        int a0, a1;
        if (!bc4_refit(image.pos[c], x, a0, a1)) a0 = own[0], a1 = own[1];
        const float ji = float(bc4_sse(a0, a1, bits, x)) + index_bytes;
        if (ji < best_ja) {
          best_ja = ji;
          best_a[0] = uint8_t(a0);
          best_a[1] = uint8_t(a1);
          std::memcpy(best_a + 2, cand + 2, 6);
          index_src = c;
        }
      }
      std::memcpy(own, best_a, 8);
      // Colour half: own, or the nearest whole earlier half with the same R and B bits (the AO
      // stays exact).
      const float best_jc = float(own_ec) + lambda * 8.0f;
      int src_c = -1;
      if (from_c >= 0 && float(sse16(image.y[from_c], y)) + lambda * kMatchBytes < best_jc) src_c = from_c;
      if (src_c >= 0) std::memcpy(own + 8, blocks + size_t(src_c) * kBlockBytes + 8, 8);
      if (index_src >= 0 || src_a >= 0 || src_c >= 0) decode_for_rdo(own, image, b);
      n.half_copies += uint64_t(index_src < 0 && src_a >= 0) + uint64_t(src_c >= 0);
      n.index_copies += uint64_t(index_src >= 0);
    }
  if (counts) {
    counts->blocks += n.blocks;
    counts->half_copies += n.half_copies;
    counts->index_copies += n.index_copies;
  }
}

namespace {

// Albedo blocks as the pass keeps them: decoded RGB (hole texels 0, as the decoder gives them:
// 48 bytes, texel-interleaved, in three 16-byte planes so that the source scan reads consecutive
// blocks with one load), the transparency mask, and for 4-colour blocks each texel's position along
// c0 -> c1 (0..3).
struct DecodedAlbedo {
  static constexpr int kCount = kBlocksX * kBlocksX;
  alignas(32) uint8_t rgb[3][kCount][16];  // rgb[k][b] = bytes 16k .. 16k + 15 of block b's colours
  alignas(32) uint8_t pos[kCount][16];
  int32_t holes[kCount];
  int32_t four[kCount];  // -1 for a 4-colour block, else 0
};

// One block's decoded colours (48 bytes, texel-interleaved RGB), its positions and masks; the
// fields of DecodedAlbedo for one block.
struct DecodedColour {
  uint8_t rgb[48];
  uint8_t pos[16];
  int32_t holes = 0;
  bool four = false;
};

// Decodes a BC1 block into its colours (bytes 16k .. 16k + 15 of the texel-interleaved RGB at
// rgb[k]) and positions; returns the hole mask and sets `four`. The definition;
// decode_colour_for_rdo takes the AVX2 form where the CPU has it (the same bytes).
int decode_colour_scalar(const uint8_t* block, uint8_t* const rgb[3], uint8_t pos[16], bool& four) {
  uint8_t palette[16];
  decode_bc1_palette(block, palette);  // entry 3 of a 3-colour block is transparent black
  uint32_t sel;
  std::memcpy(&sel, block + 4, 4);
  const uint16_t c0 = uint16_t(block[0] | (block[1] << 8)), c1 = uint16_t(block[2] | (block[3] << 8));
  four = c0 > c1;
  static constexpr uint8_t kPos[4] = {0, 3, 1, 2};
  uint8_t rgbx[16 * 3 + 1];  // each texel's 4 palette bytes land at 3i; the 4th is overwritten
  for (int i = 0; i < 16; ++i) {
    const uint32_t k = (sel >> (2 * i)) & 3;
    std::memcpy(rgbx + 3 * i, palette + 4 * k, 4);
    pos[i] = kPos[k];
  }
  for (int k = 0; k < 3; ++k) std::memcpy(rgb[k], rgbx + 16 * k, 16);
  return bc1_transparent_mask(block);
}

#if defined(TERRAIN_RDO_AVX2)
TERRAIN_TARGET_AVX2 int decode_colour_avx2(const uint8_t* block, uint8_t* const rgb[3], uint8_t pos[16], bool& four) {
  uint8_t palette[16];
  decode_bc1_palette(block, palette);
  const __m128i pal = _mm_loadu_si128(reinterpret_cast<const __m128i*>(palette));
  const uint16_t c0 = uint16_t(block[0] | (block[1] << 8)), c1 = uint16_t(block[2] | (block[3] << 8));
  four = c0 > c1;
  const __m128i idx = bc1_selectors(block + 4);
  _mm_storeu_si128(reinterpret_cast<__m128i*>(pos),
                   _mm_shuffle_epi8(_mm_setr_epi8(0, 3, 1, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0), idx));
  // Byte j of the interleaved colours is channel j % 3 of texel j / 3: palette byte 4 idx + j % 3.
  const __m128i entry = _mm_slli_epi16(idx, 2);  // idx <= 3: no carry into the next byte
  const __m128i texel[3] = {_mm_setr_epi8(0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3, 4, 4, 4, 5),
                            _mm_setr_epi8(5, 5, 6, 6, 6, 7, 7, 7, 8, 8, 8, 9, 9, 9, 10, 10),
                            _mm_setr_epi8(10, 11, 11, 11, 12, 12, 12, 13, 13, 13, 14, 14, 14, 15, 15, 15)};
  const __m128i channel[3] = {_mm_setr_epi8(0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0),
                              _mm_setr_epi8(1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1),
                              _mm_setr_epi8(2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2)};
  for (int k = 0; k < 3; ++k)
    _mm_storeu_si128(reinterpret_cast<__m128i*>(rgb[k]),
                     _mm_shuffle_epi8(pal, _mm_add_epi8(_mm_shuffle_epi8(entry, texel[k]), channel[k])));
  return four ? 0 : _mm_movemask_epi8(_mm_cmpeq_epi8(idx, _mm_set1_epi8(3)));
}
#endif

int decode_colour(const uint8_t* block, uint8_t* const rgb[3], uint8_t pos[16], bool& four) {
#if defined(TERRAIN_RDO_AVX2)
  if (avx2_scan_enabled) return decode_colour_avx2(block, rgb, pos, four);
#endif
  return decode_colour_scalar(block, rgb, pos, four);
}

void decode_colour_for_rdo(const uint8_t* block, DecodedColour& d) {
  uint8_t* const rgb[3] = {d.rgb, d.rgb + 16, d.rgb + 32};
  d.holes = decode_colour(block, rgb, d.pos, d.four);
}

void decode_colour_for_rdo(const uint8_t* block, DecodedAlbedo& image, int b) {
  uint8_t* const rgb[3] = {image.rgb[0][b], image.rgb[1][b], image.rgb[2][b]};
  bool four = false;
  image.holes[b] = decode_colour(block, rgb, image.pos[b], four);
  image.four[b] = four ? -1 : 0;
}

inline int sse48(const uint8_t* a, const uint8_t* b) {
  return sse16(a, b) + sse16(a + 16, b + 16) + sse16(a + 32, b + 32);
}
inline int sse48(const DecodedAlbedo& image, int b, const uint8_t* ref) {
  return sse16(image.rgb[0][b], ref) + sse16(image.rgb[1][b], ref + 16) + sse16(image.rgb[2][b], ref + 32);
}
inline int sad48(const DecodedAlbedo& image, int b, const uint8_t* ref) {
  return sad16(image.rgb[0][b], ref) + sad16(image.rgb[1][b], ref + 16) + sad16(image.rgb[2][b], ref + 32);
}

// Albedo sources among the kAlbedoWindowBlocks blocks before block b, all with b's hole mask: the
// nearest whole block by absolute difference of the decoded colours against `ref`, and (for a
// 4-colour block) the 4-colour block whose selector positions are nearest. Keys and ties as in
// scan_sources.
struct ColourScan {
  int whole = -1, near = -1;
};

// Folds the per-lane keys of a vector search (lanes[0] whole blocks, lanes[1] selector positions)
// into the running least keys.
inline void fold_colour_keys(const int32_t (*lanes)[8], int count, int32_t& kw, int32_t& kn) {
  for (int i = 0; i < count; ++i) {
    kw = std::min(kw, lanes[0][i]);
    kn = std::min(kn, lanes[1][i]);
  }
}

#if defined(TERRAIN_RDO_AVX2)
// The keys of scan_colour_sources for the candidates back .. (while 8 fit in the window), 8 at a
// time; advances back past them and folds its lanes into kw and kn.
TERRAIN_TARGET_AVX2 void scan_colour_sources_avx2(const DecodedAlbedo& image, int b, const uint8_t ref[48], int window,
                                                  int& back, int32_t& kw, int32_t& kn) {
  const __m256i none = _mm256_set1_epi32(kNoKey);
  const __m256i r0 = own16(ref), r1 = own16(ref + 16), r2 = own16(ref + 32), op = own16(image.pos[b]);
  const __m256i holes = _mm256_set1_epi32(image.holes[b]);
  const __m256i order = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
  const bool four = image.four[b] != 0;
  __m256i vw = none, vn = none;
  for (; back + 7 <= window; back += 8) {
    const int base = b - back - 7;  // block base + i is back + 7 - i blocks before b
    const __m256i backs = _mm256_setr_epi32(back + 7, back + 5, back + 3, back + 1, back + 6, back + 4, back + 2, back);
    const __m256i same = _mm256_cmpeq_epi32(
        _mm256_permutevar8x32_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(image.holes + base)), order), holes);
    const __m256i sums = _mm256_add_epi32(_mm256_add_epi32(sad8(image.rgb[0][base], r0), sad8(image.rgb[1][base], r1)),
                                          sad8(image.rgb[2][base], r2));
    vw = _mm256_min_epi32(vw, keys8(sums, backs, same));
    if (four) {
      const __m256i fours = _mm256_and_si256(
          same, _mm256_permutevar8x32_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(image.four + base)), order));
      vn = _mm256_min_epi32(vn, keys8(sad8(image.pos[base], op), backs, fours));
    }
  }
  alignas(32) int32_t lanes[2][8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(lanes[0]), vw);
  _mm256_store_si256(reinterpret_cast<__m256i*>(lanes[1]), vn);
  fold_colour_keys(lanes, 8, kw, kn);
}
#endif

ColourScan scan_colour_sources(const DecodedAlbedo& image, int b, const uint8_t ref[48]) {
  int32_t kw = kNoKey, kn = kNoKey;
  const int window = std::min(kAlbedoWindowBlocks, b);
  const bool four = image.four[b] != 0;
  int back = 1;
#if defined(TERRAIN_RDO_AVX2)
  if (avx2_scan_enabled) scan_colour_sources_avx2(image, b, ref, window, back, kw, kn);
#endif
#if defined(__SSE2__)
  const __m128i r0 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(ref));
  const __m128i r1 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(ref + 16));
  const __m128i r2 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(ref + 32));
  const __m128i op = _mm_loadu_si128(reinterpret_cast<const __m128i*>(image.pos[b]));
  const __m128i holes = _mm_set1_epi32(image.holes[b]);
  __m128i vw = _mm_set1_epi32(kNoKey), vn = vw;
  for (; back + 3 <= window; back += 4) {
    const int base = b - back - 3;
    const __m128i backs = _mm_setr_epi32(back + 3, back + 2, back + 1, back);
    const __m128i same = _mm_cmpeq_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(image.holes + base)), holes);
    const __m128i sums = _mm_add_epi32(_mm_add_epi32(sad4(image.rgb[0][base], 16, r0), sad4(image.rgb[1][base], 16, r1)),
                                       sad4(image.rgb[2][base], 16, r2));
    vw = min32(vw, keys4(sums, backs, same));
    if (four) {
      const __m128i fours = _mm_and_si128(same, _mm_loadu_si128(reinterpret_cast<const __m128i*>(image.four + base)));
      vn = min32(vn, keys4(sad4(image.pos[base], 16, op), backs, fours));
    }
  }
  alignas(16) int32_t lanes[2][8];
  _mm_store_si128(reinterpret_cast<__m128i*>(lanes[0]), vw);
  _mm_store_si128(reinterpret_cast<__m128i*>(lanes[1]), vn);
  fold_colour_keys(lanes, 4, kw, kn);
#endif
  for (; back <= window; ++back) {
    const int c = b - back;
    if (image.holes[c] != image.holes[b]) continue;
    kw = std::min(kw, int32_t((sad48(image, c, ref) << kBackBits) | back));
    if (four && image.four[c]) kn = std::min(kn, int32_t((sad16(image.pos[c], image.pos[b]) << kBackBits) | back));
  }
  const auto source = [b](int32_t key) { return key == kNoKey ? -1 : b - int(key & ((1 << kBackBits) - 1)); };
  return {source(kw), source(kn)};
}

}  // namespace

void rdo_albedo_blocks(const uint8_t* rgba, float lambda, uint8_t* blocks, RdoCounts* counts) {
  if (!(lambda > 0)) return;
  constexpr int kBytes = 8;
  constexpr int kBlocks = kBlocksX * kBlocksX;
  RdoCounts n;
  static thread_local DecodedAlbedo image;
  // Reference colours with hole texels at 0 (a source must have the same transparency mask, so
  // those texels decode to 0 on both sides and add nothing), and the plain blocks' squared error.
  static thread_local uint8_t refs[kBlocks][48];
  static thread_local int plain_sse[kBlocks];
  const auto inner = [](int bx, int by) { return bx > 0 && by > 0 && bx < kBlocksX - 1 && by < kBlocksX - 1; };
  int64_t total = 0;
  for (int by = 0; by < kBlocksX; ++by)
    for (int bx = 0; bx < kBlocksX; ++bx) {
      const int b = by * kBlocksX + bx;
      decode_colour_for_rdo(blocks + size_t(b) * kBytes, image, b);
      if (!inner(bx, by)) continue;
      uint8_t* ref = refs[b];
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) {
          const uint8_t* t = rgba + (size_t(by * 4 + r) * kTexels + size_t(bx * 4 + c)) * 4;
          for (int k = 0; k < 3; ++k) ref[(r * 4 + c) * 3 + k] = t[3] < 128 ? 0 : t[k];
        }
      plain_sse[b] = sse48(image, b, ref);
      total += plain_sse[b];
    }
  // The node's squared error may grow by kAlbedoBudget of the plain encoding's in all: its PSNR
  // drops by at most 10 log10(1 + kAlbedoBudget) dB however large lambda is.
  int64_t budget = int64_t(std::floor(double(total) * kAlbedoBudget));
  for (int by = 0; by < kBlocksX; ++by)
    for (int bx = 0; bx < kBlocksX; ++bx) {
      if (!inner(bx, by)) continue;
      const int b = by * kBlocksX + bx;
      uint8_t* own = blocks + size_t(b) * kBytes;
      const uint8_t* ref = refs[b];
      ++n.blocks;
      const int own_e = plain_sse[b];
      const ColourScan scan = scan_colour_sources(image, b, ref);
      // Options: own (8 literals), the nearest earlier block whole (a match), own endpoints with
      // the nearest source's selectors (4 literals and a match); the least cost among those the
      // remaining budget allows.
      float best_j = float(own_e) + lambda * 8.0f;
      int best_e = own_e;
      uint8_t best[8];
      std::memcpy(best, own, 8);
      int kind = 0;
      const auto consider = [&](const uint8_t* cand, int e, float bytes, int k) {
        const float j = float(e) + lambda * bytes;
        if (j < best_j && e - own_e <= budget)
          best_j = j, best_e = e, std::memcpy(best, cand, 8), kind = k;
      };
      if (scan.whole >= 0)
        consider(blocks + size_t(scan.whole) * kBytes, sse48(image, scan.whole, ref), kMatchBytes, 1);
      if (scan.near >= 0) {
        uint8_t trial[8];
        std::memcpy(trial, own, 4);
        std::memcpy(trial + 4, blocks + size_t(scan.near) * kBytes + 4, 4);
        DecodedColour t;
        decode_colour_for_rdo(trial, t);
        consider(trial, sse48(t.rgb, ref), 4.0f + kMatchBytes, 2);
      }
      if (kind != 0) {
        std::memcpy(own, best, 8);
        decode_colour_for_rdo(own, image, b);
        budget -= best_e - own_e;
      }
      n.half_copies += uint64_t(kind == 1);
      n.index_copies += uint64_t(kind == 2);
    }
  if (counts) {
    counts->blocks += n.blocks;
    counts->half_copies += n.half_copies;
    counts->index_copies += n.index_copies;
  }
}

}  // namespace terrain::cook
