// LOD stitching of one patch vertex: terrain::stitched_vertex() of
// format/include/terrain/surface_contract.h (format/SPEC.md section 16.5) restated in GLSL. The
// shader cannot call the C++ function, so ViewerGpu.VertexShaderStitchingEqualsTheContract runs
// this file in a compute shader (tests/viewer/stitch_probe.comp) and compares every vertex, every
// decimation and every delta 0..7 on every side with the C++ rule.
#include "config.h"

// Node vertex (0..128) that vertex `index` (j * (n + 1) + i, n = 16 >> e) of the patch entry's
// mesh is drawn at, with the edge deltas of `deltas` (the entry's y word, or 0 for no stitching):
// on an edge whose neighbour is coarser by d, k -> (k >> d) << d in node vertices.
uvec2 stitched_vertex(uint entry_x, uint deltas, uint index) {
  uint px = (entry_x >> TV_PATCH_PX_SHIFT) & 7u, py = (entry_x >> TV_PATCH_PY_SHIFT) & 7u;
  uint e = (entry_x >> TV_PATCH_DECIM_SHIFT) & 7u;  // decimation: mesh of n = 16 >> e quads per side
  uint n = uint(TV_QUADS_PER_PATCH) >> e;
  uint i = index % (n + 1u), j = index / (n + 1u);
  uint ni = px * uint(TV_QUADS_PER_PATCH) + (i << e), nj = py * uint(TV_QUADS_PER_PATCH) + (j << e);
  uint ds = (deltas >> TV_EDGE_S) & 15u, dw = (deltas >> TV_EDGE_W) & 15u;
  uint dn = (deltas >> TV_EDGE_N) & 15u, de = (deltas >> TV_EDGE_E) & 15u;
  if (j == 0u && ds > 0u) ni = (ni >> ds) << ds;
  if (j == n && dn > 0u) ni = (ni >> dn) << dn;
  if (i == 0u && dw > 0u) nj = (nj >> dw) << dw;
  if (i == n && de > 0u) nj = (nj >> de) << de;
  return uvec2(ni, nj);
}
