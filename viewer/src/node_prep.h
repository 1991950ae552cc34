// Per-node data the viewer derives on the CPU when a node arrives (one pass over 129x129 per
// quantity): per-patch height bounds for culling, the root coarsening and patch decimation errors,
// and the decoded patch cones for the CPU reference. The renderer's upload calls prepare_slot();
// tests/viewer/core_tests.cpp (ViewerNodePrep) recomputes its results by brute force.
#pragma once
#include <array>
#include <cstdint>

#include "gpu_types.h"
#include "terrain/format.h"
#include "terrain/surface_contract.h"

namespace terrain::view {

using PatchBoundsArray = std::array<GpuPatchBounds, TV_PATCHES_PER_NODE>;
using ConeTexels = std::array<std::array<uint8_t, 4>, TV_PATCHES_PER_NODE>;  // RGBA8, patch (p, q) at q*8+p

// Min/max height units over each patch's 17x17 vertices (hole vertices included).
PatchBoundsArray compute_patch_bounds(const NodeData& data, int32_t height_offset, int step_log2);
ConeTexels decode_cones(const NodeData& data);
// Height at (a, b) in [0, 1]^2 of a quad with corner heights h00 (SW), h10 (SE), h01 (NW) and h11
// (NE), drawn as two triangles split SW->NE (the index buffer's split; the triangle holding (a, b)
// has its third corner at SE when a >= b, else at NW). The errors below and terrain-view-bench's
// drawn surface use it.
inline double quad_height(double h00, double h10, double h01, double h11, double a, double b) {
  return a >= b ? h00 + a * (h10 - h00) + b * (h11 - h10) : h00 + a * (h11 - h01) + b * (h01 - h00);
}

// Root coarsening (config.h TV_MAX_COARSEN): for c = 1..TV_MAX_COARSEN, the largest vertical distance (metres)
// between the node's surface and the surface of every (1 << c)-th vertex (same SW->NE
// triangulation), over non-hole vertices. Index 0 is 0.
std::array<float, 4> coarsening_errors(const NodeData& data, int32_t height_offset, int step_log2);

// Patch decimation (config.h): per patch of every coarsening c = 0..3 (index
// TV_PATCH_ERROR_BASE(c) + py * (8 >> c) + px), for e = 1..TV_MAX_DECIMATE in component e - 1, the
// largest vertical distance (metres) between the node's surface over the patch (every vertex) and
// the surface of its every (1 << (c + e))-th vertex (same SW->NE triangulation). A patch with a
// hole vertex: the distance over the vertices the coarse mesh draws (coarse triangles without a
// hole corner), and kNeverDecimate where c + e > TV_MAX_COARSEN.
inline constexpr float kNeverDecimate = 1e30f;  // squared at any distance: +inf, never within the target
using PatchErrorArray = std::array<std::array<float, 4>, TV_PATCH_ERRORS_PER_NODE>;
inline constexpr uint32_t patch_error_index(uint32_t c, uint32_t px, uint32_t py) {
  return uint32_t(TV_PATCH_ERROR_BASE(c)) + py * (TV_PATCHES_PER_SIDE >> c) + px;
}
static_assert(TV_MAX_DECIMATE == 4);
PatchErrorArray patch_decimation_errors(const NodeData& data, int32_t height_offset, int step_log2);

// Decoded cone of one texel, as the patch pass sees it (layout and test: the surface layers'
// terrain/surface_contract.h). Culling is allowed only when `cullable`.
struct Cone {
  float axis[3] = {0, 0, 1};  // not normalised: axis_len2 = |axis|^2
  float axis_len2 = 1;
  float sin2 = 0;             // sin^2(half angle + margin)
  bool cullable = false;
};
// R: axis x = (v8 - 132) / 123, G: axis y = (v8 - 130) / 125, z rebuilt positive; A: half angle
// v8/255 * 90 degrees, 255 = never cull (terrain/surface_contract.h). `sin2_table` comes from cone_sin2_table for the margin in use.
Cone decode_cone(const std::array<uint8_t, 4>& texel, const float* sin2_table);
// sin^2(half angle(a) + margin) per alpha value a, or -1 where the patch must never be culled.
void cone_sin2_table(double margin_deg, float out[256]);
// Largest edge LOD delta whose stitched triangles the cooked cones include.
inline constexpr uint32_t kConeMaxStitchDelta = uint32_t(terrain::kMaxConeStitchDelta);

// Per-slot CPU data derived at upload (the GPU gets the same values in buffers).
struct SlotCpuData {
  PatchBoundsArray bounds{};
  ConeTexels cones{};
  // Total error (metres) of the node drawn with coarsening c = 1..3 (roots only; see config.h):
  // its geometric error plus the decimation error. Index 0 unused.
  std::array<float, 4> coarse_error{};
  // Total error (metres) of each patch of each coarsening drawn with decimation e = 1..4 in
  // component e - 1 (roots only; index patch_error_index(c, px, py); config.h "Patch
  // decimation"): geometric error plus the patch's decimation error.
  PatchErrorArray patch_error{};
};

// What the renderer derives from a node payload at upload (bounds, cones, coarsening errors), with
// the quantization and geometric error of the slot's descriptor.
SlotCpuData prepare_slot(const NodeData& data, const SlotDescriptor& desc);

}  // namespace terrain::view
