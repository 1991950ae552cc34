// The analytic_surface shape of the synthetic generator (synthetic_archive.h).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>

#include "../../cooker/src/surface/noise.h"  // header-only: the cook's albedo variation (fbm_noise)
#include "bc_encode.h"
#include "synthetic_shapes.h"
#include "terrain/bc_decode.h"
#include "terrain/surface_contract.h"

namespace terrain::synthetic {
namespace {

// Weight of the hills at local x: 1, fading to 0 over 300 m east of flat_from_x_m and west of flat_until_x_m.
double relief_weight(const Spec& o, double lx) {
  return std::min(std::clamp((o.flat_from_x_m - lx) / 300.0, 0.0, 1.0), std::clamp((lx - o.flat_until_x_m) / 300.0, 0.0, 1.0));
}

double height_local(double lx, double ly, double relief, double detail, const Spec& o) {
  const double w = relief_weight(o, lx);
  return 300.0 + w * relief * (0.35 * std::sin(lx / 700.0) * std::cos(ly / 900.0) + 0.25 * std::sin(lx / 230.0 + ly / 310.0) +
                           detail * (0.12 * std::sin(lx / 61.0) * std::cos(ly / 47.0) +
                                     0.04 * std::sin(lx / 13.0 + 0.7) * std::sin(ly / 17.0)));
}

// Canonical height units of the vertex at (hx, hy) half metres: a multiple of the step, the same
// for every level holding it.
int32_t canonical_units(int64_t hx, int64_t hy, double relief, double detail, const Spec& o) {
  const double h = height_local(double(hx) * 0.5, double(hy) * 0.5, relief, detail, o);
  return int32_t(std::llround(h * 1024.0 / 16.0) * 16);
}

struct Ctx {
  const Spec* o;
  double origin_x, origin_y;
};

bool is_hole(const Ctx& c, int64_t hx, int64_t hy) {
  if (c.o->hole_radius_m <= 0) return false;
  const double x = c.origin_x + double(hx) * 0.5 - c.o->hole_x_m, y = c.origin_y + double(hy) * 0.5 - c.o->hole_y_m;
  return x * x + y * y < c.o->hole_radius_m * c.o->hole_radius_m;
}

uint8_t to_u8(double v) { return uint8_t(std::clamp(std::lround(v), 0L, 255L)); }

double srgb8_to_linear(uint8_t v) {
  const double c = v / 255.0;
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}
uint8_t linear_to_srgb8(double l) {
  l = std::clamp(l, 0.0, 1.0);
  return to_u8(255.0 * (l <= 0.0031308 ? l * 12.92 : 1.055 * std::pow(l, 1.0 / 2.4) - 0.055));
}

// Splat id of the straight-boundary option at local x (m).
uint8_t boundary_id(const Spec& o, double lx) { return lx < o.splat_boundary_x_m ? 0 : 1; }

// The albedo the cook bakes from the straight-boundary splat (format/SPEC.md 16.3): lattice sample
// (k, l) at vertex (2k - 2, 2l - 2) takes its palette colour in linear light times
// 1 + 0.5 * strength * fbm (wavelength max(48 m, 6 s), seed 0xA1BED0); texel (t, u) is the
// bilinear blend at lattice ((t + 0.5) / 2, (u + 0.5) / 2), in sRGB8.
void bake_boundary_albedo(const Ctx& c, const NodeKey& key, double s, std::vector<uint8_t>& rgba) {
  const std::vector<Material>& pal = world_info(*c.o).palette;
  constexpr int kLattice = kSplatSamples + 2;
  std::vector<double> lin(size_t(kLattice) * kLattice * 3);
  const double scale = std::max(48.0, 6.0 * s);
  for (int l = 0; l < kLattice; ++l)
    for (int k = 0; k < kLattice; ++k) {
      const double lx = (double(key.x) * kQuadsPerSide + 2 * k - 2) * s, ly = (double(key.y) * kQuadsPerSide + 2 * l - 2) * s;
      const Material& m = pal[boundary_id(*c.o, lx)];
      const double v = 1.0 + m.detail_strength * 0.5 * cook::fbm_noise(c.origin_x + lx, c.origin_y + ly, scale, 2, 0xA1BED0u);
      for (int ch = 0; ch < 3; ++ch) lin[(size_t(l) * kLattice + k) * 3 + ch] = srgb8_to_linear(m.albedo_srgb[size_t(ch)]) * v;
    }
  for (int u = 0; u < kTexels; ++u)
    for (int t = 0; t < kTexels; ++t) {
      const int k0 = t / 2, l0 = u / 2;
      const double fx = t % 2 == 0 ? 0.25 : 0.75, fy = u % 2 == 0 ? 0.25 : 0.75;
      for (int ch = 0; ch < 3; ++ch) {
        auto at = [&](int k, int l) { return lin[(size_t(l) * kLattice + k) * 3 + ch]; };
        const double v = (1 - fy) * ((1 - fx) * at(k0, l0) + fx * at(k0 + 1, l0)) + fy * ((1 - fx) * at(k0, l0 + 1) + fx * at(k0 + 1, l0 + 1));
        rgba[(size_t(u) * kTexels + t) * 4 + ch] = linear_to_srgb8(v);
      }
    }
}

// Calls `emit(normal)` for every triangle the renderer can draw in patch (p, q): the regular
// 16x16 quads and, on the patch border, the same quads with edge vertices collapsed for every
// stitch delta d = 1..4 (both deltas at corners). Triangles touching a hole vertex are skipped.
template <class Vertex, class Hole, class Emit>
void for_each_patch_normal(int p, int q, Vertex&& vertex, Hole&& hole, Emit&& emit) {
  auto tri = [&](int a0, int b0, int a1, int b1, int a2, int b2) {
    if ((a0 == a1 && b0 == b1) || (a0 == a2 && b0 == b2) || (a1 == a2 && b1 == b2)) return;
    if (hole(a0, b0) || hole(a1, b1) || hole(a2, b2)) return;
    double v0[3], v1[3], v2[3];
    vertex(a0, b0, v0);
    vertex(a1, b1, v1);
    vertex(a2, b2, v2);
    const double e1[3] = {v1[0] - v0[0], v1[1] - v0[1], v1[2] - v0[2]};
    const double e2[3] = {v2[0] - v0[0], v2[1] - v0[1], v2[2] - v0[2]};
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (len <= 0) return;
    for (double& v : n) v /= len;
    emit(n);
  };
  auto quad = [&](int i, int j, const int dl[4]) {  // dl: south, west, north, east
    const PatchMesh mesh{p, q, 0, {dl[0], dl[1], dl[2], dl[3]}};
    for (int t = 0; t < 2; ++t) {
      const PatchTriangle tr = stitched_quad_triangle(mesh, i - p * kQuadsPerPatch, j - q * kQuadsPerPatch, t);
      tri(tr.v[0].i, tr.v[0].j, tr.v[1].i, tr.v[1].j, tr.v[2].i, tr.v[2].j);
    }
  };
  const int zero[4] = {0, 0, 0, 0};
  for (int j = q * 16; j < q * 16 + 16; ++j)
    for (int i = p * 16; i < p * 16 + 16; ++i) {
      quad(i, j, zero);
      const bool south = j == q * 16, north = j == q * 16 + 15, west = i == p * 16, east = i == p * 16 + 15;
      if (!(south || north || west || east)) continue;
      for (int a = 0; a <= 4; ++a)
        for (int b = 0; b <= 4; ++b) {
          const int dl[4] = {south ? a : 0, west ? b : 0, north ? a : 0, east ? b : 0};
          if (dl[0] + dl[1] + dl[2] + dl[3] > 0) quad(i, j, dl);
        }
    }
}

void build_node(const Ctx& c, const NodeKey& key, Node& out) {
  const int level = int(key.level);
  const double s = vertex_spacing_m(level);
  const double relief = c.o->relief_m;
  NodeRecord& rec = out.record;
  rec.key = key;
  NodeData& d = out.data;
  // Canonical units of vertices -2..130 (the node's 129 plus the apron's neighbours).
  constexpr int kExt = kHeightSamples + 4;
  std::vector<int32_t> ext(size_t(kExt) * kExt);
  for (int j = 0; j < kExt; ++j)
    for (int i = 0; i < kExt; ++i) {
      const int64_t hx = (int64_t(key.x) * kQuadsPerSide + i - 2) * (int64_t(1) << level);
      const int64_t hy = (int64_t(key.y) * kQuadsPerSide + j - 2) * (int64_t(1) << level);
      ext[size_t(j) * kExt + i] = canonical_units(hx, hy, relief, c.o->detail, *c.o);
    }
  auto ext_units = [&](int i, int j) { return ext[size_t(j + 2) * kExt + size_t(i + 2)]; };
  std::vector<int32_t> units(kHeightCount);
  std::vector<uint8_t> holes(kHeightCount);
  int32_t lo = INT32_MAX, hi = INT32_MIN, all_lo = INT32_MAX;
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) {
      const int64_t hx = (int64_t(key.x) * kQuadsPerSide + i) << level, hy = (int64_t(key.y) * kQuadsPerSide + j) << level;
      const int32_t u = ext_units(i, j);
      units[size_t(j) * kHeightSamples + i] = u;
      holes[size_t(j) * kHeightSamples + i] = is_hole(c, hx, hy);
      all_lo = std::min(all_lo, u);
      if (!holes[size_t(j) * kHeightSamples + i]) {
        lo = std::min(lo, u);
        hi = std::max(hi, u);
      }
    }
  rec.height_offset = int32_t(std::floor(all_lo / 16.0)) * 16;
  for (int k = 0; k < kHeightCount; ++k) d.heights[size_t(k)] = uint16_t((units[size_t(k)] - rec.height_offset) >> kSurfaceStepLog2);
  if (lo > hi) lo = hi = rec.height_offset;
  rec.min_height = lo;
  rec.max_height = hi;
  rec.flags = std::any_of(holes.begin(), holes.end(), [](uint8_t h) { return h != 0; }) ? kNodeFlagHasHoles : 0;
  // Geometric error: largest gap between the field at a quad's centre and the node's surface there.
  double err = 0;
  for (int j = 0; j < kQuadsPerSide; ++j)
    for (int i = 0; i < kQuadsPerSide; ++i) {
      const double lx = (double(key.x) * kQuadsPerSide + i + 0.5) * s, ly = (double(key.y) * kQuadsPerSide + j + 0.5) * s;
      const double mid = (ext_units(i, j) + ext_units(i + 1, j + 1)) / 2048.0;  // on the SW-NE diagonal
      err = std::max(err, std::abs(height_local(lx, ly, relief, c.o->detail, *c.o) - mid));
    }
  const double centre_x = (double(key.x) + 0.5) * node_size_m(level);
  const double weight = relief_weight(*c.o, centre_x);
  rec.geometric_error_m = float(std::max(err, c.o->error_floor_m * std::pow(4.0, level) * weight));

  // Normals and albedo (132 x 132): texel (t, u) is the cell between vertices (t-2, u-2) and (t-1, u-1).
  std::vector<uint8_t> normal_rgba(size_t(kTexels) * kTexels * 4), albedo_rgba(size_t(kTexels) * kTexels * 4);
  for (int u = 0; u < kTexels; ++u)
    for (int t = 0; t < kTexels; ++t) {
      const double h00 = ext_units(t - 2, u - 2) / 1024.0, h10 = ext_units(t - 1, u - 2) / 1024.0;
      const double h01 = ext_units(t - 2, u - 1) / 1024.0, h11 = ext_units(t - 1, u - 1) / 1024.0;
      const double dx = (h10 + h11 - h00 - h01) / (2 * s), dy = (h01 + h11 - h00 - h10) / (2 * s);
      const double len = std::sqrt(dx * dx + dy * dy + 1);
      const double n[3] = {-dx / len, -dy / len, 1 / len};
      uint8_t* nn = &normal_rgba[(size_t(u) * kTexels + t) * 4];
      nn[0] = 255;  // ambient occlusion: open
      nn[1] = normal_texel_of(float(n[1]));
      nn[2] = 0;
      nn[3] = normal_texel_of(float(n[0]));
      const double h = (h00 + h10 + h01 + h11) * 0.25;
      const double slope = std::sqrt(1.0 - n[2] * n[2]);
      double rgb[3] = {0.36, 0.45, 0.22};  // grass
      if (h > 420) {
        rgb[0] = 0.85; rgb[1] = 0.86; rgb[2] = 0.88;  // snow-ish
      } else if (slope > 0.45) {
        rgb[0] = 0.45; rgb[1] = 0.40; rgb[2] = 0.35;  // rock
      } else if (h < 200) {
        rgb[0] = 0.70; rgb[1] = 0.64; rgb[2] = 0.46;  // sand
      }
      uint8_t* a = &albedo_rgba[(size_t(u) * kTexels + t) * 4];
      if (c.o->splat_boundary_x_m < 0)
        for (int k = 0; k < 3; ++k) a[k] = to_u8(rgb[k] * 255.0);
      // Alpha: the hole flag of vertex (t - 2, u - 2) (apron texels included: world-defined).
      const int64_t hx = (int64_t(key.x) * kQuadsPerSide + t - kApron) * (int64_t(1) << level);
      const int64_t hy = (int64_t(key.y) * kQuadsPerSide + u - kApron) * (int64_t(1) << level);
      a[3] = is_hole(c, hx, hy) ? 0 : 255;
    }
  if (c.o->splat_boundary_x_m >= 0) bake_boundary_albedo(c, key, s, albedo_rgba);  // colour only, alpha kept
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      uint8_t nb[16][4], ab[16][4];
      for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
          std::memcpy(nb[j * 4 + i], &normal_rgba[((size_t(by) * 4 + j) * kTexels + bx * 4 + i) * 4], 4);
          std::memcpy(ab[j * 4 + i], &albedo_rgba[((size_t(by) * 4 + j) * kTexels + bx * 4 + i) * 4], 4);
        }
      uint8_t* nblock = &d.normals_bc3[(size_t(by) * kTexelBlocks + bx) * 16];
      uint8_t alpha_t[16];
      for (int t = 0; t < 16; ++t) alpha_t[t] = nb[t][3];
      encode_bc3_alpha(alpha_t, false, nblock);
      encode_bc3_colour(nb, nblock + 8);
      encode_bc1(ab, &d.albedo_bc1[(size_t(by) * kTexelBlocks + bx) * 8]);
    }

  // Splat: material by height band, vertex (2a, 2b).
  for (int b = 0; b < kSplatSamples; ++b)
    for (int a = 0; a < kSplatSamples; ++a) {
      const int32_t u = units[size_t(2 * b) * kHeightSamples + 2 * a];
      const double h = u / 1024.0;
      d.splat[size_t(b) * kSplatSamples + a] = uint8_t(h > 420 ? 3 : h > 330 ? 2 : h > 200 ? 1 : 0);
      if (c.o->splat_boundary_x_m >= 0) d.splat[size_t(b) * kSplatSamples + a] = boundary_id(*c.o, (double(key.x) * kQuadsPerSide + 2 * a) * s);
    }

  // Patch cones from the exact triangles (quantized heights), stitched edges d <= 4 included.
  auto vertex = [&](int i, int j, double v[3]) {
    v[0] = i * s;
    v[1] = j * s;
    v[2] = double(float(units[size_t(j) * kHeightSamples + i]) * (1.0f / 1024.0f));
  };
  auto is_hole_vertex = [&](int i, int j) { return holes[size_t(j) * kHeightSamples + i] != 0; };
  uint8_t cone_rgba[64][4];
  std::vector<std::array<double, 3>> patch_normals[64];
  for (int q = 0; q < 8; ++q)
    for (int p = 0; p < 8; ++p) {
      auto& normals = patch_normals[q * 8 + p];
      if (c.o->cones)
        for_each_patch_normal(p, q, vertex, is_hole_vertex, [&](const double n[3]) { normals.push_back({n[0], n[1], n[2]}); });
      double axis[3] = {0, 0, 0};
      for (auto& n : normals)
        for (int k = 0; k < 3; ++k) axis[k] += n[k];
      const double len = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
      uint8_t* cr = cone_rgba[q * 8 + p];
      cr[2] = 0;
      if (!c.o->cones || normals.empty() || len <= 0) {
        cr[0] = uint8_t(cone::kConeRCentre);
        cr[1] = uint8_t(cone::kConeGCentre);
        cr[3] = 255;  // never cull
        continue;
      }
      cr[0] = cone::cone_texel_of_axis_x(axis[0] / len);
      cr[1] = cone::cone_texel_of_axis_y(axis[1] / len);
      cr[3] = 0;
    }
  // Encode the axes, decode them back, then store angles that cover every normal from the decoded
  // axis with 1 degree to spare (GPU decoders may differ by one step in the interpolants).
  uint8_t colour_blocks[4][8];
  for (int by = 0; by < 2; ++by)
    for (int bx = 0; bx < 2; ++bx) {
      uint8_t blk[16][4];
      for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) std::memcpy(blk[j * 4 + i], cone_rgba[(by * 4 + j) * 8 + bx * 4 + i], 4);
      encode_bc3_colour(blk, colour_blocks[by * 2 + bx]);
    }
  uint8_t targets[64];
  for (int q = 0; q < 8; ++q)
    for (int p = 0; p < 8; ++p) {
      if (cone_rgba[q * 8 + p][3] == 255) {
        targets[q * 8 + p] = 255;
        continue;
      }
      uint8_t full[16] = {};
      std::memcpy(full + 8, colour_blocks[(q / 4) * 2 + p / 4], 8);
      uint8_t dec[64];
      decode_bc3_block(full, dec, BcRounding::truncate);
      const int t = (q % 4) * 4 + p % 4;
      const double x = cone::cone_axis_x(dec[4 * t]), y = cone::cone_axis_y(dec[4 * t + 1]);
      const double rr = x * x + y * y;
      const double z = rr < 1 ? std::sqrt(1 - rr) : 0;
      const double al = std::sqrt(x * x + y * y + z * z);
      double worst = 0;
      for (auto& n : patch_normals[q * 8 + p]) {
        const double cosang = std::clamp((n[0] * x + n[1] * y + n[2] * z) / al, -1.0, 1.0);
        worst = std::max(worst, std::acos(cosang) * 180.0 / M_PI);
      }
      const double angle = worst + 1.0;
      targets[q * 8 + p] = angle >= 89.5 ? 255 : uint8_t(std::min(254.0, std::ceil(angle / 90.0 * 255.0)));
    }
  for (int by = 0; by < 2; ++by)
    for (int bx = 0; bx < 2; ++bx) {
      uint8_t t16[16];
      for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) t16[j * 4 + i] = targets[(by * 4 + j) * 8 + bx * 4 + i];
      uint8_t* blk = &d.cones_bc3[size_t(by * 2 + bx) * 16];
      encode_bc3_alpha(t16, true, blk);
      std::memcpy(blk + 8, colour_blocks[by * 2 + bx], 8);
    }
}

void add_subtree(const Ctx& c, const NodeKey& key, std::vector<NodeKey>& order) {
  order.push_back(key);
  if (key.level == 0) return;
  for (int ch = 0; ch < 4; ++ch) {
    const NodeKey k = child_of(key, ch);
    if (c.o->keep(k)) add_subtree(c, k, order);
  }
}

}  // namespace

Status generate_analytic_surface(const Spec& o, const NodeSink& sink) {
  Ctx c{&o, o.origin_x_m, o.origin_y_m};
  std::vector<NodeKey> order;
  for (uint32_t y = 0; y < o.roots_y; ++y)
    for (uint32_t x = 0; x < o.roots_x; ++x) add_subtree(c, NodeKey{uint32_t(kRootLevel), x, y}, order);
  std::stable_sort(order.begin(), order.end(), [](const NodeKey& a, const NodeKey& b) { return a.level > b.level; });
  std::vector<NodeKey> sorted = order;
  std::sort(sorted.begin(), sorted.end(), key_less);
  auto node = std::make_unique<Node>();
  for (const NodeKey& key : order) {
    node->record = NodeRecord{};
    build_node(c, key, *node);
    if (key.level > 0)
      for (int ch = 0; ch < 4; ++ch)
        if (std::binary_search(sorted.begin(), sorted.end(), child_of(key, ch), key_less))
          node->record.child_mask |= uint8_t(1u << ch);
    TERRAIN_TRY(sink(node->record, node->data));
  }
  return Status::success();
}

}  // namespace terrain::synthetic
