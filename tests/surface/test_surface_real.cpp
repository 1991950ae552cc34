// cook_surface_layers on nodes of the shared real DEMs: exact punch-through where the data has
// holes (Kilauea's sea, N22W160's voids), neighbour agreement, spiky lidar, cone conservativeness
// with random eyes, and the albedo encoder against the library encoders on the same nodes.
#include <gtest/gtest.h>

#include <cmath>

#include "bc_blocks.h"
#include "surface_encoders.h"
#include "normals.h"
#include "splat.h"
#include "surface_test_support.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::cook;
using namespace terrain::cook::test;

namespace {

bench::DemRaster load(const std::string& file) {
  bench::DemRaster dem;
  const Status st = bench::load_dem(terrain::test::data_file(file).string(), dem);
  EXPECT_TRUE(st.ok()) << st.to_string();
  return dem;
}

// Nodes of `level` that contain both data and holes (up to `max`).
std::vector<bench::DemNode> nodes_with_holes(const bench::DemRaster& dem, uint32_t level, int step, size_t max) {
  std::vector<bench::DemNode> out;
  const uint32_t nx = bench::nodes_across(dem, level, false), ny = bench::nodes_across(dem, level, true);
  for (uint32_t y = 0; y < ny && out.size() < max; ++y)
    for (uint32_t x = 0; x < nx && out.size() < max; ++x) {
      bench::DemNode n;
      bench::make_dem_node(dem, level, x, y, step, n);
      if (n.hole_vertices > 200 && n.data_vertices > 2000) out.push_back(std::move(n));
    }
  return out;
}

void expect_exact_punch_through(const bench::DemNode& node, const NodeData& d) {
  const auto alb = decode_albedo(d);
  uint64_t wrong = 0, holes = 0;
  for (int u = 0; u < kTexels; ++u)
    for (int t = 0; t < kTexels; ++t) {
      const bool want = texel_is_hole(node, t, u);
      holes += want;
      wrong += (alb[size_t(u * kTexels + t) * 4 + 3] == 0) != want;
    }
  EXPECT_GT(holes, 0u);
  EXPECT_EQ(wrong, 0u) << "node " << node.key.level << "/" << node.key.x << "/" << node.key.y;
}

}  // namespace

TEST(SurfaceReal, KilaueaSeaHolesSurviveCompressionExactly) {
  TERRAIN_REQUIRE_DATA(terrain::test::data_file("kilauea_utm5n.tif"));
  const auto nodes = nodes_with_holes(load("kilauea_utm5n.tif"), 4, 6, 6);
  ASSERT_GE(nodes.size(), 3u);
  for (const auto& n : nodes)
    for (BcQuality q : {BcQuality::fast, BcQuality::balanced, BcQuality::best}) {
      const Cooked c = cook_node(n, default_rules(), q);
      ASSERT_TRUE(c.status.ok()) << c.status.to_string();
      expect_exact_punch_through(n, c.data);
    }
}

TEST(SurfaceReal, N22W160VoidsSurviveCompressionExactly) {
  TERRAIN_REQUIRE_DATA(terrain::test::data_file("N22W160.hgt.zip"));
  const auto nodes = nodes_with_holes(load("N22W160.hgt.zip"), 5, 6, 6);
  ASSERT_GE(nodes.size(), 3u);
  for (const auto& n : nodes) {
    const Cooked c = cook_node(n, default_rules(), BcQuality::balanced);
    ASSERT_TRUE(c.status.ok());
    expect_exact_punch_through(n, c.data);
    EXPECT_EQ(check_cones(n, c.data, 60, n.key.x).violations, 0u);
  }
}

TEST(SurfaceReal, KilaueaNeighboursAgreeInTheirOverlap) {
  TERRAIN_REQUIRE_DATA(terrain::test::data_file("kilauea_utm5n.tif"));
  const auto dem = load("kilauea_utm5n.tif");
  // Caldera area, level 3 (4 m vertices on 30 m data), an east-west and a south-north pair.
  bench::DemNode a, east, north;
  bench::make_dem_node(dem, 3, 20, 18, 5, a);
  bench::make_dem_node(dem, 3, 21, 18, 5, east);
  bench::make_dem_node(dem, 3, 20, 19, 5, north);
  ASSERT_EQ(a.hole_vertices, 0);
  const Cooked ca = cook_node(a, default_rules()), ce = cook_node(east, default_rules()), cn = cook_node(north, default_rules());
  const auto da = decode_normals(ca.data), de = decode_normals(ce.data), dn = decode_normals(cn.data);
  auto compare = [&](const std::vector<uint8_t>& other, bool east_pair) {
    double worst = 0, sum = 0;
    int count = 0;
    for (int u = 0; u < kTexels; ++u)
      for (int t = 0; t < kTexels; ++t) {
        const bool in_overlap = east_pair ? t >= 128 : u >= 128;
        if (!in_overlap) continue;
        const int t2 = east_pair ? t - 128 : t, u2 = east_pair ? u : u - 128;
        double va[3], vb[3];
        texel_normal(&da[size_t(u * kTexels + t) * 4], va);
        texel_normal(&other[size_t(u2 * kTexels + t2) * 4], vb);
        const double deg = std::acos(std::min(1.0, va[0] * vb[0] + va[1] * vb[1] + va[2] * vb[2])) * 180 / kPi;
        worst = std::max(worst, deg);
        sum += deg;
        ++count;
      }
    // Bound 0, from the layout rather than the encoder's own error statistic: the overlap texels
    // are computed from the same DEM window, texel t of a node is texel t - 128 of its eastern
    // (northern) neighbour and 128 is a multiple of the 4-texel block, so both nodes encode the
    // same blocks from the same inputs with a deterministic encoder (SPEC 16.2).
    std::printf("%s overlap: mean %.3f deg, max %.3f deg over %d texels\n", east_pair ? "east" : "north", sum / count,
                worst, count);
    // (acos of the dot product of two equal unit vectors rounds to ~1e-6 degrees, hence 1e-5.)
    EXPECT_LE(worst, 1e-5);
  };
  compare(de, true);
  compare(dn, false);
  // The splat maps share their edge samples exactly.
  for (int j = 0; j < kSplatSamples; ++j)
    EXPECT_EQ(ca.data.splat[size_t(j * kSplatSamples + 64)], ce.data.splat[size_t(j * kSplatSamples)]);
  for (int i = 0; i < kSplatSamples; ++i)
    EXPECT_EQ(ca.data.splat[size_t(64 * kSplatSamples + i)], cn.data.splat[size_t(i)]);
}

TEST(SurfaceReal, TahoeHighestHitSpikyNormalsAndCones) {
  TERRAIN_REQUIRE_DATA(terrain::test::data_file("tahoe_lidar_highesthit.tif"));
  const auto dem = load("tahoe_lidar_highesthit.tif");
  bench::DemNode n;
  bench::make_dem_node(dem, 0, 1, 1, 2, n);
  ASSERT_EQ(n.hole_vertices, 0);
  double mean_fast = 0;
  for (BcQuality q : {BcQuality::fast, BcQuality::balanced}) {
    const Cooked c = cook_node(n, default_rules(), q);
    ASSERT_TRUE(c.status.ok());
    const double mean = c.stats.normal_err_sum_deg / double(c.stats.normal_samples);
    std::printf("tahoe highest-hit, quality %d: normal error mean %.3f max %.3f deg; cones exact %.1f encoded %.1f deg\n",
                int(q), mean, c.stats.normal_err_max_deg, c.stats.cone_exact_deg_sum / double(c.stats.cone_patches),
                c.stats.cone_encoded_deg_sum / double(c.stats.cone_patches));
    // Tree-top normals change direction from texel to texel, which no 4x4-block format follows;
    // the bound is the measured level (8.8-8.9 degrees mean on this node) with a little room.
    EXPECT_LT(mean, 9.5);
    if (q == BcQuality::fast) mean_fast = mean;
    else EXPECT_LE(mean, mean_fast + 1e-9);
    const ConeCheck check = check_cones(n, c.data, 300, 7);
    EXPECT_EQ(check.violations, 0u) << "worst cos " << check.worst_cos;
  }
}

TEST(SurfaceReal, ConesNeverCullFrontFacingTrianglesOnRealNodes) {
  struct Pick {
    const char* file;
    uint32_t level, x, y;
    int step;
  };
  const Pick picks[] = {{"kilauea_utm5n.tif", 3, 18, 17, 5},  // caldera walls
                        {"srtm_oetztal.tif", 4, 20, 20, 6},   // alpine ridges
                        {"slovenia_TM1_564_146.tif", 1, 3, 3, 3}};
  for (const Pick& p : picks) {
    const auto path = terrain::test::data_file(p.file);
    if (!std::filesystem::exists(path)) GTEST_SKIP() << "real data not found: " << path;
    const auto dem = load(p.file);
    bench::DemNode n;
    bench::make_dem_node(dem, p.level, p.x, p.y, p.step, n);
    ASSERT_GT(n.data_vertices, 10000) << p.file;
    const Cooked c = cook_node(n, default_rules());
    ASSERT_TRUE(c.status.ok());
    const ConeCheck check = check_cones(n, c.data, 400, p.x * 131 + p.y);
    std::printf("%s: %llu eyes, %llu of %llu patch tests culled, %llu triangles checked, worst cos %.4f\n", p.file,
                (unsigned long long)check.eyes, (unsigned long long)check.culled,
                (unsigned long long)check.patch_tests, (unsigned long long)check.triangles_checked, check.worst_cos);
    EXPECT_EQ(check.violations, 0u) << p.file;
    EXPECT_GT(check.culled, 0u) << p.file;
  }
}

namespace {

// Splat-baked albedo of the given nodes encoded with each method; PSNR over non-hole texels.
struct AlbedoPsnr {
  double own = 0, cluster = 0, stb = 0, squish = 0;
  uint64_t mismatches = 0;  // punch-through mismatches of our two settings
};
AlbedoPsnr albedo_psnr(const std::vector<bench::DemNode>& nodes) {
  AlbedoCheck own, cluster, stb, squish;
  for (const bench::DemNode& n : nodes) {
    SplatLattice lattice;
    const SurfaceInput in = n.input(&default_rules(), BcQuality::balanced);
    compute_splat_lattice(in, default_rules(), lattice);
    std::vector<uint8_t> rgba(size_t(kTexelCount) * 4);
    bake_albedo(in, default_rules(), lattice, rgba.data());
    std::vector<uint8_t> blocks(static_cast<size_t>(kAlbedoBytes));
    auto add = [&](Bc1Method m, AlbedoCheck& acc) {
      encode_bc1_image(rgba.data(), m, blocks.data());
      const AlbedoCheck c = check_albedo(rgba.data(), blocks.data());
      acc.sq_err += c.sq_err;
      acc.samples += c.samples;
      acc.alpha_mismatches += c.alpha_mismatches;
    };
    add(albedo_method(BcQuality::balanced), own);
    add(Bc1Method::ordering_search, cluster);
    add(Bc1Method::stb, stb);
    add(Bc1Method::squish_cluster, squish);
  }
  return {psnr_db(own.sq_err, own.samples), psnr_db(cluster.sq_err, cluster.samples), psnr_db(stb.sq_err, stb.samples),
          psnr_db(squish.sq_err, squish.samples), own.alpha_mismatches + cluster.alpha_mismatches};
}

}  // namespace

TEST(SurfaceReal, DefaultAlbedoEncoderMatchesTheBestLibraryOnKilauea) {
  TERRAIN_REQUIRE_DATA(terrain::test::data_file("kilauea_utm5n.tif"));
  const auto dem = load("kilauea_utm5n.tif");
  std::vector<bench::DemNode> nodes;
  for (uint32_t k = 0; k < 6; ++k) {
    bench::DemNode n;
    bench::make_dem_node(dem, 4, 4 + 2 * k, 3 + k, 6, n);
    nodes.push_back(std::move(n));
  }
  const AlbedoPsnr p = albedo_psnr(nodes);
  std::printf("Kilauea splat albedo PSNR: default %.3f dB, ordering-search %.3f dB, stb_dxt %.3f dB, squish cluster %.3f dB\n",
              p.own, p.cluster, p.stb, p.squish);
  EXPECT_EQ(p.mismatches, 0u);
  EXPECT_GE(p.own, std::max(p.stb, p.squish));
  EXPECT_GE(p.cluster, p.own);
}

// Alpine splat albedo (many material borders plus noise: 12-16 distinct colours in most blocks)
// is the hardest set for the default. Issue 4's target (default >= max(stb_dxt, squish cluster))
// is NOT met here yet: the default loses 0.3 dB to libsquish cluster fit, broadly over all
// non-smooth blocks (own/squish error ratio ~1.10 across the worst 50 % of blocks, measured with
// terrain-bc-bench --block-stats), and no effort setting of ours reaches squish at stb_dxt's time
// (terrain-bc-bench --frontier). The test pins what holds: the default beats stb_dxt, stays
// within the measured gap of squish (bound 0.4 dB; 0.26 dB on these nodes), and ordering-search (ordering
// search) is at least libsquish cluster fit's PSNR (+0.03 dB on these nodes, a tie on the bench's).
TEST(SurfaceReal, AlbedoEncodersAgainstTheLibrariesOnOetztal) {
  TERRAIN_REQUIRE_DATA(terrain::test::data_file("srtm_oetztal.tif"));
  const auto dem = load("srtm_oetztal.tif");
  // Six level-5 nodes with data, spread over the raster like terrain-bc-bench picks them.
  const uint32_t nx = bench::nodes_across(dem, 5, false), ny = bench::nodes_across(dem, 5, true);
  std::vector<bench::DemNode> nodes;
  const uint32_t total = nx * ny, stride = std::max(1u, total / 12);
  for (uint32_t c = stride / 2; c < total && nodes.size() < 6; c += stride) {
    bench::DemNode n;
    bench::make_dem_node(dem, 5, c % nx, c / nx, 6, n);
    if (n.data_vertices > kHeightCount / 4) nodes.push_back(std::move(n));
  }
  ASSERT_GE(nodes.size(), 4u);
  const AlbedoPsnr p = albedo_psnr(nodes);
  std::printf("Oetztal splat albedo PSNR over %zu nodes: default %.3f dB, ordering-search %.3f dB, stb_dxt %.3f dB, "
              "squish cluster %.3f dB\n", nodes.size(), p.own, p.cluster, p.stb, p.squish);
  EXPECT_EQ(p.mismatches, 0u);
  EXPECT_GE(p.own, p.stb);
  EXPECT_GE(p.own, p.squish - 0.4);
  EXPECT_GE(p.cluster, p.squish);
  EXPECT_GE(p.cluster, p.own);
}
