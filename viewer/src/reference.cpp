// Compiled with -ffp-contract=off (see viewer/CMakeLists.txt): no fused multiply-add, like the
// shaders' `precise` expressions.
#include "reference.h"

#include <algorithm>

namespace terrain::view {
namespace {

struct Box {
  float mn[3], mx[3];
};

float rel_x(int64_t half_metres, const FrameUniforms& u) {
  return float(int32_t(half_metres) - u.cam_hm[0]) * 0.5f - u.cam_frac[0];
}
float rel_y(int64_t half_metres, const FrameUniforms& u) {
  return float(int32_t(half_metres) - u.cam_hm[1]) * 0.5f - u.cam_frac[1];
}
float rel_z(int32_t units, const FrameUniforms& u) { return float(units) * (1.0f / 1024.0f) - u.cam_frac[2]; }
// Squared distance from the camera (the origin) to a box of camera-relative bounds (0 inside),
// the same operations as the shaders' node and patch tests.
float box_distance2(float mnx, float mxx, float mny, float mxy, float mnz, float mxz) {
  const float dx = std::max(std::max(mnx, -mxx), 0.0f);
  const float dy = std::max(std::max(mny, -mxy), 0.0f);
  const float dz = std::max(std::max(mnz, -mxz), 0.0f);
  return dx * dx + dy * dy + dz * dz;
}

// Same expression order as frustum_visible() in shaders/patches.comp.
bool frustum_visible(const Box& b, const FrameUniforms& u) {
  for (int p = 0; p < 6; ++p) {
    const float* n = u.planes[p];
    const float px = n[0] >= 0.0f ? b.mx[0] : b.mn[0];
    const float py = n[1] >= 0.0f ? b.mx[1] : b.mn[1];
    const float pz = n[2] >= 0.0f ? b.mx[2] : b.mn[2];
    const float s = n[0] * px + n[1] * py + n[2] * pz + n[3];
    if (s < 0.0f) return false;
  }
  return true;
}

// Every point of the box sees only back faces of the cone (terrain/surface_contract.h): for all corners v,
// dot(axis, v) >= sin(theta) |v| |axis|, squared: dot >= 0 and dot^2 >= sin2 * (|v|^2 |axis|^2).
bool cone_backfacing(const Box& b, const Cone& c) {
  if (!c.cullable) return false;
  for (int k = 0; k < 8; ++k) {
    const float vx = (k & 1) ? b.mx[0] : b.mn[0];
    const float vy = (k & 2) ? b.mx[1] : b.mn[1];
    const float vz = (k & 4) ? b.mx[2] : b.mn[2];
    const float d = c.axis[0] * vx + c.axis[1] * vy + c.axis[2] * vz;
    const float vv = vx * vx + vy * vy + vz * vz;
    if (!(d >= 0.0f) || !(d * d >= c.sin2 * (vv * c.axis_len2))) return false;
  }
  return true;
}

// Bounds of patch (px, py) of a node drawn with coarsening c: its (1 << c)^2 node patches.
void coarse_patch_bounds(const PatchBoundsArray& b, uint32_t c, uint32_t px, uint32_t py, int32_t& lo, int32_t& hi) {
  for (uint32_t q = py << c; q < (py + 1) << c; ++q)
    for (uint32_t p = px << c; p < (px + 1) << c; ++p) {
      lo = std::min(lo, b[q * 8 + p].min_units);
      hi = std::max(hi, b[q * 8 + p].max_units);
    }
}

}  // namespace

bool wants_split(const GpuNodeDesc& n, float error_m, const FrameUniforms& u) {
  const int level = n.level;
  const float mnx = rel_x(vertex_half_metres(n.x, level, 0), u);
  const float mxx = rel_x(vertex_half_metres(n.x + 1, level, 0), u);
  const float mny = rel_y(vertex_half_metres(n.y, level, 0), u);
  const float mxy = rel_y(vertex_half_metres(n.y + 1, level, 0), u);
  const float mnz = rel_z(n.min_height, u);
  const float mxz = rel_z(n.max_height, u);
  const float d2 = box_distance2(mnx, mxx, mny, mxy, mnz, mxz);
  const float e = error_m * u.cam_frac[3];
  const float t = u.lod[0];
  return e * e > (t * t) * d2;
}

NodeList reference_traverse(const TerrainState& state, const FrameUniforms& u, const std::vector<SlotCpuData>& slots) {
  NodeList out;
  // From the top level's resident nodes; lists bounded by the slot count (distinct resident slots).
  std::vector<uint32_t> current = state.start_slots(), next;
  const size_t cap = state.slot_count();
  for (int level = state.top_level(); level >= 0; --level) {
    next.clear();
    for (uint32_t slot : current) {
      const GpuNodeDesc& d = state.descriptor(slot);
      uint32_t mask = 0xF, coarse = 0;
      const bool wants = level > 0 && wants_split(d, u) && (level != kRootLevel || root_in_window(u, d.x, d.y));
      if (wants) {
        uint16_t child[4];
        bool any_empty = false, any_resident = false;
        for (int c = 0; c < 4; ++c) {
          child[c] = state.child(slot, c);
          any_empty |= child[c] == TV_SLOT_EMPTY;
          any_resident |= child[c] < TV_SLOT_INVALID;
        }
        if (!any_empty && any_resident) {
          uint32_t resident = 0;
          for (int c = 0; c < 4; ++c) resident += child[c] < TV_SLOT_INVALID;
          if (next.size() + resident <= cap) {
            for (int c = 0; c < 4; ++c)
              if (child[c] < TV_SLOT_INVALID) {
                next.push_back(child[c]);
                mask &= ~(1u << c);
              }
          } else {
            ++out.overflow;
          }
        }
      } else if (level == kRootLevel) {
        // Coarsest drawing whose error the target still accepts (level 8 only beside roots that
        // do not split, see config.h).
        auto neighbour_splits = [&] {
          const int64_t off[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
          for (const auto& o : off) {
            const uint16_t s = state.root(int64_t(d.x) + o[0], int64_t(d.y) + o[1]);
            if (s < TV_SLOT_INVALID && root_in_window(u, uint32_t(int64_t(d.x) + o[0]), uint32_t(int64_t(d.y) + o[1])) &&
                wants_split(state.descriptor(s), u))
              return true;
          }
          return false;
        };
        for (uint32_t c = TV_MAX_COARSEN; c >= 1; --c)
          if (!wants_split(d, slots[slot].coarse_error[c], u) && (c < 3 || !neighbour_splits())) {
            coarse = c;
            break;
          }
      }
      if (mask != 0) {
        out.entries.push_back(slot | mask << TV_ENTRY_QUAD_SHIFT | coarse << TV_ENTRY_COARSE_SHIFT);
        ++out.level_counts[size_t(level)];
      }
    }
    current.swap(next);
  }
  return out;
}

std::vector<uint32_t> reference_lod_map(const TerrainState& state, const FrameUniforms& u, const NodeList& list) {
  std::vector<uint32_t> map(lod_map_size(u), 0);
  const size_t base = size_t(u.lodwin[2]) * u.lodwin[3];
  // Paint coarse to fine: a finer node always covers area its (partial) parent does not draw.
  std::vector<uint32_t> sorted = list.entries;
  std::sort(sorted.begin(), sorted.end(), [&](uint32_t a, uint32_t b) {
    return state.descriptor(a & TV_ENTRY_SLOT_MASK).level > state.descriptor(b & TV_ENTRY_SLOT_MASK).level;
  });
  for (uint32_t e : sorted) {
    const GpuNodeDesc& d = state.descriptor(e & TV_ENTRY_SLOT_MASK);
    const uint32_t mask = (e >> TV_ENTRY_QUAD_SHIFT) & 0xFu, coarse = (e >> TV_ENTRY_COARSE_SHIFT) & 3u;
    const int level = d.level;
    const uint32_t value = uint32_t(level) + coarse + 1;
    if (level >= kRootLevel) {  // root cells
      const uint32_t rs = 1u << (level - kRootLevel), rhalf = rs >> 1;
      const uint32_t rx0 = d.x << (level - kRootLevel), ry0 = d.y << (level - kRootLevel);
      for (uint32_t j = 0; j < rs && ry0 + j < u.world[1]; ++j)
        for (uint32_t i = 0; i < rs && rx0 + i < u.world[0]; ++i) {
          const uint32_t quadrant = uint32_t(i >= rhalf) | uint32_t(j >= rhalf) << 1;
          if (rs > 1 && !(mask & (1u << quadrant))) continue;
          map[base + size_t(ry0 + j) * u.world[0] + rx0 + i] = value;
        }
    }
    const int64_t size = int64_t(1) << level, half = size >> 1;
    const int64_t x0 = int64_t(d.x) << level, y0 = int64_t(d.y) << level;
    for (int64_t sy = std::max<int64_t>(y0, u.lodwin[1]); sy < std::min<int64_t>(y0 + size, int64_t(u.lodwin[1]) + u.lodwin[3]); ++sy)
      for (int64_t sx = std::max<int64_t>(x0, u.lodwin[0]); sx < std::min<int64_t>(x0 + size, int64_t(u.lodwin[0]) + u.lodwin[2]);
           ++sx) {
        const uint32_t quadrant = level == 0 ? 0u : uint32_t(sx - x0 >= half) | uint32_t(sy - y0 >= half) << 1;
        if (level > 0 && !(mask & (1u << quadrant))) continue;
        map[size_t(sy - u.lodwin[1]) * u.lodwin[2] + size_t(sx - u.lodwin[0])] = value;
      }
  }
  return map;
}

uint32_t decimation_budget(const FrameUniforms& u, const NodeList& list) {
  if (!(u.misc[1] & TV_FLAG_DECIMATE)) return 0;
  uint32_t finest = kRootLevel;
  for (int l = kRootLevel; l >= 0; --l)
    if (list.level_counts[size_t(l)] > 0) finest = uint32_t(l);
  return 7 + finest - kRootLevel;
}

uint32_t max_patch_decimation(const FrameUniforms& u, uint32_t budget, uint32_t c) {
  if (c > 0 && u.misc[0] != uint32_t(kRootLevel)) return 0;  // LOD map values 7.. may be overview nodes
  return budget > c ? std::min<uint32_t>(TV_MAX_DECIMATE, budget - c) : 0u;
}

uint32_t patch_decimation(const TerrainState& state, const FrameUniforms& u, const std::vector<SlotCpuData>& slots,
                          const std::vector<uint32_t>& lod_map, uint32_t slot, uint32_t c, uint32_t px, uint32_t py,
                          uint32_t max_e) {
  // Same operations, in the same order, as patch_decimation() in shaders/patches.comp.
  const GpuNodeDesc& d = state.descriptor(slot);
  if (max_e == 0) return 0;
  // Edges facing a root drawn at coarsening c' (LOD map value 5 + c' + 1): e <= c' - c when
  // c' > c, c - c' + e <= 4 when c' < c (config.h "Patch decimation").
  const int64_t rx = int64_t(d.x) << kRootLevel, ry = int64_t(d.y) << kRootLevel;
  const uint32_t pps = TV_PATCHES_PER_SIDE >> c;
  const int64_t spp = int64_t(TV_SECTORS_PER_ROOT / TV_PATCHES_PER_SIDE) << c;
  const int64_t mx = rx + int64_t(px) * spp + spp / 2, my = ry + int64_t(py) * spp + spp / 2;
  auto cap = [&](int64_t sx, int64_t sy) {
    const int64_t k = lod_index(u, sx, sy);
    if (k < 0) return;
    const uint32_t v = lod_map[size_t(k)];
    if (v >= kRootLevel + 2 + c)
      max_e = std::min(max_e, v - (kRootLevel + 1) - c);
    else if (v >= kRootLevel + 1 && v < kRootLevel + 1 + c)
      max_e = std::min(max_e, TV_QUADS_PER_PATCH_LOG2 + (v - (kRootLevel + 1)) - c);
  };
  if (px == 0) cap(rx - 1, my);
  if (px == pps - 1) cap(rx + TV_SECTORS_PER_ROOT, my);
  if (py == 0) cap(mx, ry - 1);
  if (py == pps - 1) cap(mx, ry + TV_SECTORS_PER_ROOT);
  if (max_e == 0) return 0;
  int32_t lo = INT32_MAX, hi = INT32_MIN;
  coarse_patch_bounds(slots[slot].bounds, c, px, py, lo, hi);
  const int q = TV_QUADS_PER_PATCH;
  const float mnx = rel_x(vertex_half_metres(d.x, kRootLevel, (int(px) * q) << c), u);
  const float mxx = rel_x(vertex_half_metres(d.x, kRootLevel, (int(px + 1) * q) << c), u);
  const float mny = rel_y(vertex_half_metres(d.y, kRootLevel, (int(py) * q) << c), u);
  const float mxy = rel_y(vertex_half_metres(d.y, kRootLevel, (int(py + 1) * q) << c), u);
  const float mnz = rel_z(lo, u);
  const float mxz = rel_z(hi, u);
  const float d2 = box_distance2(mnx, mxx, mny, mxy, mnz, mxz);
  const float t = u.lod[0];
  const auto& errors = slots[slot].patch_error[patch_error_index(c, px, py)];
  for (uint32_t e = max_e; e >= 1; --e) {
    const float err = errors[e - 1] * u.cam_frac[3];
    if (!(err * err > (t * t) * d2)) return e;
  }
  return 0;
}

PatchList reference_patches(const TerrainState& state, const FrameUniforms& u, const NodeList& list,
                            const std::vector<uint32_t>& lod_map, const std::vector<SlotCpuData>& slots,
                            const float* sin2_table) {
  PatchList out;
  auto lod_at = [&](int64_t sx, int64_t sy) -> uint32_t {
    const int64_t k = lod_index(u, sx, sy);
    return k < 0 ? 0u : lod_map[size_t(k)];
  };
  const uint32_t budget = decimation_budget(u, list);
  // Effective level + 1 of the surface drawn at a sector: the LOD map's, plus the decimation of
  // the root patch there when a root draws it (coarsened or not).
  auto eff_at = [&](int64_t sx, int64_t sy) -> uint32_t {
    const uint32_t v = lod_at(sx, sy);
    if (v < kRootLevel + 1 || v > kRootLevel + 1 + TV_MAX_COARSEN) return v;
    const uint32_t c = v - (kRootLevel + 1), max_e = max_patch_decimation(u, budget, c);
    if (max_e == 0) return v;
    const uint16_t root = state.root(sx >> kRootLevel, sy >> kRootLevel);
    const uint32_t sectors_per_patch = (TV_SECTORS_PER_ROOT / TV_PATCHES_PER_SIDE) << c;
    return v + patch_decimation(state, u, slots, lod_map, root, c, uint32_t(sx & (TV_SECTORS_PER_ROOT - 1)) / sectors_per_patch,
                                uint32_t(sy & (TV_SECTORS_PER_ROOT - 1)) / sectors_per_patch, max_e);
  };
  for (uint32_t e : list.entries) {
    const uint32_t slot = e & TV_ENTRY_SLOT_MASK, mask = (e >> TV_ENTRY_QUAD_SHIFT) & 0xFu;
    const uint32_t c = (e >> TV_ENTRY_COARSE_SHIFT) & 3u;
    const GpuNodeDesc& d = state.descriptor(slot);
    const int level = d.level;
    const uint32_t geo = uint32_t(level) + c, pps = TV_PATCHES_PER_SIDE >> c;
    const SlotCpuData& cpu = slots[slot];
    for (uint32_t py = 0; py < pps; ++py)
      for (uint32_t px = 0; px < pps; ++px) {
        const uint32_t quadrant = uint32_t(px >= pps / 2) | uint32_t(py >= pps / 2) << 1;
        if (c == 0 && !(mask & (1u << quadrant))) continue;
        ++out.considered;
        // Decimation: root patches, coarsened or not (their edges then also face decimated patches
        // of the same node, so every edge is looked up).
        const uint32_t max_e = level == kRootLevel ? max_patch_decimation(u, budget, c) : 0u;
        const bool root_patch = max_e > 0;
        const uint32_t dec = root_patch ? patch_decimation(state, u, slots, lod_map, slot, c, px, py, max_e) : 0u;
        // Per-edge LOD deltas (in node vertices at this node's geometric level) from the sector just
        // outside the patch edge's middle: the finer side collapses onto the coarser one.
        const int64_t node_sx = int64_t(d.x) << level, node_sy = int64_t(d.y) << level;
        auto start = [&](int64_t node_s, uint32_t p) { return node_s + (int64_t(p) << level) / pps; };
        const int64_t mid_x = node_sx + ((int64_t(px) * 2 + 1) << level) / (2 * pps);
        const int64_t mid_y = node_sy + ((int64_t(py) * 2 + 1) << level) / (2 * pps);
        auto delta = [&](uint32_t v) -> uint32_t {
          return v > geo + dec + 1 ? std::min<uint32_t>(v - 1 - geo, TV_MAX_DELTA) : 0u;  // clamped: see config.h
        };
        const uint32_t ds = py == 0 || root_patch ? delta(eff_at(mid_x, start(node_sy, py) - 1)) : 0u;
        const uint32_t dw = px == 0 || root_patch ? delta(eff_at(start(node_sx, px) - 1, mid_y)) : 0u;
        const uint32_t dn = py == pps - 1 || root_patch ? delta(eff_at(mid_x, start(node_sy, py + 1))) : 0u;
        const uint32_t de = px == pps - 1 || root_patch ? delta(eff_at(start(node_sx, px + 1), mid_y)) : 0u;
        // Bounds; a south/north edge collapsing groups wider than a patch reaches west into earlier
        // patches of the same row (a west/east edge: south), so the box grows to cover them.
        const uint32_t dsn = std::max(ds, dn), dwe = std::max(dw, de);
        const uint32_t px0 = ((px * TV_QUADS_PER_PATCH) >> dsn << dsn) / TV_QUADS_PER_PATCH;
        const uint32_t py0 = ((py * TV_QUADS_PER_PATCH) >> dwe << dwe) / TV_QUADS_PER_PATCH;
        int32_t lo = INT32_MAX, hi = INT32_MIN;
        coarse_patch_bounds(cpu.bounds, c, px, py, lo, hi);
        for (uint32_t q = px0; q < px; ++q) coarse_patch_bounds(cpu.bounds, c, q, py, lo, hi);
        for (uint32_t q = py0; q < py; ++q) coarse_patch_bounds(cpu.bounds, c, px, q, lo, hi);
        Box b;
        b.mn[0] = rel_x(vertex_half_metres(d.x, level, int(px0 * TV_QUADS_PER_PATCH) << c), u);
        b.mx[0] = rel_x(vertex_half_metres(d.x, level, int((px + 1) * TV_QUADS_PER_PATCH) << c), u);
        b.mn[1] = rel_y(vertex_half_metres(d.y, level, int(py0 * TV_QUADS_PER_PATCH) << c), u);
        b.mx[1] = rel_y(vertex_half_metres(d.y, level, int((py + 1) * TV_QUADS_PER_PATCH) << c), u);
        b.mn[2] = rel_z(lo, u);
        b.mx[2] = rel_z(hi, u);
        if ((u.misc[1] & TV_FLAG_FRUSTUM_CULL) && !frustum_visible(b, u)) {
          ++out.culled_frustum;
          continue;
        }
        const uint32_t deltas = ds << TV_EDGE_S | dw << TV_EDGE_W | dn << TV_EDGE_N | de << TV_EDGE_E;
        // The cooked cones cover the node's own triangles, stitched up to kConeMaxStitchDelta, but
        // not those touching hole vertices: with holes drawn, nodes with holes are not culled.
        const bool cones_valid = (u.misc[1] & TV_FLAG_HOLES) || !(d.flags & kNodeFlagHasHoles);
        if ((u.misc[1] & TV_FLAG_CONE_CULL) && c == 0 && dec == 0 && std::max(dsn, dwe) <= kConeMaxStitchDelta && cones_valid &&
            cone_backfacing(b, decode_cone(cpu.cones[py * 8 + px], sin2_table))) {
          ++out.culled_cone;
          continue;
        }
        // Shading group (same operations as patches.comp).
        bool near = false;
        if (u.misc[1] & TV_FLAG_SPLAT) {
          const float nx = std::max(std::max(b.mn[0], -b.mx[0]), 0.0f);
          const float ny = std::max(std::max(b.mn[1], -b.mx[1]), 0.0f);
          const float nz = std::max(std::max(b.mn[2], -b.mx[2]), 0.0f);
          const float n2 = nx * nx + ny * ny + nz * nz;
          near = n2 < u.lod[3] * u.lod[3];
        }
        GpuPatch p;
        p.slot_patch_level = slot | px << TV_PATCH_PX_SHIFT | py << TV_PATCH_PY_SHIFT | geo << TV_PATCH_LEVEL_SHIFT |
                             dec << TV_PATCH_DECIM_SHIFT | c << TV_PATCH_COARSE_SHIFT;
        p.edge_deltas = deltas | (near ? TV_PATCH_NEAR_BIT : 0u);
        p.node_x = d.x;
        p.node_y = d.y;
        out.patches.push_back(p);
      }
  }
  return out;
}

PatchMesh patch_mesh(const GpuPatch& p) {
  PatchMesh m;
  m.px = int(patch_px(p));
  m.py = int(patch_py(p));
  m.decimation = int(patch_decimation(p));
  m.deltas = {int(edge_delta(p, TV_EDGE_S)), int(edge_delta(p, TV_EDGE_W)), int(edge_delta(p, TV_EDGE_N)),
              int(edge_delta(p, TV_EDGE_E))};
  return m;
}

void stitch_vertex(const GpuPatch& p, int i, int j, int& ni, int& nj) {
  const NodeVertex v = stitched_vertex(patch_mesh(p), i, j);
  ni = v.i;
  nj = v.j;
}

void patch_vertex(const GpuPatch& p, int i, int j, int64_t& hx, int64_t& hy, int& ti, int& tj) {
  int ni, nj;
  stitch_vertex(p, i, j, ni, nj);
  const uint32_t c = patch_coarsening(p);
  const int level = patch_node_level(p);
  ti = ni << c;
  tj = nj << c;
  hx = vertex_half_metres(p.node_x, level, ti);
  hy = vertex_half_metres(p.node_y, level, tj);
}

}  // namespace terrain::view
