#version 450
// One instance per visible patch, 17x17 vertices of the shared grid. Heights come from the R16
// atlas (integer units -> one float multiply, so shared vertices are bit-identical); edge vertices
// collapse onto the coarser neighbour's vertices (groups of 2^d onto the group's first, any d);
// hole vertices drop their triangles.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(std430, set = 0, binding = 8) readonly buffer Patches { uvec4 patches[]; };
layout(set = 0, binding = 9) uniform usampler2DArray heights_tex;
layout(set = 0, binding = 11) uniform sampler2DArray albedo_tex;

// Few varyings: a CPU rasteriser sets up every one of them for every triangle.
layout(location = 0) out float v_dist;        // distance to the camera (m; linear over a triangle is
                                              // within fog's and the near blend's needs, 2 fewer varyings)
layout(location = 1) out vec2 v_node;         // node-local vertex coordinates (0..128)
layout(location = 2) out float v_hole;        // > 0 inside triangles touching a hole vertex
layout(location = 3) flat out uvec4 v_patch;  // the patch entry

void main() {
  uvec4 p = patches[gl_InstanceIndex];  // includes firstInstance: the far list starts at capacity
  uint slot = p.x & 0xFFFFu;
  uint px = (p.x >> TV_PATCH_PX_SHIFT) & 7u, py = (p.x >> TV_PATCH_PY_SHIFT) & 7u;
  uint geo = (p.x >> TV_PATCH_LEVEL_SHIFT) & 15u;  // geometric level (6, 7: a coarsened root)
  uint level = min(geo, uint(TV_ROOT_LEVEL));
  uint c = geo - level;
  uint e = (p.x >> TV_PATCH_DECIM_SHIFT) & 7u;  // decimation: mesh of n = 16 >> e quads per side
  uint n = uint(TV_QUADS_PER_PATCH) >> e;
  uint i = uint(gl_VertexIndex) % (n + 1u), j = uint(gl_VertexIndex) / (n + 1u);
  uint ni = px * uint(TV_QUADS_PER_PATCH) + (i << e), nj = py * uint(TV_QUADS_PER_PATCH) + (j << e);
  // Stitching (stitch_vertex() in src/reference.cpp).
  uint ds = (p.y >> TV_EDGE_S) & 15u, dw = (p.y >> TV_EDGE_W) & 15u;
  uint dn = (p.y >> TV_EDGE_N) & 15u, de = (p.y >> TV_EDGE_E) & 15u;
  if ((frame.misc.y & TV_FLAG_NO_STITCH) != 0u) ds = dw = dn = de = 0u;
  if (j == 0u && ds > 0u) ni = (ni >> ds) << ds;
  if (j == n && dn > 0u) ni = (ni >> dn) << dn;
  if (i == 0u && dw > 0u) nj = (nj >> dw) << dw;
  if (i == n && de > 0u) nj = (nj >> de) << de;

  ni <<= c;  // coarsened roots read every (1 << c)-th vertex
  nj <<= c;
  NodeDesc d = nodes[slot];
  uint r = texelFetch(heights_tex, ivec3(int(ni), int(nj), int(slot)), 0).r;
  int units = d.height_offset + (int(r) << node_step(d));
  vec3 pos = vec3(rel_x(half_metres(p.z, level, ni)), rel_y(half_metres(p.w, level, nj)), rel_z(units));
  gl_Position = frame.view_proj * vec4(pos, 1.0);

  // Only nodes flagged kNodeFlagHasHoles (bit 0 of the flags byte) pay for the BC1 fetch.
  bool hole = ((d.packed >> 16) & 1u) != 0u &&
              texelFetch(albedo_tex, ivec3(int(ni) + TV_APRON, int(nj) + TV_APRON, int(slot)), 0).a < 0.5;
  v_hole = 0.0;
  uint flags = frame.misc.y;
  if (hole && (flags & TV_FLAG_HOLES) != 0u) {
    if ((flags & TV_FLAG_HOLE_NAN) != 0u) gl_Position = vec4(uintBitsToFloat(0x7FC00000u));
    else v_hole = 1.0;  // defined method: the fragment shader discards where this is > 0
  } else if (hole) {
    v_hole = -1.0;       // holes kept (debug view marks them)
  }
  v_dist = length(pos);
  v_node = vec2(ni, nj);
  v_patch = p;
}
