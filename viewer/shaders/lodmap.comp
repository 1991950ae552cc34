#version 450
// LOD map (FC5 section 4.3): every sector holds the geometric level + 1 of the node of this frame's
// list that draws it; 0 = nothing drawn (the buffer is cleared before the traversal). One
// workgroup per listed node scatters its level over the sectors of the quadrants it draws: a CPU
// device runs ~10k invocations here instead of one per sector searching 6 levels (measured
// 1.2 ms -> see viewer/README.md).
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = TV_LODMAP_GROUP) in;
layout(std430, set = 0, binding = 4) readonly buffer NodeList { uint node_list[]; };
layout(std430, set = 0, binding = 6) writeonly buffer LodMap { uint lod_map[]; };
// The same buffer as groups of 4 sectors (rows hold roots_x * 32 sectors): nodes of level >= 3
// (quadrants of 4+ sectors) start on a multiple of 4 sectors and write 4 at once.
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
  if (level >= 3u) {
    uint groups = size >> 2;  // groups of 4 sectors per row
    for (uint k = gl_LocalInvocationIndex; k < groups * size; k += uint(TV_LODMAP_GROUP)) {
      uint g = k % groups, j = k / groups;
      uint quadrant = (g * 4u >= half_size ? 1u : 0u) | (j >= half_size ? 2u : 0u);
      if ((mask & (1u << quadrant)) == 0u) continue;
      lod_map4[((y0 + j) * frame.world.z + x0) / 4u + g] = uvec4(value);
    }
    return;
  }
  for (uint k = gl_LocalInvocationIndex; k < size * size; k += uint(TV_LODMAP_GROUP)) {
    uint i = k & (size - 1u), j = k >> level;
    uint quadrant = level == 0u ? 0u : (i >= half_size ? 1u : 0u) | (j >= half_size ? 2u : 0u);
    if (level > 0u && (mask & (1u << quadrant)) == 0u) continue;
    lod_map[(y0 + j) * frame.world.z + x0 + i] = value;
  }
}
