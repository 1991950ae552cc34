#include "surface_test_support.h"

#include <algorithm>
#include <cmath>
#include <random>

#include "bc_blocks.h"
#include "terrain/surface_contract.h"

namespace terrain::cook::test {

const MaterialRules& default_rules() {
  static const MaterialRules r = default_material_rules();
  return r;
}

bench::DemNode synthetic_node(const HeightFn& f, uint32_t level, uint32_t nx, uint32_t ny, int step_log2,
                              const HoleFn& hole) {
  bench::DemRaster r;
  r.name = "synthetic";
  const double s = vertex_spacing_m(int(level));
  r.dx_m = r.dy_m = s;
  // Cover the node and its window margin (and one node beyond).
  r.width = int((nx + 2) * kQuadsPerSide + kWindowMargin + 2);
  r.height = int((ny + 2) * kQuadsPerSide + kWindowMargin + 2);
  r.h.resize(size_t(r.width) * size_t(r.height));
  for (int y = 0; y < r.height; ++y)
    for (int x = 0; x < r.width; ++x) {
      const double X = x * s, Y = y * s;
      const bool h = hole && hole(X, Y);
      r.h[size_t(y) * size_t(r.width) + size_t(x)] = h ? NAN : float(f(X, Y));
    }
  bench::DemNode node;
  bench::make_dem_node(r, level, nx, ny, step_log2, node);
  return node;
}

Cooked cook_node(const bench::DemNode& node, const MaterialRules& rules, BcQuality q) {
  Cooked c;
  c.data.heights = node.node.heights;
  c.status = cook_surface_layers(node.input(&rules, q), node.node, node.height_offset, node.step_log2, c.data, &c.stats);
  return c;
}

namespace {
template <int kBytes, void (*Decode)(const uint8_t*, uint8_t*)>
std::vector<uint8_t> decode_image(const uint8_t* blocks) {
  std::vector<uint8_t> img(size_t(kTexels) * kTexels * 4);
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      uint8_t px[64];
      Decode(blocks + size_t(by * kTexelBlocks + bx) * kBytes, px);
      for (int r = 0; r < 4; ++r)
        std::copy_n(px + 16 * r, 16, img.begin() + ptrdiff_t((size_t(by * 4 + r) * kTexels + size_t(bx) * 4) * 4));
    }
  return img;
}
}  // namespace

std::vector<uint8_t> decode_albedo(const NodeData& d) { return decode_image<8, decode_bc1_block>(d.albedo_bc1.data()); }
std::vector<uint8_t> decode_normals(const NodeData& d) { return decode_image<16, decode_bc3_block>(d.normals_bc3.data()); }

void texel_normal(const uint8_t* rgba, double n[3]) {
  double x = (double(rgba[3]) - 128.0) / 127.0, y = (double(rgba[1]) - 128.0) / 127.0;
  const double rr = x * x + y * y;
  double z = 0;
  if (rr < 1) {
    z = std::sqrt(1 - rr);
  } else {
    x /= std::sqrt(rr);
    y /= std::sqrt(rr);
  }
  n[0] = x;
  n[1] = y;
  n[2] = z;
}

bool texel_is_hole(const bench::DemNode& node, int t, int u) {
  return node.holes[size_t((u - kApron + kWindowMargin) * kWindowSize + (t - kApron + kWindowMargin))] != 0;
}

namespace {

struct P3 {
  double x, y, z;
};

// Every triangle the renderer can draw in patch (p, q): the two triangles of each quad (split
// SW->NE) and, for quads on the patch border, the LOD-stitched versions (edge vertex k -> (k >> d)
// << d, d = 0..4 per edge, corner quads with both edges' levels). Hole rule: dropped if a vertex is
// a hole both at its collapsed and at its original position.
void drawn_triangles(const bench::DemNode& node, int p, int q, std::vector<std::array<P3, 3>>& out) {
  out.clear();
  const double s = node.spacing_m;
  auto z = [&](int i, int j) {
    return units_to_metres(vertex_units(node.height_offset, node.node.heights[size_t(j * kHeightSamples + i)], node.step_log2));
  };
  auto hole = [&](int i, int j) { return node.holes[size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin)] != 0; };
  const int n = kQuadsPerPatch;
  for (int v = 0; v < n; ++v)
    for (int u = 0; u < n; ++u) {
      const int dmax[4] = {v == 0 ? 4 : 0, u == n - 1 ? 4 : 0, v == n - 1 ? 4 : 0, u == 0 ? 4 : 0};  // S E N W
      for (int dS = 0; dS <= dmax[0]; ++dS)
        for (int dE = 0; dE <= dmax[1]; ++dE)
          for (int dN = 0; dN <= dmax[2]; ++dN)
            for (int dW = 0; dW <= dmax[3]; ++dW) {
              auto snap = [&](int a, int b, int& sa, int& sb) {
                sa = a;
                sb = b;
                if (a > 0 && a < n && b == 0) sa = a >> dS << dS;
                if (a > 0 && a < n && b == n) sa = a >> dN << dN;
                if (b > 0 && b < n && a == 0) sb = b >> dW << dW;
                if (b > 0 && b < n && a == n) sb = b >> dE << dE;
              };
              const int c[4][2] = {{u, v}, {u + 1, v}, {u + 1, v + 1}, {u, v + 1}};
              const int tris[2][3] = {{0, 1, 2}, {0, 2, 3}};
              for (const auto& t : tris) {
                std::array<P3, 3> tri;
                int sv[3][2];
                bool hs = false, ho = false;
                for (int k = 0; k < 3; ++k) {
                  snap(c[t[k]][0], c[t[k]][1], sv[k][0], sv[k][1]);
                  const int gi = p * n + sv[k][0], gj = q * n + sv[k][1];
                  hs = hs || hole(gi, gj);
                  ho = ho || hole(p * n + c[t[k]][0], q * n + c[t[k]][1]);
                  tri[size_t(k)] = {gi * s, gj * s, z(gi, gj)};
                }
                const bool degenerate = (sv[0][0] == sv[1][0] && sv[0][1] == sv[1][1]) ||
                                        (sv[1][0] == sv[2][0] && sv[1][1] == sv[2][1]) ||
                                        (sv[0][0] == sv[2][0] && sv[0][1] == sv[2][1]);
                if (degenerate || (hs && ho)) continue;
                out.push_back(tri);
              }
            }
    }
}

}  // namespace

ConeCheck check_cones(const bench::DemNode& node, const NodeData& data, int eyes, uint64_t seed) {
  ConeCheck r;
  // Node height range over non-hole vertices (what the node record stores).
  double hmin = 1e300, hmax = -1e300;
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) {
      if (node.holes[size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin)]) continue;
      const double h = units_to_metres(vertex_units(node.height_offset, node.node.heights[size_t(j * kHeightSamples + i)], node.step_log2));
      hmin = std::min(hmin, h);
      hmax = std::max(hmax, h);
    }
  if (hmin > hmax) return r;
  cone::DecodedCone cones[64];
  for (int b = 0; b < 4; ++b) {
    uint8_t dec[64];
    decode_bc3_block(data.cones_bc3.data() + 16 * b, dec);
    for (int t = 0; t < 16; ++t) {
      const int p = (b % 2) * 4 + t % 4, q = (b / 2) * 4 + t / 4;
      cones[q * 8 + p] = cone::decode_cone_texel(dec[4 * t], dec[4 * t + 1], dec[4 * t + 3]);
    }
  }
  std::vector<std::vector<std::array<P3, 3>>> tris(64);
  for (int k = 0; k < 64; ++k) drawn_triangles(node, k % 8, k / 8, tris[size_t(k)]);
  std::mt19937_64 rng(seed);
  const double size = node_size_m(int(node.key.level)), s = node.spacing_m;
  std::uniform_real_distribution<double> ux(-0.5 * size, 1.5 * size), uz(hmin - 0.2 * size, hmax + 0.5 * size);
  for (int e = 0; e < eyes; ++e) {
    const double eye[3] = {ux(rng), ux(rng), uz(rng)};
    ++r.eyes;
    for (int k = 0; k < 64; ++k) {
      const double bmin[3] = {(k % 8) * 16 * s, (k / 8) * 16 * s, hmin};
      const double bmax[3] = {(k % 8 + 1) * 16 * s, (k / 8 + 1) * 16 * s, hmax};
      ++r.patch_tests;
      if (!cone::cone_patch_backfacing(cones[k], eye, bmin, bmax)) continue;
      ++r.culled;
      for (const auto& t : tris[size_t(k)]) {
        const P3 a = t[0], b = t[1], c = t[2];
        const double ux1 = b.x - a.x, uy1 = b.y - a.y, uz1 = b.z - a.z, vx = c.x - a.x, vy = c.y - a.y, vz = c.z - a.z;
        const double n[3] = {uy1 * vz - uz1 * vy, uz1 * vx - ux1 * vz, ux1 * vy - uy1 * vx};
        const double d[3] = {eye[0] - a.x, eye[1] - a.y, eye[2] - a.z};
        const double nl = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        const double dl = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        const double cosv = (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / (nl * dl);
        ++r.triangles_checked;
        r.worst_cos = std::max(r.worst_cos, cosv);
        if (cosv > 0) ++r.violations;
      }
    }
  }
  return r;
}

MaterialRules per_sample(MaterialRules r) {
  r.scale_m = 0;
  r.despeckle = false;
  r.band_limit_noise = false;
  r.scales = {0.0};
  for (MaterialRule& rule : r.rules) rule.scale_m = 0, rule.scale_index = 0;
  return r;
}

}  // namespace terrain::cook::test
