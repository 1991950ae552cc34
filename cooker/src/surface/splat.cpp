// Splat rules evaluation and the baked albedo.
#include "splat.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "avx2_clones.h"
#include "fast_math.h"
#include "noise.h"

namespace terrain::cook {
namespace {

constexpr double kRadToDeg = 57.29577951308232;

inline float wh(const float* h, int i, int j) {
  return h[size_t((j + kWindowMargin) * kWindowSize + (i + kWindowMargin))];
}

// sRGB <-> linear tables (exact sRGB transfer function).
struct SrgbTables {
  float to_linear[256];
  uint8_t to_srgb[4096];
  SrgbTables() {
    for (int i = 0; i < 256; ++i) {
      const double c = i / 255.0;
      to_linear[i] = float(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
    }
    for (int i = 0; i < 4096; ++i) {
      const double l = (i + 0.5) / 4096.0;
      const double c = l <= 0.0031308 ? l * 12.92 : 1.055 * std::pow(l, 1 / 2.4) - 0.055;
      to_srgb[i] = uint8_t(std::clamp(std::lround(c * 255.0), 0L, 255L));
    }
  }
};
const SrgbTables& srgb() {
  static const SrgbTables t;
  return t;
}
inline uint8_t linear_to_srgb8(float l) {
  return srgb().to_srgb[std::clamp(int(l * 4096.0f), 0, 4095)];
}

// Compass bearing (degrees, 0 = north, clockwise) of the vector (east, north).
double bearing_deg(double east, double north) {
  const double ae = std::fabs(east), an = std::fabs(north);
  if (ae == 0 && an == 0) return 0.0;
  double a = fast_atan(ae / an) * kRadToDeg;  // angle from north toward east, 0..90 (an may be 0: inf -> 90)
  if (an == 0) a = 90.0;
  if (north < 0) a = 180.0 - a;
  if (east < 0) a = 360.0 - a;
  return a >= 360.0 ? a - 360.0 : a;
}

// Albedo variation field: wavelength 48 m or 6 vertex spacings, whichever is longer.
constexpr uint32_t kAlbedoNoiseSeed = 0xA1BED0u;

}  // namespace

namespace {

// Horn's 3x3 gradient (as GDAL's slope) of vertex (i, j), whose height c is data; falls back to
// central, then one-sided differences.
void field_gradient(const float* h, int i, int j, double s, float c, double& gx, double& gy) {
  float z[3][3];
  bool full = true;
  for (int b = -1; b <= 1; ++b)
    for (int a = -1; a <= 1; ++a) {
      z[b + 1][a + 1] = wh(h, i + a, j + b);
      full = full && !std::isnan(z[b + 1][a + 1]);
    }
  if (full) {
    gx = ((z[0][2] + 2.0 * z[1][2] + z[2][2]) - (z[0][0] + 2.0 * z[1][0] + z[2][0])) / (8 * s);
    gy = ((z[2][0] + 2.0 * z[2][1] + z[2][2]) - (z[0][0] + 2.0 * z[0][1] + z[0][2])) / (8 * s);
    return;
  }
  auto one_axis = [&](float m, float p) {
    if (!std::isnan(m) && !std::isnan(p)) return (double(p) - m) / (2 * s);
    if (!std::isnan(p)) return (double(p) - c) / s;
    if (!std::isnan(m)) return (double(c) - m) / s;
    return 0.0;
  };
  gx = one_axis(z[1][0], z[1][2]);
  gy = one_axis(z[0][1], z[2][1]);
}

// Laplacian over +-2 spacings (the splat spacing) of vertex (i, j) with height c; missing
// neighbours contribute nothing.
double field_curvature(const float* h, int i, int j, double s, float c) {
  const float e = wh(h, i + 2, j), w = wh(h, i - 2, j), n = wh(h, i, j + 2), so = wh(h, i, j - 2);
  double lap = 0;
  int terms = 0;
  if (!std::isnan(e) && !std::isnan(w)) { lap += double(e) + w - 2.0 * c; ++terms; }
  if (!std::isnan(n) && !std::isnan(so)) { lap += double(n) + so - 2.0 * c; ++terms; }
  return terms ? lap * (2.0 / terms) / (4 * s * s) : 0.0;
}

}  // namespace

// Attributes of vertex (i, j) read from a window-shaped field h (raw or filtered heights).
bool measure_field(const SurfaceInput& in, const float* h, int i, int j, SurfaceSample& out, unsigned needs) {
  const double s = in.spacing_m;
  out.x_m = in.x0_m + i * s;
  out.y_m = in.y0_m + j * s;
  const float c = wh(h, i, j);
  if (std::isnan(c)) return false;
  out.height_m = c;
  double gx = 0, gy = 0;
  field_gradient(h, i, j, s, c, gx, gy);
  out.slope_deg = fast_atan(std::sqrt(gx * gx + gy * gy)) * kRadToDeg;
  if (needs & kNeedAspect) out.aspect_deg = bearing_deg(-gx, -gy);  // the downhill direction
  if (needs & kNeedCurvature) out.curvature = field_curvature(h, i, j, s, c);
  return true;
}

namespace {

// The ids are first computed on the lattice with two more rings (vertices -6 .. 134, element
// (k, l) = vertex (2k - 6, 2l - 6)) so the two despeckle passes see every neighbour they read.
constexpr int kWide = kLatticeRow;  // 71
constexpr int kFirstVertex = -6;
// Measuring a lattice vertex reads the field 2 vertices out (curvature), the field reads the raw
// heights kMaxFilterRadius out: -6 - 2 - kMaxFilterRadius >= -kWindowMargin.
constexpr int kFieldReach = 2 - kFirstVertex;  // 8
constexpr int kMaxFilterRadius = kWindowMargin - kFieldReach;  // 10
static_assert(kMaxFilterRadius >= 2, "the window margin leaves no room for the splat filters");

// dst[i] = sum over d = 0 .. taps - 1, in that order from +0, of w[d] * src[i + d * tap_stride]:
// one tap run per output. 16 outputs' sums stay in registers over all the taps (GCC's vector
// extensions: two AVX2 registers in the AVX2 clone, four SSE2 ones otherwise; the same operations
// per output, so the same floats) instead of a pass over the row per tap.
TERRAIN_AVX2_CLONES void weighted_sums(const float* src, ptrdiff_t tap_stride, const float* w, int taps, int n,
                                       float* dst) {
  typedef float V8f __attribute__((vector_size(32)));
  int i = 0;
  for (; i + 16 <= n; i += 16) {
    V8f a = {}, b = {};
    const float* p = src + i;
    for (int d = 0; d < taps; ++d, p += tap_stride) {
      const V8f wd = {w[d], w[d], w[d], w[d], w[d], w[d], w[d], w[d]};
      V8f x, y;
      std::memcpy(&x, p, sizeof x);
      std::memcpy(&y, p + 8, sizeof y);
      a += wd * x;
      b += wd * y;
    }
    std::memcpy(dst + i, &a, sizeof a);
    std::memcpy(dst + i + 8, &b, sizeof b);
  }
  for (; i < n; ++i) {
    float a = 0.0f;
    for (int d = 0; d < taps; ++d) a += w[d] * src[i + d * tap_stride];
    dst[i] = a;
  }
}

// Gaussian-filtered heights (sigma = scale_m, in metres) over the vertices the lattice measures:
// a normalized convolution (missing taps drop out; a vertex without data stays NaN), separable,
// fixed summation order, so the bits are the same on every thread and in every node that shares
// the vertex. The radius is 2 sigma, capped by the window margin (sigma is then radius / 2), so at
// fine levels the largest scale is kMaxFilterRadius / 2 spacings. Returns false (use the raw
// heights) when sigma is under half a spacing.
}  // namespace

bool filter_heights(const float* h, double scale_m, double spacing_m, std::vector<float>& out) {
  double sigma = scale_m / spacing_m;
  if (sigma < 0.5) return false;
  int radius = int(std::ceil(2.0 * sigma));
  if (radius > kMaxFilterRadius) {
    radius = kMaxFilterRadius;
    sigma = radius / 2.0;
  }
  float w[2 * kMaxFilterRadius + 1];
  for (int d = -radius; d <= radius; ++d) w[d + radius] = float(std::exp(-0.5 * d * d / (sigma * sigma)));
  const int lo = -kFieldReach, hi = kHeightSamples - 1 + kFieldReach;  // vertices -8 .. 136
  constexpr int kSpan = kHeightSamples + 2 * kFieldReach;             // 145 vertices per row
  // Only lo..hi of `out` is written (the lattice reads nothing else); the rest stays NaN.
  if (out.size() != size_t(kWindowCount)) out.assign(size_t(kWindowCount), NAN);
  static thread_local std::vector<float> sum, weight;  // horizontal pass, rows lo - radius .. hi + radius
  sum.resize(size_t(kWindowCount));
  weight.resize(size_t(kWindowCount));
  const auto at = [](int i, int j) { return size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin); };
  // Weight sum of a tap run with data everywhere, accumulated in the per-tap order of the general path.
  float wsum = 0;
  for (int d = -radius; d <= radius; ++d) wsum += w[d + radius];
  // Every accumulation below runs its taps in the order d = -radius .. radius from 0, as the plain
  // per-vertex loops did, so the sums are the same floats; loops over i (independent vertices) let
  // the compiler use SIMD without reordering any one sum.
  // A tap without data adds w * 0 to the sum and w * 0 to the weight: adding +0 leaves a float
  // unchanged (the sums start at +0 and can never be -0), so this is the skip of the plain loop.
  constexpr int kRun = kSpan + 2 * kMaxFilterRadius;
  float vals[kRun], ones[kRun];
  bool all_full = true;
  for (int j = lo - radius; j <= hi + radius; ++j) {
    const float* row = h + at(lo - radius, j);
    const int n = kSpan + 2 * radius;
    int missing = 0;
    for (int i = 0; i < n; ++i) {
      const bool bad = std::isnan(row[i]);
      missing += bad;
      vals[i] = bad ? 0.0f : row[i];
      ones[i] = bad ? 0.0f : 1.0f;
    }
    float* sv = &sum[at(lo, j)];
    float* sw = &weight[at(lo, j)];
    weighted_sums(vals, 1, w, 2 * radius + 1, kSpan, sv);
    if (missing == 0) {
      for (int i = 0; i < kSpan; ++i) sw[i] = wsum;
      continue;
    }
    all_full = false;
    weighted_sums(ones, 1, w, 2 * radius + 1, kSpan, sw);
  }
  // Vertical pass. With data everywhere every vertex's weight is the same sum.
  float wtotal = 0;
  for (int d = 0; d <= 2 * radius; ++d) wtotal += w[d] * wsum;
  float acc[kSpan], accw[kSpan];
  for (int j = lo; j <= hi; ++j) {
    weighted_sums(&sum[at(lo, j - radius)], kWindowSize, w, 2 * radius + 1, kSpan, acc);
    if (!all_full) weighted_sums(&weight[at(lo, j - radius)], kWindowSize, w, 2 * radius + 1, kSpan, accw);
    const float* centre = h + at(lo, j);
    float* dst = &out[at(lo, j)];
    for (int i = 0; i < kSpan; ++i)
      dst[i] = std::isnan(centre[i]) ? NAN : acc[i] / (all_full ? wtotal : accw[i]);
  }
  return true;
}

namespace {

// Most common class material in the (2r+1)^2 box around window vertex (i, j); ties keep the
// centre's value when it is among the most common, else the lowest index. Shared boundaries of
// two classes become smooth curves at the rule scale instead of following the raster's pixels.
uint8_t mode_class(const uint8_t* classes, int i, int j, int r) {
  uint16_t count[256] = {};
  for (int b = -r; b <= r; ++b) {
    const uint8_t* row = classes + size_t((j + b + kWindowMargin) * kWindowSize + kWindowMargin);
    for (int a = -r; a <= r; ++a) ++count[row[i + a]];
  }
  const uint8_t centre = classes[size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin)];
  uint8_t best = centre;
  for (int v = 0; v < 256; ++v)
    if (count[v] > count[best]) best = uint8_t(v);
  return best;
}

// Despeckle rule for lattice element e: with fewer than `keep` neighbours (of the `n` in nb, those
// with data, at least `min_data` of them) holding its id, it takes the neighbours' most common id
// (ties: the first in nb's order), unless none is more common than its own.
uint8_t despeckled(const std::array<uint8_t, kWide * kWide>& ids, const std::array<uint8_t, kWide * kWide>& has,
                   size_t e, const size_t* nb, int n, int keep, int min_data) {
  const uint8_t own = ids[e];
  int same = 0, with_data = 0;
  for (int q = 0; q < n; ++q)
    if (has[nb[q]]) {
      ++with_data;
      same += ids[nb[q]] == own;
    }
  if (same >= keep || with_data < min_data) return own;
  uint8_t best = own;
  int best_count = same;
  for (int q = 0; q < n; ++q) {
    if (!has[nb[q]]) continue;
    int c = 0;
    for (int p = 0; p < n; ++p) c += has[nb[p]] && ids[nb[p]] == ids[nb[q]];
    if (c > best_count) best_count = c, best = ids[nb[q]];
  }
  return best;
}

// same[k], k = 1 .. kWide - 2, for the lattice row at ids / has (rows of kWide, with a row above
// and below): how many of the 4 edge neighbours (and with `diagonals` the 4 corner ones) have
// data (has is 0 or 1) and the id of element k. 16 elements at a time in GCC's vector extensions
// (the plain byte loop stayed scalar: its pointers may alias), the rest one by one.
void same_neighbours(const uint8_t* ids, const uint8_t* has, bool diagonals, uint8_t* same) {
  typedef uint8_t V16 __attribute__((vector_size(16)));
  const int offsets[8] = {kWide, 1, -kWide, -1, kWide + 1, kWide - 1, -kWide + 1, -kWide - 1};
  const int count = diagonals ? 8 : 4;
  constexpr int kVectorEnd = 1 + (kWide - 2) / 16 * 16;
  for (int k = 1; k < kVectorEnd; k += 16) {
    V16 own, sum = {};
    std::memcpy(&own, ids + k, sizeof own);
    for (int q = 0; q < count; ++q) {
      V16 other, other_has;
      std::memcpy(&other, ids + k + offsets[q], sizeof other);
      std::memcpy(&other_has, has + k + offsets[q], sizeof other_has);
      sum += V16(other == own) & other_has;
    }
    std::memcpy(same + k, &sum, sizeof sum);
  }
  for (int k = kVectorEnd; k + 1 < kWide; ++k) {
    int n = 0;
    for (int q = 0; q < count; ++q) n += (ids[k + offsets[q]] == ids[k]) & has[k + offsets[q]];
    same[k] = uint8_t(n);
  }
}

}  // namespace

// GCC's vector extensions, 4 lanes (an AVX2 register, two SSE2 ones): the auto-vectoriser turns
// fast_atan_select's select back into a branch around the division. Each lane does the scalar
// forms' operations in their order (no FMA: this file is built without contraction).
typedef double V4d __attribute__((vector_size(32)));
typedef int64_t V4l __attribute__((vector_size(32)));
constexpr int kLaneRow = (kLatticeRow + 3) / 4 * 4;  // a lattice row padded to whole lanes

#define SPLAT4(v) (V4d{(v), (v), (v), (v)})

// fast_atan_select of 4 lanes (out, not a return value: a V4d by value needs the AVX ABI).
inline void fast_atan_lanes(const V4d& x, V4d& out) {
  const V4l inv = x > SPLAT4(1.0);
  const V4d r = SPLAT4(1.0) / x;
  const V4d t = inv ? r : x;
  const V4d t2 = t * t;
  const V4d p = t * (SPLAT4(0.99997726) +
                     t2 * (SPLAT4(-0.33262347) +
                           t2 * (SPLAT4(0.19354346) + t2 * (SPLAT4(-0.11643287) + t2 * (SPLAT4(0.05265332) + t2 * SPLAT4(-0.01172120))))));
  out = inv ? SPLAT4(1.5707963267948966) - p : p;
}

// slope[k] = fast_atan_select(|(gx, gy)|) in degrees and, when wanted, aspect[k] =
// bearing_deg(-gx, -gy) (its operations on each path as selects), for k < kLaneRow.
TERRAIN_AVX2_CLONES void slope_aspect_lanes(const double* gx, const double* gy, bool aspect_too, double* slope,
                                            double* aspect) {
  double len[kLaneRow];
  for (int k = 0; k < kLaneRow; ++k) len[k] = std::sqrt(gx[k] * gx[k] + gy[k] * gy[k]);
  const V4d deg = SPLAT4(kRadToDeg), zero = SPLAT4(0.0);
  for (int k = 0; k < kLaneRow; k += 4) {
    V4d l, a;
    std::memcpy(&l, len + k, sizeof l);
    fast_atan_lanes(l, a);
    a *= deg;
    std::memcpy(slope + k, &a, sizeof a);
  }
  if (!aspect_too) return;
  const V4l abs_bits = {INT64_MAX, INT64_MAX, INT64_MAX, INT64_MAX};
  for (int k = 0; k < kLaneRow; k += 4) {
    V4d x, y;
    std::memcpy(&x, gx + k, sizeof x);
    std::memcpy(&y, gy + k, sizeof y);
    const V4d east = -x, north = -y;
    const V4d ae = V4d(V4l(east) & abs_bits), an = V4d(V4l(north) & abs_bits);  // fabs
    V4d a;
    fast_atan_lanes(ae / an, a);
    a *= deg;
    a = an == zero ? SPLAT4(90.0) : a;
    a = north < zero ? SPLAT4(180.0) - a : a;
    a = east < zero ? SPLAT4(360.0) - a : a;
    a = a >= SPLAT4(360.0) ? a - SPLAT4(360.0) : a;
    a = ((ae == zero) & (an == zero)) ? zero : a;
    std::memcpy(aspect + k, &a, sizeof a);
  }
}
#undef SPLAT4

bool measure_sample(const SurfaceInput& in, int i, int j, SurfaceSample& out) {
  return measure_field(in, in.heights_m, i, j, out, kNeedAll);
}

void measure_lattice_row(const SurfaceInput& in, const float* h, int j, unsigned needs, SurfaceSample* out,
                         uint8_t* ok) {
  const double s = in.spacing_m;
  const float* row = h + size_t((j + kWindowMargin) * kWindowSize + kWindowMargin);  // vertex (0, j)
  const float* below = row - kWindowSize;
  const float* above = row + kWindowSize;
  // Horn's gradient of every element, branch-free. Each of the 8 neighbours appears in gx or gy,
  // so a missing one makes one of them NaN: exactly the elements field_gradient sends to its
  // fallback, which they then take.
  alignas(32) double gx[kLaneRow] = {}, gy[kLaneRow] = {}, slope[kLaneRow], aspect[kLaneRow];
  for (int k = 0; k < kLatticeRow; ++k) {
    const int i = 2 * k + kFirstVertex;
    const float z00 = below[i - 1], z01 = below[i], z02 = below[i + 1];
    const float z10 = row[i - 1], z12 = row[i + 1];
    const float z20 = above[i - 1], z21 = above[i], z22 = above[i + 1];
    gx[k] = ((z02 + 2.0 * z12 + z22) - (z00 + 2.0 * z10 + z20)) / (8 * s);
    gy[k] = ((z20 + 2.0 * z21 + z22) - (z00 + 2.0 * z01 + z02)) / (8 * s);
  }
  for (int k = 0; k < kLatticeRow; ++k) {
    const int i = 2 * k + kFirstVertex;
    ok[k] = !std::isnan(row[i]);
    if (!ok[k])
      gx[k] = gy[k] = 0;  // not measured (keeps the loops below free of NaN)
    else if (std::isnan(gx[k]) || std::isnan(gy[k]))
      field_gradient(h, i, j, s, row[i], gx[k], gy[k]);
  }
  // Slope and aspect in vector lanes: the same doubles as fast_atan, bearing_deg.
  slope_aspect_lanes(gx, gy, (needs & kNeedAspect) != 0, slope, aspect);
  for (int k = 0; k < kLatticeRow; ++k) {
    const int i = 2 * k + kFirstVertex;
    SurfaceSample& o = out[k];
    o = SurfaceSample{};
    o.x_m = in.x0_m + i * s;
    o.y_m = in.y0_m + j * s;
    if (!ok[k]) continue;
    o.height_m = row[i];
    o.slope_deg = slope[k];
    if (needs & kNeedAspect) o.aspect_deg = aspect[k];
    if (needs & kNeedCurvature) o.curvature = field_curvature(h, i, j, s, row[i]);
  }
}

void compute_splat_lattice(const SurfaceInput& in, const MaterialRules& rules, SplatLattice& out,
                           double* fields_seconds) {
  // One height field per distinct rule scale (index 0.. of rules.scales).
  static thread_local std::vector<float> fields[kMaxRuleScales];
  const float* field[kMaxRuleScales] = {};
  const size_t scales = rules.scales.size();
  const double t0 = fields_seconds ? thread_cpu_seconds() : 0.0;
  for (size_t k = 0; k < scales; ++k)
    field[k] = filter_heights(in.heights_m, rules.scales[k], in.spacing_m, fields[k]) ? fields[k].data() : in.heights_m;
  if (fields_seconds) *fields_seconds = thread_cpu_seconds() - t0;
  // Per scale, the attributes some rule at that scale reads (e.g. the built-in 1 m cliff rule only
  // reads slope): the others are not measured.
  unsigned needs[kMaxRuleScales] = {};
  for (const MaterialRule& r : rules.rules)
    needs[r.scale_index] |= (r.aspect_deg.active ? kNeedAspect : 0u) | (r.curvature.active ? kNeedCurvature : 0u);
  // Class raster (--landcover): mode filter over the document scale (one radius per level).
  const int class_radius = std::min(kWindowMargin + kFirstVertex,
                                    int(std::lround(rules.scale_m / in.spacing_m)));
  std::array<uint8_t, kWide * kWide> wide;
  std::array<uint8_t, kWide * kWide> has{};
  // Each lattice row measured per scale at once (measure_lattice_row: measure_field's values).
  SurfaceSample measured[kMaxRuleScales][kWide];
  uint8_t measured_ok[kMaxRuleScales][kWide];
  // The rules' choice for every element of a row at once (choose_materials_row), from the
  // measures laid out an array per attribute.
  static_assert(kWide <= kMaxRowSamples);
  double attr[kMaxRuleScales][4][kWide];
  SampleRow rows[kMaxRuleScales];
  for (size_t s = 0; s < scales; ++s) rows[s] = SampleRow{attr[s][0], attr[s][1], attr[s][2], attr[s][3]};
  double x_m[kWide];
  uint8_t chosen[kWide];
  const double min_noise_wavelength_m = rules.band_limit_noise ? 4.0 * in.spacing_m : 0.0;
  for (int l = 0; l < kWide; ++l) {
    const int j = 2 * l + kFirstVertex;
    for (size_t s = 0; s < scales; ++s) {
      measure_lattice_row(in, field[s], j, needs[s], measured[s], measured_ok[s]);
      for (int k = 0; k < kWide; ++k) {
        const SurfaceSample& m = measured[s][k];
        attr[s][0][k] = m.height_m;
        attr[s][1][k] = m.slope_deg;
        attr[s][2][k] = m.curvature;
        attr[s][3][k] = m.aspect_deg;
      }
    }
    // Elements with data in every field: the ones whose choice is used.
    uint8_t data[kWide];
    for (int k = 0; k < kWide; ++k) {
      const int i = 2 * k + kFirstVertex;
      data[k] = !std::isnan(wh(in.heights_m, i, j));
      for (size_t s = 0; s < scales && data[k]; ++s) data[k] = measured_ok[s][k] != 0;
    }
    if (scales > 0) {
      for (int k = 0; k < kWide; ++k) x_m[k] = measured[0][k].x_m;
      choose_materials_row(rules, rows, x_m, measured[0][0].y_m, min_noise_wavelength_m, kWide, data, chosen);
    }
    for (int k = 0; k < kWide; ++k) {
      const int i = 2 * k + kFirstVertex;
      const size_t e = size_t(l * kWide + k);
      has[e] = data[k];
      if (!data[k]) {
        wide[e] = rules.default_material;
        continue;
      }
      // A class raster's material (--landcover) wins over the rules where it has one.
      uint8_t cls = kNoClassMaterial;
      if (in.class_materials)
        cls = class_radius > 0 ? mode_class(in.class_materials, i, j, class_radius)
                               : in.class_materials[size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin)];
      if (cls != kNoClassMaterial && cls < rules.palette.size()) {
        wide[e] = cls;
      } else if (scales == 0) {
        wide[e] = rules.default_material;
      } else {
        wide[e] = chosen[k];
      }
    }
  }
  if (!rules.despeckle) {
    for (int l = 0; l < kSplatLattice; ++l)
      for (int k = 0; k < kSplatLattice; ++k) out.ids[size_t(l * kSplatLattice + k)] = wide[size_t((l + 2) * kWide + k + 2)];
    return;
  }
  despeckle_lattice(wide.data(), has.data(), out.ids.data());
}

// Pass 1 (lattice elements 1 .. 69): a sample with fewer than 2 of its own id among its 8
// neighbours with data (a speck, a pair, a line's loose end) takes their most common id (ties: the
// first in the order N, E, S, W, NE, NW, SE, SW). Along a line one sample wide each sample has 2.
// Pass 2 (the 67x67 lattice): a sample unlike each of its 4 neighbours with data (at least 2)
// takes their most common id (ties: N, E, S, W).
template <bool kCountFirst>
void despeckle_passes(const uint8_t* wide_ids, const uint8_t* has_data, uint8_t* ids) {
  std::array<uint8_t, kWide * kWide> wide, has;
  std::copy(wide_ids, wide_ids + wide.size(), wide.begin());
  std::copy(has_data, has_data + has.size(), has.begin());
  std::array<uint8_t, kWide * kWide> pass = wide;
  uint8_t same[kWide] = {};
  for (int l = 1; l + 1 < kWide; ++l) {
    const size_t row = size_t(l * kWide);
    if (kCountFirst) same_neighbours(wide.data() + row, has.data() + row, true, same);
    for (int k = 1; k + 1 < kWide; ++k) {
      const size_t e = row + size_t(k);
      if (!has[e] || (kCountFirst && same[k] >= 2)) continue;
      const size_t nb[8] = {e + kWide, e + 1, e - kWide, e - 1, e + kWide + 1, e + kWide - 1, e - kWide + 1, e - kWide - 1};
      pass[e] = despeckled(wide, has, e, nb, 8, 2, 4);
    }
  }
  for (int l = 0; l < kSplatLattice; ++l) {
    const size_t row = size_t((l + 2) * kWide);
    if (kCountFirst) same_neighbours(pass.data() + row, has.data() + row, false, same);
    for (int k = 0; k < kSplatLattice; ++k) {
      const size_t e = row + size_t(k + 2);
      const size_t nb[4] = {e + kWide, e + 1, e - kWide, e - 1};
      const bool check = has[e] && (!kCountFirst || same[k + 2] == 0);
      ids[size_t(l * kSplatLattice + k)] = check ? despeckled(pass, has, e, nb, 4, 1, 2) : pass[e];
    }
  }
}

// The passes first count, a row at a time in vector code, the neighbours with data that share a
// sample's id: despeckled keeps the id of any sample with enough of them, so only the others go
// through it.
void despeckle_lattice(const uint8_t* wide, const uint8_t* has, uint8_t* ids) {
  despeckle_passes<true>(wide, has, ids);
}
void despeckle_lattice_per_sample(const uint8_t* wide, const uint8_t* has, uint8_t* ids) {
  despeckle_passes<false>(wide, has, ids);
}

void copy_node_splat(const SplatLattice& lattice, std::array<uint8_t, kSplatCount>& splat) {
  for (int j = 0; j < kSplatSamples; ++j)
    for (int i = 0; i < kSplatSamples; ++i)
      splat[size_t(j * kSplatSamples + i)] = lattice.ids[size_t((j + 1) * kSplatLattice + i + 1)];
}

void bake_albedo(const SurfaceInput& in, const MaterialRules& rules, const SplatLattice& lattice, uint8_t* rgba) {
  const SrgbTables& tab = srgb();
  const double s = in.spacing_m;
  if (in.albedo_rgb) {
    // Orthophoto: mean of the cell's four corner colours, in linear light.
    for (int u = 0; u < kTexels; ++u)
      for (int t = 0; t < kTexels; ++t) {
        const int a = t - kApron + kWindowMargin, b = u - kApron + kWindowMargin;
        const size_t k = size_t(u * kTexels + t);
        for (int c = 0; c < 3; ++c) {
          float sum = 0;
          for (int db = 0; db <= 1; ++db)
            for (int da = 0; da <= 1; ++da)
              sum += tab.to_linear[in.albedo_rgb[size_t((b + db) * kWindowSize + a + da) * 3 + size_t(c)]];
          rgba[k * 4 + size_t(c)] = linear_to_srgb8(sum * 0.25f);
        }
      }
  } else {
    // Linear colour per lattice sample, with the material's gentle world-space variation.
    static thread_local std::array<float, kSplatLattice * kSplatLattice * 3> lin;
    const double scale = std::max(48.0, 6.0 * s);
    static thread_local NoiseRowTables noise_tables;
    double x[kSplatLattice], noise[kSplatLattice];
    for (int k = 0; k < kSplatLattice; ++k) x[k] = in.x0_m + (2 * k - 2) * s;
    for (int l = 0; l < kSplatLattice; ++l) {
      const double y = in.y0_m + (2 * l - 2) * s;
      fbm_noise_row(x, nullptr, kSplatLattice, y, scale, 2, kAlbedoNoiseSeed, 0.0, noise_tables, noise);  // fbm_noise's bits
      for (int k = 0; k < kSplatLattice; ++k) {
        const size_t e = size_t(l * kSplatLattice + k);
        const Material& m = rules.palette[lattice.ids[e]];
        const double v = 1.0 + m.detail_strength * 0.5 * noise[k];
        for (int c = 0; c < 3; ++c) lin[e * 3 + size_t(c)] = float(tab.to_linear[m.albedo_srgb[size_t(c)]] * v);
      }
    }
    // Texel (t, u) centre is at vertex coordinate (t - 1.5, u - 1.5) = lattice (t + 0.5) / 2:
    // lattice t / 2 with weight 1/4 (t even) or 3/4 (t odd) toward the next sample. Rows first
    // (one vertical blend per lattice column), then the horizontal blend per texel.
    // Texels 2k (1/4) and 2k + 1 (3/4) blend lattice samples k and k + 1 of the row, per channel
    // (planar rows, so SSE2 blends and converts 4 samples' texel pairs at a time: the same float
    // operations, then the same table).
    static_assert(kTexels == 2 * (kSplatLattice - 1));
    float row[3][kSplatLattice];
    int16_t index[2][kSplatLattice];  // sRGB table entries of texels 2k and 2k + 1
    for (int u = 0; u < kTexels; ++u) {
      const int l0 = u / 2;
      const float fy = (u % 2 == 0) ? 0.25f : 0.75f;
      const float* a = &lin[size_t(l0 * kSplatLattice) * 3];
      const float* b = &lin[size_t((l0 + 1) * kSplatLattice) * 3];
      for (int k = 0; k < kSplatLattice; ++k)
        for (int c = 0; c < 3; ++c) row[c][k] = a[3 * k + c] + fy * (b[3 * k + c] - a[3 * k + c]);
      uint8_t* dst = rgba + size_t(u * kTexels) * 4;
      for (int c = 0; c < 3; ++c) {
        const float* r = row[c];
        int k = 0;
#if defined(__SSE2__)
        const __m128 quarter = _mm_set1_ps(0.25f), three_quarters = _mm_set1_ps(0.75f), steps = _mm_set1_ps(4096.0f);
        const __m128i top = _mm_set1_epi16(4095), zero = _mm_setzero_si128();
        for (; k + 8 <= kSplatLattice - 1; k += 8) {
          __m128i even[2], odd[2];
          for (int h = 0; h < 2; ++h) {
            const __m128 v0 = _mm_loadu_ps(r + k + 4 * h), v1 = _mm_loadu_ps(r + k + 4 * h + 1);
            const __m128 d = _mm_sub_ps(v1, v0);
            even[h] = _mm_cvttps_epi32(_mm_mul_ps(_mm_add_ps(v0, _mm_mul_ps(quarter, d)), steps));
            odd[h] = _mm_cvttps_epi32(_mm_mul_ps(_mm_add_ps(v0, _mm_mul_ps(three_quarters, d)), steps));
          }
          // Saturating to 16 bits, then clamping, is the clamp of the 32-bit values.
          const __m128i e = _mm_min_epi16(_mm_max_epi16(_mm_packs_epi32(even[0], even[1]), zero), top);
          const __m128i o = _mm_min_epi16(_mm_max_epi16(_mm_packs_epi32(odd[0], odd[1]), zero), top);
          _mm_storeu_si128(reinterpret_cast<__m128i*>(&index[0][k]), e);
          _mm_storeu_si128(reinterpret_cast<__m128i*>(&index[1][k]), o);
        }
#endif
        for (; k < kSplatLattice - 1; ++k) {
          const float v0 = r[k], v1 = r[k + 1];
          index[0][k] = int16_t(std::clamp(int((v0 + 0.25f * (v1 - v0)) * 4096.0f), 0, 4095));
          index[1][k] = int16_t(std::clamp(int((v0 + 0.75f * (v1 - v0)) * 4096.0f), 0, 4095));
        }
        for (k = 0; k < kSplatLattice - 1; ++k) {
          dst[8 * k + c] = tab.to_srgb[index[0][k]];
          dst[8 * k + 4 + c] = tab.to_srgb[index[1][k]];
        }
      }
    }
  }
  // Alpha: texel (t, u) carries the hole flag of vertex (t - 2, u - 2).
  for (int u = 0; u < kTexels; ++u)
    for (int t = 0; t < kTexels; ++t) {
      const bool hole = in.holes && in.holes[size_t((u - kApron + kWindowMargin) * kWindowSize + t - kApron + kWindowMargin)];
      rgba[size_t(u * kTexels + t) * 4 + 3] = hole ? 0 : 255;
    }
}

}  // namespace terrain::cook
