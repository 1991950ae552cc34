#version 450
// One instance per visible patch, 17x17 vertices of the shared grid. Heights come from the R16
// atlas (integer units -> one float multiply, so shared vertices are bit-identical); edge vertices
// collapse onto the coarser neighbour's vertices (groups of 2^d onto the group's first, any d);
// hole vertices drop their triangles.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
#include "stitch.glsl"

layout(std430, set = 0, binding = 8) readonly buffer Patches { uvec4 patches[]; };
layout(set = 0, binding = 9) uniform usampler2DArray heights_tex;
layout(set = 0, binding = 11) uniform sampler2DArray albedo_tex;

// Few varyings: a CPU rasteriser sets up every one of them for every triangle.
layout(location = 0) out float v_dist;        // distance to the camera (m; linear over a triangle is
                                              // within fog's and the near blend's needs, 2 fewer varyings)
layout(location = 1) out vec2 v_node;         // node-local vertex coordinates (0..128)
layout(location = 2) out float v_hole;        // > 0 inside triangles touching a hole vertex
layout(location = 3) flat out uvec4 v_patch;  // the patch entry
layout(location = 4) out float v_fog;         // fog amount 0..1 (exponential height fog, per vertex)

void main() {
  uvec4 p = patches[gl_InstanceIndex];  // includes firstInstance: the far list starts at capacity
  uint slot = p.x & 0xFFFFu;
  uint c = p.x >> TV_PATCH_COARSE_SHIFT;  // coarsening of a root drawn at level 5 + c
  uint level = ((p.x >> TV_PATCH_LEVEL_SHIFT) & TV_PATCH_LEVEL_MASK) - c;  // the node's own level (6+: overview)
  // Stitching: terrain::stitched_vertex() (format/include/terrain/surface_contract.h) in stitch.glsl.
  uint deltas = (frame.misc.y & TV_FLAG_NO_STITCH) != 0u ? 0u : p.y;
  uvec2 node_vertex = stitched_vertex(p.x, deltas, uint(gl_VertexIndex));
  uint ni = node_vertex.x, nj = node_vertex.y;

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
  // Optical depth from the camera to the vertex through fog of density fog.w * exp(-h / H): the
  // closed form of the integral along the straight ray; a level ray gives density * distance.
  float hc = frame.cam_frac.z / TV_FOG_SCALE_HEIGHT_M, dh = pos.z / TV_FOG_SCALE_HEIGHT_M;
  float ec = exp(-hc);
  float mean = abs(dh) < 1e-3 ? ec * (1.0 - 0.5 * dh) : (ec - exp(-(hc + dh))) / dh;
  v_fog = 1.0 - exp(-frame.fog.w * v_dist * mean);
  v_node = vec2(ni, nj);
  v_patch = p;
}
