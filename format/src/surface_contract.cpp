#include "terrain/surface_contract.h"

namespace terrain {

std::string node_name(const NodeKey& k) {
  return std::to_string(k.level) + "/" + std::to_string(k.x) + "/" + std::to_string(k.y);
}

std::vector<PatchTriangle> patch_triangles(const PatchMesh& m) {
  std::vector<PatchTriangle> out;
  const int n = patch_mesh_quads(m.decimation);
  out.reserve(size_t(2 * n * n));
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      for (int t = 0; t < 2; ++t) {
        const PatchTriangle tri = stitched_quad_triangle(m, i, j, t);
        if (!tri.degenerate()) out.push_back(tri);
      }
  return out;
}

}  // namespace terrain
