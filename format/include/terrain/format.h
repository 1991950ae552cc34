// Archive format v1 and v2: constants, value types and the height quantization scheme.
// format/SPEC.md is the byte-level definition; names here follow the SPEC's field names.
// Light header: no I/O, no third-party includes.
#pragma once
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace terrain {

// ---- Quadtree geometry ------------------------------------------------------------------------
inline constexpr int kLevelCount = 6;          // level 0 = finest (64 m nodes), level 5 = roots (2048 m)
inline constexpr int kRootLevel = kLevelCount - 1;
// Overview levels (format v2, SPEC section 19): levels 6 .. 5+K above the roots (4096 m, 8192 m,
// ... nodes), declared by the overview_levels extension record. kLevelCount stays the six FC5
// levels; arrays that must hold overview levels too use kMaxLevels.
inline constexpr int kMaxOverviewLevels = 14;  // 2^14 roots per overview node side: 65536 roots -> 4 x 4
inline constexpr int kMaxLevels = kLevelCount + kMaxOverviewLevels;
inline constexpr uint32_t kMaxTopNodes = 16;   // directory entries at the top level of an archive with overview levels
// Roots per side the reference streamer (terrain-view) opens, and so the widest plan terrain-cook
// writes (SPEC section 12). The streamer's residency index stores slots, never node coordinates:
// a root cell and a child half hold a 16-bit slot (the budget bounds them, not the world), the
// start list holds the top level's nodes (at most 16 with overview levels, which reach 65536 roots
// per side with 14 levels), and node coordinates travel as 32-bit words (level-0 coordinates below
// 2^21). So nothing in it is narrower than the format's own bound (SPEC section 4: 1..65536).
inline constexpr uint32_t kStreamerMaxRootsPerSide = 1u << 16;
inline constexpr double kLevel0NodeSizeM = 64.0;
inline constexpr int kQuadsPerSide = 128;      // 8 patches x 16 quads
inline constexpr int kHeightSamples = 129;     // vertices per node side (shared edge rows with neighbours)
inline constexpr int kHeightCount = kHeightSamples * kHeightSamples;
inline constexpr int kApron = 2;               // texels of real neighbour data around the 128 interior texels
inline constexpr int kTexels = 132;            // normals and albedo: 128 + 2 * kApron, cell-centred
inline constexpr int kTexelBlocks = kTexels / 4;                  // 33 BC blocks per side
inline constexpr int kNormalsBytes = kTexelBlocks * kTexelBlocks * 16;  // BC3
inline constexpr int kAlbedoBytes = kTexelBlocks * kTexelBlocks * 8;    // BC1
inline constexpr int kSplatSamples = 65;       // vertex-aligned at twice the vertex spacing
inline constexpr int kSplatCount = kSplatSamples * kSplatSamples;
inline constexpr int kPatchesPerSide = 8;      // cones: one texel per patch of 16x16 quads
inline constexpr int kQuadsPerPatch = 16;
inline constexpr int kConesBytes = 2 * 2 * 16;  // BC3 8x8 = 2x2 blocks

inline constexpr double node_size_m(int level) { return kLevel0NodeSizeM * double(1 << level); }
inline constexpr double vertex_spacing_m(int level) { return node_size_m(level) / kQuadsPerSide; }

// ---- Heights ----------------------------------------------------------------------------------
// Every stored height is an integer number of height units; one unit is 2^kHeightUnitLog2 m
// (1/1024 m). Level L stores R16 values r with a per-level step of 2^step_log2[L] units and a
// per-node integer offset:  units = height_offset + (r << step_log2[L]),  metres = units * 2^-10.
// A vertex shared by several nodes (neighbours, parent and child) has one canonical unit value,
// so every node that holds it dequantizes it to the same bits; |units| < 2^24 keeps that exact
// in float32 (|h| < 16384 m).
inline constexpr int kHeightUnitLog2 = -10;
inline constexpr double kHeightUnitM = 1.0 / 1024.0;
inline constexpr int32_t kMaxHeightUnits = (1 << 24) - 1;

inline constexpr int32_t vertex_units(int32_t height_offset, uint16_t r, int step_log2) {
  return height_offset + (int32_t(r) << step_log2);
}
inline constexpr double units_to_metres(int32_t units) { return double(units) * kHeightUnitM; }
// The float a shader computes: exact for |units| < 2^24.
inline float units_to_metres_f32(int32_t units) { return float(units) * float(kHeightUnitM); }

// ---- Coordinate frame -------------------------------------------------------------------------
enum class ProjectionKind : uint8_t {
  local = 0,                // metric engineering frame with no geodetic meaning (game heightmaps)
  transverse_mercator = 1,  // GeographicLib TransverseMercator (exact) on the given ellipsoid
  proj = 2,                 // any projected CRS in metres, defined by `definition` (PROJ WKT2:2019); format v2
};

struct FrameCrs {
  ProjectionKind kind = ProjectionKind::local;
  int32_t epsg = 0;                   // 0 = no EPSG code known
  double semi_major_m = 0;            // ellipsoid a (0 for local)
  double inverse_flattening = 0;      // 1/f (0 for a sphere or local)
  double lat0_deg = 0;                // latitude of natural origin
  double lon0_deg = 0;                // central meridian
  double scale_k0 = 1;
  double false_easting_m = 0;
  double false_northing_m = 0;
  std::string name;                   // human-readable, e.g. "WGS 84 / UTM zone 5N"
  // projection_kind proj only (format v2, SPEC 6.5): the frame CRS as PROJ WKT2:2019, which defines
  // it; lat0..false_northing are then unused (written 0, 0, 1, 0, 0), the ellipsoid is the CRS's.
  std::string definition;
};

// One entry of the material palette (the splat map stores indices into it).
struct Material {
  std::string name;                   // at most 31 bytes of UTF-8
  std::array<uint8_t, 3> albedo_srgb{};  // far-distance colour
  uint8_t flags = 0;                  // reserved in v1 (write 0)
  float roughness = 0.8f;             // 0..1
  float detail_scale_m = 4.0f;        // world size of one repeat of the procedural detail
  float detail_strength = 0.2f;       // 0..1 amplitude of the procedural detail
  float height_blend = 0.5f;          // 0..1 weight of height-based blending against neighbours
};

struct WorldInfo {
  FrameCrs crs;
  double origin_x_m = 0, origin_y_m = 0;  // frame coords of the south-west corner of root (0,0)
  uint32_t roots_x = 0, roots_y = 0;      // root grid (node grid at level L is roots * 2^(5-L))
  double extent_min_x_m = 0, extent_min_y_m = 0;  // data footprint, frame coords
  double extent_max_x_m = 0, extent_max_y_m = 0;
  std::array<uint8_t, kLevelCount> step_log2{};   // quantization step exponent per level (units)
  std::vector<Material> palette;          // at most 256 entries
  std::string cook_info_json;             // cook options and input provenance (UTF-8 JSON object)
  // Format v2, SPEC section 19: step_log2 of the overview levels 6, 7, ... (K = size(), 0..14;
  // empty = none, the roots are the top of the tree). Never decreasing upward from step_log2[5].
  std::vector<uint8_t> overview_step_log2;
  // Format v2, SPEC 16.7: node payloads may code their normals with codec 4 (derived from the
  // heights); declared by the derived_normals extension record.
  bool derived_normals = false;
};

// Levels of the archive's tree: 6 + K (K overview levels).
inline int level_count(const WorldInfo& w) { return kLevelCount + int(w.overview_step_log2.size()); }
// The coarsest level: kRootLevel without overview levels, else 5 + K.
inline int top_level(const WorldInfo& w) { return level_count(w) - 1; }
// step_log2 of any level 0 .. top_level(w).
inline int level_step_log2(const WorldInfo& w, int level) {
  const auto l = size_t(unsigned(level));
  return l < size_t(kLevelCount) ? w.step_log2[l] : w.overview_step_log2[l - size_t(kLevelCount)];
}
// Node grid of a level (SPEC 3 and 19): roots << (5 - L) below the roots, ceil(roots / 2^(L-5)) above.
inline uint64_t level_grid_cells(uint32_t roots, int level) {
  if (level <= kRootLevel) return uint64_t(roots) << (kRootLevel - level);
  const uint64_t span = uint64_t(1) << (level - kRootLevel);
  return (uint64_t(roots) + span - 1) / span;
}
// The fewest overview levels whose top level grid holds at most kMaxTopNodes nodes (0 when the
// root grid itself is that small).
inline int overview_levels_needed(uint32_t roots_x, uint32_t roots_y) {
  for (int k = 0; k < kMaxOverviewLevels; ++k)
    if (level_grid_cells(roots_x, kRootLevel + k) * level_grid_cells(roots_y, kRootLevel + k) <= kMaxTopNodes) return k;
  return kMaxOverviewLevels;
}

// A level's place in the payload order of a cooked archive (SPEC 18, 19): level 5 first, then
// towards 0, then the overview levels from 6 upward (they are built from the cooked roots).
inline int payload_order_rank(uint32_t level) {
  return level <= uint32_t(kRootLevel) ? kRootLevel - int(level) : int(level);
}

// ---- Nodes ------------------------------------------------------------------------------------
struct NodeKey {
  uint32_t level = 0;  // 0 = finest
  uint32_t x = 0;      // east, in nodes of this level from the frame origin
  uint32_t y = 0;      // north
  friend constexpr bool operator==(const NodeKey&, const NodeKey&) = default;
};
// Row order: level ascending, then y, then x. The order of a level's nodes in the payload section
// (SPEC 18) and of version 1 and 2 directories.
inline constexpr bool key_less(const NodeKey& a, const NodeKey& b) {
  if (a.level != b.level) return a.level < b.level;
  if (a.y != b.y) return a.y < b.y;
  return a.x < b.x;
}
// Directory order (SPEC 20, version 3): level ascending, then by tiles of 32 x 32 nodes of the level
// (tile row, tile column), then by y and x inside the tile. A directory page of 1024 entries then
// covers one tile where the data is dense, so the nodes a camera wants lie in few pages. A band of
// 32 rows of a level is contiguous in both this order and row order (key_less).
inline constexpr uint32_t kDirectoryTileLog2 = 5;
inline constexpr bool directory_less(const NodeKey& a, const NodeKey& b) {
  if (a.level != b.level) return a.level < b.level;
  constexpr uint32_t t = kDirectoryTileLog2;
  if ((a.y >> t) != (b.y >> t)) return (a.y >> t) < (b.y >> t);
  if ((a.x >> t) != (b.x >> t)) return (a.x >> t) < (b.x >> t);
  if (a.y != b.y) return a.y < b.y;
  return a.x < b.x;
}
inline constexpr NodeKey parent_of(const NodeKey& k) { return {k.level + 1, k.x / 2, k.y / 2}; }
// Child c (0..3): bit 0 = east half, bit 1 = north half.
inline constexpr NodeKey child_of(const NodeKey& k, int c) {
  return {k.level - 1, k.x * 2 + uint32_t(c & 1), k.y * 2 + uint32_t(c >> 1)};
}

inline constexpr uint8_t kNodeFlagHasHoles = 1;  // some vertex of the node is a hole

// One directory entry (decoded). Heights in height units.
struct NodeRecord {
  NodeKey key;
  uint8_t child_mask = 0;        // bit c set: child_of(key, c) exists in the archive
  uint8_t flags = 0;             // kNodeFlag*
  int32_t height_offset = 0;     // units; vertex = offset + (r << step_log2[level])
  int32_t min_height = 0;        // units, over the node's 129x129 non-hole vertices
  int32_t max_height = 0;
  float geometric_error_m = 0;   // max |node surface - source| over the source samples it covers
  uint64_t payload_offset = 0;   // filled in by the writer
  uint32_t payload_size = 0;
  uint32_t payload_crc32 = 0;
};

// Decoded payload of one node. Row-major grids; row 0 is the southern edge, column 0 the western.
//  heights: vertex (i, j) at (x0 + i*s, y0 + j*s), s = vertex_spacing_m(level).
//  normals/albedo texel (t, u) is centred on (x0 + (t - kApron + 0.5)*s, y0 + (u - kApron + 0.5)*s);
//    texels 0,1 and 130,131 are the apron, filled from the neighbours' data.
//  albedo alpha: vertex (i, j) is a hole when texel (i + kApron, j + kApron) has alpha 0.
//  splat sample (i, j) at (x0 + 2*i*s, y0 + 2*j*s).
//  cones: texel (p, q) is patch p (east) q (north).
struct NodeData {
  std::array<uint16_t, kHeightCount> heights{};
  std::array<uint8_t, kNormalsBytes> normals_bc3{};  // 33x33 BC3 blocks, block rows south to north
  std::array<uint8_t, kAlbedoBytes> albedo_bc1{};    // 33x33 BC1 blocks
  std::array<uint8_t, kSplatCount> splat{};          // material ids
  std::array<uint8_t, kConesBytes> cones_bc3{};      // 2x2 BC3 blocks
};

// Which sections to decode (bit set).
enum Section : unsigned {
  kSectionHeights = 1u << 0,
  kSectionNormals = 1u << 1,
  kSectionAlbedo = 1u << 2,
  kSectionSplat = 1u << 3,
  kSectionCones = 1u << 4,
  kSectionAll = 0x1Fu,
};

}  // namespace terrain
