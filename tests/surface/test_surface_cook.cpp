// terrain-cook's --albedo (orthophoto) and --holes (mask) on real data. The rasters are made at
// test time from the Kilauea DEM with GDAL (gdaldem color-relief, then gdalwarp to EPSG:4326, a
// different CRS from the DEM's UTM frame), and GDAL also resamples them back onto the archive's
// texel / vertex grid as the independent oracle.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "materials.h"
#include "surface_test_support.h"
#include "terrain/archive_reader.h"
#include "terrain/cook.h"
#include "test_data.h"

namespace fs = std::filesystem;
using namespace terrain;
using namespace terrain::cook;

namespace {

bool have_gdal() {
  // (gdaldem exits 1 on --version and --help, so look the tools up instead.)
  return std::system("command -v gdalwarp > /dev/null && command -v gdaldem > /dev/null && "
                     "command -v gdal_translate > /dev/null") == 0;
}

#define REQUIRE_GDAL()                                                              \
  do {                                                                              \
    if (!have_gdal()) GTEST_SKIP() << "GDAL command-line tools (gdal-bin) not found"; \
  } while (0)

void run(const std::string& cmd) { ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd; }

// Single-quoted for the shell (the scratch paths hold no quotes).
std::string q(const fs::path& p) {
  std::string out(1, '\'');
  out.append(p.string());
  out.push_back('\'');
  return out;
}

// Kilauea heights ramp (sea = nodata -> transparent). Colourful and smooth at 30 m.
void write_ramp(const fs::path& p) {
  std::ofstream f(p);
  f << "nv 0 0 0 0\n0 30 90 160\n200 60 140 70\n600 150 170 90\n1000 190 150 110\n1500 240 235 230\n";
}

// A raw (ENVI, band-sequential bytes) raster that GDAL resampled onto a UTM grid of `n` x `n`
// pixels of `s` metres whose first pixel centre is (cx0, cy0); rows returned south to north.
struct Grid {
  int n = 0, bands = 0;
  std::vector<uint8_t> bytes;  // band-sequential, GDAL row order (north first)
  uint8_t at(int band, int k, int l) const {  // k east, l north (0 = south row)
    return bytes[(size_t(band) * size_t(n) + size_t(n - 1 - l)) * size_t(n) + size_t(k)];
  }
};
Grid warp_to_grid(const fs::path& src, const fs::path& dir, const std::string& name, double cx0, double cy0, double s,
                  int n, const char* resampling) {
  const fs::path out = dir / (name + ".bin");
  char te[256];
  std::snprintf(te, sizeof te, "-te %.6f %.6f %.6f %.6f -ts %d %d", cx0 - s / 2, cy0 - s / 2, cx0 - s / 2 + n * s,
                cy0 - s / 2 + n * s, n, n);
  // The Kilauea DEM's explicit TM parameters are those of UTM zone 5N on WGS 84.
  const std::string cmd = "gdalwarp -q -overwrite -et 0 -of ENVI -t_srs EPSG:32605 -r " + std::string(resampling) + " " + te +
                          " " + q(src) + " " + q(out);
  Grid g;
  if (std::system(cmd.c_str()) != 0) return g;
  std::ifstream f(out, std::ios::binary);
  g.bytes.assign(std::istreambuf_iterator<char>(f), {});
  g.n = n;
  g.bands = int(g.bytes.size() / (size_t(n) * size_t(n)));
  return g;
}

Status cook_kilauea(const fs::path& out, const std::string& albedo, const std::string& holes, int finest_level = 5) {
  CookOptions o;
  o.inputs = {terrain::test::data_file("kilauea_utm5n.tif").string()};
  o.output = out.string();
  o.finest_level = finest_level;
  o.albedo_path = albedo;
  o.holes_path = holes;
  CookReport report;
  return terrain::cook::cook(o, {}, report);
}

// photo_4326.tif: an RGBA "orthophoto" in EPSG:4326 whose red and blue are a colour relief of the
// DEM (smooth) and whose green is its hillshade (sharp texel-scale features); the sea is alpha 0.
void make_photo(const fs::path& dir) {
  const std::string dem = q(terrain::test::data_file("kilauea_utm5n.tif"));
  write_ramp(dir / "ramp.txt");
  run("gdaldem color-relief -q -alpha " + dem + " " + q(dir / "ramp.txt") + " " + q(dir / "relief.tif"));
  run("gdaldem hillshade -q -compute_edges " + dem + " " + q(dir / "shade.tif"));
  for (int b : {1, 3, 4})
    run("gdal_translate -q -b " + std::to_string(b) + " " + q(dir / "relief.tif") + " " +
        q(dir / ("band" + std::to_string(b) + ".tif")));
  run("gdalbuildvrt -q -separate " + q(dir / "mix.vrt") + " " + q(dir / "band1.tif") + " " + q(dir / "shade.tif") + " " +
      q(dir / "band3.tif") + " " + q(dir / "band4.tif"));
  run("gdal_translate -q -colorinterp red,green,blue,alpha " + q(dir / "mix.vrt") + " " + q(dir / "photo_utm.tif"));
  run("gdalwarp -q -overwrite -t_srs EPSG:4326 -r bilinear " + q(dir / "photo_utm.tif") + " " + q(dir / "photo_4326.tif"));
}

// mask_4326.tif: band 1 = 255 above 1100 m, else 0 (EPSG:4326, nearest).
void make_mask(const fs::path& dir) {
  const std::string dem = q(terrain::test::data_file("kilauea_utm5n.tif"));
  std::ofstream(dir / "mask.txt") << "0 0 0 0\n1099.99 0 0 0\n1100 255 255 255\n3000 255 255 255\n";
  run("gdaldem color-relief -q -nearest_color_entry " + dem + " " + q(dir / "mask.txt") + " " + q(dir / "mask_utm.tif"));
  run("gdalwarp -q -overwrite -t_srs EPSG:4326 -r near " + q(dir / "mask_utm.tif") + " " + q(dir / "mask_4326.tif"));
}

// The nodes of `level` in `a`, each with its index in `b` (a cook of the same DEM without an
// overlay): (index in a, index in b). A node `b` lacks is a fatal test failure.
void nodes_in_both(const ArchiveReader& a, const ArchiveReader& b, int level, std::vector<std::pair<size_t, size_t>>& out) {
  for (size_t i = 0; i < a.nodes().size(); ++i) {
    if (a.nodes()[i].key.level != uint32_t(level)) continue;
    const int64_t j = b.find(a.nodes()[i].key);
    ASSERT_GE(j, 0);
    out.emplace_back(i, size_t(j));
  }
}

}  // namespace

// Cooks Kilauea with `photo` as --albedo and compares the level-5 albedo with GDAL's bilinear
// resampling of the same photo onto the texel centres (texel (t, u) of node (nx, ny) is global
// pixel (nx * 128 + t - 2, ny * 128 + u - 2), centred at origin + (k + 0.5) s), over texels with
// data in both; also against the oracle shifted by up to 2 texels (same texel set for every shift).
constexpr int kShift = 2;
struct OrthoCompare {
  double psnr = 0;                                     // all three channels, zero shift
  double mse[3][2 * kShift + 1][2 * kShift + 1] = {};  // per channel, [dy][dx]
  uint64_t samples = 0;
  int nodes = 0;
};
void compare_ortho(const fs::path& dir, const fs::path& photo, OrthoCompare& out) {
  const fs::path archive = dir / (photo.stem().string() + ".terrain");
  const Status st = cook_kilauea(archive, photo.string(), "");
  ASSERT_TRUE(st.ok()) << st.to_string();
  ArchiveReader r;
  ASSERT_TRUE(r.open(archive.string()).ok());
  const WorldInfo& w = r.world();
  const int level = 5;
  const double s = vertex_spacing_m(level);
  const int n = int(std::max(w.roots_x, w.roots_y)) * kQuadsPerSide;
  const Grid g = warp_to_grid(photo, dir, photo.stem().string() + "_oracle", w.origin_x_m + 0.5 * s,
                              w.origin_y_m + 0.5 * s, s, n, "bilinear");
  ASSERT_EQ(g.bands, 4) << "expected RGBA from gdalwarp";
  auto oracle_ok = [&](int k, int l) { return k >= 0 && l >= 0 && k < n && l < n && g.at(3, k, l) == 255; };
  double shift_sq[3][2 * kShift + 1][2 * kShift + 1] = {};
  for (size_t i = 0; i < r.nodes().size(); ++i) {
    const NodeRecord& rec = r.nodes()[i];
    if (rec.key.level != uint32_t(level)) continue;
    NodeData d;
    ASSERT_TRUE(r.decode_node(i, d, kSectionAlbedo).ok());
    const std::vector<uint8_t> alb = terrain::cook::test::decode_albedo(d);
    ++out.nodes;
    for (int u = kApron; u < kTexels - kApron; ++u)
      for (int t = kApron; t < kTexels - kApron; ++t) {
        const uint8_t* px = &alb[size_t(u * kTexels + t) * 4];
        if (px[3] == 0) continue;  // hole (the sea)
        const int k = int(rec.key.x) * kQuadsPerSide + t - kApron, l = int(rec.key.y) * kQuadsPerSide + u - kApron;
        bool all = true;
        for (int dy = -kShift; dy <= kShift && all; ++dy)
          for (int dx = -kShift; dx <= kShift && all; ++dx) all = oracle_ok(k + dx, l + dy);
        if (!all) continue;
        for (int dy = -kShift; dy <= kShift; ++dy)
          for (int dx = -kShift; dx <= kShift; ++dx)
            for (int c = 0; c < 3; ++c) {
              const double e = double(px[c]) - g.at(c, k + dx, l + dy);
              shift_sq[c][dy + kShift][dx + kShift] += e * e;
            }
        out.samples += 3;
      }
  }
  ASSERT_GT(out.samples, 0u);
  const double sq = shift_sq[0][kShift][kShift] + shift_sq[1][kShift][kShift] + shift_sq[2][kShift][kShift];
  out.psnr = 10 * std::log10(255.0 * 255.0 * double(out.samples) / sq);
  for (int c = 0; c < 3; ++c)
    for (int dy = 0; dy <= 2 * kShift; ++dy)
      for (int dx = 0; dx <= 2 * kShift; ++dx) out.mse[c][dy][dx] = shift_sq[c][dy][dx] / double(out.samples / 3);
  for (int c = 0; c < 3; ++c)
    std::printf("%s channel %d vs GDAL: mse at shift 0: %.2f, one texel east %.2f, west %.2f, north %.2f, south %.2f\n",
                photo.filename().c_str(), c, out.mse[c][kShift][kShift], out.mse[c][kShift][kShift + 1],
                out.mse[c][kShift][kShift - 1], out.mse[c][kShift + 1][kShift], out.mse[c][kShift - 1][kShift]);
  std::printf("%s vs GDAL: %.2f dB over %llu samples, %d nodes\n", photo.filename().c_str(), out.psnr,
              (unsigned long long)out.samples, out.nodes);
}

// The orthophoto (EPSG:4326; the DEM and frame are UTM 5N) matches GDAL's resampling and lands in
// place: in the hillshade channel (sharp texel-scale features) the best alignment is at zero
// shift and one texel (16 m) off costs clearly more; PSNR over all channels bounds the colour error.
TEST(SurfaceCook, OrthophotoInAnotherCrsMatchesGdalAndLandsInPlace) {
  TERRAIN_REQUIRE_DATA(terrain::test::data_file("kilauea_utm5n.tif"));
  REQUIRE_GDAL();
  const fs::path dir = terrain::test::scratch_dir("surface-ortho");
  make_photo(dir);
  OrthoCompare photo;
  compare_ortho(dir, dir / "photo_4326.tif", photo);
  EXPECT_GT(photo.nodes, 100);
  EXPECT_GT(photo.samples, 3000000u);
  // Bound: the cooked texel averages its four corner vertices (each bilinear from the photo) in
  // linear light where GDAL samples the centre once, then BC1 compression. Measured 46.7 dB
  // (mse 0.95 / 2.2 / 1.0 per channel); the bound leaves ~4.7 dB.
  EXPECT_GT(photo.psnr, 42.0);
  const auto& shade = photo.mse[1];
  int best_dx = 99, best_dy = 99;
  double best = 1e300;
  for (int dy = -kShift; dy <= kShift; ++dy)
    for (int dx = -kShift; dx <= kShift; ++dx)
      if (shade[dy + kShift][dx + kShift] < best) {
        best = shade[dy + kShift][dx + kShift];
        best_dx = dx;
        best_dy = dy;
      }
  EXPECT_EQ(best_dx, 0);
  EXPECT_EQ(best_dy, 0);
  // Measured (hillshade channel): mse 2.2 at zero shift, 5.9-6.0 one texel east/west, 8.2-8.4
  // north/south.
  const double mse0 = shade[kShift][kShift];
  for (int d : {-1, 1}) {
    EXPECT_GT(shade[kShift][kShift + d], 2 * mse0);
    EXPECT_GT(shade[kShift + d][kShift], 2 * mse0);
  }
  fs::remove_all(dir);
}

// A hole mask in EPSG:4326 punches exact holes: every vertex the DEM leaves a hole stays one, every
// vertex inside the mask (it and its 8 neighbours masked per GDAL's nearest resampling) is
// transparent, and only vertices on the mask's border may disagree with GDAL (sampling ties).
// The masked vertices drop their triangles: the drawn-triangle count falls by the right amount.
TEST(SurfaceCook, HoleMaskInAnotherCrsPunchesExactHolesAndDropsTriangles) {
  TERRAIN_REQUIRE_DATA(terrain::test::data_file("kilauea_utm5n.tif"));
  REQUIRE_GDAL();
  const fs::path dir = terrain::test::scratch_dir("surface-holes");
  make_mask(dir);
  Status st = cook_kilauea(dir / "plain.terrain", "", "");
  ASSERT_TRUE(st.ok()) << st.to_string();
  st = cook_kilauea(dir / "masked.terrain", "", (dir / "mask_4326.tif").string());
  ASSERT_TRUE(st.ok()) << st.to_string();
  ArchiveReader plain, masked;
  ASSERT_TRUE(plain.open((dir / "plain.terrain").string()).ok());
  ASSERT_TRUE(masked.open((dir / "masked.terrain").string()).ok());
  ASSERT_EQ(plain.nodes().size(), masked.nodes().size());
  const WorldInfo& w = masked.world();
  const int level = 5;
  const double s = vertex_spacing_m(level);
  const int n = int(w.roots_x) * kQuadsPerSide + 1;
  const Grid g = warp_to_grid(dir / "mask_4326.tif", dir, "mask_oracle", w.origin_x_m, w.origin_y_m, s, n, "near");
  ASSERT_GE(g.bands, 1);
  auto mask = [&](int k, int l) { return k >= 0 && l >= 0 && k < n && l < n && g.at(0, k, l) != 0; };

  uint64_t dem_holes = 0, dem_hole_lost = 0, interior = 0, interior_missed = 0, border = 0, border_wrong = 0, extra = 0;
  uint64_t tri_plain = 0, tri_masked = 0;
  std::vector<std::pair<size_t, size_t>> nodes;
  ASSERT_NO_FATAL_FAILURE(nodes_in_both(masked, plain, level, nodes));
  for (const auto& [i, j] : nodes) {
    const NodeRecord& rec = masked.nodes()[i];
    NodeData dp, dm;
    ASSERT_TRUE(plain.decode_node(j, dp, kSectionAlbedo).ok());
    ASSERT_TRUE(masked.decode_node(i, dm, kSectionAlbedo).ok());
    const auto ap = terrain::cook::test::decode_albedo(dp), am = terrain::cook::test::decode_albedo(dm);
    auto hole = [](const std::vector<uint8_t>& a, int vi, int vj) {
      return a[size_t((vj + kApron) * kTexels + vi + kApron) * 4 + 3] == 0;
    };
    for (int vj = 0; vj <= kQuadsPerSide; ++vj)
      for (int vi = 0; vi <= kQuadsPerSide; ++vi) {
        const int k = int(rec.key.x) * kQuadsPerSide + vi, l = int(rec.key.y) * kQuadsPerSide + vj;
        const bool hp = hole(ap, vi, vj), hm = hole(am, vi, vj), m = mask(k, l);
        if (hp) {
          ++dem_holes;
          dem_hole_lost += !hm;
          continue;
        }
        bool all = m, any = m;
        for (int b = -1; b <= 1; ++b)
          for (int a = -1; a <= 1; ++a) {
            all = all && mask(k + a, l + b);
            any = any || mask(k + a, l + b);
          }
        if (all) {
          ++interior;
          interior_missed += !hm;
        } else if (any) {
          ++border;
          border_wrong += hm != m;
        } else {
          extra += hm;  // far from the mask: must stay opaque
        }
      }
    for (int vj = 0; vj < kQuadsPerSide; ++vj)
      for (int vi = 0; vi < kQuadsPerSide; ++vi) {
        // Two triangles per quad; a triangle is drawn when none of its vertices is a hole
        // (format/SPEC.md: quads split south-west to north-east).
        auto drawn = [&](const std::vector<uint8_t>& a, int tri) {
          const bool sw = hole(a, vi, vj), ne = hole(a, vi + 1, vj + 1);
          const bool other = tri == 0 ? hole(a, vi + 1, vj) : hole(a, vi, vj + 1);
          return !(sw || ne || other);
        };
        for (int tri = 0; tri < 2; ++tri) {
          const bool p = drawn(ap, tri), m = drawn(am, tri);
          tri_plain += p;
          tri_masked += m;
          EXPECT_FALSE(m && !p);
        }
      }
  }
  std::printf("dem holes %llu (lost %llu); mask interior %llu (missed %llu); border %llu (differ from GDAL %llu); "
              "outside %llu extra; triangles %llu -> %llu\n",
              (unsigned long long)dem_holes, (unsigned long long)dem_hole_lost, (unsigned long long)interior,
              (unsigned long long)interior_missed, (unsigned long long)border, (unsigned long long)border_wrong,
              (unsigned long long)extra, (unsigned long long)tri_plain, (unsigned long long)tri_masked);
  EXPECT_GT(dem_holes, 1000u);
  EXPECT_EQ(dem_hole_lost, 0u);
  EXPECT_GT(interior, 10000u);
  EXPECT_EQ(interior_missed, 0u);
  EXPECT_EQ(extra, 0u);
  // Border vertices: nearest sampling here and in GDAL (exact transforms, -et 0) agrees except on
  // exact ties; measured 0 of ~9300 (bound: 0.2 %).
  EXPECT_LE(double(border_wrong), 0.002 * double(border));
  // Each interior mask vertex drops the six triangles around it, each shared by at most three
  // such vertices: at least 2 triangles per interior vertex disappear.
  EXPECT_LE(double(tri_masked), double(tri_plain) - 2.0 * double(interior));
  fs::remove_all(dir);
}

// Bad --albedo / --holes files: clear messages naming the file and the problem.
TEST(SurfaceCook, BadOverlayFilesGiveClearErrors) {
  TERRAIN_REQUIRE_DATA(terrain::test::data_file("kilauea_utm5n.tif"));
  const fs::path dir = terrain::test::scratch_dir("surface-bad");
  auto expect_error = [&](const std::string& albedo, const std::string& holes, const std::string& words) {
    const Status st = cook_kilauea(dir / "bad.terrain", albedo, holes);
    EXPECT_FALSE(st.ok()) << albedo << " / " << holes;
    EXPECT_NE(st.message.find(words), std::string::npos) << st.to_string();
    EXPECT_FALSE(fs::exists(dir / "bad.terrain"));
  };
  expect_error("/nonexistent/photo.tif", "", "/nonexistent/photo.tif");
  // A single-band DEM is not an RGB orthophoto.
  expect_error(terrain::test::data_file("kilauea_utm5n.tif").string(), "", "expected an RGB image");
  // A mask on the other side of the planet (Tahoe) does not overlap Kilauea.
  if (fs::exists(terrain::test::data_file("tahoe_lidar_bareearth.tif")))
    expect_error("", terrain::test::data_file("tahoe_lidar_bareearth.tif").string(), "does not overlap");
  // Not a GeoTIFF at all.
  std::ofstream(dir / "junk.tif") << "this is not a tiff";
  expect_error("", (dir / "junk.tif").string(), "junk.tif");
  expect_error("", (dir / "mask.png").string(), "only GeoTIFF");
  if (have_gdal()) {
    // A TIFF without georeferencing keys.
    run("gdal_translate -q -of GTiff -co PROFILE=BASELINE " + q(terrain::test::data_file("kilauea_utm5n.tif")) + " " +
        q(dir / "nogeo.tif"));
    expect_error("", (dir / "nogeo.tif").string(), "no georeferencing");
  }
  fs::remove_all(dir);
}

// --landcover: a class raster made from the DEM (height bands -> classes 10, 20, 30; the sea has
// class 0, not in the table) in EPSG:4326, with a table naming materials by name and by index.
// Every splat sample with data takes its class's material (GDAL's nearest resampling onto the
// splat vertices is the oracle), and without the raster the rules choose differently.
TEST(SurfaceCook, LandcoverClassesDriveTheSplatMaterials) {
  TERRAIN_REQUIRE_DATA(terrain::test::data_file("kilauea_utm5n.tif"));
  REQUIRE_GDAL();
  const fs::path dir = terrain::test::scratch_dir("surface-landcover");
  const std::string dem = q(terrain::test::data_file("kilauea_utm5n.tif"));
  std::ofstream(dir / "classes.txt") << "0 10 10 10\n299.99 10 10 10\n300 20 20 20\n899.99 20 20 20\n900 30 30 30\n"
                                        "3000 30 30 30\n";
  run("gdaldem color-relief -q -nearest_color_entry " + dem + " " + q(dir / "classes.txt") + " " + q(dir / "lc_utm.tif"));
  run("gdalwarp -q -overwrite -t_srs EPSG:4326 -r near " + q(dir / "lc_utm.tif") + " " + q(dir / "lc_4326.tif"));
  const MaterialRules rules = default_material_rules();
  auto index_of = [&](const std::string& name) {
    for (size_t m = 0; m < rules.palette.size(); ++m)
      if (rules.palette[m].name == name) return int(m);
    return -1;
  };
  const int snow = index_of("snow"), sand = index_of("sand"), scree = index_of("scree");
  ASSERT_GE(snow, 0);
  ASSERT_GE(sand, 0);
  ASSERT_GE(scree, 0);
  std::ofstream(dir / "table.json") << "{\"classes\": {\"10\": \"snow\", \"20\": \"sand\", \"30\": " << scree << "}}";

  CookOptions o;
  o.inputs = {terrain::test::data_file("kilauea_utm5n.tif").string()};
  o.output = (dir / "lc.terrain").string();
  o.finest_level = 5;
  o.landcover_path = (dir / "lc_4326.tif").string();
  o.landcover_table_path = (dir / "table.json").string();
  CookReport report;
  Status st = terrain::cook::cook(o, {}, report);
  ASSERT_TRUE(st.ok()) << st.to_string();
  o.output = (dir / "plain.terrain").string();
  o.landcover_path.clear();
  o.landcover_table_path.clear();
  st = terrain::cook::cook(o, {}, report);
  ASSERT_TRUE(st.ok()) << st.to_string();

  ArchiveReader lc, plain;
  ASSERT_TRUE(lc.open((dir / "lc.terrain").string()).ok());
  ASSERT_TRUE(plain.open((dir / "plain.terrain").string()).ok());
  const WorldInfo& w = lc.world();
  const int level = 5;
  const double s = vertex_spacing_m(level);
  const int n = int(std::max(w.roots_x, w.roots_y)) * kQuadsPerSide + 1;
  const Grid g = warp_to_grid(dir / "lc_4326.tif", dir, "lc_oracle", w.origin_x_m, w.origin_y_m, s, n, "near");
  ASSERT_GE(g.bands, 1);
  uint64_t checked = 0, wrong = 0, plain_same = 0, by_class[3] = {0, 0, 0};
  std::vector<std::pair<size_t, size_t>> nodes;
  ASSERT_NO_FATAL_FAILURE(nodes_in_both(lc, plain, level, nodes));
  for (const auto& [i, j] : nodes) {
    const NodeRecord& rec = lc.nodes()[i];
    NodeData d, dp;
    ASSERT_TRUE(lc.decode_node(i, d, kSectionAlbedo | kSectionSplat).ok());
    ASSERT_TRUE(plain.decode_node(j, dp, kSectionSplat).ok());
    const auto alb = terrain::cook::test::decode_albedo(d);
    for (int sj = 0; sj < kSplatSamples; ++sj)
      for (int si = 0; si < kSplatSamples; ++si) {
        const int vi = 2 * si, vj = 2 * sj;  // splat sample (si, sj) is vertex (2 si, 2 sj)
        if (alb[size_t((vj + kApron) * kTexels + vi + kApron) * 4 + 3] == 0) continue;  // hole: no data
        const int cls = g.at(0, int(rec.key.x) * kQuadsPerSide + vi, int(rec.key.y) * kQuadsPerSide + vj);
        if (cls != 10 && cls != 20 && cls != 30) continue;
        const int want = cls == 10 ? snow : cls == 20 ? sand : scree;
        ++by_class[cls / 10 - 1];
        ++checked;
        wrong += d.splat[size_t(sj * kSplatSamples + si)] != want;
        plain_same += dp.splat[size_t(sj * kSplatSamples + si)] == want;
      }
  }
  std::printf("landcover: %llu splat samples checked (classes 10/20/30: %llu/%llu/%llu), %llu differ from GDAL's "
              "nearest class; without --landcover %llu match by chance\n",
              (unsigned long long)checked, (unsigned long long)by_class[0], (unsigned long long)by_class[1],
              (unsigned long long)by_class[2], (unsigned long long)wrong, (unsigned long long)plain_same);
  EXPECT_GT(checked, 100000u);
  for (uint64_t c : by_class) EXPECT_GT(c, 1000u);
  // Nearest sampling with exact transforms on both sides: only exact ties may differ (bound 0.1 %).
  EXPECT_LE(double(wrong), 0.001 * double(checked));
  EXPECT_LT(double(plain_same), 0.2 * double(checked));

  // Bad tables and pairings: clear errors.
  auto expect_error = [&](const std::string& table_text, const std::string& words) {
    std::ofstream(dir / "bad.json") << table_text;
    CookOptions b = o;
    b.output = (dir / "bad.terrain").string();
    b.landcover_path = (dir / "lc_4326.tif").string();
    b.landcover_table_path = (dir / "bad.json").string();
    const Status e = terrain::cook::cook(b, {}, report);
    EXPECT_FALSE(e.ok());
    EXPECT_NE(e.message.find(words), std::string::npos) << e.to_string();
  };
  expect_error("{\"classes\": {\"10\": \"lava\"}}", "\"lava\" is not a material of the palette");
  expect_error("{\"classes\": {\"ten\": \"snow\"}}", "class 'ten' is not an integer");
  expect_error("{\"classes\": ", "not valid JSON");
  expect_error("{\"snow\": 10}", "expected {\"classes\"");
  CookOptions half = o;
  half.output = (dir / "bad.terrain").string();
  half.landcover_path = (dir / "lc_4326.tif").string();
  const Status e = terrain::cook::cook(half, {}, report);
  EXPECT_NE(e.message.find("--landcover and --landcover-table go together"), std::string::npos) << e.to_string();
  fs::remove_all(dir);
}
