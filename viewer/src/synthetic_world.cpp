#include "synthetic_world.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

#include "terrain/archive_writer.h"
#include "terrain/bc_decode.h"
#include "terrain/surface_contract.h"

namespace terrain::view {
namespace {

constexpr int kStepLog2 = 4;  // every level: 1/64 m, range 1024 m per node

double height_local(double lx, double ly, double relief, double detail, double flat_from) {
  const double w = std::clamp((flat_from - lx) / 300.0, 0.0, 1.0);
  return 300.0 + w * relief * (0.35 * std::sin(lx / 700.0) * std::cos(ly / 900.0) + 0.25 * std::sin(lx / 230.0 + ly / 310.0) +
                           detail * (0.12 * std::sin(lx / 61.0) * std::cos(ly / 47.0) +
                                     0.04 * std::sin(lx / 13.0 + 0.7) * std::sin(ly / 17.0)));
}

// Canonical height units of the vertex at (hx, hy) half metres: a multiple of the step, the same
// for every level holding it.
int32_t canonical_units(int64_t hx, int64_t hy, double relief, double detail, double flat_from) {
  const double h = height_local(double(hx) * 0.5, double(hy) * 0.5, relief, detail, flat_from);
  return int32_t(std::llround(h * 1024.0 / 16.0) * 16);
}

struct Ctx {
  const SyntheticOptions* o;
  double origin_x, origin_y;
};

bool is_hole(const Ctx& c, int64_t hx, int64_t hy) {
  if (c.o->hole_radius_m <= 0) return false;
  const double x = c.origin_x + double(hx) * 0.5 - c.o->hole_x_m, y = c.origin_y + double(hy) * 0.5 - c.o->hole_y_m;
  return x * x + y * y < c.o->hole_radius_m * c.o->hole_radius_m;
}

uint16_t pack565(int r, int g, int b) { return uint16_t((r >> 3) << 11 | (g >> 2) << 5 | (b >> 3)); }

// BC1 with exact punch-through: a block with a hole texel uses the 3-colour mode, index 3 = hole.
void encode_bc1(const uint8_t rgba[16][4], uint8_t out[8]) {
  bool any_hole = false;
  int lo = 0, hi = 0;
  auto luma = [&](int t) { return rgba[t][0] * 2 + rgba[t][1] * 4 + rgba[t][2]; };
  for (int t = 0; t < 16; ++t) {
    if (rgba[t][3] < 128) {
      any_hole = true;
      continue;
    }
    if (luma(t) < luma(lo) || rgba[lo][3] < 128) lo = t;
    if (luma(t) > luma(hi) || rgba[hi][3] < 128) hi = t;
  }
  uint16_t a = pack565(rgba[hi][0], rgba[hi][1], rgba[hi][2]), b = pack565(rgba[lo][0], rgba[lo][1], rgba[lo][2]);
  uint16_t c0, c1;
  if (any_hole) {  // 3-colour mode: c0 <= c1
    c0 = std::min(a, b);
    c1 = std::max(a, b);
  } else {
    if (a == b) {
      if (a > 0) b = uint16_t(a - 1); else a = 1;  // keep c0 > c1 for the 4-colour mode
    }
    c0 = std::max(a, b);
    c1 = std::min(a, b);
  }
  uint8_t block[8] = {uint8_t(c0), uint8_t(c0 >> 8), uint8_t(c1), uint8_t(c1 >> 8), 0, 0, 0, 0};
  uint8_t pal[8][4];  // entries 4..7: the palette (decoded from probe blocks with fixed indices)
  for (int idx = 0; idx < 4; ++idx) {
    uint8_t probe[8], dec[64];
    std::memcpy(probe, block, 4);
    const uint8_t bits = uint8_t(idx | idx << 2 | idx << 4 | idx << 6);
    probe[4] = probe[5] = probe[6] = probe[7] = bits;
    decode_bc1_block(probe, dec, BcRounding::truncate);
    std::memcpy(pal[idx + 4], dec, 4);
  }
  uint32_t indices = 0;
  for (int t = 0; t < 16; ++t) {
    int best = 0;
    if (any_hole && rgba[t][3] < 128) {
      best = 3;
    } else {
      int best_d = 1 << 30;
      for (int idx = 0; idx < (any_hole ? 3 : 4); ++idx) {
        int d = 0;
        for (int k = 0; k < 3; ++k) d += (pal[idx + 4][k] - rgba[t][k]) * (pal[idx + 4][k] - rgba[t][k]);
        if (d < best_d) {
          best_d = d;
          best = idx;
        }
      }
    }
    indices |= uint32_t(best) << (2 * t);
  }
  for (int k = 0; k < 4; ++k) block[4 + k] = uint8_t(indices >> (8 * k));
  std::memcpy(out, block, 8);
}

// BC3 alpha: 8-value mode between the block's max and min; `conservative` picks, per texel, the
// smallest decoded value >= target + 1 (or the exact max endpoint), so GPU rounding of the
// interpolants can never lower a stored cone angle below its target.
void encode_alpha(const uint8_t target[16], bool conservative, uint8_t out[8]) {
  int a0 = 0, a1 = 255;
  for (int t = 0; t < 16; ++t) {
    a0 = std::max(a0, int(target[t]));
    a1 = std::min(a1, int(target[t]));
  }
  int pal[8] = {a0, a1};
  if (a0 > a1)
    for (int k = 1; k < 7; ++k) pal[k + 1] = ((7 - k) * a0 + k * a1) / 7;
  else
    for (int k = 2; k < 8; ++k) pal[k] = a0;
  uint64_t bits = 0;
  for (int t = 0; t < 16; ++t) {
    int best = 0, best_v = 1 << 30;
    for (int idx = 0; idx < 8; ++idx) {
      const int v = pal[idx];
      if (conservative) {
        const bool exact = idx < 2;
        if (v < target[t] + (exact ? 0 : 1)) continue;
        if (v < best_v) {
          best_v = v;
          best = idx;
        }
      } else {
        const int d = std::abs(v - int(target[t]));
        if (d < best_v) {
          best_v = d;
          best = idx;
        }
      }
    }
    bits |= uint64_t(best) << (3 * t);
  }
  out[0] = uint8_t(a0);
  out[1] = uint8_t(a1);
  for (int k = 0; k < 6; ++k) out[2 + k] = uint8_t(bits >> (8 * k));
}

// BC3 colour block (always 4-colour): endpoints = per-channel max and min.
void encode_bc3_colour(const uint8_t rgba[16][4], uint8_t out[8]) {
  int mx[3] = {0, 0, 0}, mn[3] = {255, 255, 255};
  for (int t = 0; t < 16; ++t)
    for (int k = 0; k < 3; ++k) {
      mx[k] = std::max(mx[k], int(rgba[t][k]));
      mn[k] = std::min(mn[k], int(rgba[t][k]));
    }
  const uint16_t c0 = pack565(mx[0], mx[1], mx[2]), c1 = pack565(mn[0], mn[1], mn[2]);
  uint8_t probe[16] = {};
  probe[8] = uint8_t(c0);
  probe[9] = uint8_t(c0 >> 8);
  probe[10] = uint8_t(c1);
  probe[11] = uint8_t(c1 >> 8);
  uint8_t pal[4][4];
  for (int idx = 0; idx < 4; ++idx) {
    uint8_t dec[64];
    const uint8_t bits = uint8_t(idx | idx << 2 | idx << 4 | idx << 6);
    probe[12] = probe[13] = probe[14] = probe[15] = bits;
    decode_bc3_block(probe, dec, BcRounding::truncate);
    std::memcpy(pal[idx], dec, 4);
  }
  uint32_t indices = 0;
  for (int t = 0; t < 16; ++t) {
    int best = 0, best_d = 1 << 30;
    for (int idx = 0; idx < 4; ++idx) {
      int d = 0;
      for (int k = 0; k < 3; ++k) d += (pal[idx][k] - rgba[t][k]) * (pal[idx][k] - rgba[t][k]);
      if (d < best_d) {
        best_d = d;
        best = idx;
      }
    }
    indices |= uint32_t(best) << (2 * t);
  }
  out[0] = uint8_t(c0);
  out[1] = uint8_t(c0 >> 8);
  out[2] = uint8_t(c1);
  out[3] = uint8_t(c1 >> 8);
  for (int k = 0; k < 4; ++k) out[4 + k] = uint8_t(indices >> (8 * k));
}

uint8_t to_u8(double v) { return uint8_t(std::clamp(std::lround(v), 0L, 255L)); }

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
    int vi[4] = {i, i + 1, i + 1, i}, vj[4] = {j, j, j + 1, j + 1};
    for (int k = 0; k < 4; ++k) {
      const int li = vi[k] - p * 16, lj = vj[k] - q * 16;
      if (lj == 0 && dl[0]) vi[k] = vi[k] >> dl[0] << dl[0];
      if (lj == 16 && dl[2]) vi[k] = vi[k] >> dl[2] << dl[2];
      if (li == 0 && dl[1]) vj[k] = vj[k] >> dl[1] << dl[1];
      if (li == 16 && dl[3]) vj[k] = vj[k] >> dl[3] << dl[3];
    }
    tri(vi[0], vj[0], vi[1], vj[1], vi[2], vj[2]);
    tri(vi[0], vj[0], vi[2], vj[2], vi[3], vj[3]);
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

void build_node(const Ctx& c, const NodeKey& key, SyntheticNode& out) {
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
      ext[size_t(j) * kExt + i] = canonical_units(hx, hy, relief, c.o->detail, c.o->flat_from_x_m);
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
  for (int k = 0; k < kHeightCount; ++k) d.heights[size_t(k)] = uint16_t((units[size_t(k)] - rec.height_offset) >> kStepLog2);
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
      err = std::max(err, std::abs(height_local(lx, ly, relief, c.o->detail, c.o->flat_from_x_m) - mid));
    }
  const double centre_x = (double(key.x) + 0.5) * node_size_m(level);
  const double weight = std::clamp((c.o->flat_from_x_m - centre_x) / 300.0, 0.0, 1.0);
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
      for (int k = 0; k < 3; ++k) a[k] = to_u8(rgb[k] * 255.0);
      // Alpha: the hole flag of vertex (t - 2, u - 2) (apron texels included: world-defined).
      const int64_t hx = (int64_t(key.x) * kQuadsPerSide + t - kApron) * (int64_t(1) << level);
      const int64_t hy = (int64_t(key.y) * kQuadsPerSide + u - kApron) * (int64_t(1) << level);
      a[3] = is_hole(c, hx, hy) ? 0 : 255;
    }
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
      encode_alpha(alpha_t, false, nblock);
      encode_bc3_colour(nb, nblock + 8);
      encode_bc1(ab, &d.albedo_bc1[(size_t(by) * kTexelBlocks + bx) * 8]);
    }

  // Splat: material by height band, vertex (2a, 2b).
  for (int b = 0; b < kSplatSamples; ++b)
    for (int a = 0; a < kSplatSamples; ++a) {
      const int32_t u = units[size_t(2 * b) * kHeightSamples + 2 * a];
      const double h = u / 1024.0;
      d.splat[size_t(b) * kSplatSamples + a] = uint8_t(h > 420 ? 3 : h > 330 ? 2 : h > 200 ? 1 : 0);
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
      encode_alpha(t16, true, blk);
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

SyntheticWorld make_synthetic_world(const SyntheticOptions& o) {
  SyntheticWorld w;
  WorldInfo& wi = w.world;
  wi.crs.kind = ProjectionKind::local;
  wi.crs.name = "synthetic";
  wi.origin_x_m = o.origin_x_m;
  wi.origin_y_m = o.origin_y_m;
  wi.roots_x = o.roots_x;
  wi.roots_y = o.roots_y;
  wi.extent_min_x_m = o.origin_x_m;
  wi.extent_min_y_m = o.origin_y_m;
  wi.extent_max_x_m = o.origin_x_m + o.roots_x * node_size_m(kRootLevel);
  wi.extent_max_y_m = o.origin_y_m + o.roots_y * node_size_m(kRootLevel);
  wi.step_log2.fill(uint8_t(kStepLog2));
  const char* names[4] = {"sand", "grass", "rock", "snow"};
  const uint8_t colours[4][3] = {{178, 164, 118}, {92, 116, 56}, {116, 104, 92}, {216, 220, 226}};
  for (int m = 0; m < 4; ++m) {
    Material mat;
    mat.name = names[m];
    mat.albedo_srgb = {colours[m][0], colours[m][1], colours[m][2]};
    mat.detail_scale_m = 3.0f + float(m);
    mat.detail_strength = 0.25f;
    mat.height_blend = 0.6f;
    wi.palette.push_back(mat);
  }
  wi.cook_info_json = "{\"synthetic\":true}";
  Ctx c{&o, o.origin_x_m, o.origin_y_m};
  std::vector<NodeKey> order;
  for (uint32_t y = 0; y < o.roots_y; ++y)
    for (uint32_t x = 0; x < o.roots_x; ++x) add_subtree(c, NodeKey{uint32_t(kRootLevel), x, y}, order);
  std::stable_sort(order.begin(), order.end(), [](const NodeKey& a, const NodeKey& b) { return a.level > b.level; });
  w.nodes.resize(order.size());
  for (size_t i = 0; i < order.size(); ++i) build_node(c, order[i], w.nodes[i]);
  // Child masks.
  std::vector<NodeKey> sorted = order;
  std::sort(sorted.begin(), sorted.end(), key_less);
  for (auto& n : w.nodes) {
    n.record.child_mask = 0;
    if (n.record.key.level == 0) continue;
    for (int ch = 0; ch < 4; ++ch)
      if (std::binary_search(sorted.begin(), sorted.end(), child_of(n.record.key, ch), key_less))
        n.record.child_mask |= uint8_t(1u << ch);
  }
  return w;
}

Status write_synthetic_archive(const SyntheticWorld& w, const std::string& path) {
  ArchiveWriter writer;
  Status s = writer.open(path);
  if (!s.ok()) return s;
  std::vector<uint8_t> payload;
  for (const auto& n : w.nodes) {
    s = encode_node_payload(n.data, PayloadOptions{1, true}, payload);
    if (!s.ok()) return s;
    s = writer.add_node(n.record, payload);
    if (!s.ok()) return s;
  }
  return writer.finish(w.world);
}

}  // namespace terrain::view
