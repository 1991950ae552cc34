#include "node_prep.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <vector>

#include "terrain/bc_decode.h"

namespace terrain::view {

PatchBoundsArray compute_patch_bounds(const NodeData& data, int32_t height_offset, int step_log2) {
  PatchBoundsArray out;
  for (int q = 0; q < TV_PATCHES_PER_SIDE; ++q)
    for (int p = 0; p < TV_PATCHES_PER_SIDE; ++p) {
      int32_t lo = INT32_MAX, hi = INT32_MIN;
      for (int j = q * TV_QUADS_PER_PATCH; j <= (q + 1) * TV_QUADS_PER_PATCH; ++j)
        for (int i = p * TV_QUADS_PER_PATCH; i <= (p + 1) * TV_QUADS_PER_PATCH; ++i) {
          const int32_t u = vertex_units(height_offset, data.heights[size_t(j) * kHeightSamples + i], step_log2);
          lo = std::min(lo, u);
          hi = std::max(hi, u);
        }
      out[q * TV_PATCHES_PER_SIDE + p] = {lo, hi};
    }
  return out;
}

ConeTexels decode_cones(const NodeData& data) {
  uint8_t rgba[8 * 8 * 4];
  decode_bc3_image(data.cones_bc3.data(), 2, 2, rgba, BcRounding::truncate);  // as the device samples them
  ConeTexels out;
  for (int t = 0; t < 64; ++t)
    for (int k = 0; k < 4; ++k) out[t][k] = rgba[t * 4 + k];
  return out;
}

std::array<float, 4> coarsening_errors(const NodeData& data, int32_t height_offset, int step_log2) {
  std::array<float, 4> out{};
  std::vector<uint8_t> holes(kHeightCount);
  decode_hole_mask(data, holes.data());
  auto h = [&](int i, int j) {
    return double(vertex_units(height_offset, data.heights[size_t(j) * kHeightSamples + i], step_log2)) * kHeightUnitM;
  };
  for (int c = 1; c <= TV_MAX_COARSEN; ++c) {
    const int s = 1 << c;
    double worst = 0;
    for (int j = 0; j < kHeightSamples; ++j)
      for (int i = 0; i < kHeightSamples; ++i) {
        if (holes[size_t(j) * kHeightSamples + i]) continue;
        const int ci = std::min(i / s, (kQuadsPerSide / s) - 1), cj = std::min(j / s, (kQuadsPerSide / s) - 1);
        const double a = double(i - ci * s) / s, b = double(j - cj * s) / s;
        const double h00 = h(ci * s, cj * s), h10 = h(ci * s + s, cj * s);
        const double h01 = h(ci * s, cj * s + s), h11 = h(ci * s + s, cj * s + s);
        worst = std::max(worst, std::abs(quad_height(h00, h10, h01, h11, a, b) - h(i, j)));
      }
    out[size_t(c)] = float(worst);
  }
  return out;
}

PatchErrorArray patch_decimation_errors(const NodeData& data, int32_t height_offset, int step_log2) {
  PatchErrorArray out{};
  std::vector<uint8_t> holes(kHeightCount);
  decode_hole_mask(data, holes.data());
  std::vector<double> heights(kHeightCount);
  for (size_t k = 0; k < heights.size(); ++k)
    heights[k] = double(vertex_units(height_offset, data.heights[k], step_log2)) * kHeightUnitM;
  auto h = [&](int i, int j) { return heights[size_t(j) * kHeightSamples + i]; };
  for (int c = 0; c <= TV_MAX_COARSEN; ++c) {
    const int pps = TV_PATCHES_PER_SIDE >> c, span = TV_QUADS_PER_PATCH << c;  // node quads per patch side
    for (int q = 0; q < pps; ++q)
      for (int p = 0; p < pps; ++p) {
        auto& errors = out[patch_error_index(uint32_t(c), uint32_t(p), uint32_t(q))];
        const int i0 = p * span, j0 = q * span;
        // A patch with a hole vertex decimates only as far as a root may coarsen (c + e <= 3): a
        // coarse triangle with a hole corner drops, one without draws over the holes inside it, so
        // the drawn outline of the holes moves by up to one quad of at most 128 m, as for coarsened
        // roots. Its error is taken over the vertices the coarse mesh draws (no hole corner).
        bool any_hole = false;
        for (int j = j0; j <= j0 + span; ++j)
          for (int i = i0; i <= i0 + span; ++i) any_hole = any_hole || holes[size_t(j) * kHeightSamples + i];
        auto hole = [&](int i, int j) { return holes[size_t(j) * kHeightSamples + i] != 0; };
        for (int e = 1; e <= TV_MAX_DECIMATE; ++e) {
          if (any_hole && c + e > TV_MAX_COARSEN) {
            errors[size_t(e - 1)] = kNeverDecimate;
            continue;
          }
          const int s = 1 << (c + e), cells = span / s;
          double worst = 0;
          for (int j = 0; j <= span; ++j)
            for (int i = 0; i <= span; ++i) {
              const int ci = std::min(i / s, cells - 1) * s, cj = std::min(j / s, cells - 1) * s;
              const double a = double(i - ci) / s, b = double(j - cj) / s;
              if (any_hole && (hole(i0 + i, j0 + j) || hole(i0 + ci, j0 + cj) || hole(i0 + ci + s, j0 + cj + s) ||
                               (a >= b ? hole(i0 + ci + s, j0 + cj) : hole(i0 + ci, j0 + cj + s))))
                continue;  // not drawn by the coarse mesh (or a hole itself)
              const double h00 = h(i0 + ci, j0 + cj), h10 = h(i0 + ci + s, j0 + cj);
              const double h01 = h(i0 + ci, j0 + cj + s), h11 = h(i0 + ci + s, j0 + cj + s);
              worst = std::max(worst, std::abs(quad_height(h00, h10, h01, h11, a, b) - h(i0 + i, j0 + j)));
            }
          errors[size_t(e - 1)] = float(worst);
        }
      }
  }
  return out;
}

void cone_sin2_table(double margin_deg, float out[256]) {
  for (int a = 0; a < 256; ++a) {
    const double angle = a / 255.0 * 90.0 + margin_deg;
    if (a == 255 || angle >= 90.0) {
      out[a] = -1.0f;
    } else {
      const double s = std::sin(std::max(angle, 0.0) * M_PI / 180.0);
      out[a] = float(s * s);
    }
  }
}

Cone decode_cone(const std::array<uint8_t, 4>& t, const float* sin2_table) {
  // Same operation order as cone_backfacing() in shaders/patches.comp.
  Cone c;
  const float x = (float(t[0]) - float(cone::kConeRCentre)) * (1.0f / float(cone::kConeRScale));
  const float y = (float(t[1]) - float(cone::kConeGCentre)) * (1.0f / float(cone::kConeGScale));
  const float rr = x * x + y * y;
  const float z = rr < 1.0f ? std::sqrt(1.0f - rr) : 0.0f;
  c.axis[0] = x;
  c.axis[1] = y;
  c.axis[2] = z;
  c.axis_len2 = x * x + y * y + z * z;
  c.sin2 = sin2_table[t[3]];
  c.cullable = c.sin2 >= 0.0f;
  return c;
}

}  // namespace terrain::view
