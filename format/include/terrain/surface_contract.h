// The rules cooker and runtime must agree on beyond the byte layout of format.h: how surface
// texels encode normals and patch cones, the runtime's back-face test, the slot table and the
// residency index the streamer hands to the GPU, and how a node is named in messages. One
// definition here; the viewer's GLSL reads the residency index layout below from this file
// (viewer/shaders/config.h includes it) and mirrors the other constants, which
// viewer/src/gpu_types.h static_asserts. Also the patch triangulation and LOD stitching. BC block
// decoding is terrain/bc_decode.h.
#ifndef TERRAIN_SURFACE_CONTRACT_H
#define TERRAIN_SURFACE_CONTRACT_H

// ---- Residency index: GPU layout (format/SPEC.md section 12; terrain/residency_index.h) ----------
// Plain #defines, so GLSL includes this block as it is (everything after it is C++ behind
// __cplusplus). The index is two arrays an engine uploads as they are:
//  - the root grid: roots_x * roots_y uint16, row-major, row 0 = south: per root cell the root's
//    slot, TERRAIN_INDEX_NOT_RESIDENT or TERRAIN_INDEX_NO_NODE;
//  - the tree: uint32 words. [0] start count, [1] slot count, [2] and [3] zero; from
//    TERRAIN_INDEX_TREE_START, slot count words: the start list (the top level's resident nodes'
//    slots in key order, then unused words); from TERRAIN_INDEX_TREE_START + slot count, two
//    words per slot s: child c of the node in s in word 2 s + (c >> 1), low half when c & 1 is 0,
//    high half otherwise (c as terrain::child_of: bit 0 east, bit 1 north). A child half holds the
//    child's slot, TERRAIN_INDEX_NOT_RESIDENT (it exists, not resident) or TERRAIN_INDEX_NO_NODE (no
//    such child, or its payload failed); both words of a slot without a resident node hold
//    TERRAIN_INDEX_NO_NODE in both halves.
// A traversal starts at the start list and follows resident children: nodes are never looked up
// by coordinates below the roots, so no value in the index grows with the world's extent.
#define TERRAIN_INDEX_NOT_RESIDENT 0xFFFFu  // the node exists but is not resident
#define TERRAIN_INDEX_NO_NODE 0xFFFEu       // no node here, or its payload failed to load
#define TERRAIN_INDEX_TREE_START 4          // tree words before the start list

#ifdef __cplusplus
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "terrain/format.h"

namespace terrain {

// ---- Node names -------------------------------------------------------------------------------
// "L/X/Y", the form every message and report uses.
std::string node_name(const NodeKey& k);

// ---- Normal texels (normals atlas, BC3: x in A, y in G, z rebuilt) ------------------------------
// v8 = 128 + 127 * c rounded half up, clamped to 1..255 (so -1, 0, 1 are exact and 0 unused);
// c = (v8 - 128) / 127.
inline constexpr int kNormalCentre = 128, kNormalScale = 127;
inline uint8_t normal_texel_of(float c) { return uint8_t(std::clamp(int(128.5f + 127.0f * c), 1, 255)); }
inline float normal_of_texel(uint8_t v8) { return (float(v8) - 128.0f) / 127.0f; }

// ---- Which node answers a point (SurfaceSampler, the streamer's resident queries) ---------------
// The nodes of `level` whose closed square holds the point (fx, fy) (in node units of that level,
// from the frame's grid origin), in the order the surface asks them: the node containing the point,
// then, on a shared edge or corner, its west, south and south-west neighbours; nodes outside the
// grid_x by grid_y grid are left out. Fills out[0 .. returned count - 1] (at most 4).
inline int nodes_holding_point(int level, double fx, double fy, double grid_x, double grid_y, NodeKey out[4]) {
  const double nx = std::floor(fx), ny = std::floor(fy);
  int n = 0;
  for (int cand = 0; cand < 4; ++cand) {
    const double cx = nx - ((cand & 1) ? 1 : 0), cy = ny - ((cand & 2) ? 1 : 0);
    if ((cand & 1) && fx != nx) continue;
    if ((cand & 2) && fy != ny) continue;
    if (cx < 0 || cy < 0 || cx >= grid_x || cy >= grid_y) continue;
    out[n++] = NodeKey{uint32_t(level), uint32_t(cx), uint32_t(cy)};
  }
  return n;
}

// ---- Slot table and residency index (streamer -> GPU) ----------------------------------------
inline constexpr uint16_t kIndexNotResident = TERRAIN_INDEX_NOT_RESIDENT;
inline constexpr uint16_t kIndexNoNode = TERRAIN_INDEX_NO_NODE;
inline constexpr uint32_t kMaxSlots = 0xFFFE;  // slot ids are 0 .. 0xFFFD (below both markers)
inline constexpr uint32_t kIndexTreeStart = TERRAIN_INDEX_TREE_START;
// Words of the index tree of `slot_count` slots; the first of slot s's two child words.
inline constexpr size_t index_tree_words(uint32_t slot_count) { return kIndexTreeStart + 3 * size_t(slot_count); }
inline constexpr size_t index_child_word(uint32_t slot_count, uint32_t s) {
  return kIndexTreeStart + slot_count + 2 * size_t(s);
}
// Both halves of a child word that names no node.
inline constexpr uint32_t kIndexNoChildren = uint32_t(kIndexNoNode) << 16 | kIndexNoNode;

// One entry of the node descriptor table (the FC5 "node description buffer"), indexed by slot.
// 32 bytes, std430/scalar compatible: in GLSL declare it as
//   struct SlotDescriptor { int min_height; int max_height; int height_offset; float geometric_error_m;
//                           uint x; uint y; uint packed; uint reserved; };
// with level = packed & 0xFF, step_log2 = (packed >> 8) & 0xFF, flags = (packed >> 16) & 0xFF,
// child_mask = packed >> 24 (little endian).
// Heights: vertex units = height_offset + (r16 << step_log2); metres = units * 2^-10.
// A slot's descriptor is written when a node is delivered into it and left untouched when the
// node is evicted (the index stops pointing at it at once; the fence protects the rest).
struct SlotDescriptor {
  int32_t min_height = 0;       // height units, over the node's non-hole vertices
  int32_t max_height = 0;
  int32_t height_offset = 0;    // quantization offset, height units
  float geometric_error_m = 0;  // from the archive (metres)
  uint32_t x = 0, y = 0;        // node coordinates at its level
  uint8_t level = 0;            // 0 = finest
  uint8_t step_log2 = 0;        // quantization step exponent of the level (height units)
  uint8_t flags = 0;            // kNodeFlag* of the archive record
  uint8_t child_mask = 0;       // children that exist in the archive (bit c = child_of(key, c))
  uint32_t reserved = 0;
};
static_assert(sizeof(SlotDescriptor) == 32);

// The descriptor of the node `r` of an archive with `world` (what the slot table holds for it).
inline SlotDescriptor slot_descriptor_of(const NodeRecord& r, const WorldInfo& world) {
  SlotDescriptor d;
  d.min_height = r.min_height;
  d.max_height = r.max_height;
  d.height_offset = r.height_offset;
  d.geometric_error_m = r.geometric_error_m;
  d.x = r.key.x;
  d.y = r.key.y;
  d.level = uint8_t(r.key.level);
  d.step_log2 = uint8_t(level_step_log2(world, int(r.key.level)));
  d.flags = r.flags;
  d.child_mask = r.child_mask;
  return d;
}

// ---- Patch triangulation and LOD stitching (format/SPEC.md section 16.5) ----------------------
// One rule for the cooker's cones, the viewer's CPU reference and its vertex shader
// (viewer/shaders/terrain.vert restates stitched_vertex() in GLSL; tests/viewer checks the two agree).
// A patch (px, py) drawn with decimation e (0..4) is a mesh of n = 16 >> e quads per side; mesh
// vertex (i, j), 0..n, is node vertex (16 px + (i << e), 16 py + (j << e)). On an edge whose
// neighbour is coarser by d, the edge's vertices collapse in node coordinates: k -> (k >> d) << d
// (groups of 2^d onto the group's first; for d > 4 the group reaches past the patch corner). A
// corner vertex takes both of its edges. Mesh quad (i, j) is drawn as (i,j),(i+1,j),(i+1,j+1) and
// (i,j),(i+1,j+1),(i,j+1) (SW->NE diagonal, counter-clockwise seen from above); a triangle whose
// collapsed vertices coincide has no area and is not drawn.
inline constexpr int kMaxConeStitchDelta = 4;  // the cones cover stitching with d <= 4

// Levels by which each edge's neighbour is coarser (0: not coarser, nothing collapses).
struct EdgeDeltas {
  int south = 0, west = 0, north = 0, east = 0;
};

// What decides a patch's triangles.
struct PatchMesh {
  int px = 0, py = 0;   // patch in the node, 0..7
  int decimation = 0;   // e: every 2^e-th node vertex
  EdgeDeltas deltas;
};

// A vertex of the node grid (0..128 each way).
struct NodeVertex {
  int i = 0, j = 0;
  friend bool operator==(const NodeVertex&, const NodeVertex&) = default;
};

// Corners of a patch triangle, counter-clockwise seen from above, in node vertices.
struct PatchTriangle {
  NodeVertex v[3];
  bool degenerate() const { return v[0] == v[1] || v[0] == v[2] || v[1] == v[2]; }
};

inline constexpr int patch_mesh_quads(int decimation) { return kQuadsPerPatch >> decimation; }

// Node vertex that mesh vertex (i, j) (0..16 >> decimation) of the patch is drawn at.
inline NodeVertex stitched_vertex(const PatchMesh& m, int i, int j) {
  const int n = patch_mesh_quads(m.decimation);
  NodeVertex v{m.px * kQuadsPerPatch + (i << m.decimation), m.py * kQuadsPerPatch + (j << m.decimation)};
  const EdgeDeltas& d = m.deltas;
  if (j == 0) v.i = v.i >> d.south << d.south;
  if (j == n) v.i = v.i >> d.north << d.north;
  if (i == 0) v.j = v.j >> d.west << d.west;
  if (i == n) v.j = v.j >> d.east << d.east;
  return v;
}

// Corners of the two triangles of a mesh quad, as offsets from its south-west mesh vertex.
inline constexpr int kQuadTriangleCorners[2][3][2] = {{{0, 0}, {1, 0}, {1, 1}}, {{0, 0}, {1, 1}, {0, 1}}};

// Triangle t (0, 1) of mesh quad (i, j) after stitching; may be degenerate.
inline PatchTriangle stitched_quad_triangle(const PatchMesh& m, int i, int j, int t) {
  PatchTriangle tri;
  for (int k = 0; k < 3; ++k)
    tri.v[k] = stitched_vertex(m, i + kQuadTriangleCorners[t][k][0], j + kQuadTriangleCorners[t][k][1]);
  return tri;
}

// Every triangle the patch draws, quads row by row from the south-west, triangle 0 then 1 of each
// quad, degenerate ones left out.
std::vector<PatchTriangle> patch_triangles(const PatchMesh& m);

}  // namespace terrain

// ---- Patch cones ---------------------------------------------------------------------------------
// Cone texture: BC3 8x8 per node, texel (p, q) = patch p east, q north (rows south to north).
// Read with texelFetch (no filtering) as UNORM; v8 = round(channel * 255):
//   R: axis x (east)   x = (v8 - 132) / 123   (132 is a 5-bit endpoint value: x = 0 is exact)
//   G: axis y (north)  y = (v8 - 130) / 125   (130 is a 6-bit endpoint value: y = 0 is exact)
//   B: 0 (unused)
//   A: half-angle      theta = v8 / 255 * 90 degrees;  v8 = 255 means "never cull"
//   axis z = sqrt(max(0, 1 - x^2 - y^2)), then the axis is normalised.
// Every triangle normal the renderer draws in the patch (including stitched edge triangles,
// edge collapse d <= 4) lies within theta of the decoded axis, with margins for GPU decoder
// differences (see format/SPEC.md section 16), so the test below is conservative as written.
namespace terrain::cone {

inline constexpr double kHalfPi = 1.57079632679489661923;

struct DecodedCone {
  double axis[3] = {0, 0, 1};
  double half_angle_rad = kHalfPi;
  bool never_cull = true;
};

inline constexpr int kConeRCentre = 132, kConeRScale = 123, kConeGCentre = 130, kConeGScale = 125;
inline double cone_axis_x(double r8) { return (r8 - kConeRCentre) / kConeRScale; }
inline double cone_axis_y(double g8) { return (g8 - kConeGCentre) / kConeGScale; }
// The texel values of axis components x, y (nearest, clamped to 0..255).
inline uint8_t cone_texel_of_axis_x(double x) {
  return uint8_t(std::clamp(std::lround(kConeRCentre + kConeRScale * x), 0L, 255L));
}
inline uint8_t cone_texel_of_axis_y(double y) {
  return uint8_t(std::clamp(std::lround(kConeGCentre + kConeGScale * y), 0L, 255L));
}

inline DecodedCone decode_cone_texel(uint8_t r, uint8_t g, uint8_t a) {
  DecodedCone c;
  double x = cone_axis_x(r), y = cone_axis_y(g);
  const double rr = x * x + y * y;
  double z = rr < 1.0 ? std::sqrt(1.0 - rr) : 0.0;
  const double len = std::sqrt(x * x + y * y + z * z);
  c.axis[0] = x / len;
  c.axis[1] = y / len;
  c.axis[2] = z / len;
  c.half_angle_rad = double(a) / 255.0 * kHalfPi;
  c.never_cull = a == 255;
  return c;
}

// True when no triangle of the patch can face the eye: for every corner C of the patch box
// (the patch's x/y footprint times [min height, max height]; node min/max are fine),
//   dot(C - eye, axis) >= sin(theta) * |C - eye|.
// The left side minus the right is concave in C, so checking the 8 box corners covers every
// point of the box, and for every normal n within theta of the axis, dot(P - eye, n) >= 0.
inline bool cone_patch_backfacing(const DecodedCone& c, const double eye[3], const double box_min[3],
                                  const double box_max[3]) {
  if (c.never_cull || c.half_angle_rad >= kHalfPi) return false;
  const double s = std::sin(c.half_angle_rad);
  for (int k = 0; k < 8; ++k) {
    const double p[3] = {(k & 1) ? box_max[0] : box_min[0], (k & 2) ? box_max[1] : box_min[1],
                         (k & 4) ? box_max[2] : box_min[2]};
    const double d[3] = {p[0] - eye[0], p[1] - eye[1], p[2] - eye[2]};
    const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (d[0] * c.axis[0] + d[1] * c.axis[1] + d[2] * c.axis[2] < s * len) return false;
  }
  return true;
}

}  // namespace terrain::cone

#endif  // __cplusplus
#endif  // TERRAIN_SURFACE_CONTRACT_H
