// The sparse_tree shape of the synthetic generator (synthetic_archive.h).
#include "synthetic_shapes.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

namespace terrain::synthetic {
namespace {

uint64_t mix(uint64_t z) {  // splitmix64 finaliser
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
uint64_t hash(uint64_t seed, uint64_t a, uint64_t b = 0, uint64_t c = 0, uint64_t d = 0) {
  return mix(seed ^ mix(a ^ mix(b ^ mix(c ^ mix(d)))));
}
double unit(uint64_t h) { return double(h >> 11) * 0x1.0p-53; }

// Value noise on an integer lattice with smooth interpolation, in [-1, 1].
double value_noise(uint64_t seed, double x, double y) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = int64_t(fx), iy = int64_t(fy);
  const double tx = x - fx, ty = y - fy;
  const double sx = tx * tx * (3 - 2 * tx), sy = ty * ty * (3 - 2 * ty);
  auto v = [&](int64_t a, int64_t b) { return 2 * unit(hash(seed, uint64_t(a), uint64_t(b), 77)) - 1; };
  const double a = v(ix, iy) + (v(ix + 1, iy) - v(ix, iy)) * sx;
  const double b = v(ix, iy + 1) + (v(ix + 1, iy + 1) - v(ix, iy + 1)) * sx;
  return a + (b - a) * sy;
}

struct Generator {
  const Spec& spec;
  const WorldInfo& world;

  double height_m(double x, double y) const { return surface_height_m(spec, x, y); }

  NodeRecord make_record(const NodeKey& key, uint8_t child_mask) const {
    NodeRecord r;
    r.key = key;
    r.child_mask = child_mask;
    const double spacing = vertex_spacing_m(int(key.level));
    r.geometric_error_m = float(spec.error_scale * spacing * (0.3 + 1.4 * unit(hash(spec.seed, 11, key.level, key.x, key.y))));
    return r;
  }

  bool root_exists(uint64_t x, uint64_t y) const {
    if (x >= spec.roots_x || y >= spec.roots_y) return false;
    return unit(hash(spec.seed, 1, x, y)) < spec.root_fill || (x == 0 && y == 0);
  }

  // The units a root stores at its vertex (i, j): what make_payload() writes, without the rest.
  // The per-node offset is a multiple of the step, so it does not change the rounded value.
  struct RootVertices {
    const Generator& gen;
    uint32_t rx = 0, ry = 0;
    double h00 = 0, h10 = 0, h01 = 0, h11 = 0;
    RootVertices(const Generator& g, uint32_t x, uint32_t y) : gen(g), rx(x), ry(y) {
      const double size = node_size_m(kRootLevel);
      const double x0 = g.world.origin_x_m + double(x) * size, y0 = g.world.origin_y_m + double(y) * size;
      h00 = g.height_m(x0, y0);
      h10 = g.height_m(x0 + size, y0);
      h01 = g.height_m(x0, y0 + size);
      h11 = g.height_m(x0 + size, y0 + size);
    }
    int32_t units(int i, int j) const {
      const int step = gen.world.step_log2[kRootLevel];
      const auto round = [step](int32_t u) { return ((u + ((1 << step) >> 1)) >> step) << step; };
      if (gen.spec.realistic_payload) {
        const double s = vertex_spacing_m(kRootLevel), size = node_size_m(kRootLevel);
        const double x0 = gen.world.origin_x_m + double(rx) * size, y0 = gen.world.origin_y_m + double(ry) * size;
        return round(int32_t(std::lround(gen.height_m(x0 + i * s, y0 + j * s) * 1024.0)));
      }
      return round(bilinear_units(h00, h10, h01, h11, i, j));
    }
  };

  static int32_t bilinear_units(double h00, double h10, double h01, double h11, int i, int j) {
    const double v = double(j) / kQuadsPerSide;
    const double a = h00 * (1 - v) + h01 * v, b = h10 * (1 - v) + h11 * v;
    const double u = double(i) / kQuadsPerSide;
    return int32_t((a * (1 - u) + b * u) * 1024.0);
  }

  // An overview node (level >= 6): its vertices are the roots' vertices at the same points (the
  // crack-free rule with the roots' step), holes where no root holds a point; constant surface
  // layers with the holes marked in the albedo's alpha.
  void make_overview_payload(NodeRecord& r, NodeData& d) const {
    const int level = int(r.key.level);
    const int step = level_step_log2(world, level);
    const uint64_t f = uint64_t(1) << (level - kRootLevel);  // root-vertex units per vertex of this level
    std::vector<int32_t> units(kHeightCount);
    std::vector<uint8_t> hole(kHeightCount, 1);
    std::vector<std::unique_ptr<RootVertices>> cache;
    auto root_at = [&](uint32_t x, uint32_t y) -> const RootVertices* {
      if (!root_exists(x, y)) return nullptr;
      for (const auto& c : cache)
        if (c->rx == x && c->ry == y) return c.get();
      if (cache.size() > 64) cache.erase(cache.begin());
      cache.push_back(std::make_unique<RootVertices>(*this, x, y));
      return cache.back().get();
    };
    int32_t lo = 0, hi = 0;
    bool any = false;
    for (int j = 0; j < kHeightSamples; ++j)
      for (int i = 0; i < kHeightSamples; ++i) {
        const uint64_t gx = uint64_t(r.key.x) * 128 * f + uint64_t(i) * f, gy = uint64_t(r.key.y) * 128 * f + uint64_t(j) * f;
        const RootVertices* holder = nullptr;
        uint64_t hx = 0, hy = 0;
        const bool edge_x = gx % 128 == 0 && gx > 0, edge_y = gy % 128 == 0 && gy > 0;
        for (int c = 0; c < 4 && !holder; ++c) {  // a point on a root edge is held by up to 4 roots
          if (((c & 1) && !edge_x) || ((c >> 1) && !edge_y)) continue;
          const uint64_t cx = gx / 128 - uint64_t(c & 1), cy = gy / 128 - uint64_t(c >> 1);
          holder = root_at(uint32_t(cx), uint32_t(cy));
          hx = cx;
          hy = cy;
        }
        if (!holder) continue;
        const size_t k = size_t(j * kHeightSamples + i);
        units[k] = holder->units(int(gx - hx * 128), int(gy - hy * 128));
        hole[k] = 0;
        lo = any ? std::min(lo, units[k]) : units[k];
        hi = any ? std::max(hi, units[k]) : units[k];
        any = true;
      }
    const int32_t offset = any ? lo : 0;  // a multiple of the step: every value is
    r.height_offset = offset;
    r.min_height = any ? lo : offset;
    r.max_height = any ? hi : offset;
    d.albedo_bc1.fill(0x11);  // 3-colour BC1 blocks (colour0 <= colour1): index 3 is transparent
    bool holes = false;
    for (size_t k = 0; k < units.size(); ++k) {
      d.heights[k] = hole[k] ? uint16_t(0) : uint16_t((units[k] - offset) >> step);
      if (!hole[k]) continue;
      holes = true;
      const int tx = int(k % kHeightSamples) + kApron, ty = int(k / kHeightSamples) + kApron;
      uint8_t& row = d.albedo_bc1[size_t((ty / 4) * kTexelBlocks + tx / 4) * 8 + 4 + size_t(ty % 4)];
      row = uint8_t(row | (3u << (2 * (tx % 4))));
    }
    r.flags = holes ? kNodeFlagHasHoles : 0;
    d.normals_bc3.fill(0);
    d.splat.fill(0);
    d.cones_bc3.fill(0);
    d.splat[0] = 0x5E;
    d.splat[1] = uint8_t(r.key.level);
    d.splat[2] = uint8_t(r.key.x);
    d.splat[3] = uint8_t(r.key.x >> 8);
    d.splat[4] = uint8_t(r.key.y);
    d.splat[5] = uint8_t(r.key.y >> 8);
  }

  // Fills heights (quantized with the level's step), normals/albedo/splat/cones, and the record's heights.
  void make_payload(NodeRecord& r, NodeData& d) const {
    const int level = int(r.key.level);
    const int step = world.step_log2[size_t(level)];
    const double s = vertex_spacing_m(level);
    const double x0 = world.origin_x_m + double(r.key.x) * node_size_m(level);
    const double y0 = world.origin_y_m + double(r.key.y) * node_size_m(level);
    auto quantize = [&](int32_t offset, int32_t u) {
      return uint16_t(std::clamp((u - offset + ((1 << step) >> 1)) >> step, 0, 0xFFFF));
    };
    int32_t offset = 0;
    uint16_t rmin = 0xFFFF, rmax = 0;
    if (spec.realistic_payload) {
      std::vector<int32_t> units(kHeightCount);
      for (int j = 0; j < kHeightSamples; ++j)
        for (int i = 0; i < kHeightSamples; ++i)
          units[size_t(j * kHeightSamples + i)] = int32_t(std::lround(height_m(x0 + i * s, y0 + j * s) * 1024.0));
      const int32_t lo = *std::min_element(units.begin(), units.end());
      offset = (lo >> step) << step;
      for (size_t k = 0; k < units.size(); ++k) d.heights[k] = quantize(offset, units[k]);
    } else {
      // Cheap (tests write thousands of nodes, also under sanitizers): bilinear between the
      // surface at the node's corners, so the lowest sample is a corner.
      const double size = node_size_m(level);
      const double h00 = height_m(x0, y0), h10 = height_m(x0 + size, y0);
      const double h01 = height_m(x0, y0 + size), h11 = height_m(x0 + size, y0 + size);
      const auto lo = int32_t(std::min({h00, h10, h01, h11}) * 1024.0);
      offset = (lo >> step) << step;
      for (int j = 0; j < kHeightSamples; ++j) {
        for (int i = 0; i < kHeightSamples; ++i)
          d.heights[size_t(j * kHeightSamples + i)] = quantize(offset, bilinear_units(h00, h10, h01, h11, i, j));
      }
    }
    for (uint16_t r16 : d.heights) {
      rmin = std::min(rmin, r16);
      rmax = std::max(rmax, r16);
    }
    r.height_offset = offset;
    r.min_height = vertex_units(offset, rmin, step);
    r.max_height = vertex_units(offset, rmax, step);

    const uint64_t node_seed = hash(spec.seed, 5, r.key.level, r.key.x, r.key.y);
    if (spec.realistic_payload) {
      // BC-like blocks: endpoints vary smoothly, index bits look random (as in real BC data).
      for (int b = 0; b < kTexelBlocks * kTexelBlocks; ++b) {
        const uint64_t h = hash(node_seed, uint64_t(b));
        uint8_t* n = &d.normals_bc3[size_t(b) * 16];
        const int bx = b % kTexelBlocks, by = b / kTexelBlocks;
        const auto e = uint8_t(128 + 60 * value_noise(node_seed, bx * 0.2, by * 0.2));
        n[0] = e;
        n[1] = uint8_t(e - 9);
        for (int k = 2; k < 8; ++k) n[k] = uint8_t(h >> (8 * k));
        n[8] = uint8_t(e ^ 0x40);
        n[9] = uint8_t(e >> 1);
        n[10] = uint8_t(e + 3);
        n[11] = 0x84;
        for (int k = 12; k < 16; ++k) n[k] = uint8_t(h >> (8 * (k - 12) + 3));
        uint8_t* a = &d.albedo_bc1[size_t(b) * 8];
        a[0] = uint8_t(e + 17);
        a[1] = 0x5A;
        a[2] = uint8_t(e - 21);
        a[3] = 0x3B;
        for (int k = 4; k < 8; ++k) a[k] = uint8_t(h >> (8 * k - 13));
      }
      for (int j = 0; j < kSplatSamples; ++j)
        for (int i = 0; i < kSplatSamples; ++i)
          d.splat[size_t(j * kSplatSamples + i)] =
              uint8_t(4 + 3 * value_noise(spec.seed + 9, (x0 + 2 * i * s) / 40.0, (y0 + 2 * j * s) / 40.0));
      for (size_t k = 0; k < d.cones_bc3.size(); ++k) d.cones_bc3[k] = uint8_t(hash(node_seed, 99, k));
    }  // fast payloads: the other sections keep the constant content generate_sparse_tree() gave them
    // The key marker (key_marker_matches).
    d.splat[0] = 0x5E;
    d.splat[1] = uint8_t(r.key.level);
    d.splat[2] = uint8_t(r.key.x);
    d.splat[3] = uint8_t(r.key.x >> 8);
    d.splat[4] = uint8_t(r.key.y);
    d.splat[5] = uint8_t(r.key.y >> 8);
  }
};

}  // namespace

double surface_height_m(const Spec& spec, double x, double y) {
  const double u = x - spec.origin_x_m, v = y - spec.origin_y_m;
  double h = 300.0 + 120.0 * std::sin(u / 1500.0) * std::cos(v / 1900.0);
  if (spec.realistic_payload) {
    double amplitude = 60.0, wavelength = 800.0;
    for (int octave = 0; octave < 7; ++octave) {
      h += amplitude * value_noise(spec.seed + uint64_t(octave), u / wavelength, v / wavelength);
      amplitude *= 0.45;
      wavelength *= 0.4;
    }
  }
  return h;
}

bool key_marker_matches(const NodeData& data, const NodeKey& key) {
  return data.splat[0] == 0x5E && data.splat[1] == key.level && (data.splat[2] | (data.splat[3] << 8)) == int(key.x & 0xFFFF) &&
         (data.splat[4] | (data.splat[5] << 8)) == int(key.y & 0xFFFF);
}

Status generate_sparse_tree(const Spec& spec, const WorldInfo& world, const NodeSink& sink) {
  const Generator gen{spec, world};
  // The tree: roots by fill ratio (at least one), children by probability.
  std::vector<NodeRecord> records;
  std::vector<NodeKey> frontier;
  for (uint32_t y = 0; y < spec.roots_y; ++y)
    for (uint32_t x = 0; x < spec.roots_x; ++x)
      if (unit(hash(spec.seed, 1, x, y)) < spec.root_fill || (x == 0 && y == 0))
        frontier.push_back({uint32_t(kRootLevel), x, y});
  while (!frontier.empty()) {
    std::vector<NodeKey> next;
    for (const NodeKey& k : frontier) {
      uint8_t mask = 0;
      if (k.level > spec.min_level && k.level > 0)
        for (int c = 0; c < 4; ++c)
          if (unit(hash(spec.seed, 2, k.level, k.x, k.y + (uint64_t(c) << 40))) < spec.child_probability) {
            mask = uint8_t(mask | (1u << c));
            next.push_back(child_of(k, c));
          }
      records.push_back(gen.make_record(k, mask));
    }
    frontier.swap(next);
  }
  std::sort(records.begin(), records.end(), [](const NodeRecord& a, const NodeRecord& b) { return key_less(a.key, b.key); });
  // Overview levels (SPEC 19): the parents of the level below, up to the top; sorted per level.
  for (int level = kLevelCount; level < level_count(world); ++level) {
    std::vector<NodeRecord> parents;
    for (const NodeRecord& c : records) {
      if (c.key.level != uint32_t(level - 1)) continue;
      const NodeKey pk = parent_of(c.key);
      auto it = std::find_if(parents.rbegin(), parents.rend(), [&](const NodeRecord& p) { return p.key == pk; });
      if (it == parents.rend()) {
        parents.push_back(gen.make_record(pk, 0));
        it = parents.rbegin();
      }
      it->child_mask = uint8_t(it->child_mask | (1u << ((c.key.x & 1) | ((c.key.y & 1) << 1))));
      it->geometric_error_m = std::max(it->geometric_error_m, c.geometric_error_m);  // never below a child's
    }
    std::sort(parents.begin(), parents.end(), [](const NodeRecord& a, const NodeRecord& b) { return key_less(a.key, b.key); });
    records.insert(records.end(), parents.begin(), parents.end());
  }

  auto data = std::make_unique<NodeData>();
  for (NodeRecord& r : records) {
    if (r.key.level > uint32_t(kRootLevel)) {
      gen.make_overview_payload(r, *data);
    } else {
      data->albedo_bc1.fill(0x11);  // constant sections of fast payloads (normals, splat, cones stay 0)
      gen.make_payload(r, *data);
    }
    TERRAIN_TRY(sink(r, *data));
  }
  return Status::success();
}

}  // namespace terrain::synthetic
