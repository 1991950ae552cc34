// Deterministic world-space value noise (fBm) for splat transitions and albedo variation.
// A pure function of (x, y, seed): every node, level and thread sees the same field, so material
// boundaries perturbed by it stay seamless across node edges.
#pragma once
#include <cmath>
#include <cstdint>
#include <vector>

namespace terrain::cook {

// 32-bit integer hash of a lattice point (lowbias32-style finaliser): no tables, no state.
inline uint32_t lattice_hash(int64_t ix, int64_t iy, uint32_t seed) {
  const uint64_t k = (uint64_t(ix) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(iy) * 0xC2B2AE3D27D4EB4Full) ^ seed;
  uint32_t h = uint32_t(k ^ (k >> 29));
  h ^= h >> 16; h *= 0x7feb352du;
  h ^= h >> 15;
  return h;
}

// Value in [-1, 1] at a lattice point.
inline double lattice_value(int64_t ix, int64_t iy, uint32_t seed) {
  return double(lattice_hash(ix, iy, seed)) * (2.0 / 4294967295.0) - 1.0;
}

// Smoothly interpolated value noise, period-free, in [-1, 1]; u, v in lattice units.
// floor() without a libm call on baseline x86-64 (exact for |x| < 2^62).
inline double fast_floor(double x) {
  const double t = double(int64_t(x));
  return t > x ? t - 1.0 : t;
}

// The four corner values of the last cell seen per seed slot: the cooker walks its lattices row by
// row at spacings far below the noise wavelengths (1 m against 12-90 m at level 0), so most calls
// land in the cell of the call before and skip the four hashes. The values are the same either way.
struct NoiseCell {
  int64_t iu = 0, iv = 0;
  uint32_t seed = 0;
  bool valid = false;
  double a = 0, b = 0, c = 0, d = 0;
};
inline thread_local NoiseCell noise_cells[16];

inline double value_noise(double u, double v, uint32_t seed) {
  const double fu = fast_floor(u), fv = fast_floor(v);
  const int64_t iu = int64_t(fu), iv = int64_t(fv);
  const double tu = u - fu, tv = v - fv;
  const double su = tu * tu * (3 - 2 * tu), sv = tv * tv * (3 - 2 * tv);  // smoothstep: C1 across cells
  NoiseCell& cell = noise_cells[(seed ^ (seed >> 4) ^ (seed >> 9)) & 15u];
  if (!cell.valid || cell.iu != iu || cell.iv != iv || cell.seed != seed) {
    cell.valid = true;
    cell.iu = iu;
    cell.iv = iv;
    cell.seed = seed;
    cell.a = lattice_value(iu, iv, seed);
    cell.b = lattice_value(iu + 1, iv, seed);
    cell.c = lattice_value(iu, iv + 1, seed);
    cell.d = lattice_value(iu + 1, iv + 1, seed);
  }
  const double a = cell.a, b = cell.b, c = cell.c, d = cell.d;
  const double ab = a + (b - a) * su, cd = c + (d - c) * su;
  return ab + (cd - ab) * sv;
}

// Fractal sum of `octaves` value-noise layers (lacunarity 2, gain 0.5), normalised to [-1, 1].
// x, y in metres (frame coordinates); scale_m is the wavelength of the first octave.
// Octaves whose wavelength is under min_wavelength_m are left out but still count in the
// normalisation: the result is the same field low-passed (a sampling lattice too coarse for an
// octave would only alias it into per-sample speckle).
inline double fbm_noise(double x_m, double y_m, double scale_m, int octaves, uint32_t seed,
                        double min_wavelength_m = 0) {
  double sum = 0, amp = 1, norm = 0, f = 1.0 / scale_m;
  for (int o = 0; o < octaves; ++o) {
    if (f * min_wavelength_m <= 1.0) sum += amp * value_noise(x_m * f, y_m * f, seed + uint32_t(o) * 0x9E37u);
    norm += amp;
    amp *= 0.5;
    f *= 2.0;
  }
  return norm > 0 ? sum / norm : 0.0;
}

// fbm_noise at many points of one row (the same y) at once, the same bits as fbm_noise point by
// point. Per octave the row needs only two lattice rows: their values are hashed once into a table
// (kept while later rows stay between the same lattice rows) instead of a cell check per point.
// Rows that span more than kMaxNoiseTableCells cells of an octave, or non-finite coordinates, take
// fbm_noise itself.
inline constexpr int kMaxNoiseTableCells = 1024;
struct NoiseRowTable {
  bool valid = false;
  uint32_t seed = 0;
  int64_t iv = 0, iu0 = 0;
  std::vector<double> below, above;  // lattice values (iu0 + j, iv) and (iu0 + j, iv + 1)
};
struct NoiseRowTables {
  NoiseRowTable octave[8];  // the rules' octave limit (materials.cpp) and the albedo's 2
};
// out[i] = fbm_noise(x_m[idx ? idx[i] : i], y_m, scale_m, octaves, seed, min_wavelength_m), i < count.
void fbm_noise_row(const double* x_m, const int* idx, int count, double y_m, double scale_m, int octaves,
                   uint32_t seed, double min_wavelength_m, NoiseRowTables& tables, double* out);

}  // namespace terrain::cook
