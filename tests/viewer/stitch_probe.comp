#version 450
// Tests only: runs viewer/shaders/stitch.glsl's stitched_vertex() (the code terrain.vert runs) for
// a list of queries, so ViewerGpu.VertexShaderStitchingEqualsTheContract can compare every result
// with terrain::stitched_vertex() in C++.
#extension GL_GOOGLE_include_directive : require
#include "stitch.glsl"

layout(local_size_x = 64) in;
// x = patch entry x word, y = edge-delta word, z = vertex index (as gl_VertexIndex), w unused.
layout(std430, set = 0, binding = 0) readonly buffer Queries { uvec4 queries[]; };
layout(std430, set = 0, binding = 1) writeonly buffer Results { uvec2 results[]; };
layout(push_constant) uniform Count { uint count; } pc;

void main() {
  uint k = gl_GlobalInvocationID.x;
  if (k >= pc.count) return;
  uvec4 q = queries[k];
  results[k] = stitched_vertex(q.x, q.y, q.z);
}
