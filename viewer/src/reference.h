// CPU reference of the GPU pipeline (FC5 sections 4-6): traversal, LOD map, patch list (frustum and
// cone culling, per-edge LOD deltas) and vertex stitching. Every float decision uses the operations,
// in the order, that the shaders use (precise, no contraction), so the GPU lists must equal these.
// The tests' oracle and the benchmark's: the renderer itself never includes it. It takes the slots'
// CPU data as the renderer prepared it (node_prep.h prepare_slot).
#pragma once
#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "gpu_types.h"
#include "node_prep.h"
#include "terrain_state.h"

namespace terrain::view {

// Screen-space error test of one node (the traversal's "LOD criterion"): `error_m` seen from the
// camera at the distance of the node's box is larger than the target.
bool wants_split(const GpuNodeDesc& node, float error_m, const FrameUniforms& u);
inline bool wants_split(const GpuNodeDesc& node, const FrameUniforms& u) {
  return wants_split(node, node.geometric_error_m, u);
}

NodeList reference_traverse(const TerrainState& state, const FrameUniforms& u, const std::vector<SlotCpuData>& slots);

// The LOD map of config.h (lod_map_size(u) uints: the window's sectors row-major, then one cell
// per root): geometric level + 1 of the node drawing it, 0 if none. Read it with lod_index().
std::vector<uint32_t> reference_lod_map(const TerrainState& state, const FrameUniforms& u, const NodeList& list);

struct PatchList {
  std::vector<GpuPatch> patches;
  uint32_t considered = 0, culled_frustum = 0, culled_cone = 0;
};

PatchList reference_patches(const TerrainState& state, const FrameUniforms& u, const NodeList& list,
                            const std::vector<uint32_t>& lod_map, const std::vector<SlotCpuData>& slots,
                            const float* cone_sin2_table);

// Largest c + e (coarsening plus patch decimation) of a root patch this frame allows (0 = no
// decimation): every stitch onto it then collapses by d <= 7 (config.h), from the list's finest level.
uint32_t decimation_budget(const FrameUniforms& u, const NodeList& list);
// Largest decimation of a patch of a root drawn at coarsening c: TV_MAX_DECIMATE within the budget;
// 0 for coarsened roots in worlds with overview levels (config.h "Patch decimation").
uint32_t max_patch_decimation(const FrameUniforms& u, uint32_t budget, uint32_t c);
// Decimation e of patch (px, py) of the root `slot` drawn at coarsening c, at most `max_e`: the
// largest e whose total error seen at the patch box's distance meets the target. On an edge facing
// a root drawn at coarsening c' (level 5 + c' in the LOD map): e <= c' - c when c' > c (that root's
// patches are wider and take one delta per edge, so they must never be the finer side there), and
// c - c' + e <= 4 when c' < c (the narrower patches' collapse stays within each of them).
uint32_t patch_decimation(const TerrainState& state, const FrameUniforms& u, const std::vector<SlotCpuData>& slots,
                          const std::vector<uint32_t>& lod_map, uint32_t slot, uint32_t c, uint32_t px, uint32_t py,
                          uint32_t max_e);

// The patch's place, decimation and edge deltas, as the stitching rule takes them
// (terrain/surface_contract.h).
PatchMesh patch_mesh(const GpuPatch& patch);

// Stitching (terrain::stitched_vertex): vertex indices in the patch's node grid (0..128 >> coarsening)
// that patch vertex (i, j) (0..16 >> decimation, every 2^decimation-th node vertex) is drawn at after
// collapsing onto every coarser neighbour (groups of 2^d vertices fall onto the group's first).
void stitch_vertex(const GpuPatch& patch, int i, int j, int& node_i, int& node_j);

// Vertex position in half metres from the world origin (exact integers).
inline int64_t vertex_half_metres(uint32_t node_coord, int level, int node_index) {
  return (int64_t(node_coord) * TV_QUADS_PER_NODE + node_index) << level;
}

// Whether root (x, y) lies in the LOD map window (only those split: config.h "LOD map").
inline bool root_in_window(const FrameUniforms& u, uint32_t x, uint32_t y) {
  const uint32_t wx = u.lodwin[0] >> kRootLevel, wy = u.lodwin[1] >> kRootLevel;
  return x >= wx && y >= wy && x < wx + (u.lodwin[2] >> kRootLevel) && y < wy + (u.lodwin[3] >> kRootLevel);
}

// Drawn position of patch vertex (i, j): half metres from the world origin, and the height texel
// (0..128) of the node it reads.
void patch_vertex(const GpuPatch& patch, int i, int j, int64_t& hx, int64_t& hy, int& texel_i, int& texel_j);

}  // namespace terrain::view
