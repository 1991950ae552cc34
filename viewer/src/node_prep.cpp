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

namespace {

// Largest vertical distance between the surface of every s-th vertex (SW->NE triangles) and the
// vertices of [i0, i0 + span]^2 that drawn(i, j, ci, cj, upper) accepts (patch-local vertex i, j in
// the cell whose SW corner is ci, cj; upper: the triangle with the SE corner). `h` holds the
// node's 129 x 129 heights in metres. Vertices on the far edges belong to the last cell. One cell
// at a time, so its corners are read once.
template <class Drawn>
double coarse_surface_error(const std::vector<double>& h, int i0, int j0, int span, int s, Drawn&& drawn) {
  const int cells = span / s;
  const double inv_s = 1.0 / s;  // s is a power of two: x * inv_s == x / s exactly
  double worst = 0;
  for (int cj = 0; cj < span; cj += s)
    for (int ci = 0; ci < span; ci += s) {
      const size_t sw = size_t(j0 + cj) * kHeightSamples + size_t(i0 + ci), nw = sw + size_t(s) * kHeightSamples;
      const double h00 = h[sw], h10 = h[sw + size_t(s)], h01 = h[nw], h11 = h[nw + size_t(s)];
      const int j_end = cj + s - (cj / s < cells - 1 ? 1 : 0), i_end = ci + s - (ci / s < cells - 1 ? 1 : 0);
      for (int j = cj; j <= j_end; ++j)
        for (int i = ci; i <= i_end; ++i) {
          const double a = double(i - ci) * inv_s, b = double(j - cj) * inv_s;
          if (!drawn(i, j, ci, cj, a >= b)) continue;
          worst = std::max(worst, std::abs(quad_height(h00, h10, h01, h11, a, b) - h[size_t(j0 + j) * kHeightSamples + size_t(i0 + i)]));
        }
    }
  return worst;
}

std::vector<double> heights_m(const NodeData& data, int32_t height_offset, int step_log2) {
  std::vector<double> heights(kHeightCount);
  for (size_t k = 0; k < heights.size(); ++k)
    heights[k] = double(vertex_units(height_offset, data.heights[k], step_log2)) * kHeightUnitM;
  return heights;
}

}  // namespace

std::array<float, 4> coarsening_errors(const NodeData& data, int32_t height_offset, int step_log2) {
  std::array<float, 4> out{};
  std::vector<uint8_t> holes(kHeightCount);
  decode_hole_mask(data, holes.data());
  const std::vector<double> heights = heights_m(data, height_offset, step_log2);
  for (int c = 1; c <= TV_MAX_COARSEN; ++c)
    out[size_t(c)] = float(coarse_surface_error(heights, 0, 0, kQuadsPerSide, 1 << c, [&](int i, int j, int, int, bool) {
      return holes[size_t(j) * kHeightSamples + size_t(i)] == 0;
    }));
  return out;
}

PatchErrorArray patch_decimation_errors(const NodeData& data, int32_t height_offset, int step_log2) {
  PatchErrorArray out{};
  std::vector<uint8_t> holes(kHeightCount);
  decode_hole_mask(data, holes.data());
  const std::vector<double> heights = heights_m(data, height_offset, step_log2);
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
        auto hole = [&](int i, int j) { return holes[size_t(j0 + j) * kHeightSamples + size_t(i0 + i)] != 0; };
        for (int e = 1; e <= TV_MAX_DECIMATE; ++e) {
          if (any_hole && c + e > TV_MAX_COARSEN) {
            errors[size_t(e - 1)] = kNeverDecimate;
            continue;
          }
          const int s = 1 << (c + e);
          errors[size_t(e - 1)] = float(coarse_surface_error(heights, i0, j0, span, s, [&](int i, int j, int ci, int cj, bool upper) {
            // Not drawn by the coarse mesh (or a hole itself).
            return !any_hole || !(hole(i, j) || hole(ci, cj) || hole(ci + s, cj + s) || (upper ? hole(ci + s, cj) : hole(ci, cj + s)));
          }));
        }
      }
  }
  return out;
}

SlotCpuData prepare_slot(const NodeData& data, const SlotDescriptor& desc) {
  SlotCpuData cpu;
  cpu.bounds = compute_patch_bounds(data, desc.height_offset, desc.step_log2);
  cpu.cones = decode_cones(data);
  if (desc.level == kRootLevel) {
    const auto dec = coarsening_errors(data, desc.height_offset, desc.step_log2);
    for (int c = 1; c <= TV_MAX_COARSEN; ++c) cpu.coarse_error[size_t(c)] = desc.geometric_error_m + dec[size_t(c)];
    cpu.patch_error = patch_decimation_errors(data, desc.height_offset, desc.step_log2);
    for (auto& p : cpu.patch_error)
      for (float& e : p) e = desc.geometric_error_m + e;
  }
  return cpu;
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
