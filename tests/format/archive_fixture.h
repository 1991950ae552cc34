// Builders for test archives: a synthetic world whose shared vertices are canonical (heights
// come from one integer function of the world position), and windows of a real DEM.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "terrain/archive_reader.h"
#include "terrain/archive_writer.h"
#include "terrain/bc_decode.h"
#include "terrain/derived_normals.h"
#include "terrain/format.h"

namespace terrain::test {

inline WorldInfo make_world(uint32_t roots_x = 2, uint32_t roots_y = 1) {
  WorldInfo w;
  w.crs.kind = ProjectionKind::transverse_mercator;
  w.crs.epsg = 32605;
  w.crs.semi_major_m = 6378137.0;
  w.crs.inverse_flattening = 298.257223563;
  w.crs.lat0_deg = 0;
  w.crs.lon0_deg = -153;
  w.crs.scale_k0 = 0.9996;
  w.crs.false_easting_m = 500000;
  w.crs.false_northing_m = 0;
  w.crs.name = "WGS 84 / UTM zone 5N";
  w.origin_x_m = 254000.0;
  w.origin_y_m = 2130000.0;
  w.roots_x = roots_x;
  w.roots_y = roots_y;
  w.extent_min_x_m = w.origin_x_m + 10.5;
  w.extent_min_y_m = w.origin_y_m + 3.25;
  w.extent_max_x_m = w.origin_x_m + roots_x * 2048.0 - 7.0;
  w.extent_max_y_m = w.origin_y_m + roots_y * 2048.0 - 1.0;
  w.step_log2 = {0, 1, 2, 3, 4, 5};
  w.palette = {
      {"rock", {120, 110, 100}, 0, 0.9f, 3.0f, 0.4f, 0.6f},
      {"grass", {60, 120, 40}, 0, 0.8f, 2.0f, 0.2f, 0.3f},
      {"snow", {240, 240, 250}, 0, 0.3f, 8.0f, 0.1f, 0.9f},
  };
  w.cook_info_json = R"({"tool":"test","inputs":[{"path":"synthetic","sha256":"00"}],"options":{"zstd_level":9}})";
  return w;
}

// Canonical world heights in units: multiples of 32 (= 2^max step) so every level stores them exactly.
inline int32_t world_units(double x, double y) {
  const double h = 300.0 + 40.0 * std::sin(x * 0.0031) * std::cos(y * 0.0027) + 3.0 * std::sin(x * 0.05 + y * 0.07) +
                   0.4 * std::sin(x * 0.9) * std::cos(y * 1.3);
  return int32_t(std::lround(h * 1024.0 / 32.0)) * 32;
}
inline bool world_hole(double x, double y) {  // a round hole near (300, 200) m from the origin
  return (x - 300.0) * (x - 300.0) + (y - 200.0) * (y - 200.0) < 20.0 * 20.0;
}

// Encodes a BC1 grid whose alpha marks `holes` (129x129 vertices at texels +2) with varied colours.
inline void fill_albedo(const std::vector<uint8_t>& holes, std::mt19937& rng, NodeData& d) {
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      uint8_t* b = d.albedo_bc1.data() + size_t(by * kTexelBlocks + bx) * 8;
      bool any_hole = false;
      uint32_t indices = 0;
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) {
          const int i = bx * 4 + c - kApron, j = by * 4 + r - kApron;
          const bool hole = i >= 0 && j >= 0 && i < kHeightSamples && j < kHeightSamples && holes[size_t(j * kHeightSamples + i)];
          any_hole |= hole;
          indices |= uint32_t(hole ? 3 : int(rng() % 3)) << (2 * (4 * r + c));
        }
      uint16_t c0 = uint16_t(rng() & 0xFFFF), c1 = uint16_t(rng() & 0xFFFF);
      if (c0 == c1) c1 ^= 1;
      if (any_hole) {
        if (c0 > c1) std::swap(c0, c1);  // 3-colour mode: index 3 = transparent
      } else {
        if (c0 < c1) std::swap(c0, c1);  // 4-colour mode
      }
      b[0] = uint8_t(c0);
      b[1] = uint8_t(c0 >> 8);
      b[2] = uint8_t(c1);
      b[3] = uint8_t(c1 >> 8);
      for (int k = 0; k < 4; ++k) b[4 + k] = uint8_t(indices >> (8 * k));
    }
}

struct BuiltNode {
  NodeRecord record;
  std::unique_ptr<NodeData> data;
};

// One node of the synthetic world, with record fields filled in (child_mask left 0).
inline BuiltNode make_synthetic_node(const WorldInfo& w, const NodeKey& key, uint32_t seed) {
  BuiltNode n;
  n.data = std::make_unique<NodeData>();
  NodeData& d = *n.data;
  const double s = vertex_spacing_m(int(key.level));
  const double x0 = key.x * node_size_m(int(key.level)), y0 = key.y * node_size_m(int(key.level));
  std::vector<int32_t> units(static_cast<size_t>(kHeightCount));
  std::vector<uint8_t> holes(static_cast<size_t>(kHeightCount));
  int32_t lo = INT32_MAX, hi = INT32_MIN, all_lo = INT32_MAX;
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) {
      const size_t k = size_t(j * kHeightSamples + i);
      units[k] = world_units(x0 + i * s, y0 + j * s);
      holes[k] = world_hole(x0 + i * s, y0 + j * s) ? 1 : 0;
      all_lo = std::min(all_lo, units[k]);
      if (!holes[k]) {
        lo = std::min(lo, units[k]);
        hi = std::max(hi, units[k]);
      }
    }
  const int step = w.step_log2[key.level];
  NodeRecord& r = n.record;
  r.key = key;
  r.height_offset = all_lo;  // a multiple of 32: exact at every step
  for (size_t k = 0; k < units.size(); ++k) d.heights[k] = uint16_t((units[k] - r.height_offset) >> step);
  const bool any_hole = lo == INT32_MAX ? true : std::count(holes.begin(), holes.end(), 1) > 0;
  r.min_height = lo == INT32_MAX ? r.height_offset : lo;
  r.max_height = hi == INT32_MIN ? r.height_offset : hi;
  r.flags = any_hole ? kNodeFlagHasHoles : 0;
  r.geometric_error_m = 0.01f * float(key.level) + 0.001f * float(seed % 7);
  std::mt19937 rng(seed ^ (key.level * 7919u) ^ (key.x * 104729u) ^ (key.y * 1299709u));
  fill_albedo(holes, rng, d);
  for (auto& b : d.normals_bc3) b = uint8_t(rng() & 0x3F);  // partly compressible
  for (size_t k = 0; k < d.splat.size(); ++k) d.splat[k] = uint8_t((k / 7 + rng() % 2) % w.palette.size());
  for (auto& b : d.cones_bc3) b = uint8_t(rng());
  return n;
}

// All ancestors of `leaves` plus the leaves themselves, with child masks, in key order.
inline std::vector<NodeKey> close_tree(const std::vector<NodeKey>& leaves) {
  std::set<std::tuple<uint32_t, uint32_t, uint32_t>> keys;
  for (NodeKey k : leaves) {
    keys.insert({k.level, k.y, k.x});
    while (k.level < uint32_t(kRootLevel)) {
      k = parent_of(k);
      keys.insert({k.level, k.y, k.x});
    }
  }
  std::vector<NodeKey> out;
  for (const auto& [l, y, x] : keys) out.push_back({l, x, y});
  return out;
}

inline uint8_t child_mask_of(const std::vector<NodeKey>& keys, const NodeKey& k) {
  uint8_t mask = 0;
  if (k.level == 0) return 0;
  for (int c = 0; c < 4; ++c)
    if (std::find(keys.begin(), keys.end(), child_of(k, c)) != keys.end()) mask |= uint8_t(1u << c);
  return mask;
}

// Writes the nodes `build(key)` (a BuiltNode) makes for `keys` (already closed under parents), in
// that order, with child masks from `keys`. Returns the status.
template <class Build>
Status write_archive_of(const std::string& path, const WorldInfo& w, const std::vector<NodeKey>& keys,
                        const PayloadOptions& options, Build&& build) {
  ArchiveWriter writer;
  TERRAIN_TRY(writer.open(path));
  std::vector<uint8_t> payload;
  for (const NodeKey& k : keys) {
    BuiltNode n = build(k);
    n.record.child_mask = child_mask_of(keys, k);
    TERRAIN_TRY(encode_node_payload(*n.data, options, payload));
    TERRAIN_TRY(writer.add_node(n.record, payload));
  }
  return writer.finish(w);
}

// Writes the synthetic world over `keys` (already closed under parents). Returns the status.
inline Status write_synthetic_archive(const std::string& path, const WorldInfo& w, const std::vector<NodeKey>& keys,
                                      const PayloadOptions& options = {}, uint32_t seed = 1) {
  return write_archive_of(path, w, keys, options, [&](const NodeKey& k) { return make_synthetic_node(w, k, seed); });
}

// A small sparse tree: a few level-0 leaves under root (0,0) and one leaf under root (1,0).
inline std::vector<NodeKey> sparse_keys() {
  return close_tree({{0, 0, 0}, {0, 1, 0}, {0, 4, 3}, {0, 5, 3}, {0, 31, 31}, {1, 20, 2}, {2, 9, 7}});
}

}  // namespace terrain::test

namespace terrain::test {

// Small, highly compressible node for golden files and fuzz seeds (a few hundred bytes each).
inline BuiltNode make_seed_node(const WorldInfo& w, const NodeKey& key) {
  BuiltNode n = make_synthetic_node(w, key, 3);
  NodeData& d = *n.data;
  for (size_t k = 0; k < d.normals_bc3.size(); ++k) d.normals_bc3[k] = uint8_t((k % 16) < 8 ? 0x80 : k % 4);
  std::mt19937 rng(7);
  std::vector<uint8_t> holes(static_cast<size_t>(kHeightCount));
  decode_hole_mask(d, holes.data());
  // Constant colour per block keeps BC1 small; the alpha (holes) stays as built.
  for (int b = 0; b < kTexelBlocks * kTexelBlocks; ++b) {
    uint8_t* blk = d.albedo_bc1.data() + size_t(b) * 8;
    const bool punch = uint16_t(blk[0] | blk[1] << 8) <= uint16_t(blk[2] | blk[3] << 8);
    uint32_t idx = 0;
    for (int p = 0; p < 16; ++p) {
      const int old = (blk[4 + p / 4] >> (2 * (p % 4))) & 3;
      idx |= uint32_t(punch && old == 3 ? 3 : 0) << (2 * p);
    }
    const uint16_t c0 = punch ? 0x4208 : 0x8410, c1 = punch ? 0x8410 : 0x4208;
    blk[0] = uint8_t(c0);
    blk[1] = uint8_t(c0 >> 8);
    blk[2] = uint8_t(c1);
    blk[3] = uint8_t(c1 >> 8);
    for (int q = 0; q < 4; ++q) blk[4 + q] = uint8_t(idx >> (8 * q));
  }
  for (size_t k = 0; k < d.splat.size(); ++k) d.splat[k] = uint8_t((k / 65 / 16) % w.palette.size());
  d.cones_bc3.fill(0);
  // A plane (multiples of 32 units, canonical at every level) instead of the bumpy surface.
  const double sp = vertex_spacing_m(int(key.level));
  const double x0 = key.x * node_size_m(int(key.level)), y0 = key.y * node_size_m(int(key.level));
  auto plane = [&](int i, int j) { return int32_t(32 * std::lround(2 * (x0 + i * sp) + 4 * (y0 + j * sp))); };
  NodeRecord& r = n.record;
  r.height_offset = plane(0, 0);
  r.min_height = INT32_MAX;
  r.max_height = INT32_MIN;
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) {
      const int32_t u = plane(i, j);
      d.heights[size_t(j * kHeightSamples + i)] = uint16_t((u - r.height_offset) >> w.step_log2[key.level]);
      if (!holes[size_t(j * kHeightSamples + i)]) {
        r.min_height = std::min(r.min_height, u);
        r.max_height = std::max(r.max_height, u);
      }
    }
  if (r.min_height > r.max_height) r.min_height = r.max_height = r.height_offset;
  return n;
}

// Seed archives: 0 = one root in a local frame; 1 = a 6-level chain with a hole (UTM frame);
// 2 = one root with plain-zstd heights and a stored (incompressible) cones section;
// 3 = one root whose heights are constant (heights codec 3, SPEC 9.3);
// 4 = one root whose normals are derived from its heights (normals codec 4, SPEC 16.7).
inline Status write_seed_archive(const std::string& path, int kind) {
  WorldInfo w = make_world(1, 1);
  w.derived_normals = kind == 4;
  NormalsDerivation derivation;
  derivation.rise_per_unit = 1.0f / 512.0f;
  for (size_t i = 0; i < derivation.apron.size(); ++i) derivation.apron[i] = uint8_t(120 + (i / 2) % 16);
  for (size_t i = 0; i < derivation.ao.size(); ++i) derivation.ao[i] = uint8_t(31 - i % 4);
  if (kind != 1) {
    w.crs = FrameCrs{};
    w.crs.name = "local";
    w.cook_info_json = R"({"tool":"golden"})";
  }
  std::vector<NodeKey> keys = kind == 1 ? close_tree({{0, 4, 3}}) : std::vector<NodeKey>{{5, 0, 0}};
  PayloadOptions options;
  if (kind == 2) options = PayloadOptions{1, false};
  ArchiveWriter writer;
  TERRAIN_TRY(writer.open(path));
  std::vector<uint8_t> payload;
  for (const NodeKey& k : keys) {
    BuiltNode n = make_seed_node(w, k);
    n.record.child_mask = child_mask_of(keys, k);
    if (kind == 2)
      for (size_t i = 0; i < n.data->cones_bc3.size(); ++i) n.data->cones_bc3[i] = uint8_t(i * 151 + 7);
    if (kind == 3) {  // flat at the offset: every r = 0
      n.data->heights.fill(0);
      n.record.min_height = n.record.max_height = n.record.height_offset;
    }
    TERRAIN_TRY(encode_node_payload(*n.data, options, payload, nullptr, kind == 4 ? &derivation : nullptr));
    TERRAIN_TRY(writer.add_node(n.record, payload));
  }
  return writer.finish(w);
}

}  // namespace terrain::test
