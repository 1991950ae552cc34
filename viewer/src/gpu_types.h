// C++ mirrors of the GPU-side layouts (std140 uniforms, std430 buffers) and the bit packings of
// shaders/config.h. Plain structs; static_asserts pin sizes and the agreement with terrain/format.h.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "terrain/format.h"
#include "terrain/surface_contract.h"
#include "../shaders/config.h"

namespace terrain::view {

static_assert(TV_LEVELS == kLevelCount && TV_ROOT_LEVEL == kRootLevel && TV_MAX_LEVELS == kMaxLevels);
static_assert(TV_QUADS_PER_NODE == kQuadsPerSide && TV_HEIGHT_SAMPLES == kHeightSamples);
static_assert(TV_TEXELS == kTexels && TV_APRON == kApron && TV_SPLAT_SAMPLES == kSplatSamples);
static_assert(TV_PATCHES_PER_SIDE == kPatchesPerSide && TV_QUADS_PER_PATCH == kQuadsPerPatch);
static_assert(TV_PATCHES_PER_SIDE * TV_QUADS_PER_PATCH == TV_QUADS_PER_NODE);
static_assert((1 << TV_QUADS_PER_PATCH_LOG2) == TV_QUADS_PER_PATCH);
static_assert(TV_SECTORS_PER_ROOT == (1 << TV_ROOT_LEVEL));
// The GLSL mirror of terrain/surface_contract.h.
static_assert(TV_SLOT_EMPTY == kIndexNotResident && TV_SLOT_INVALID == kIndexNoNode && TV_TREE_START == kIndexTreeStart);
static_assert(TV_NORMAL_CENTRE == kNormalCentre && TV_NORMAL_SCALE == kNormalScale);
static_assert(TV_CONE_R_CENTRE == cone::kConeRCentre && TV_CONE_R_SCALE == cone::kConeRScale);
static_assert(TV_CONE_G_CENTRE == cone::kConeGCentre && TV_CONE_G_SCALE == cone::kConeGScale);

// Node descriptor, one per atlas slot: the streamer's slot table entry, uploaded as it is
// (std430, 32 bytes; NodeDesc in shaders/common.glsl). Heights in units of 2^-10 m.
using GpuNodeDesc = SlotDescriptor;
static_assert(sizeof(GpuNodeDesc) == 32);

// The traversal's output as read back (config.h "Node-list entry"; the CPU reference's too).
struct NodeList {
  std::vector<uint32_t> entries;  // slot | quadrant mask << 16 | coarsening << 20 (unordered on the GPU)
  std::array<uint32_t, kMaxLevels> level_counts{};
  uint32_t overflow = 0;
};

// Per-patch bounds (std430 ivec2), 64 per slot: min and max height units over the patch's
// 17x17 vertices (hole vertices included: conservative).
struct GpuPatchBounds {
  int32_t min_units = 0, max_units = 0;
};
static_assert(sizeof(GpuPatchBounds) == 8);

// One visible patch (uvec4), see config.h "Patch entry".
struct GpuPatch {
  uint32_t slot_patch_level = 0;
  uint32_t edge_deltas = 0;
  uint32_t node_x = 0, node_y = 0;
  friend bool operator==(const GpuPatch&, const GpuPatch&) = default;
};
static_assert(sizeof(GpuPatch) == 16);

inline uint32_t patch_slot(const GpuPatch& p) { return p.slot_patch_level & 0xFFFFu; }
inline uint32_t patch_px(const GpuPatch& p) { return (p.slot_patch_level >> TV_PATCH_PX_SHIFT) & 7u; }
inline uint32_t patch_py(const GpuPatch& p) { return (p.slot_patch_level >> TV_PATCH_PY_SHIFT) & 7u; }
// Geometric level (vertex spacing 2^level / 2 m); the node's own level is that minus the coarsening.
inline uint32_t patch_level(const GpuPatch& p) { return (p.slot_patch_level >> TV_PATCH_LEVEL_SHIFT) & TV_PATCH_LEVEL_MASK; }
inline uint32_t patch_coarsening(const GpuPatch& p) { return p.slot_patch_level >> TV_PATCH_COARSE_SHIFT; }
inline int patch_node_level(const GpuPatch& p) { return int(patch_level(p) - patch_coarsening(p)); }
inline uint32_t patch_decimation(const GpuPatch& p) { return (p.slot_patch_level >> TV_PATCH_DECIM_SHIFT) & 7u; }
inline uint32_t patch_quads(const GpuPatch& p) { return uint32_t(TV_QUADS_PER_PATCH) >> patch_decimation(p); }  // per side
inline uint32_t edge_delta(const GpuPatch& p, int shift) { return (p.edge_deltas >> shift) & 0xFu; }
inline bool patch_near(const GpuPatch& p) { return (p.edge_deltas & TV_PATCH_NEAR_BIT) != 0; }

// Per-frame uniforms (std140; every member is a vec4-sized row).
struct FrameUniforms {
  float view_proj[16] = {};   // column-major, camera-relative world -> clip (reversed Z, infinite far)
  float planes[6][4] = {};    // frustum planes in camera-relative world space, inside: dot(n,p)+d >= 0
  int32_t cam_hm[4] = {};     // camera x, y as whole half metres from the world origin (floor)
  float cam_frac[4] = {};     // x, y remainder in metres [0, 0.5); z camera height m; w pixels per radian
  float lod[4] = {};          // x error target px, y cone margin (sin), z near-shading start m, w end m
  uint32_t world[4] = {};     // roots_x, roots_y, sectors_x, sectors_y
  uint32_t misc[4] = {};      // top level, flags (TV_FLAG_*), debug view (TV_DEBUG_*), patch capacity
  float sun_dir[4] = {};      // towards the sun, w unused
  float sun_color[4] = {};    // linear rgb, w ambient strength
  float sky_color[4] = {};    // linear rgb, w unused
  float fog[4] = {};          // linear rgb, w density per metre
  float viewport[4] = {};     // width, height, 1/width, 1/height
  float wrap_origin[4] = {};  // xy: camera position modulo the detail period (m), for noise
  uint32_t lodwin[4] = {};    // LOD map window: x0, y0, width, height in sectors (config.h "LOD map")
};
static_assert(sizeof(FrameUniforms) % 16 == 0);

// Material palette entry (std140 vec4 x 2).
struct GpuMaterial {
  float albedo_roughness[4] = {};  // linear rgb, roughness
  float detail[4] = {};            // detail scale m, detail strength, height blend, 1 = albedo baked from the palette
};
static_assert(sizeof(GpuMaterial) == 32);

inline constexpr uint32_t level_grid_width(uint32_t roots, int level) { return roots << (kRootLevel - level); }

// The LOD map window (config.h "LOD map") for a camera at frame point (x, y): at most
// TV_LODMAP_WINDOW_ROOTS roots per side, centred on the camera's root, clamped to the world.
void lod_window(const WorldInfo& world, double cam_x, double cam_y, uint32_t out[4]);
// Index into the LOD map of sector (sx, sy) (the shaders' lod_index()), or -1 outside the world.
int64_t lod_index(const FrameUniforms& u, int64_t sx, int64_t sy);
// Size of the LOD map in uints: window plus one cell per root.
inline size_t lod_map_size(const FrameUniforms& u) {
  return size_t(u.lodwin[2]) * u.lodwin[3] + size_t(u.world[0]) * u.world[1];
}

}  // namespace terrain::view
