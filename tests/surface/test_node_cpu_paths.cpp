// The node-CPU rewrites (cooker/src/surface) against the plain loops they replaced, value for value:
// the splat height filter on real DEM nodes (inner nodes and data-edge nodes with NaN in the window),
// the aspect mask's wrap without fmod, the branch-free atan2 of the normal-error statistics, the
// baked albedo's texel blend, the splat lattice's row-wise slope, aspect and curvature, and the
// normal texels' row loops.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>

#include "cones.h"
#include "fast_math.h"
#include "materials.h"
#include "noise.h"
#include "normals.h"
#include "splat.h"
#include "surface_test_support.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::cook;

namespace {

// The per-vertex filter as it was before the SIMD-friendly restatement (splat.cpp at 0aabd17).
bool reference_filter(const float* h, double scale_m, double spacing_m, std::vector<float>& out) {
  auto wh = [&](int i, int j) { return h[size_t((j + kWindowMargin) * kWindowSize + (i + kWindowMargin))]; };
  constexpr int kReach = 8, kMaxRadius = kWindowMargin - kReach;
  double sigma = scale_m / spacing_m;
  if (sigma < 0.5) return false;
  int radius = int(std::ceil(2.0 * sigma));
  if (radius > kMaxRadius) {
    radius = kMaxRadius;
    sigma = radius / 2.0;
  }
  float w[2 * kMaxRadius + 1];
  for (int d = -radius; d <= radius; ++d) w[d + radius] = float(std::exp(-0.5 * d * d / (sigma * sigma)));
  const int lo = -kReach, hi = kHeightSamples - 1 + kReach;
  out.assign(size_t(kWindowCount), NAN);
  std::vector<float> sum(size_t(kWindowCount), 0.0f), weight(size_t(kWindowCount), 0.0f);
  for (int j = lo - radius; j <= hi + radius; ++j)
    for (int i = lo; i <= hi; ++i) {
      float sv = 0, sw = 0;
      for (int d = -radius; d <= radius; ++d) {
        const float v = wh(i + d, j);
        if (!std::isnan(v)) { sv += w[d + radius] * v; sw += w[d + radius]; }
      }
      const size_t k = size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin);
      sum[k] = sv;
      weight[k] = sw;
    }
  for (int j = lo; j <= hi; ++j)
    for (int i = lo; i <= hi; ++i) {
      if (std::isnan(wh(i, j))) continue;
      float sv = 0, sw = 0;
      for (int d = -radius; d <= radius; ++d) {
        const size_t k = size_t((j + d + kWindowMargin) * kWindowSize + i + kWindowMargin);
        sv += w[d + radius] * sum[k];
        sw += w[d + radius] * weight[k];
      }
      out[size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin)] = sv / sw;
    }
  return true;
}

// Compares the lattice's region (-8 .. 136) bit for bit; returns the number of differing vertices.
int differing(const std::vector<float>& a, const std::vector<float>& b) {
  int n = 0;
  for (int j = -8; j <= kHeightSamples - 1 + 8; ++j)
    for (int i = -8; i <= kHeightSamples - 1 + 8; ++i) {
      const size_t k = size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin);
      n += std::memcmp(&a[k], &b[k], sizeof(float)) != 0;
    }
  return n;
}

// fn(node, level, x, y) for the nodes with data among about per_side x per_side spread over each
// of the levels 0, 2 and 4 of a real DEM (inner nodes and nodes cut by the data's edge).
template <class Fn>
void for_each_real_node(const bench::DemRaster& dem, uint32_t per_side, Fn&& fn) {
  for (uint32_t level : {0u, 2u, 4u}) {
    const uint32_t nx = bench::nodes_across(dem, level, false), ny = bench::nodes_across(dem, level, true);
    for (uint32_t y = 0; y < ny; y += std::max(1u, ny / per_side))
      for (uint32_t x = 0; x < nx; x += std::max(1u, nx / per_side)) {
        bench::DemNode n;
        bench::make_dem_node(dem, level, x, y, 2, n);
        if (n.data_vertices > 0) fn(n, level, x, y);
      }
  }
}

}  // namespace

TEST(NodeCpuPaths, SplatFilterMatchesThePerVertexLoopOnRealNodes) {
  const auto file = terrain::test::data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(file);
  bench::DemRaster dem;
  ASSERT_TRUE(bench::load_dem(file.string(), dem).ok());
  int inner = 0, edge = 0;
  std::vector<float> fast, slow;
  for_each_real_node(dem, 5, [&](const bench::DemNode& n, uint32_t level, uint32_t x, uint32_t y) {
    bool any_nan = false;
    for (float v : n.window) any_nan = any_nan || std::isnan(v);
    (any_nan ? edge : inner) += 1;
    // The built-in rule scales (16 m, 1 m) and one whose radius is not capped at any level here.
    for (double scale : {16.0, 1.0, 3.0}) {
      fast.clear();
      const bool f = filter_heights(n.window.data(), scale, n.spacing_m, fast);
      const bool s = reference_filter(n.window.data(), scale, n.spacing_m, slow);
      ASSERT_EQ(f, s) << "level " << level << " scale " << scale;
      if (f) {
        EXPECT_EQ(differing(fast, slow), 0) << "level " << level << " node " << x << "," << y << " scale " << scale;
      }
    }
  });
  // Both paths of the filter ran: windows with data everywhere and windows cut by the sea (NaN).
  EXPECT_GT(inner, 5);
  EXPECT_GT(edge, 5);
}

// bake_albedo's colours (no orthophoto) as the per-texel loop computed them before the planar SSE2
// blend (splat.cpp at 9fccfc0): every texel's RGB, on real nodes at three levels.
TEST(NodeCpuPaths, AlbedoBlendMatchesThePerTexelLoopOnRealNodes) {
  const auto file = terrain::test::data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(file);
  bench::DemRaster dem;
  ASSERT_TRUE(bench::load_dem(file.string(), dem).ok());
  // The exact sRGB transfer tables of splat.cpp.
  std::vector<float> to_linear(256);
  std::vector<uint8_t> to_srgb(4096);
  for (int i = 0; i < 256; ++i) {
    const double c = i / 255.0;
    to_linear[size_t(i)] = float(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
  }
  for (int i = 0; i < 4096; ++i) {
    const double l = (i + 0.5) / 4096.0;
    const double c = l <= 0.0031308 ? l * 12.92 : 1.055 * std::pow(l, 1 / 2.4) - 0.055;
    to_srgb[size_t(i)] = uint8_t(std::clamp(std::lround(c * 255.0), 0L, 255L));
  }
  const MaterialRules& rules = cook::test::default_rules();
  int nodes = 0;
  long texels = 0;
  for_each_real_node(dem, 4, [&](const bench::DemNode& n, uint32_t level, uint32_t x, uint32_t y) {
    const SurfaceInput in = n.input(&rules, BcQuality::balanced);
    SplatLattice lattice;
    compute_splat_lattice(in, rules, lattice);
    std::vector<uint8_t> rgba(size_t(kTexels * kTexels) * 4);
    bake_albedo(in, rules, lattice, rgba.data());
    const double s = in.spacing_m, scale = std::max(48.0, 6.0 * s);
    std::vector<float> lin(size_t(kSplatLattice * kSplatLattice) * 3);
    for (int l = 0; l < kSplatLattice; ++l)
      for (int k = 0; k < kSplatLattice; ++k) {
        const size_t e = size_t(l * kSplatLattice + k);
        const Material& m = rules.palette[lattice.ids[e]];
        const double v = 1.0 + m.detail_strength * 0.5 *
                                   fbm_noise(in.x0_m + (2 * k - 2) * s, in.y0_m + (2 * l - 2) * s, scale, 2, 0xA1BED0u);
        for (int c = 0; c < 3; ++c) lin[e * 3 + size_t(c)] = float(to_linear[m.albedo_srgb[size_t(c)]] * v);
      }
    int differ = 0;
    for (int u = 0; u < kTexels; ++u)
      for (int t = 0; t < kTexels; ++t)
        for (int c = 0; c < 3; ++c) {
          const float fy = (u % 2 == 0) ? 0.25f : 0.75f, fx = (t % 2 == 0) ? 0.25f : 0.75f;
          auto at = [&](int k, int l) { return lin[size_t(l * kSplatLattice + k) * 3 + size_t(c)]; };
          const int k0 = t / 2, l0 = u / 2;
          const float v0 = at(k0, l0) + fy * (at(k0, l0 + 1) - at(k0, l0));
          const float v1 = at(k0 + 1, l0) + fy * (at(k0 + 1, l0 + 1) - at(k0 + 1, l0));
          const uint8_t want = to_srgb[size_t(std::clamp(int((v0 + fx * (v1 - v0)) * 4096.0f), 0, 4095))];
          differ += rgba[size_t(u * kTexels + t) * 4 + size_t(c)] != want;
          ++texels;
        }
    EXPECT_EQ(differ, 0) << "level " << level << " node " << x << "," << y;
    ++nodes;
  });
  EXPECT_GT(nodes, 10);
  std::printf("%d nodes, %ld texel channels compared\n", nodes, texels);
}

// measure_lattice_row (loops that vectorise) against measure_field element by element, bit for bit:
// raw and filtered fields, every combination of attributes, every lattice row of real nodes with
// data everywhere and nodes cut by the sea (the one-sided fallback and elements without data).
TEST(NodeCpuPaths, LatticeRowMeasuresEqualMeasureField) {
  const auto file = terrain::test::data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(file);
  bench::DemRaster dem;
  ASSERT_TRUE(bench::load_dem(file.string(), dem).ok());
  const MaterialRules& rules = cook::test::default_rules();
  long compared = 0, fallback = 0, missing = 0;
  std::vector<float> filtered;
  for_each_real_node(dem, 4, [&](const bench::DemNode& n, uint32_t level, uint32_t, uint32_t) {
    const SurfaceInput in = n.input(&rules, BcQuality::balanced);
    const bool have_filtered = filter_heights(in.heights_m, 16.0, in.spacing_m, filtered);
    for (const float* h : {in.heights_m, have_filtered ? filtered.data() : in.heights_m})
      for (unsigned needs = 0; needs <= kNeedAll; ++needs)
        for (int l = 0; l < kLatticeRow; ++l) {
          const int j = 2 * l - 6;
          SurfaceSample row[kLatticeRow];
          uint8_t ok[kLatticeRow];
          measure_lattice_row(in, h, j, needs, row, ok);
          for (int k = 0; k < kLatticeRow; ++k) {
            const int i = 2 * k - 6;
            SurfaceSample want;
            const bool data = measure_field(in, h, i, j, want, needs);
            ASSERT_EQ(ok[k] != 0, data) << "level " << level << " vertex " << i << "," << j;
            missing += !data;
            if (!data) continue;
            bool full = true;
            for (int b = -1; b <= 1; ++b)
              for (int a = -1; a <= 1; ++a)
                full = full && !std::isnan(h[size_t((j + b + kWindowMargin) * kWindowSize + i + a + kWindowMargin)]);
            fallback += !full;
            ASSERT_EQ(std::memcmp(&row[k], &want, sizeof want), 0)
                << "level " << level << " vertex " << i << "," << j << " needs " << needs << ": slope "
                << row[k].slope_deg << " / " << want.slope_deg << ", aspect " << row[k].aspect_deg << " / "
                << want.aspect_deg << ", curvature " << row[k].curvature << " / " << want.curvature;
            ++compared;
          }
        }
  });
  EXPECT_GT(fallback, 100);  // the sea's edge took the fallback
  EXPECT_GT(missing, 1000);
  std::printf("%ld elements equal (%ld by the fallback), %ld without data\n", compared, fallback, missing);
}

// compute_normal_texels' row loops (gradients without branches, then the cells with a missing
// corner) against the per-texel loop they replaced (normals.cpp at ca61a28), bit for bit, on real
// nodes inside the data and cut by the sea.
TEST(NodeCpuPaths, NormalTexelsMatchThePerTexelLoopOnRealNodes) {
  const auto file = terrain::test::data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(file);
  bench::DemRaster dem;
  ASSERT_TRUE(bench::load_dem(file.string(), dem).ok());
  const MaterialRules& rules = cook::test::default_rules();
  int nodes = 0, edge_cells = 0;
  for_each_real_node(dem, 4, [&](const bench::DemNode& n, uint32_t level, uint32_t x, uint32_t y) {
    const SurfaceInput in = n.input(&rules, BcQuality::balanced);
    NormalTexels got;
    compute_normal_texels(in, got);
    auto wh = [&](int i, int j) { return in.heights_m[size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin)]; };
    auto mean_diff = [](float a0, float a1, float b0, float b1, double& out) {
      int c = 0;
      double sum = 0;
      if (!std::isnan(a0) && !std::isnan(a1)) { sum += double(a1) - a0; ++c; }
      if (!std::isnan(b0) && !std::isnan(b1)) { sum += double(b1) - b0; ++c; }
      if (!c) return false;
      out = sum / c;
      return true;
    };
    const double s = in.spacing_m;
    const float half_inv_s = float(0.5 / s);
    int differ = 0;
    for (int u = 0; u < kTexels; ++u)
      for (int t = 0; t < kTexels; ++t) {
        const int i = t - kApron, j = u - kApron;
        const float h00 = wh(i, j), h10 = wh(i + 1, j), h01 = wh(i, j + 1), h11 = wh(i + 1, j + 1);
        float gx, gy;
        if (!std::isnan(h00 + h10 + h01 + h11)) {
          gx = ((h10 - h00) + (h11 - h01)) * half_inv_s;
          gy = ((h01 - h00) + (h11 - h10)) * half_inv_s;
        } else {
          double dx = 0, dy = 0;
          if (!mean_diff(h00, h10, h01, h11, dx)) dx = 0;
          if (!mean_diff(h00, h01, h10, h11, dy)) dy = 0;
          gx = float(dx / s);
          gy = float(dy / s);
          ++edge_cells;
        }
        const float inv = 1.0f / std::sqrt(gx * gx + gy * gy + 1.0f);
        const float want[3] = {-gx * inv, -gy * inv, inv};
        differ += std::memcmp(&got.n[size_t(u * kTexels + t) * 3], want, sizeof want) != 0;
      }
    EXPECT_EQ(differ, 0) << "level " << level << " node " << x << "," << y;
    ++nodes;
  });
  EXPECT_GT(nodes, 10);
  EXPECT_GT(edge_cells, 100);  // the fallback ran
  std::printf("%d nodes equal, %d cells at the edge of the data\n", nodes, edge_cells);
}

TEST(NodeCpuPaths, AspectMaskEqualsTheFmodFormula) {
  // aspect_mask_value() as written with fmod before.
  auto reference = [](const MaskRange& m, double aspect) {
    const double lo = std::fmod(std::fmod(m.lo, 360.0) + 360.0, 360.0);
    const double width = std::fmod(std::fmod(m.hi - m.lo, 360.0) + 360.0, 360.0);
    const double into = std::fmod(std::fmod(aspect - lo, 360.0) + 360.0, 360.0);
    double outside = 0;
    if (into > width) outside = std::min(into - width, 360.0 - into);
    if (m.fade <= 0) return outside > 0 ? 0.0 : 1.0;
    const double inside_depth = outside > 0 ? -outside : std::min(into, width - into);
    return std::clamp(inside_depth * m.inv_fade + 0.5, 0.0, 1.0);
  };
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> deg(0.0, 360.0);
  const double edges[] = {0.0, -0.0, 1e-300, 359.99999999999994, 360.0, 180.0, 90.0, 1e-13, 359.9999999999999};
  int checked = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    MaskRange m;
    m.active = true;
    m.lo = trial < 81 ? edges[trial % 9] : deg(rng);
    m.hi = trial < 81 ? edges[trial / 9] : deg(rng);
    m.fade = trial % 3 == 0 ? 0.0 : 40.0;
    m.inv_fade = m.fade > 0 ? 1.0 / m.fade : 0.0;
    for (int k = 0; k < 20; ++k) {
      const double a = k < 9 ? edges[k] : deg(rng);
      const double got = aspect_mask_value(m, a), want = reference(m, a);
      ASSERT_EQ(std::memcmp(&got, &want, sizeof got), 0) << m.lo << " " << m.hi << " " << a;
      ++checked;
    }
  }
  EXPECT_EQ(checked, 80000);
}

TEST(NodeCpuPaths, BranchFreeAtan2EqualsTheBranchyOne) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double specials[] = {0.0, -0.0, 1e-300, 1.0, 2.0, 1e300, 0.5};
  int n = 0;
  for (int k = 0; k < 200000; ++k) {
    double y = std::fabs(u(rng)), x = u(rng);
    if (k < 49) y = specials[k % 7], x = (k / 7) % 2 ? -specials[k / 7] : specials[k / 7];
    const double a = fast_atan2_pos(y, x), b = fast_atan2_pos_select(y, x);
    ASSERT_EQ(std::memcmp(&a, &b, sizeof a), 0) << y << " " << x;
    ++n;
  }
  EXPECT_EQ(n, 200000);
}

// argmin_dot (one double pass where the dot products crowd within 4e-5 of their minimum, else
// the per-candidate loop) against the float-prefiltered, per-candidate loop alone, on the patch normals of real Kilauea nodes (sea-cut, smooth and
// steep patches): for each patch's cone axis, axes tilted 1e-3 and 0.1 from it, the vertical and
// random axes, over whole patches and over prefixes of 1..11 normals (the scalar tail); and on
// lists where every normal ties, or two equal minima lie in different lanes.
TEST(NodeCpuPaths, ArgminDotEqualsThePerCandidateLoop) {
  const auto file = terrain::test::data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(file);
  bench::DemRaster dem;
  ASSERT_TRUE(bench::load_dem(file.string(), dem).ok());
  std::mt19937 rng(7);
  std::normal_distribution<double> gauss(0.0, 1.0);
  long queries = 0, crowded = 0, spread = 0;
  PatchNormals pn;
  auto check = [&](NormalSpan v, double ax, double ay, double az) {
    ASSERT_EQ(argmin_dot(v, ax, ay, az), argmin_dot_per_candidate(v, ax, ay, az))
        << "n " << v.n << " axis " << ax << "," << ay << "," << az;
    ++queries;
    // Which path argmin_dot took (its test: every dot product within 4e-5 of the float minimum).
    float low = 4.0f;
    for (int i = 0; i < v.n; ++i) low = std::min(low, float(ax) * v.x[i] + float(ay) * v.y[i] + float(az) * v.z[i]);
    (std::sqrt(ax * ax + ay * ay + az * az) - double(low) <= 4e-5 ? crowded : spread) += 1;
  };
  for_each_real_node(dem, 4, [&](const bench::DemNode& n, uint32_t, uint32_t, uint32_t) {
    collect_patch_normals(n.node, n.height_offset, n.step_log2, n.spacing_m, n.holes.data(), pn);
    for (int k = 0; k < kPatchCount; ++k) {
      const NormalSpan v = pn.patch(k);
      if (v.n == 0) continue;
      const Cone c = smallest_enclosing_cone(v);
      check(v, c.axis[0], c.axis[1], c.axis[2]);
      check(v, 0, 0, 1);
      for (double tilt : {1e-3, 0.1}) {
        double a[3] = {c.axis[0] + tilt * gauss(rng), c.axis[1] + tilt * gauss(rng), c.axis[2] + tilt * gauss(rng)};
        const double len = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        check(v, a[0] / len, a[1] / len, a[2] / len);
        const double r[3] = {gauss(rng), gauss(rng), gauss(rng)};
        const double rl = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
        check(v, r[0] / rl, r[1] / rl, r[2] / rl);
      }
      for (int m = 1; m <= 11 && m < v.n; m += 2) check({v.x, v.y, v.z, m}, c.axis[0], c.axis[1], c.axis[2]);
    }
  });
  // Every normal equal: the first. Two equal minima at 9 and 6, in different lanes of a later
  // group (4 lanes: lanes 1 and 2; SSE2 pairs: lane 1 of the first pair, lane 0 of the second): 6.
  std::vector<float> x(703, 0.0f), y(703, 0.0f), z(703, 1.0f);
  EXPECT_EQ(argmin_dot({x.data(), y.data(), z.data(), 703}, 0.1, 0.0, 0.995), 0);
  for (int i : {9, 6}) {
    x[size_t(i)] = 0.6f;
    z[size_t(i)] = 0.8f;
  }
  check({x.data(), y.data(), z.data(), 703}, -0.6, 0.0, 0.8);
  EXPECT_EQ(argmin_dot({x.data(), y.data(), z.data(), 703}, -0.6, 0.0, 0.8), 6);
  EXPECT_GT(crowded, 1000);
  EXPECT_GT(spread, 1000);
  std::printf("%ld queries equal: %ld by the double pass, %ld by candidates\n", queries, crowded, spread);
}

namespace {

// collect_patch_normals as it was at 6a60d73, one triangle at a time: per patch, the two
// unstitched triangles of every quad (their row-form normals; in a node without holes a row's
// first triangles, then its second ones) unless a vertex is a hole, then
// every distinct moved, non-degenerate stitched triangle (edge deltas 0..4, in the enumeration
// order of the stitch table), dropped when a hole kills it both at its collapsed and at its
// original vertices, kept when its normal faces up.
void reference_patch_normals(const bench::DemNode& n, std::vector<std::array<float, 3>> out[kPatchCount]) {
  auto at = [](int i, int j) { return size_t(j * kHeightSamples + i); };
  std::vector<double> z(static_cast<size_t>(kHeightCount));
  std::vector<uint8_t> hole(static_cast<size_t>(kHeightCount));
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) {
      z[at(i, j)] = units_to_metres(vertex_units(n.height_offset, n.node.heights[at(i, j)], n.step_log2));
      hole[at(i, j)] = n.holes[size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin)] != 0;
    }
  const double s = n.spacing_m;
  const float sf = float(s), s2 = sf * sf;
  struct Tri {
    int snapped[3][2], orig[3][2];
    bool operator==(const Tri& o) const { return std::memcmp(this, &o, sizeof o) == 0; }
  };
  std::vector<Tri> table;
  for (int v = 0; v < kQuadsPerPatch; ++v)
    for (int u = 0; u < kQuadsPerPatch; ++u) {
      const bool onS = v == 0, onN = v == kQuadsPerPatch - 1, onW = u == 0, onE = u == kQuadsPerPatch - 1;
      if (!(onS || onN || onW || onE)) continue;
      const size_t first = table.size();
      for (int dS = 0; dS <= (onS ? 4 : 0); ++dS)
        for (int dN = 0; dN <= (onN ? 4 : 0); ++dN)
          for (int dW = 0; dW <= (onW ? 4 : 0); ++dW)
            for (int dE = 0; dE <= (onE ? 4 : 0); ++dE)
              for (int t = 0; t < 2; ++t) {
                const PatchTriangle a = stitched_quad_triangle(PatchMesh{0, 0, 0, {dS, dW, dN, dE}}, u, v, t);
                const PatchTriangle b = stitched_quad_triangle(PatchMesh{}, u, v, t);
                if (a.degenerate()) continue;
                Tri tri{};
                bool moved = false;
                for (int k = 0; k < 3; ++k) {
                  moved = moved || a.v[k] != b.v[k];
                  tri.snapped[k][0] = a.v[k].i, tri.snapped[k][1] = a.v[k].j;
                  tri.orig[k][0] = b.v[k].i, tri.orig[k][1] = b.v[k].j;
                }
                if (moved && std::find(table.begin() + long(first), table.end(), tri) == table.end()) table.push_back(tri);
              }
    }
  for (int k = 0; k < kPatchCount; ++k) {
    out[k].clear();
    const int gi0 = (k % kPatchesPerSide) * kQuadsPerPatch, gj0 = (k / kPatchesPerSide) * kQuadsPerPatch;
    const bool node_holes = std::find(hole.begin(), hole.end(), 1) != hole.end();
    for (int v = 0; v < kQuadsPerPatch; ++v) {
      std::vector<std::array<float, 3>> second;  // without holes: a row's first triangles, then its second ones
      for (int u = 0; u < kQuadsPerPatch; ++u) {
        const int i = gi0 + u, j = gj0 + v;
        const float x1 = float(z[at(i, j)] - z[at(i + 1, j)]), y1 = float(z[at(i + 1, j)] - z[at(i + 1, j + 1)]);
        const float x2 = float(z[at(i, j + 1)] - z[at(i + 1, j + 1)]), y2 = float(z[at(i, j)] - z[at(i, j + 1)]);
        const float i1 = 1.0f / std::sqrt(x1 * x1 + y1 * y1 + s2), i2 = 1.0f / std::sqrt(x2 * x2 + y2 * y2 + s2);
        const bool common = hole[at(i, j)] || hole[at(i + 1, j + 1)];
        if (!(common || hole[at(i + 1, j)])) out[k].push_back({x1 * i1, y1 * i1, sf * i1});
        if (!(common || hole[at(i, j + 1)])) (node_holes ? out[k] : second).push_back({x2 * i2, y2 * i2, sf * i2});
      }
      out[k].insert(out[k].end(), second.begin(), second.end());
    }
    for (const Tri& t : table) {
      bool hole_snapped = false, hole_orig = false;
      for (int c = 0; c < 3; ++c) {
        hole_snapped = hole_snapped || hole[at(gi0 + t.snapped[c][0], gj0 + t.snapped[c][1])];
        hole_orig = hole_orig || hole[at(gi0 + t.orig[c][0], gj0 + t.orig[c][1])];
      }
      if (hole_snapped && hole_orig) continue;
      const int i0 = gi0 + t.snapped[0][0], j0 = gj0 + t.snapped[0][1];
      const int i1 = gi0 + t.snapped[1][0], j1 = gj0 + t.snapped[1][1];
      const int i2 = gi0 + t.snapped[2][0], j2 = gj0 + t.snapped[2][1];
      const float ax = float(i1 - i0), ay = float(j1 - j0), az = float((z[at(i1, j1)] - z[at(i0, j0)]) / s);
      const float bx = float(i2 - i0), by = float(j2 - j0), bz = float((z[at(i2, j2)] - z[at(i0, j0)]) / s);
      const float nx = ay * bz - az * by, ny = az * bx - ax * bz, nz = ax * by - ay * bx;
      if (!(nz > 0)) continue;
      const float inv = 1.0f / std::sqrt(nx * nx + ny * ny + nz * nz);
      out[k].push_back({nx * inv, ny * inv, nz * inv});
    }
  }
}

}  // namespace

// The patch normals (stitched triangles computed for the whole table at once, hole tests only in
// patches that hold a hole) are, list for list and bit for bit, those of the per-triangle loop, on
// real Kilauea nodes: inland patches, patches cut by the sea (holes) and hole-free patches of nodes
// that hold holes elsewhere.
TEST(NodeCpuPaths, PatchNormalsEqualThePerTriangleLoop) {
  const auto file = terrain::test::data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(file);
  bench::DemRaster dem;
  ASSERT_TRUE(bench::load_dem(file.string(), dem).ok());
  PatchNormals pn;
  std::vector<std::array<float, 3>> want[kPatchCount];
  long normals = 0;
  int patches_with_holes = 0, clear_patches_in_holed_nodes = 0, clear_nodes = 0;
  for_each_real_node(dem, 4, [&](const bench::DemNode& n, uint32_t level, uint32_t x, uint32_t y) {
    collect_patch_normals(n.node, n.height_offset, n.step_log2, n.spacing_m, n.holes.data(), pn);
    reference_patch_normals(n, want);
    clear_nodes += n.hole_vertices == 0;
    for (int k = 0; k < kPatchCount; ++k) {
      const NormalSpan v = pn.patch(k);
      ASSERT_EQ(size_t(v.n), want[k].size()) << "level " << level << " node " << x << "," << y << " patch " << k;
      for (int i = 0; i < v.n; ++i) {
        const float got[3] = {v.x[i], v.y[i], v.z[i]};
        ASSERT_EQ(std::memcmp(got, want[k][size_t(i)].data(), sizeof got), 0)
            << "level " << level << " node " << x << "," << y << " patch " << k << " normal " << i;
      }
      normals += v.n;
      if (n.hole_vertices > 0) {
        bool holed = false;  // a hole among the patch's 17 x 17 vertices
        const int gi0 = (k % kPatchesPerSide) * kQuadsPerPatch, gj0 = (k / kPatchesPerSide) * kQuadsPerPatch;
        for (int j = gj0; j <= gj0 + kQuadsPerPatch; ++j)
          for (int i = gi0; i <= gi0 + kQuadsPerPatch; ++i)
            holed = holed || n.holes[size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin)] != 0;
        (holed ? patches_with_holes : clear_patches_in_holed_nodes) += 1;
      }
    }
  });
  EXPECT_GT(patches_with_holes, 20);
  EXPECT_GT(clear_patches_in_holed_nodes, 20);
  EXPECT_GT(clear_nodes, 5);
  std::printf("%ld normals equal; %d patches with holes, %d clear patches in nodes with holes, %d nodes without holes\n",
              normals, patches_with_holes, clear_patches_in_holed_nodes, clear_nodes);
}

// PatchNormals::same (every normal of the patch equal: flat ground) lets argmin_dot answer 0
// without a scan. Bound checked: the flag is exactly the per-normal comparison, on real Kilauea
// nodes (its sea is flat), a flat synthetic node and spans differing in one normal at every
// position (an 8-lane block or the tail); and where it is set, argmin_dot gives the per-candidate
// loop's index for axes all around.
TEST(NodeCpuPaths, SameNormalsFlagIsThePerNormalComparison) {
  const auto per_normal = [](NormalSpan v) {
    if (v.n <= 0 || std::isnan(v.x[0]) || std::isnan(v.y[0]) || std::isnan(v.z[0])) return false;
    for (int i = 1; i < v.n; ++i)
      if (!(v.x[i] == v.x[0] && v.y[i] == v.y[0] && v.z[i] == v.z[0])) return false;
    return true;
  };
  std::mt19937 rng(5);
  std::normal_distribution<double> gauss(0.0, 1.0);
  int same = 0, differ = 0;
  PatchNormals pn;
  const auto check_node = [&](const bench::DemNode& n) {
    collect_patch_normals(n.node, n.height_offset, n.step_log2, n.spacing_m, n.holes.data(), pn);
    for (int k = 0; k < kPatchCount; ++k) {
      const NormalSpan v = pn.patch(k);
      ASSERT_EQ(v.same, per_normal(v)) << "patch " << k;
      (v.same ? same : differ) += 1;
      if (!v.same) continue;
      for (int a = 0; a < 8; ++a) {
        const double r[3] = {gauss(rng), gauss(rng), a < 4 ? std::abs(gauss(rng)) : gauss(rng)};
        const double len = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
        ASSERT_EQ(argmin_dot(v, r[0] / len, r[1] / len, r[2] / len),
                  argmin_dot_per_candidate(v, r[0] / len, r[1] / len, r[2] / len));
      }
    }
  };
  check_node(terrain::cook::test::synthetic_node([](double, double) { return 0.0; }, 0, 3, 3));
  check_node(terrain::cook::test::synthetic_node([](double, double) { return 812.5; }, 3, 1, 2));
  EXPECT_EQ(same, 2 * kPatchCount);
  const auto file = terrain::test::data_file("kilauea_utm5n.tif");
  if (std::filesystem::exists(file)) {
    bench::DemRaster dem;
    ASSERT_TRUE(bench::load_dem(file.string(), dem).ok());
    for_each_real_node(dem, 4, [&](const bench::DemNode& n, uint32_t, uint32_t, uint32_t) { check_node(n); });
    EXPECT_GT(differ, 500);
  } else {
    std::printf("%s not found: synthetic nodes only\n", file.string().c_str());
  }
  // One normal off (a signed zero is not off), at every position of 1..40-normal spans (a single
  // normal equals itself unless it is NaN).
  for (int n = 1; n <= 40; ++n) {
    std::vector<float> x(size_t(n), 0.0f), y(size_t(n), -0.0f), z(size_t(n), 1.0f);
    for (int i = 0; i < n; i += 3) x[size_t(i)] = -0.0f;
    EXPECT_TRUE(all_normals_equal({x.data(), y.data(), z.data(), n})) << n;
    for (int off = 0; off < n; ++off) {
      std::vector<float> zz = z;
      zz[size_t(off)] = std::nextafter(1.0f, 0.0f);
      EXPECT_EQ(all_normals_equal({x.data(), y.data(), zz.data(), n}), n == 1) << n << " " << off;
      zz[size_t(off)] = NAN;
      EXPECT_EQ(all_normals_equal({x.data(), y.data(), zz.data(), n}), false) << n << " " << off;
    }
  }
  EXPECT_FALSE(all_normals_equal({nullptr, nullptr, nullptr, 0}));
  std::printf("%d patches with one normal, %d with several\n", same, differ);
}

// pack_normal_texels (4 texels at a time in SSE2) against pack_normal_texels_per_texel, byte for
// byte, with and without AO in red: texels holding every edge of normal_texel_of (components
// beyond +-1, signed zeros, exactly on its rounding steps) and AO outside 0..1, then the normals of
// real Kilauea nodes. (Non-finite components are outside its domain: it converts to int.)
TEST(NodeCpuPaths, PackedNormalTexelsEqualThePerTexelLoop) {
  std::mt19937 rng(20261204);
  std::uniform_real_distribution<float> uni(-1.2f, 1.2f);
  const float odd[] = {-1.0f, 1.0f, 0.0f, -0.0f, -1.2f, 1.2f, -127.5f / 127.0f, -126.5f / 127.0f,
                       127.0f / 127.0f, 126.5f / 127.0f, 0.5f / 127.0f, 1.5f / 127.0f};
  long compared = 0;
  auto check = [&](const NormalTexels& n, const char* what) {
    for (bool ao : {true, false}) {
      std::array<uint8_t, kTexelCount * 4> got{}, want{};
      pack_normal_texels(n, got, ao);
      pack_normal_texels_per_texel(n, want, ao);
      for (size_t k = 0; k < kTexelCount; ++k)
        ASSERT_EQ(std::memcmp(&got[k * 4], &want[k * 4], 4), 0)
            << what << " texel " << k << ": " << n.n[k * 3] << "," << n.n[k * 3 + 1] << " ao " << ao;
      compared += kTexelCount;
    }
  };
  NormalTexels synthetic;
  for (int trial = 0; trial < 20; ++trial) {
    for (float& c : synthetic.n) c = rng() % 3 == 0 ? odd[rng() % std::size(odd)] : uni(rng);
    for (float& a : synthetic.ao) a = rng() % 4 == 0 ? odd[rng() % std::size(odd)] : uni(rng);
    check(synthetic, "synthetic");
  }
  const auto file = terrain::test::data_file("kilauea_utm5n.tif");
  if (!file.empty() && std::filesystem::exists(file)) {
    bench::DemRaster dem;
    ASSERT_TRUE(bench::load_dem(file.string(), dem).ok());
    const MaterialRules& rules = cook::test::default_rules();
    for_each_real_node(dem, 4, [&](const bench::DemNode& node, uint32_t, uint32_t, uint32_t) {
      const SurfaceInput in = node.input(&rules, BcQuality::balanced);
      NormalTexels n;
      compute_normal_texels(in, n);
      check(n, "kilauea");
    });
  }
  EXPECT_GE(compared, 20L * 2 * kTexelCount);  // more with the Kilauea nodes (skipped without the shared data)
}

// append_far_normals (8 dot products at a time, blocks kept whole or lane by lane) against the
// per-normal test, list for list: 2000 spans of 0..300 normals against limits that keep all, none
// or some of each block of 8, written after earlier entries.
TEST(NodeCpuPaths, FarNormalsEqualThePerNormalTest) {
  std::mt19937 rng(20261204);
  std::normal_distribution<float> gauss(0.0f, 1.0f);
  long kept = 0, listed = 0, whole_blocks = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const int n = int(rng() % 301);
    std::vector<float> x(static_cast<size_t>(n)), y(x), z(x);
    const float spread = trial % 3 == 0 ? 0.05f : 0.6f;
    for (int i = 0; i < n; ++i) {
      float v[3] = {spread * gauss(rng), spread * gauss(rng), 1.0f};
      const float len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
      x[size_t(i)] = v[0] / len, y[size_t(i)] = v[1] / len, z[size_t(i)] = v[2] / len;
    }
    const float ax = 0.1f * gauss(rng), ay = 0.1f * gauss(rng), az = std::sqrt(1.0f - ax * ax - ay * ay);
    const float limits[4] = {2.0f, -2.0f, 0.999f, float(std::cos(0.3))};
    const float limit = limits[trial % 4];
    const size_t m0 = size_t(rng() % 17);
    std::vector<float> gx(m0 + size_t(n) + 1, -7.0f), gy = gx, gz = gx;
    const size_t got = append_far_normals({x.data(), y.data(), z.data(), n}, ax, ay, az, limit, gx.data(), gy.data(),
                                          gz.data(), m0);
    std::vector<int> want;
    for (int i = 0; i < n; ++i)
      if (ax * x[size_t(i)] + ay * y[size_t(i)] + az * z[size_t(i)] <= limit) want.push_back(i);
    ASSERT_EQ(got, m0 + want.size()) << "trial " << trial;
    for (size_t k = 0; k < want.size(); ++k) {
      const size_t i = size_t(want[k]);
      ASSERT_TRUE(gx[m0 + k] == x[i] && gy[m0 + k] == y[i] && gz[m0 + k] == z[i]) << "trial " << trial << " entry " << k;
    }
    for (size_t k = 0; k < m0; ++k) ASSERT_EQ(gx[k], -7.0f);  // earlier entries untouched
    kept += long(want.size());
    listed += n;
    for (int b = 0; b + 8 <= n; b += 8) {
      int in_block = 0;
      for (int i : want) in_block += i >= b && i < b + 8;
      whole_blocks += in_block == 8;
    }
  }
  EXPECT_GT(kept, listed / 10);
  EXPECT_LT(kept, listed * 9 / 10);
  EXPECT_GT(whole_blocks, 1000);
}
