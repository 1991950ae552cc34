// Constants shared by the C++ viewer and its GLSL shaders (included by both; keep it plain #defines).
// One home per constant: change a value here and both sides follow. Each knob says what it trades.
// The residency index layout is the streamer's, defined in terrain/surface_contract.h (whose
// #define block GLSL reads as it is: glslc -I format/include); the names below take it from there.
#ifndef TERRAIN_VIEW_CONFIG_H
#define TERRAIN_VIEW_CONFIG_H

#include "terrain/surface_contract.h"

// ---- Quadtree geometry (mirrors terrain/format.h; static_asserts in src/gpu_types.h check it) ----
#define TV_LEVELS 6
#define TV_ROOT_LEVEL 5
// Levels 6 .. 5+K: overview levels above the roots (format/SPEC.md section 19), nodes like any other
// at 32 m, 64 m, ... vertex spacing. TV_MAX_LEVELS bounds every per-level array.
#define TV_MAX_LEVELS 20
// Fog thins with height (exponential, the air's density scale height): from 50 km up a 100 km
// world shows through ~15 % fog instead of ~60 % at the sea-level density.
#define TV_FOG_SCALE_HEIGHT_M 8000.0
#define TV_QUADS_PER_NODE 128     // 8 patches x 16 quads
#define TV_PATCHES_PER_SIDE 8
#define TV_PATCHES_PER_NODE 64
#define TV_QUADS_PER_PATCH 16
#define TV_QUADS_PER_PATCH_LOG2 4
// Patch meshes: triangle lists of (16 >> e)^2 quads split SW->NE, one per decimation e (a strip
// per row measured no faster on lavapipe).
#define TV_HEIGHT_SAMPLES 129
#define TV_TEXELS 132             // normals/albedo, 2-texel apron
#define TV_APRON 2
#define TV_SPLAT_SAMPLES 65
#define TV_SECTORS_PER_ROOT 32    // sectors (level-0 nodes, 64 m) along a root side

// Positions are integers of half metres (the level-0 vertex spacing) relative to the world origin
// (south-west corner of root 0,0), so shared vertices convert to bit-identical floats.
#define TV_HALF_METRE 0.5

// ---- Residency index (terrain/surface_contract.h "Residency index: GPU layout") ----
#define TV_SLOT_EMPTY TERRAIN_INDEX_NOT_RESIDENT   // node exists, not resident (kIndexNotResident)
#define TV_SLOT_INVALID TERRAIN_INDEX_NO_NODE      // no node in the archive here (kIndexNoNode)

// ---- Surface texels (terrain/surface_contract.h; static_asserts in src/gpu_types.h) ----
// Normal component c = (v8 - TV_NORMAL_CENTRE) / TV_NORMAL_SCALE; cone axis x = (R - TV_CONE_R_CENTRE)
// / TV_CONE_R_SCALE, y = (G - TV_CONE_G_CENTRE) / TV_CONE_G_SCALE.
#define TV_NORMAL_CENTRE 128
#define TV_NORMAL_SCALE 127
#define TV_CONE_R_CENTRE 132
#define TV_CONE_R_SCALE 123
#define TV_CONE_G_CENTRE 130
#define TV_CONE_G_SCALE 125
// Far lighting per texel (src/far_light.h): the lit atlas holds sRGB(albedo * light / TV_LIT_SCALE),
// since the sun alone is 2.9x and a lit texel exceeds 1.
#define TV_LIT_SCALE 4.0

// ---- Traversal (one workgroup, FC5 section 4.2) ----
// Group size: more threads finish a wide level in fewer steps; lavapipe caps a group at 1024.
#define TV_TRAVERSE_GROUP 64
// The traversal starts at the top level's resident nodes (at most 16 with overview levels, the
// roots without), listed by the CPU in the tree buffer, and walks down one level per pass with
// two ping-pong lists in a storage buffer of 2 x slot_count uints. A list holds distinct resident
// slots, so it cannot overflow: the bound is the atlas, not the world (TV_NL_OVERFLOW counts
// entries that did not fit anyway and the viewer warns when it is ever non-zero).
// The index is the streamer's residency index (terrain/surface_contract.h): the tree buffer (start
// list, then 2 words of child slots per slot) and the root grid, an R16_UINT image of a texel per
// root (for the roots' neighbours and the root under a sector). Sparse: 12 bytes per slot plus 2
// per root whatever the world's area.
#define TV_TREE_START TERRAIN_INDEX_TREE_START

// Node-list entry: slot in bits 0..15, quadrant mask (bit c = child c's quarter is drawn by this
// node, c as terrain::child_of: bit 0 east, bit 1 north) in bits 16..19, coarsening in bits 20..21.
#define TV_ENTRY_SLOT_MASK 0xFFFFu
#define TV_ENTRY_QUAD_SHIFT 16
#define TV_ENTRY_COARSE_SHIFT 20

// Coarsening above the roots: a root that does not split may be drawn with every 2nd, 4th or 8th
// vertex (geometric levels 6, 7, 8: 4x4, 2x2, 1x1 patches), when the decimation error allows.
// The decimated vertices are root vertices, so stitching against them stays exact. Without it a
// whole archive seen from afar costs 32768 triangles per root however small it is on screen.
// A neighbour stitches onto a coarsened root with d = 8 - its level; collapsing works while
// 2^d <= 128 (a whole node edge), so level 8 is taken only when no edge-adjacent root splits
// (its nodes are then level >= 5: d <= 3); levels 6 and 7 give d <= 7 against any level.
#define TV_MAX_COARSEN 3

// LOD map: geometric level + 1 of the node drawing a place (1..20), 0 = nothing drawn (never
// stitches). Written by one workgroup of TV_LODMAP_GROUP threads per listed node. Two parts, so
// it is bounded near the camera and not dense over the world:
//  - fine: one uint per 64 m sector in a window of at most TV_LODMAP_WINDOW_ROOTS roots per side
//    (512 x 512 sectors, 1 MiB, 32.8 km) around the camera, aligned to roots
//    (FrameUniforms.lodwin: x0, y0, width, height in sectors);
//  - coarse: one uint per root cell (2048 m) of the world after it (4 bytes per root).
// Nodes below the roots are drawn only inside the window (a root outside it never splits), so
// outside it every root cell is drawn by one node of level >= 5 and its coarse cell says which.
#define TV_LODMAP_GROUP 64
#define TV_LODMAP_WINDOW_ROOTS 16

// ---- Patch list ----
// The traversal lists one work item per patch of a drawn quadrant (node-list index in bits 0..15,
// px << 16, py << 19); the patch pass runs one thread per item in groups of TV_PATCH_GROUP, so
// coarsened roots (1..16 patches) and partly drawn nodes cost no idle workgroups.
#define TV_PATCH_GROUP 64
// Patch entry (uvec4): x = slot | px << 16 | py << 19 | geometric level << 22 (5 bits, 0..19)
// | decimation << 27 | coarsening << 30 (node level = geometric level - coarsening);
// y = edge deltas (4 bits each: south, west, north, east); z, w = node x, y at its own level
// (min(geometric level, 5)). Patch (px, py) of a coarsened root covers its (1 << c)^2 root patches.
#define TV_PATCH_PX_SHIFT 16
#define TV_PATCH_PY_SHIFT 19
#define TV_PATCH_LEVEL_SHIFT 22
#define TV_EDGE_S 0
#define TV_EDGE_W 4
#define TV_EDGE_N 8
#define TV_EDGE_E 12

// Patch decimation (root patches, of roots drawn coarsened or not): a patch whose own error allows
// it is drawn with every 2^e-th vertex of its grid, e = 1..TV_MAX_DECIMATE (16 >> e quads per
// side), chosen per patch from its own box distance and its total error (node geometric error +
// decimation error) so that the screen-space error stays within the target. Every patch can
// evaluate a neighbour root patch's e (a pure function of the camera, the LOD map and that patch's
// data), so edges stitch without an extra pass: the finer side collapses onto the coarser one as
// for LOD differences (effective level = 5 + c + e).
// Root patches decimate, uncoarsened or coarsened (a coarsened root's patch, which spans
// (1 << c)^2 root patches, decimates on its own coarse grid: effective level 5 + c + e). Where two
// patches of different widths meet, the narrower one is never the coarser side, so the wider one
// needs no delta there: a patch of coarsening c keeps e <= c' - c on an edge facing a root drawn
// at coarsening c' > c. And the narrower patch's collapse stays within itself (d <= 4, groups of
// at most its 16 quads), because its other edges may collapse onto different neighbours too: a
// patch of coarsening c keeps c - c' + e <= 4 on an edge facing a root drawn at coarsening c' < c
// (finer nodes have no deltas inside a node, so only the d <= 7 below holds for them). Equal
// widths stitch either way (the finer collapses). The cap 5 + c + e <= 7 + finest drawn level
// keeps every collapse d <= 7. Coarsened patches decimate only in worlds without overview levels,
// where LOD map values 7..9 can only be coarsened roots.
#define TV_PATCH_DECIM_SHIFT 27   // e in bits 27..29 of the patch entry's x
#define TV_PATCH_COARSE_SHIFT 30  // coarsening c in bits 30..31 (a root drawn at level 5 + c)
#define TV_PATCH_LEVEL_MASK 31u
#define TV_MAX_DECIMATE 4
// Decimation errors per node slot: the 64 root patches (c = 0), then the coarsened patches of
// c = 1, 2, 3 (16, 4, 1), patch (px, py) of coarsening c at TV_PATCH_ERROR_BASE(c) + py * (8 >> c) + px.
#define TV_PATCH_ERRORS_PER_NODE 85
#define TV_PATCH_ERROR_BASE(c) ((c) == 0 ? 0 : (c) == 1 ? 64 : (c) == 2 ? 80 : 84)

// Shading groups (FC5 section 3, step 4): patches whose box is within the near-shading distance
// go to the near list (splat materials), the others to the far list (baked albedo + normal). Each
// group is one multi-draw of TV_MESHES indexed-indirect instanced draws (one per decimation, its
// own mesh of (16 >> e)^2 quads), with a pipeline specialised for the group: a CPU rasteriser runs
// every branch of a shader for every pixel, so far pixels must not carry the splat code. Patch
// range r = group * TV_MESHES + e holds its instances from `capacity * r` (firstInstance).
#define TV_MESHES (TV_MAX_DECIMATE + 1)
#define TV_PATCH_NEAR_BIT (1u << 16)  // in the patch entry's edge-delta word
#define TV_DRAW_NEAR 0            // VkDrawIndexedIndirectCommand x TV_MESHES of the near group (5 uints each)
#define TV_DRAW_FAR (5 * TV_MESHES)  // ... of the far group
#define TV_CNT_CONSIDERED (10 * TV_MESHES)  // patches of drawn quadrants
#define TV_CNT_FRUSTUM (TV_CNT_CONSIDERED + 1)  // culled by the frustum
#define TV_CNT_CONE (TV_CNT_CONSIDERED + 2)     // culled by the patch cone
#define TV_CNT_DEEP (TV_CNT_CONSIDERED + 3)     // patch edges facing a neighbour coarser by d > 7
                                                // (collapse clamped to 7: may crack; warned)
#define TV_MAX_DELTA 7
#define TV_DRAW_UINTS (TV_CNT_CONSIDERED + 4)
#define TV_PATCH_RANGES (2 * TV_MESHES)

// Traversal output header (uints) in the node-list buffer, before the entries.
#define TV_NL_DISPATCH 0          // x, y, z of the indirect LOD-map dispatch (x = node count)
#define TV_NL_COUNT 3             // nodes in the final list
#define TV_NL_LEVEL_COUNTS 4      // TV_MAX_LEVELS counts, nodes per level
#define TV_NL_OVERFLOW 24         // list entries that did not fit (0 by construction, see above)
#define TV_NL_PATCH_DISPATCH 25   // x, y, z of the indirect patch-pass dispatch (x = work items / group)
#define TV_NL_PATCH_ITEMS 28      // patch work items (patches of drawn quadrants)
#define TV_NL_HEADER 32

// ---- Frame flags (FrameUniforms.misc.y) ----
#define TV_FLAG_FRUSTUM_CULL 1u
#define TV_FLAG_CONE_CULL 2u
#define TV_FLAG_HOLES 4u          // drop triangles of hole vertices
#define TV_FLAG_HOLE_NAN 8u       // ... by a NaN clip position (else: defined method, see terrain.vert)
#define TV_FLAG_SPLAT 16u         // near splat shading
#define TV_FLAG_NO_STITCH 32u     // tests only: ignore the edge deltas (shows what stitching fixes)
#define TV_FLAG_DECIMATE 64u      // per-patch decimation of roots (see "Patch decimation")

// ---- Debug views (FrameUniforms.misc.z) ----
#define TV_DEBUG_NONE 0
#define TV_DEBUG_LOD 1
#define TV_DEBUG_NODES 2
#define TV_DEBUG_PATCHES 3
#define TV_DEBUG_CONES 4
#define TV_DEBUG_HOLES 5
#define TV_DEBUG_NORMALS 6
#define TV_DEBUG_SPLAT 7
#define TV_DEBUG_WIRE 8

#define TV_MAX_MATERIALS 256

#endif
