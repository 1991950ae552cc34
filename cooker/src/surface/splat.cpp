// Splat rules evaluation and the baked albedo.
#include "splat.h"

#include <algorithm>
#include <cmath>

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

bool measure_sample(const SurfaceInput& in, int i, int j, SurfaceSample& out) {
  const float* h = in.heights_m;
  const double s = in.spacing_m;
  out.x_m = in.x0_m + i * s;
  out.y_m = in.y0_m + j * s;
  const float c = wh(h, i, j);
  if (std::isnan(c)) return false;
  out.height_m = c;
  // Horn's 3x3 gradient (as GDAL's slope); falls back to central, then one-sided differences.
  float z[3][3];
  bool full = true;
  for (int b = -1; b <= 1; ++b)
    for (int a = -1; a <= 1; ++a) {
      z[b + 1][a + 1] = wh(h, i + a, j + b);
      full = full && !std::isnan(z[b + 1][a + 1]);
    }
  double gx = 0, gy = 0;
  if (full) {
    gx = ((z[0][2] + 2.0 * z[1][2] + z[2][2]) - (z[0][0] + 2.0 * z[1][0] + z[2][0])) / (8 * s);
    gy = ((z[2][0] + 2.0 * z[2][1] + z[2][2]) - (z[0][0] + 2.0 * z[0][1] + z[0][2])) / (8 * s);
  } else {
    auto one_axis = [&](float m, float p) {
      if (!std::isnan(m) && !std::isnan(p)) return (double(p) - m) / (2 * s);
      if (!std::isnan(p)) return (double(p) - c) / s;
      if (!std::isnan(m)) return (double(c) - m) / s;
      return 0.0;
    };
    gx = one_axis(z[1][0], z[1][2]);
    gy = one_axis(z[0][1], z[2][1]);
  }
  out.slope_deg = fast_atan(std::sqrt(gx * gx + gy * gy)) * kRadToDeg;
  out.aspect_deg = bearing_deg(-gx, -gy);  // the downhill direction
  // Laplacian over +-2 spacings (the splat spacing); missing neighbours contribute nothing.
  const float e = wh(h, i + 2, j), w = wh(h, i - 2, j), n = wh(h, i, j + 2), so = wh(h, i, j - 2);
  double lap = 0;
  int terms = 0;
  if (!std::isnan(e) && !std::isnan(w)) { lap += double(e) + w - 2.0 * c; ++terms; }
  if (!std::isnan(n) && !std::isnan(so)) { lap += double(n) + so - 2.0 * c; ++terms; }
  out.curvature = terms ? lap * (2.0 / terms) / (4 * s * s) : 0.0;
  return true;
}

void compute_splat_lattice(const SurfaceInput& in, const MaterialRules& rules, SplatLattice& out) {
  for (int l = 0; l < kSplatLattice; ++l)
    for (int k = 0; k < kSplatLattice; ++k) {
      SurfaceSample s;
      const bool has = measure_sample(in, 2 * k - 2, 2 * l - 2, s);
      // A class raster's material (--landcover) wins over the rules where it has one.
      const uint8_t cls = in.class_materials
                              ? in.class_materials[size_t((2 * l - 2 + kWindowMargin) * kWindowSize + 2 * k - 2 + kWindowMargin)]
                              : kNoClassMaterial;
      out.ids[size_t(l * kSplatLattice + k)] =
          !has ? rules.default_material : cls != kNoClassMaterial && cls < rules.palette.size() ? cls : choose_material(rules, s);
    }
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
    for (int l = 0; l < kSplatLattice; ++l)
      for (int k = 0; k < kSplatLattice; ++k) {
        const size_t e = size_t(l * kSplatLattice + k);
        const Material& m = rules.palette[lattice.ids[e]];
        const double x = in.x0_m + (2 * k - 2) * s, y = in.y0_m + (2 * l - 2) * s;
        const double v = 1.0 + m.detail_strength * 0.5 * fbm_noise(x, y, scale, 2, kAlbedoNoiseSeed);
        for (int c = 0; c < 3; ++c) lin[e * 3 + size_t(c)] = float(tab.to_linear[m.albedo_srgb[size_t(c)]] * v);
      }
    // Texel (t, u) centre is at vertex coordinate (t - 1.5, u - 1.5) = lattice (t + 0.5) / 2:
    // lattice t / 2 with weight 1/4 (t even) or 3/4 (t odd) toward the next sample. Rows first
    // (one vertical blend per lattice column), then the horizontal blend per texel.
    float row[kSplatLattice * 3];
    for (int u = 0; u < kTexels; ++u) {
      const int l0 = u / 2;
      const float fy = (u % 2 == 0) ? 0.25f : 0.75f;
      const float* a = &lin[size_t(l0 * kSplatLattice) * 3];
      const float* b = &lin[size_t((l0 + 1) * kSplatLattice) * 3];
      for (int e = 0; e < kSplatLattice * 3; ++e) row[e] = a[e] + fy * (b[e] - a[e]);
      uint8_t* dst = rgba + size_t(u * kTexels) * 4;
      for (int t = 0; t < kTexels; ++t) {
        const int k0 = t / 2;
        const float fx = (t % 2 == 0) ? 0.25f : 0.75f;
        for (int c = 0; c < 3; ++c) {
          const float v0 = row[k0 * 3 + c], v1 = row[(k0 + 1) * 3 + c];
          dst[t * 4 + c] = linear_to_srgb8(v0 + fx * (v1 - v0));
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
