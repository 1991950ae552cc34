#version 450
// LOD map (FC5 section 4.3): every place holds the geometric level + 1 of the node of this frame's
// list that draws it; 0 = nothing drawn (the buffer is cleared before the traversal). One
// workgroup per listed node scatters its level over the quadrants it draws: the 64 m sectors of
// the window around the camera, and for nodes of level >= 5 the root cells (config.h "LOD map").
// A CPU device runs ~10k invocations here instead of one per sector searching 6 levels (measured
// 1.2 ms -> see viewer/README.md).
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = TV_LODMAP_GROUP) in;
layout(std430, set = 0, binding = 4) readonly buffer NodeList { uint node_list[]; };
layout(std430, set = 0, binding = 6) writeonly buffer LodMap { uint lod_map[]; };
// The same buffer as groups of 4 sectors (window rows are a multiple of 32 sectors): nodes of
// level >= 3 (quadrants of 4+ sectors) start on a multiple of 4 sectors and write 4 at once.
layout(std430, set = 0, binding = 6) writeonly buffer LodMap4 { uvec4 lod_map4[]; };

void main() {
  uint entry = node_list[TV_NL_HEADER + gl_WorkGroupID.x];
  NodeDesc d = nodes[entry & TV_ENTRY_SLOT_MASK];
  uint mask = (entry >> TV_ENTRY_QUAD_SHIFT) & 15u;
  uint c = (entry >> TV_ENTRY_COARSE_SHIFT) & 3u;
  uint level = node_level(d);
  uint size = 1u << level, half_size = size >> 1;
  uint value = level + c + 1u;
  uint x0 = d.x << level, y0 = d.y << level;
  // Root cells (levels >= 5): read where the window does not reach.
  if (level >= uint(TV_ROOT_LEVEL)) {
    uint rs = 1u << (level - uint(TV_ROOT_LEVEL)), rhalf = rs >> 1;
    uint rx0 = d.x << (level - uint(TV_ROOT_LEVEL)), ry0 = d.y << (level - uint(TV_ROOT_LEVEL));
    uint rw = min(rx0 + rs, frame.world.x) - min(rx0, frame.world.x);
    uint rh = min(ry0 + rs, frame.world.y) - min(ry0, frame.world.y);
    uint base = frame.lodwin.z * frame.lodwin.w;
    for (uint k = gl_LocalInvocationIndex; k < rw * rh; k += uint(TV_LODMAP_GROUP)) {
      uint i = k % rw, j = k / rw;
      uint quadrant = rs == 1u ? 0u : (i >= rhalf ? 1u : 0u) | (j >= rhalf ? 2u : 0u);
      if (rs > 1u && (mask & (1u << quadrant)) == 0u) continue;
      lod_map[base + (ry0 + j) * frame.world.x + rx0 + i] = value;
    }
  }
  // Sectors inside the window.
  uint ax0 = max(x0, frame.lodwin.x), ax1 = min(x0 + size, frame.lodwin.x + frame.lodwin.z);
  uint ay0 = max(y0, frame.lodwin.y), ay1 = min(y0 + size, frame.lodwin.y + frame.lodwin.w);
  if (ax0 >= ax1 || ay0 >= ay1) return;
  uint cw = ax1 - ax0, ch = ay1 - ay0;
  if (level >= 3u) {
    uint groups = cw >> 2;  // groups of 4 sectors per row
    for (uint k = gl_LocalInvocationIndex; k < groups * ch; k += uint(TV_LODMAP_GROUP)) {
      uint sx = ax0 + (k % groups) * 4u, sy = ay0 + k / groups;
      uint quadrant = (sx - x0 >= half_size ? 1u : 0u) | (sy - y0 >= half_size ? 2u : 0u);
      if ((mask & (1u << quadrant)) == 0u) continue;
      lod_map4[((sy - frame.lodwin.y) * frame.lodwin.z + sx - frame.lodwin.x) / 4u] = uvec4(value);
    }
    return;
  }
  for (uint k = gl_LocalInvocationIndex; k < cw * ch; k += uint(TV_LODMAP_GROUP)) {
    uint sx = ax0 + k % cw, sy = ay0 + k / cw;
    uint quadrant = level == 0u ? 0u : (sx - x0 >= half_size ? 1u : 0u) | (sy - y0 >= half_size ? 2u : 0u);
    if (level > 0u && (mask & (1u << quadrant)) == 0u) continue;
    lod_map[(sy - frame.lodwin.y) * frame.lodwin.z + sx - frame.lodwin.x] = value;
  }
}
