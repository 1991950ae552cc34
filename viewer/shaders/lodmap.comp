#version 450
// LOD map (FC5 section 4.3): one thread per sector finds the node of this frame's list that draws
// it (the selection grid, stamped by the traversal) and writes its level + 1; 0 = nothing drawn.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = TV_LODMAP_GROUP, local_size_y = TV_LODMAP_GROUP) in;
layout(std430, set = 0, binding = 5) readonly buffer Selection { uint selection[]; };
layout(std430, set = 0, binding = 6) writeonly buffer LodMap { uint lod_map[]; };

void main() {
  uvec2 s = gl_GlobalInvocationID.xy;
  if (s.x >= frame.world.z || s.y >= frame.world.w) return;
  uint value = 0u;
  for (int level = TV_ROOT_LEVEL; level >= 0; --level) {
    uint l = uint(level);
    uint word = selection[level_offset(l) + (s.y >> l) * level_width(l) + (s.x >> l)];
    if ((word >> TV_SELECT_STAMP_SHIFT) != (frame.misc.x & TV_STAMP_MASK)) continue;
    uint q = l == 0u ? 0u : ((s.x >> (l - 1u)) & 1u) | (((s.y >> (l - 1u)) & 1u) << 1);
    if ((word & (1u << q)) != 0u) {
      value = l + ((word >> TV_SELECT_COARSE_SHIFT) & 3u) + 1u;
      break;
    }
  }
  lod_map[s.y * frame.world.z + s.x] = value;
}
