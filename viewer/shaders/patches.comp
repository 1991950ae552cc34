#version 450
// Visible render patch list (FC5 sections 4.4 and 5): one workgroup per listed node, one thread per
// patch: frustum cull, patch-cone backface cull, per-edge LOD deltas from the LOD map, then append to
// the instance buffer of the single indirect draw. Mirrors reference_patches() in src/reference.cpp.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = TV_PATCH_GROUP) in;
layout(std430, set = 0, binding = 5) readonly buffer PatchWork { uint patch_work[]; };
layout(std430, set = 0, binding = 4) readonly buffer NodeList { uint node_list[]; };
layout(std430, set = 0, binding = 6) readonly buffer LodMap { uint lod_map[]; };
layout(std430, set = 0, binding = 7) buffer Draw { uint draw[]; };
layout(std430, set = 0, binding = 8) writeonly buffer Patches { uvec4 patches[]; };
layout(set = 0, binding = 13) uniform sampler2DArray cones_tex;
// Per root patch of each coarsening (config.h): total error (m) drawn with decimation e = 1..4 in component e - 1.
layout(std430, set = 0, binding = 16) readonly buffer PatchErrors { vec4 patch_error[]; };

uint lod_at(int sx, int sy) {
  int k = lod_index(sx, sy);
  return k < 0 ? 0u : lod_map[k];
}
// A neighbour drawn coarser than this patch (effective level `own`): collapse by its level
// minus this node's geometric level. Collapsing needs 2^d <= 128 (a node edge): a larger d is
// clamped to TV_MAX_DELTA and counted (the edge may crack there; the viewer warns).
uint delta_of(uint v, uint own, uint geo) {
  uint d = v > own + 1u ? v - 1u - geo : 0u;
  if (d > uint(TV_MAX_DELTA)) {
    atomicAdd(draw[TV_CNT_DEEP], 1u);
    d = uint(TV_MAX_DELTA);
  }
  return d;
}

bool frustum_visible(vec3 mn, vec3 mx) {
  for (int p = 0; p < 6; ++p) {
    vec4 n = frame.planes[p];
    float px = n.x >= 0.0 ? mx.x : mn.x;
    float py = n.y >= 0.0 ? mx.y : mn.y;
    float pz = n.z >= 0.0 ? mx.z : mn.z;
    precise float s = n.x * px + n.y * py + n.z * pz + n.w;
    if (s < 0.0) return false;
  }
  return true;
}

// Bounds of patch (px, py) of a node drawn with coarsening c: its (1 << c)^2 node patches.
ivec2 coarse_patch_bounds(uint base, uint c, uint px, uint py, ivec2 b) {
  for (uint q = py << c; q < ((py + 1u) << c); ++q)
    for (uint p = px << c; p < ((px + 1u) << c); ++p) {
      ivec2 o = patch_bounds[base + q * 8u + p];
      b = ivec2(min(b.x, o.x), max(b.y, o.y));
    }
  return b;
}

// Largest c + e of a root patch this frame allows (decimation_budget() in src/reference.cpp).
uint decimation_budget() {
  if ((frame.misc.y & TV_FLAG_DECIMATE) == 0u) return 0u;
  uint finest = uint(TV_ROOT_LEVEL);
  for (int l = TV_ROOT_LEVEL; l >= 0; --l)
    if (node_list[TV_NL_LEVEL_COUNTS + l] > 0u) finest = uint(l);
  return 7u + finest - uint(TV_ROOT_LEVEL);
}

// max_patch_decimation() in src/reference.cpp.
uint max_patch_decimation(uint budget, uint c) {
  if (c > 0u && frame.misc.x != uint(TV_ROOT_LEVEL)) return 0u;  // LOD map values 7.. may be overview nodes
  return budget > c ? min(uint(TV_MAX_DECIMATE), budget - c) : 0u;
}

// Same operations, in the same order, as patch_decimation() in src/reference.cpp, trying
// e = max_e down to above_e + 1 only (0 when none passes: the caller only asks whether e > above_e).
// On an edge facing a root drawn at coarsening c' (LOD map 5 + c' + 1): e <= c' - c when c' > c
// (the wider patches there must never be the finer side), c - c' + e <= 4 when c' < c (the
// narrower patches there collapse within themselves). Config.h "Patch decimation".
uint neighbour_cap(uint max_e, uint c, uint v) {
  if (v >= uint(TV_ROOT_LEVEL + 2) + c) return min(max_e, v - uint(TV_ROOT_LEVEL + 1) - c);
  if (v >= uint(TV_ROOT_LEVEL + 1) && v < uint(TV_ROOT_LEVEL + 1) + c)
    return min(max_e, uint(TV_QUADS_PER_PATCH_LOG2) + (v - uint(TV_ROOT_LEVEL + 1)) - c);
  return max_e;
}

uint patch_decimation(uint slot, uint c, uint px, uint py, uint max_e, uint above_e) {
  NodeDesc d = nodes[slot];
  if (max_e == 0u) return 0u;
  int rx = int(d.x) << TV_ROOT_LEVEL, ry = int(d.y) << TV_ROOT_LEVEL;
  uint pps = uint(TV_PATCHES_PER_SIDE) >> c;
  int spp = (TV_SECTORS_PER_ROOT / TV_PATCHES_PER_SIDE) << c;
  int mx = rx + int(px) * spp + spp / 2, my = ry + int(py) * spp + spp / 2;
  if (px == 0u) max_e = neighbour_cap(max_e, c, lod_at(rx - 1, my));
  if (px == pps - 1u) max_e = neighbour_cap(max_e, c, lod_at(rx + TV_SECTORS_PER_ROOT, my));
  if (py == 0u) max_e = neighbour_cap(max_e, c, lod_at(mx, ry - 1));
  if (py == pps - 1u) max_e = neighbour_cap(max_e, c, lod_at(mx, ry + TV_SECTORS_PER_ROOT));
  if (max_e <= above_e) return 0u;
  ivec2 b = coarse_patch_bounds(slot * uint(TV_PATCHES_PER_NODE), c, px, py, ivec2(0x7FFFFFFF, -0x7FFFFFFF - 1));
  uint q = uint(TV_QUADS_PER_PATCH);
  float mnx = rel_x(half_metres(d.x, uint(TV_ROOT_LEVEL), (px * q) << c));
  float mxx = rel_x(half_metres(d.x, uint(TV_ROOT_LEVEL), ((px + 1u) * q) << c));
  float mny = rel_y(half_metres(d.y, uint(TV_ROOT_LEVEL), (py * q) << c));
  float mxy = rel_y(half_metres(d.y, uint(TV_ROOT_LEVEL), ((py + 1u) * q) << c));
  float mnz = rel_z(b.x);
  float mxz = rel_z(b.y);
  precise float dx = max(max(mnx, -mxx), 0.0);
  precise float dy = max(max(mny, -mxy), 0.0);
  precise float dz = max(max(mnz, -mxz), 0.0);
  precise float d2 = dx * dx + dy * dy + dz * dz;
  precise float t = frame.lod.x;
  vec4 errors = patch_error[slot * uint(TV_PATCH_ERRORS_PER_NODE) + uint(TV_PATCH_ERROR_BASE(c)) + py * pps + px];
  for (uint e = max_e; e > above_e; --e) {
    precise float err = errors[e - 1u] * frame.cam_frac.w;
    precise float lhs = err * err;
    precise float rhs = (t * t) * d2;
    if (!(lhs > rhs)) return e;
  }
  return 0u;
}

// Effective level + 1 of the surface drawn at a sector: the LOD map's, plus the decimation of the
// root patch there when a root draws it (coarsened or not). Exact only when above `own` (the
// effective level of the asking patch): only a coarser neighbour changes a delta.
uint eff_at(int sx, int sy, uint budget, uint own) {
  uint v = lod_at(sx, sy);
  if (v < uint(TV_ROOT_LEVEL + 1) || v > uint(TV_ROOT_LEVEL + 1 + TV_MAX_COARSEN)) return v;
  uint c = v - uint(TV_ROOT_LEVEL + 1);
  uint max_e = max_patch_decimation(budget, c);
  uint above = own + 1u > v ? own + 1u - v : 0u;
  if (max_e <= above) return v;
  uint root = texelFetch(root_tex, ivec2(sx >> TV_ROOT_LEVEL, sy >> TV_ROOT_LEVEL), 0).r;
  int spp = (TV_SECTORS_PER_ROOT / TV_PATCHES_PER_SIDE) << c;
  return v + patch_decimation(root, c, uint((sx & (TV_SECTORS_PER_ROOT - 1)) / spp),
                              uint((sy & (TV_SECTORS_PER_ROOT - 1)) / spp), max_e, above);
}

float cone_sin2(uint a) { return palette.cone_sin2[a >> 2][a & 3u]; }

// Cone texel -> axis (layout: terrain/surface_contract.h; same operations as decode_cone() in
// src/node_prep.cpp), then the 8-corner test: dot(v, a) >= sin(theta) |v| |a|, squared.
bool cone_backfacing(vec3 mn, vec3 mx, uvec4 t) {
  float sin2 = cone_sin2(t.a);
  if (!(sin2 >= 0.0)) return false;
  precise float ax = (float(t.r) - float(TV_CONE_R_CENTRE)) * (1.0 / float(TV_CONE_R_SCALE));
  precise float ay = (float(t.g) - float(TV_CONE_G_CENTRE)) * (1.0 / float(TV_CONE_G_SCALE));
  precise float rr = ax * ax + ay * ay;
  precise float az = rr < 1.0 ? sqrt(1.0 - rr) : 0.0;
  precise float aa = ax * ax + ay * ay + az * az;
  for (int k = 0; k < 8; ++k) {
    float vx = (k & 1) != 0 ? mx.x : mn.x;
    float vy = (k & 2) != 0 ? mx.y : mn.y;
    float vz = (k & 4) != 0 ? mx.z : mn.z;
    precise float d = ax * vx + ay * vy + az * vz;
    precise float vv = vx * vx + vy * vy + vz * vz;
    precise float lhs = d * d;
    precise float rhs = sin2 * (vv * aa);
    if (!(d >= 0.0) || !(lhs >= rhs)) return false;
  }
  return true;
}

void main() {
  if (gl_GlobalInvocationID.x >= node_list[TV_NL_PATCH_ITEMS]) return;
  uint item = patch_work[gl_GlobalInvocationID.x];  // a patch of a drawn quadrant
  uint entry = node_list[TV_NL_HEADER + (item & 0xFFFFu)];
  uint slot = entry & TV_ENTRY_SLOT_MASK;
  uint c = (entry >> TV_ENTRY_COARSE_SHIFT) & 3u;
  uint pps = uint(TV_PATCHES_PER_SIDE) >> c;
  uint px = (item >> 16) & 7u, py = (item >> 19) & 7u;
  NodeDesc d = nodes[slot];
  uint level = node_level(d);
  uint geo = level + c;
  // Decimation: root patches, coarsened or not (their edges then also face decimated patches of
  // the same node, so every edge is looked up).
  uint budget = decimation_budget();
  uint max_e = level == uint(TV_ROOT_LEVEL) ? max_patch_decimation(budget, c) : 0u;
  bool root_patch = max_e > 0u;
  uint dec = root_patch ? patch_decimation(slot, c, px, py, max_e, 0u) : 0u;
  // Per-edge LOD deltas (node vertices at the geometric level) from the sector just outside the
  // patch edge's middle: the finer side collapses onto the coarser one.
  int node_sx = int(d.x << level), node_sy = int(d.y << level);
  int mid_x = node_sx + int(((px * 2u + 1u) << level) / (2u * pps));
  int mid_y = node_sy + int(((py * 2u + 1u) << level) / (2u * pps));
  int x0 = node_sx + int((px << level) / pps), x1 = node_sx + int(((px + 1u) << level) / pps);
  int y0 = node_sy + int((py << level) / pps), y1 = node_sy + int(((py + 1u) << level) / pps);
  uint own = geo + dec;
  uint ds = py == 0u || root_patch ? delta_of(eff_at(mid_x, y0 - 1, budget, own), own, geo) : 0u;
  uint dw = px == 0u || root_patch ? delta_of(eff_at(x0 - 1, mid_y, budget, own), own, geo) : 0u;
  uint dn = py == pps - 1u || root_patch ? delta_of(eff_at(mid_x, y1, budget, own), own, geo) : 0u;
  uint de = px == pps - 1u || root_patch ? delta_of(eff_at(x1, mid_y, budget, own), own, geo) : 0u;

  // Bounds, grown over the earlier patches a wide stitch collapses onto (see reference.cpp).
  uint dsn = max(ds, dn), dwe = max(dw, de);
  uint px0 = (((px * uint(TV_QUADS_PER_PATCH)) >> dsn) << dsn) / uint(TV_QUADS_PER_PATCH);
  uint py0 = (((py * uint(TV_QUADS_PER_PATCH)) >> dwe) << dwe) / uint(TV_QUADS_PER_PATCH);
  uint base = slot * uint(TV_PATCHES_PER_NODE);
  ivec2 b = coarse_patch_bounds(base, c, px, py, ivec2(0x7FFFFFFF, -0x7FFFFFFF - 1));
  for (uint q = px0; q < px; ++q) b = coarse_patch_bounds(base, c, q, py, b);
  for (uint q = py0; q < py; ++q) b = coarse_patch_bounds(base, c, px, q, b);
  uint q16 = uint(TV_QUADS_PER_PATCH);
  vec3 mn = vec3(rel_x(half_metres(d.x, level, (px0 * q16) << c)), rel_y(half_metres(d.y, level, (py0 * q16) << c)),
                 rel_z(b.x));
  vec3 mx = vec3(rel_x(half_metres(d.x, level, ((px + 1u) * q16) << c)),
                 rel_y(half_metres(d.y, level, ((py + 1u) * q16) << c)), rel_z(b.y));
  uint flags = frame.misc.y;
  if ((flags & TV_FLAG_FRUSTUM_CULL) != 0u && !frustum_visible(mn, mx)) {
    atomicAdd(draw[TV_CNT_FRUSTUM], 1u);
    return;
  }
  uint deltas = (ds << TV_EDGE_S) | (dw << TV_EDGE_W) | (dn << TV_EDGE_N) | (de << TV_EDGE_E);
  // The cooked cones cover the node's own triangles, stitched up to d = 4 (terrain/surface_contract.h).
  // Cones leave out triangles touching hole vertices: with holes drawn, nodes with holes are not culled.
  bool cones_valid = (flags & TV_FLAG_HOLES) != 0u || ((d.packed >> 16) & 1u) == 0u;
  if ((flags & TV_FLAG_CONE_CULL) != 0u && c == 0u && dec == 0u && max(dsn, dwe) <= 4u && cones_valid) {
    uvec4 t = uvec4(round(texelFetch(cones_tex, ivec3(int(px), int(py), int(slot)), 0) * 255.0));
    if (cone_backfacing(mn, mx, t)) {
      atomicAdd(draw[TV_CNT_CONE], 1u);
      return;
    }
  }
  // Shading group: near when the box is closer than the end of the near-shading range.
  bool near = false;
  if ((flags & TV_FLAG_SPLAT) != 0u) {
    precise float nx = max(max(mn.x, -mx.x), 0.0);
    precise float ny = max(max(mn.y, -mx.y), 0.0);
    precise float nz = max(max(mn.z, -mx.z), 0.0);
    precise float n2 = nx * nx + ny * ny + nz * nz;
    precise float r2 = frame.lod.w * frame.lod.w;
    near = n2 < r2;
  }
  uint range = (near ? 0u : uint(TV_MESHES)) + dec;
  uint k = frame.misc.w * range + atomicAdd(draw[range * 5u + 1u], 1u);
  patches[k] = uvec4(slot | (px << TV_PATCH_PX_SHIFT) | (py << TV_PATCH_PY_SHIFT) | (geo << TV_PATCH_LEVEL_SHIFT) |
                         (dec << TV_PATCH_DECIM_SHIFT) | (c << TV_PATCH_COARSE_SHIFT),
                     deltas | (near ? TV_PATCH_NEAR_BIT : 0u), d.x, d.y);
}
