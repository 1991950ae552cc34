#version 450
// Visible render patch list (FC5 sections 4.4 and 5): one workgroup per listed node, one thread per
// patch: frustum cull, patch-cone backface cull, per-edge LOD deltas from the LOD map, then append to
// the instance buffer of the single indirect draw. Mirrors reference_patches() in src/reference.cpp.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = TV_PATCHES_PER_SIDE, local_size_y = TV_PATCHES_PER_SIDE) in;
layout(std430, set = 0, binding = 4) readonly buffer NodeList { uint node_list[]; };
layout(std430, set = 0, binding = 6) readonly buffer LodMap { uint lod_map[]; };
layout(std430, set = 0, binding = 7) buffer Draw { uint draw[]; };
layout(std430, set = 0, binding = 8) writeonly buffer Patches { uvec4 patches[]; };
layout(set = 0, binding = 13) uniform sampler2DArray cones_tex;

uint lod_at(int sx, int sy) {
  if (sx < 0 || sy < 0 || sx >= int(frame.world.z) || sy >= int(frame.world.w)) return 0u;
  return lod_map[uint(sy) * frame.world.z + uint(sx)];
}
uint delta_of(uint v, uint level) { return v > level + 1u ? v - 1u - level : 0u; }

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

float cone_sin2(uint a) { return palette.cone_sin2[a >> 2][a & 3u]; }

// Cone texel -> axis (layout: cooker/src/surface/cone_cull.h; same operations as decode_cone() in
// src/node_prep.cpp), then the 8-corner test: dot(v, a) >= sin(theta) |v| |a|, squared.
bool cone_backfacing(vec3 mn, vec3 mx, uvec4 t) {
  float sin2 = cone_sin2(t.a);
  if (!(sin2 >= 0.0)) return false;
  precise float ax = (float(t.r) - 132.0) * (1.0 / 123.0);
  precise float ay = (float(t.g) - 130.0) * (1.0 / 125.0);
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

// Bounds of patch (px, py) of a node drawn with coarsening c: its (1 << c)^2 node patches.
ivec2 coarse_patch_bounds(uint base, uint c, uint px, uint py, ivec2 b) {
  for (uint q = py << c; q < ((py + 1u) << c); ++q)
    for (uint p = px << c; p < ((px + 1u) << c); ++p) {
      ivec2 o = patch_bounds[base + q * 8u + p];
      b = ivec2(min(b.x, o.x), max(b.y, o.y));
    }
  return b;
}

void main() {
  uint entry = node_list[TV_NL_HEADER + gl_WorkGroupID.x];
  uint slot = entry & TV_ENTRY_SLOT_MASK;
  uint mask = (entry >> TV_ENTRY_QUAD_SHIFT) & 15u;
  uint c = (entry >> TV_ENTRY_COARSE_SHIFT) & 3u;
  uint pps = uint(TV_PATCHES_PER_SIDE) >> c;
  uint px = gl_LocalInvocationID.x, py = gl_LocalInvocationID.y;
  if (px >= pps || py >= pps) return;
  uint quadrant = (px >= pps / 2u ? 1u : 0u) | (py >= pps / 2u ? 2u : 0u);
  if (c == 0u && (mask & (1u << quadrant)) == 0u) return;
  atomicAdd(draw[TV_CNT_CONSIDERED], 1u);
  NodeDesc d = nodes[slot];
  uint level = node_level(d);
  uint geo = level + c;

  int node_sx = int(d.x << level), node_sy = int(d.y << level);
  int mid_x = node_sx + int(((px * 2u + 1u) << level) / (2u * pps));
  int mid_y = node_sy + int(((py * 2u + 1u) << level) / (2u * pps));
  int size = 1 << level;
  uint ds = py == 0u ? delta_of(lod_at(mid_x, node_sy - 1), geo) : 0u;
  uint dw = px == 0u ? delta_of(lod_at(node_sx - 1, mid_y), geo) : 0u;
  uint dn = py == pps - 1u ? delta_of(lod_at(mid_x, node_sy + size), geo) : 0u;
  uint de = px == pps - 1u ? delta_of(lod_at(node_sx + size, mid_y), geo) : 0u;

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
  // The cooked cones cover the node's own triangles, stitched up to d = 4 (cone_cull.h).
  // Cones leave out triangles touching hole vertices: with holes drawn, nodes with holes are not culled.
  bool cones_valid = (flags & TV_FLAG_HOLES) != 0u || ((d.packed >> 16) & 1u) == 0u;
  if ((flags & TV_FLAG_CONE_CULL) != 0u && c == 0u && max(dsn, dwe) <= 4u && cones_valid) {
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
  uint k = near ? atomicAdd(draw[TV_DRAW_NEAR + 1], 1u) : frame.misc.w + atomicAdd(draw[TV_DRAW_FAR + 1], 1u);
  patches[k] = uvec4(slot | (px << TV_PATCH_PX_SHIFT) | (py << TV_PATCH_PY_SHIFT) | (geo << TV_PATCH_LEVEL_SHIFT),
                     deltas | (near ? TV_PATCH_NEAR_BIT : 0u), d.x, d.y);
}
