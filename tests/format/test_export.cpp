// terrain-export (format/export): Unreal's size and Z rules, the lattice and tiling plan, and real
// exports of the Debian jacksboro DEM cooked by terrain-cook (fixture in CMakeLists.txt): the
// values re-read from the files against SurfaceSampler, an Unreal heightmap cooked back by
// terrain-cook, tiles whose shared edges are identical, weight and visibility maps, Godot files.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <sstream>

#include "terrain/engine_export.h"
#include "terrain/sample.h"
#include "test_data.h"

namespace ex = terrain::engine_export;
using terrain::ArchiveReader;
using terrain::SurfaceSampler;

namespace {

const std::string kArchive = (terrain::test::build_dir() / "export-test/jacksboro.terrain").string();  // the fixture's
const std::string kScratch = (terrain::test::scratch_root() / "export").string();

template <typename T>
std::vector<T> read_image(const std::string& path, OIIO::TypeDesc type, int& w, int& h, int& channels) {
  auto in = OIIO::ImageInput::open(path);
  EXPECT_TRUE(in) << path;
  if (!in) return {};
  w = in->spec().width;
  h = in->spec().height;
  channels = in->spec().nchannels;
  std::vector<T> v(size_t(w) * h * channels);
  EXPECT_TRUE(in->read_image(0, 0, 0, channels, type, v.data())) << path;
  return v;
}

nlohmann::json read_json(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return nlohmann::json::parse(ss.str());
}

struct Jacksboro : ::testing::Test {
  ArchiveReader reader;
  void SetUp() override {
    ASSERT_TRUE(std::filesystem::exists(kArchive)) << kArchive << " (fixture format.export.cook_jacksboro)";
    ASSERT_TRUE(reader.open(kArchive).ok());
  }
  ex::Plan plan_for(ex::Options o) {
    ex::Plan p;
    EXPECT_TRUE(ex::plan_export(reader, o, p).ok());
    return p;
  }
  ex::Result run(const ex::Plan& p) {
    ex::Result r;
    std::filesystem::remove_all(p.options.out_dir);
    const terrain::Status s = ex::run_export(reader, p, {}, r);
    EXPECT_TRUE(s.ok()) << s.to_string();
    return r;
  }
  // The level-4 (8 m) vertex nearest the data's centre (jacksboro: a 30 x 32 km TM frame).
  double cx() const {
    const terrain::WorldInfo& w = reader.world();
    return w.origin_x_m + 8.0 * std::round((0.5 * (w.extent_min_x_m + w.extent_max_x_m) - w.origin_x_m) / 8.0);
  }
  double cy() const {
    const terrain::WorldInfo& w = reader.world();
    return w.origin_y_m + 8.0 * std::round((0.5 * (w.extent_min_y_m + w.extent_max_y_m) - w.origin_y_m) / 8.0);
  }
};

// Samples the export plan's 8 m lattice on the original archive and on the one cooked back from the
// export; visit(original m, cooked back m, geometric error of the cooked-back node that answered).
template <class Visit>
void compare_cooked_back(const ArchiveReader& original, const ArchiveReader& again, const ex::Plan& p, Visit&& visit) {
  SurfaceSampler a(original), b(again);
  for (int row = 0; row < p.height; ++row)
    for (int col = 0; col < p.width; ++col) {
      const double x = p.west_x_m + col * 8.0, y = p.north_y_m - row * 8.0;
      std::optional<terrain::SurfaceSample> sa, sb;
      ASSERT_TRUE(a.sample(x, y, sa).ok());
      ASSERT_TRUE(b.sample(x, y, sb).ok());
      ASSERT_TRUE(sa && sb) << row << "," << col;
      visit(sa->height_m, sb->height_m, double(again.nodes()[size_t(again.find(sb->node))].geometric_error_m));
    }
}

// What cooking every tile of an export back found (cook_back_every_tile).
struct RoundTrip {
  size_t tiles = 0, all_hole_tiles = 0, samples = 0, holes = 0, hole_mismatches = 0;
  double worst = 0, worst_excess = -1e9, max_node_error = 0;
};

// Cooks every tile of an export back with the flags its JSON gives (cook_back.tiles: the tile's own
// origin, holes kept) at the export's level, and compares, at every sample of every tile, the
// original archive's surface with the cooked-back one: both answer or neither (the hole masks), and
// where both do, |difference| <= `rounding(height)` (the export's own: half the Unreal step, half
// an ulp of Godot's float32) + the geometric error of the cooked-back node that answers.
template <class Rounding>
RoundTrip cook_back_every_tile(const ArchiveReader& original, const ex::Plan& p, const nlohmann::json& j, Rounding&& rounding) {
  RoundTrip rt;
  SurfaceSampler a(original);
  const int T = p.tile_size;
  for (const nlohmann::json& tile : j["cook_back"]["tiles"]) {
    ++rt.tiles;
    if (tile["hole_samples"].get<uint64_t>() == uint64_t(T) * uint64_t(T)) {  // nothing to cook back
      ++rt.all_hole_tiles;
      continue;
    }
    const std::string file = p.options.out_dir + "/" + tile["file"].get<std::string>();
    const std::string back = file + ".back.terrain";
    const std::string cmd = terrain::test::bin_dir().string() + "/terrain-cook " + file + " -o " + back + " " +
                            tile["flags"].get<std::string>() + " --finest-level " + std::to_string(p.level) +
                            " --tolerance 0.02 --heights-only -q";
    EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
    ArchiveReader again;
    EXPECT_TRUE(again.open(back).ok()) << back;
    if (!again.is_open()) continue;
    SurfaceSampler b(again);
    const double ox = tile["origin"][0].get<double>(), oy = tile["origin"][1].get<double>();
    for (int row = 0; row < T; ++row)
      for (int col = 0; col < T; ++col) {
        const double x = ox + col * p.spacing_m, y = oy + (T - 1 - row) * p.spacing_m;
        std::optional<terrain::SurfaceSample> sa, sb;
        EXPECT_TRUE(a.sample(x, y, sa).ok());
        EXPECT_TRUE(b.sample(x, y, sb).ok());
        ++rt.samples;
        if (!sa) ++rt.holes;
        if (bool(sa) != bool(sb)) {
          if (++rt.hole_mismatches <= 5)
            ADD_FAILURE() << tile["file"] << " sample (" << col << ", " << row << "): original "
                          << (sa ? std::to_string(sa->height_m) : "hole") << ", cooked back "
                          << (sb ? std::to_string(sb->height_m) : "hole");
          continue;
        }
        if (!sa) continue;
        const double d = std::fabs(sa->height_m - sb->height_m);
        const double node_error = double(again.nodes()[size_t(again.find(sb->node))].geometric_error_m);
        rt.worst = std::max(rt.worst, d);
        rt.max_node_error = std::max(rt.max_node_error, node_error);
        rt.worst_excess = std::max(rt.worst_excess, d - (rounding(sa->height_m) + node_error + 1e-6));
      }
  }
  return rt;
}

// A Godot export of level 4 into `dir` in regions of `tile_size` samples.
ex::Options godot_level4(const std::string& dir, int tile_size) {
  ex::Options o;
  o.target = ex::Target::godot;
  o.out_dir = dir;
  o.level = 4;
  o.tile_size = tile_size;
  return o;
}

}  // namespace

// ---- size and Z rules (no archive) --------------------------------------------------------------

TEST(ExportRules, UnrealSizesAreTheRecommendedTable) {
  // Unreal's recommended table: 2x2 sections of 63 quads (126 quads per component), 1..32
  // components per side, and 2x2 sections of 127 quads with 32 components for the largest.
  std::vector<int> expected;
  for (int n = 1; n <= 32; n *= 2) expected.push_back(126 * n + 1);
  expected.push_back(254 * 32 + 1);
  ASSERT_EQ(std::size(ex::kUnrealSizes), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) EXPECT_EQ(ex::kUnrealSizes[i], expected[i]);
  EXPECT_EQ(expected, (std::vector<int>{127, 253, 505, 1009, 2017, 4033, 8129}));
  for (int s : expected) EXPECT_TRUE(ex::is_unreal_size(s)) << s;
  for (int s : {0, 126, 128, 256, 257, 1008, 1010, 1024, 1025, 2048, 4097, 8128, 8130, 8193}) EXPECT_FALSE(ex::is_unreal_size(s)) << s;
}

TEST(ExportRules, UnrealSizeForPicksTheSmallestThatHolds) {
  EXPECT_EQ(ex::unreal_size_for(1), 127);
  EXPECT_EQ(ex::unreal_size_for(127), 127);
  EXPECT_EQ(ex::unreal_size_for(128), 253);
  EXPECT_EQ(ex::unreal_size_for(253), 253);
  EXPECT_EQ(ex::unreal_size_for(254), 505);
  EXPECT_EQ(ex::unreal_size_for(1009), 1009);
  EXPECT_EQ(ex::unreal_size_for(1010), 2017);
  EXPECT_EQ(ex::unreal_size_for(4034), 8129);
  EXPECT_EQ(ex::unreal_size_for(8129), 8129);
  EXPECT_EQ(ex::unreal_size_for(8130), 0);  // tiled
}

TEST(ExportRules, UnrealZScale100Spans256MetresEachWay) {
  // Unreal: z_cm = location + (v - 32768) * scale / 128; scale 100 gives -256 m .. +256 m.
  const ex::UnrealZ z{100.0, 0.0, 100.0 / 12800.0};
  EXPECT_DOUBLE_EQ(ex::unreal_decode(z, 0), -256.0);
  EXPECT_DOUBLE_EQ(ex::unreal_decode(z, 32768), 0.0);
  EXPECT_NEAR(ex::unreal_decode(z, 65535), 256.0 - 256.0 / 32768.0, 1e-12);
  EXPECT_EQ(ex::unreal_encode(z, 0.0), 32768);
  EXPECT_EQ(ex::unreal_encode(z, -1000.0), 1);      // clamped to the lowest height: 0 is a hole
  EXPECT_EQ(ex::unreal_encode(z, -256.0), 1);
  EXPECT_EQ(ex::unreal_encode(z, 1000.0), 65535);
}

TEST(ExportRules, UnrealZCoversTheRangeWithinHalfAStep) {
  for (auto [lo, hi] : {std::pair{235.0, 1076.078}, {-12.5, 3.25}, {4000.0, 4000.0}, {-400.0, 8848.0}}) {
    const ex::UnrealZ z = ex::unreal_z_for(lo, hi);
    // The printed numbers are the exact ones: scale to 1e-4, location to 0.01 cm.
    EXPECT_DOUBLE_EQ(z.z_scale * 1e4, std::round(z.z_scale * 1e4)) << lo;
    EXPECT_DOUBLE_EQ(z.location_z_cm * 100, std::round(z.location_z_cm * 100)) << lo;
    EXPECT_DOUBLE_EQ(z.step_m, z.z_scale / 12800.0);
    // The smallest printed scale that holds the range: one 1e-4 less does not (unless at the 0.01 floor).
    const double half = std::max(hi - z.location_z_cm / 100, z.location_z_cm / 100 - lo);
    EXPECT_GE(32767 * z.step_m, half - 1e-9) << lo;
    if (z.z_scale > 0.01) {
      EXPECT_LT(32767 * (z.z_scale - 1e-4) / 12800.0, half) << lo;
    }
    for (int k = 0; k <= 1000; ++k) {
      const double h = lo + (hi - lo) * k / 1000.0;
      EXPECT_LE(std::fabs(ex::unreal_decode(z, ex::unreal_encode(z, h)) - h), z.step_m / 2 + 1e-9) << h;
    }
  }
}

// ---- plans ------------------------------------------------------------------------------------

TEST_F(Jacksboro, PlanSnapsToTheLevelLatticeAndPadsToAnUnrealSize) {
  ex::Options o;
  o.out_dir = kScratch + "/plan";
  o.level = 4;  // 8 m
  o.rect = ex::Rect{cx() - 1000.3, cy() - 500.2, cx() + 1000.1, cy() + 700.9};
  const ex::Plan p = plan_for(o);
  const terrain::WorldInfo& w = reader.world();
  EXPECT_DOUBLE_EQ(p.spacing_m, 8.0);
  const double kx = (p.west_x_m - w.origin_x_m) / 8.0, ky = (p.north_y_m - w.origin_y_m) / 8.0;
  EXPECT_EQ(kx, std::round(kx));
  EXPECT_EQ(ky, std::round(ky));
  EXPECT_LE(p.west_x_m, o.rect->min_x);
  EXPECT_GT(p.west_x_m, o.rect->min_x - 8.0);
  EXPECT_GE(p.north_y_m, o.rect->max_y);
  EXPECT_LT(p.north_y_m, o.rect->max_y + 8.0);
  EXPECT_GE(p.west_x_m + (p.width - 1) * 8.0, o.rect->max_x);
  EXPECT_LT(p.west_x_m + (p.width - 2) * 8.0, o.rect->max_x);
  EXPECT_LE(p.north_y_m - (p.height - 1) * 8.0, o.rect->min_y);
  EXPECT_EQ(p.width, 253);   // -1000.3 .. +1000.1 m around a vertex widen to -1008 .. +1008: 252 intervals
  EXPECT_EQ(p.height, 152);  // -500.2 .. +700.9 widen to -504 .. +704: 151 intervals
  EXPECT_FALSE(p.tiled);
  EXPECT_EQ(p.tile_size, 253);
  EXPECT_EQ(p.image_width, 253);
  EXPECT_EQ(p.image_height, 253);
  // Default level: the archive's finest (jacksboro: level 4).
  o.level = -1;
  EXPECT_EQ(plan_for(o).level, 4);
}

TEST_F(Jacksboro, PlanTilesWithSharedEdgesBeyondTheTileSize) {
  ex::Options o;
  o.out_dir = kScratch + "/plan";
  o.level = 4;
  o.rect = ex::Rect{cx(), cy(), cx() + 8.0 * 300, cy() + 8.0 * 130};  // 301 x 131 samples
  o.tile_size = 127;
  ex::Plan p = plan_for(o);
  ASSERT_EQ(p.width, 301);
  ASSERT_EQ(p.height, 131);
  EXPECT_TRUE(p.tiled);
  EXPECT_EQ(p.tile_step, 126);
  EXPECT_EQ(p.tiles_x, 3);  // ceil(300 / 126)
  EXPECT_EQ(p.tiles_y, 2);  // ceil(130 / 126)
  EXPECT_EQ(p.image_width, 3 * 126 + 1);
  EXPECT_EQ(p.image_height, 2 * 126 + 1);
  EXPECT_NE(std::find(p.files.begin(), p.files.end(), o.out_dir + "/terrain_x2_y1.png"), p.files.end());
  // A size Unreal does not recommend is refused.
  o.tile_size = 1024;
  EXPECT_EQ(ex::plan_export(reader, o, p).code, terrain::Error::invalid_argument);
  // Godot regions do not share edges.
  o.target = ex::Target::godot;
  o.tile_size = 128;
  p = plan_for(o);
  EXPECT_EQ(p.tile_step, 128);
  EXPECT_EQ(p.tiles_x, 3);  // ceil(301 / 128)
  EXPECT_EQ(p.tiles_y, 2);
  EXPECT_EQ(p.image_width, 384);
  // A rectangle outside the frame and an empty one are usage errors.
  o.rect = ex::Rect{1e7, 1e7, 1e7 + 10, 1e7 + 10};
  EXPECT_EQ(ex::plan_export(reader, o, p).code, terrain::Error::invalid_argument);
  o.rect = ex::Rect{cx(), cy(), cx(), cy() + 10};
  EXPECT_EQ(ex::plan_export(reader, o, p).code, terrain::Error::invalid_argument);
}

// ---- real exports -----------------------------------------------------------------------------

// Every heightmap sample decodes to the sampler's height within half a 16-bit step; no-data
// samples are the visibility layer; weights sum to 255 (+- rounding) where there is terrain.
TEST_F(Jacksboro, UnrealHeightmapMatchesTheSurfaceWithinHalfAStep) {
  ex::Options o;
  o.out_dir = kScratch + "/unreal_edge";
  o.level = 4;
  // At the east edge of the data: the padding to 505 runs past the extent into no-data.
  const double east = reader.world().extent_max_x_m;
  o.rect = ex::Rect{east - 2100, cy() - 1000, east, cy() + 1000};
  const ex::Plan p = plan_for(o);
  ASSERT_EQ(p.tile_size, 505);
  const ex::Result r = run(p);
  ASSERT_GT(r.hole_samples, 0u);
  int w = 0, h = 0, ch = 0;
  const auto hm = read_image<uint16_t>(o.out_dir + "/terrain.png", OIIO::TypeDesc::UINT16, w, h, ch);
  ASSERT_EQ(w, 505);
  ASSERT_EQ(h, 505);
  ASSERT_EQ(ch, 1);
  const auto vis = read_image<uint8_t>(o.out_dir + "/terrain_visibility.png", OIIO::TypeDesc::UINT8, w, h, ch);
  ASSERT_EQ(w, 505);
  // The Z numbers from the JSON, as a user types them.
  const nlohmann::json j = read_json(o.out_dir + "/terrain.json");
  const ex::UnrealZ z{j["unreal"]["scale"][2].get<double>(), j["unreal"]["location_z_cm"].get<double>(),
                      j["unreal"]["scale"][2].get<double>() / 12800.0};
  EXPECT_DOUBLE_EQ(j["unreal"]["scale"][0].get<double>(), 800.0);  // 8 m in cm
  std::vector<std::vector<uint8_t>> weights;
  for (const auto& layer : j["layers"]) {
    weights.push_back(read_image<uint8_t>(o.out_dir + "/terrain_weight_" + layer.get<std::string>() + ".png",
                                          OIIO::TypeDesc::UINT8, w, h, ch));
    ASSERT_EQ(w, 505);
  }
  ASSERT_FALSE(weights.empty());
  SurfaceSampler sampler(reader);
  double worst = 0;
  size_t holes = 0, on_splat_samples = 0;
  for (int row = 0; row < 505; ++row)
    for (int col = 0; col < 505; ++col) {
      const size_t k = size_t(row) * 505 + col;
      std::optional<terrain::SurfaceSample> s;
      ASSERT_TRUE(sampler.sample(p.west_x_m + col * 8.0, p.north_y_m - row * 8.0, s).ok());
      if (!s) {
        ++holes;
        ASSERT_EQ(vis[k], 255) << row << "," << col;
        for (const auto& wm : weights) ASSERT_EQ(wm[k], 0);
        continue;
      }
      ASSERT_EQ(vis[k], 0) << row << "," << col;
      worst = std::max(worst, std::fabs(ex::unreal_decode(z, hm[k]) - s->height_m));
      int sum = 0;
      for (const auto& wm : weights) sum += wm[k];
      ASSERT_EQ(sum, 255) << row << "," << col;
      // On a splat sample of the answering node (every other vertex), the layer of its material id
      // has all the weight: read the id from the node's payload here.
      const terrain::NodeKey key = s->node;
      const double size = terrain::node_size_m(int(key.level)), sp = terrain::vertex_spacing_m(int(key.level));
      const double u = (p.west_x_m + col * 8.0 - reader.world().origin_x_m - key.x * size) / (2 * sp);
      const double v = (p.north_y_m - row * 8.0 - reader.world().origin_y_m - key.y * size) / (2 * sp);
      if (u == std::floor(u) && v == std::floor(v)) {
        terrain::NodeData d;
        ASSERT_TRUE(reader.decode_node(size_t(reader.find(key)), d, terrain::kSectionSplat).ok());
        const uint8_t id = d.splat[size_t(v) * terrain::kSplatSamples + size_t(u)];
        const std::string name = reader.world().palette.at(id).name;
        size_t layer = 0;
        while (layer < j["layers"].size() && j["layers"][layer] != name) ++layer;
        ASSERT_LT(layer, weights.size()) << name;
        ASSERT_EQ(weights[layer][k], 255) << name << " at " << row << "," << col;
        ++on_splat_samples;
      }
    }
  EXPECT_GT(on_splat_samples, 10000u);
  EXPECT_EQ(holes, r.hole_samples);
  EXPECT_LE(worst, z.step_m / 2 + 1e-9);
  // The scale is tight: the 16-bit range is used (not a default 100 that wastes precision).
  EXPECT_LT(z.z_scale, 100.0);
  std::printf("unreal edge export: %zu holes, Z scale %.4f, step %.6f m, worst |decoded - sampler| %.6f m\n", holes, z.z_scale,
              z.step_m, worst);
}

// An Unreal heightmap cooked back by terrain-cook with the printed flags: the new archive's
// surface at the lattice points is the original's within (16-bit step / 2) + the new cook's
// stated geometric error of the node that answers (its error against the PNG's samples).
TEST_F(Jacksboro, UnrealHeightmapCooksBackWithinTheStatedBound) {
  ex::Options o;
  o.out_dir = kScratch + "/unreal_cook";
  o.level = 4;
  o.name = "jb";
  o.rect = ex::Rect{cx() - 1000, cy() - 1000, cx() + 1000, cy() + 1000};
  const ex::Plan p = plan_for(o);
  const ex::Result r = run(p);
  ASSERT_EQ(r.hole_samples, 0u);
  const nlohmann::json j = read_json(o.out_dir + "/jb.json");
  const auto& back = j["cook_back"];
  char cmd[2048];
  const std::string cooked = o.out_dir + "/back.terrain";
  std::snprintf(cmd, sizeof(cmd),
                "%s/terrain-cook %s/jb.png -o %s --crs local --spacing %.17g --origin %.17g,%.17g --height-scale %.17g "
                "--height-offset %.17g --finest-level 4 --tolerance 0.02 --heights-only -q",
                terrain::test::bin_dir().c_str(), o.out_dir.c_str(), cooked.c_str(), back["spacing"].get<double>(),
                back["origin"][0].get<double>(), back["origin"][1].get<double>(), back["height_scale"].get<double>(),
                back["height_offset"].get<double>());
  ASSERT_EQ(std::system(cmd), 0) << cmd;
  ArchiveReader again;
  ASSERT_TRUE(again.open(cooked).ok());
  const double half_step = r.unreal.step_m / 2;
  double worst = 0, worst_excess = -1e9, max_node_error = 0;
  ASSERT_NO_FATAL_FAILURE(compare_cooked_back(reader, again, p, [&](double ha, double hb, double node_error) {
    const double d = std::fabs(ha - hb);
    worst = std::max(worst, d);
    max_node_error = std::max(max_node_error, node_error);
    worst_excess = std::max(worst_excess, d - (half_step + node_error + 1e-6));
  }));
  EXPECT_LE(worst_excess, 0.0);
  // The cook met its tolerance at level 4 here, so the bound a user can state is step/2 + 0.02 m.
  EXPECT_LE(max_node_error, 0.02);
  EXPECT_LE(worst, half_step + 0.02);
  std::printf("cooked back: worst |original - cooked back| %.5f m, bound step/2 %.5f + node error <= %.5f m\n", worst,
              half_step, max_node_error);
}

TEST_F(Jacksboro, UnrealTilesShareIdenticalEdges) {
  ex::Options o;
  o.out_dir = kScratch + "/unreal_tiles";
  o.level = 4;
  o.tile_size = 127;
  o.rect = ex::Rect{cx(), cy(), cx() + 8.0 * 300, cy() + 8.0 * 200};
  const ex::Plan p = plan_for(o);
  ASSERT_EQ(p.tiles_x, 3);
  ASSERT_EQ(p.tiles_y, 2);
  const ex::Result r = run(p);
  ASSERT_FALSE(r.layers.empty());
  const nlohmann::json j = read_json(o.out_dir + "/terrain.json");
  const ex::UnrealZ z{j["unreal"]["scale"][2].get<double>(), j["unreal"]["location_z_cm"].get<double>(),
                      j["unreal"]["scale"][2].get<double>() / 12800.0};
  auto tile = [&](const std::string& stem, int tx, int ty) {
    int w = 0, h = 0, ch = 0;
    auto v = read_image<uint16_t>(o.out_dir + "/" + stem + "_x" + std::to_string(tx) + "_y" + std::to_string(ty) + ".png",
                                  OIIO::TypeDesc::UINT16, w, h, ch);
    EXPECT_EQ(w, 127);
    EXPECT_EQ(h, 127);
    return v;
  };
  for (const std::string& stem : {std::string("terrain"), "terrain_weight_" + r.layers[0]}) {
    size_t compared = 0;
    for (int ty = 0; ty < 2; ++ty)
      for (int tx = 0; tx < 3; ++tx) {
        const auto t = tile(stem, tx, ty);
        if (tx + 1 < 3) {  // east column == west column of the east neighbour
          const auto e = tile(stem, tx + 1, ty);
          for (int row = 0; row < 127; ++row, ++compared) ASSERT_EQ(t[size_t(row) * 127 + 126], e[size_t(row) * 127]) << stem;
        }
        if (ty + 1 < 2) {  // south row == north row of the southern neighbour (y grows south)
          const auto s = tile(stem, tx, ty + 1);
          for (int col = 0; col < 127; ++col, ++compared) ASSERT_EQ(t[126 * 127 + size_t(col)], s[size_t(col)]) << stem;
        }
      }
    EXPECT_EQ(compared, size_t(2 * 2 * 127 + 3 * 127));
  }
  // Deterministic: a second run writes the same bytes.
  ex::Plan again = p;
  again.options.out_dir = kScratch + "/unreal_tiles_again";
  for (std::string& f : again.files) f.replace(0, o.out_dir.size(), again.options.out_dir);
  const ex::Result r2 = run(again);
  ASSERT_EQ(r2.written.size(), r.written.size());
  auto bytes = [](const std::string& f) {
    std::ifstream in(f, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  for (const std::string& f : r.written) {
    const std::string name = std::filesystem::path(f).filename().string();
    EXPECT_EQ(bytes(f), bytes(again.options.out_dir + "/" + name)) << name;
  }
  // And the tile lattice is the whole one: tile (1, 1) sample (5, 7) is lattice (126 + 5, 126 + 7).
  const auto t11 = tile("terrain", 1, 1);
  SurfaceSampler sampler(reader);
  std::optional<terrain::SurfaceSample> s;
  ASSERT_TRUE(sampler.sample(p.west_x_m + (126 + 5) * 8.0, p.north_y_m - (126 + 7) * 8.0, s).ok());
  ASSERT_TRUE(s);
  EXPECT_LE(std::fabs(ex::unreal_decode(z, t11[7 * 127 + 5]) - s->height_m), z.step_m / 2 + 1e-9);
}

// Godot: EXR heights are the sampler's (as float32), NaN and control alpha 0 where it has no
// terrain; the collision heightfield holds the same floats for the rectangle, its mask the holes.
TEST_F(Jacksboro, GodotRegionsAndCollisionMatchTheSurface) {
  ex::Options o = godot_level4(kScratch + "/godot", 128);
  const double east = reader.world().extent_max_x_m;
  o.rect = ex::Rect{east - 8.0 * 150, cy(), east + 8.0 * 20, cy() + 8.0 * 100};
  const ex::Plan p = plan_for(o);
  ASSERT_EQ(p.tiles_x, 2);
  ASSERT_EQ(p.tiles_y, 1);
  const ex::Result r = run(p);
  ASSERT_GT(r.hole_samples, 0u);
  std::ifstream cf(o.out_dir + "/terrain_collision.f32", std::ios::binary), chf(o.out_dir + "/terrain_collision_holes.u8", std::ios::binary);
  std::vector<float> coll(size_t(p.width) * p.height);
  std::vector<uint8_t> coll_holes(coll.size());
  cf.read(reinterpret_cast<char*>(coll.data()), std::streamsize(coll.size() * 4));
  chf.read(reinterpret_cast<char*>(coll_holes.data()), std::streamsize(coll_holes.size()));
  ASSERT_TRUE(cf && chf);
  EXPECT_EQ(std::filesystem::file_size(o.out_dir + "/terrain_collision.f32"), coll.size() * 4);
  SurfaceSampler sampler(reader);
  size_t holes = 0, rect_holes = 0;
  for (int tx = 0; tx < 2; ++tx) {
    int w = 0, h = 0, ch = 0;
    const std::string stem = o.out_dir + "/terrain_x" + std::to_string(tx) + "_y0";
    const auto hf = read_image<float>(stem + "_height.exr", OIIO::TypeDesc::FLOAT, w, h, ch);
    ASSERT_EQ(w, 128);
    const auto ctl = read_image<uint8_t>(stem + "_control.png", OIIO::TypeDesc::UINT8, w, h, ch);
    ASSERT_EQ(ch, 4);
    for (int row = 0; row < 128; ++row)
      for (int col = 0; col < 128; ++col) {
        const int gc = tx * 128 + col;
        const size_t k = size_t(row) * 128 + col;
        std::optional<terrain::SurfaceSample> s;
        ASSERT_TRUE(sampler.sample(p.west_x_m + gc * 8.0, p.north_y_m - row * 8.0, s).ok());
        const bool in_rect = gc < p.width && row < p.height;
        const size_t ck = size_t(row) * p.width + gc;
        if (!s) {
          ++holes;
          ASSERT_TRUE(std::isnan(hf[k]));
          ASSERT_EQ(ctl[k * 4 + 3], 0);
          if (in_rect) {
            ++rect_holes;
            ASSERT_EQ(coll_holes[ck], 1);
          }
          continue;
        }
        ASSERT_EQ(hf[k], float(s->height_m)) << row << "," << gc;
        ASSERT_EQ(ctl[k * 4 + 3], 255);
        ASSERT_LT(ctl[k * 4], reader.world().palette.size());
        if (in_rect) {
          ASSERT_EQ(coll_holes[ck], 0);
          ASSERT_EQ(coll[ck], float(s->height_m));
        }
      }
  }
  EXPECT_EQ(holes, r.hole_samples);
  EXPECT_GT(rect_holes, 0u);
}

// A Godot region's EXR cooked back by terrain-cook (--crs local, the printed spacing and origin):
// the new surface at the lattice points is the original's within float32 rounding of the EXR plus
// the new cook's stated geometric error of the answering node.
TEST_F(Jacksboro, GodotHeightsCookBackWithinTheStatedBound) {
  ex::Options o = godot_level4(kScratch + "/godot_cook", 256);
  o.rect = ex::Rect{cx() - 8.0 * 100, cy() - 8.0 * 100, cx() + 8.0 * 100, cy() + 8.0 * 100};
  const ex::Plan p = plan_for(o);
  ASSERT_EQ(p.tiles_x, 1);
  ASSERT_EQ(p.tiles_y, 1);
  const ex::Result r = run(p);
  const nlohmann::json j = read_json(o.out_dir + "/terrain.json");
  const std::string cooked = o.out_dir + "/back.terrain";
  char cmd[2048];
  std::snprintf(cmd, sizeof(cmd),
                "%s/terrain-cook %s/terrain_x0_y0_height.exr -o %s --crs local --spacing %.17g --origin %.17g,%.17g "
                "--finest-level 4 --tolerance 0.02 --heights-only -q",
                terrain::test::bin_dir().c_str(), o.out_dir.c_str(), cooked.c_str(), j["cook_back"]["spacing"].get<double>(),
                j["cook_back"]["origin"][0].get<double>(), j["cook_back"]["origin"][1].get<double>());
  ASSERT_EQ(std::system(cmd), 0) << cmd;
  ArchiveReader again;
  ASSERT_TRUE(again.open(cooked).ok());
  double worst_excess = -1e9, max_node_error = 0;
  size_t compared = 0;
  ASSERT_NO_FATAL_FAILURE(compare_cooked_back(reader, again, p, [&](double ha, double hb, double node_error) {
    const double f32 = std::fabs(ha) * std::ldexp(1.0, -24);  // half an ulp of the EXR float
    max_node_error = std::max(max_node_error, node_error);
    const double bound = f32 + node_error + 1e-6;
    worst_excess = std::max(worst_excess, std::fabs(ha - hb) - bound);
    ++compared;
  }));
  EXPECT_EQ(compared, size_t(201 * 201));
  EXPECT_LE(worst_excess, 0.0);
  EXPECT_LE(max_node_error, 0.02);  // the cook met its tolerance: the bound is float rounding + 0.02 m
}

// ---- Round trips (issue 48): every target and tile layout cooked back tile by tile -----------------
// Each tile's printed command and JSON flags carry its own origin (a tiled export printed one for
// all: tile x0_y0 cooked back 1008 m south here) and keep holes as holes (Unreal's 0 with
// --nodata-value 0, Godot's NaN; the untiled Unreal cook-back made its padding a plain at the lowest
// height with ringing into the data). The rectangles straddle the data's east edge, so every
// layout has holes and tiles with data.

TEST_F(Jacksboro, RoundTripGodotRegions) {
  ex::Options o = godot_level4(kScratch + "/rt_godot", 128);
  const double east = reader.world().extent_max_x_m;
  o.rect = ex::Rect{east - 8.0 * 150, cy() - 8.0 * 60, east + 8.0 * 20, cy() + 8.0 * 100};
  const ex::Plan p = plan_for(o);
  ASSERT_EQ(p.tiles_x, 2);
  ASSERT_EQ(p.tiles_y, 2);
  const ex::Result r = run(p);
  const nlohmann::json j = read_json(o.out_dir + "/terrain.json");
  ASSERT_EQ(j["cook_back"]["tiles"].size(), 4u);
  EXPECT_FALSE(j["cook_back"].contains("origin"));  // several tiles: no one origin for all
  const std::string text = ex::import_instructions(p, r);
  for (const nlohmann::json& t : j["cook_back"]["tiles"]) {
    const ex::TileOrigin to = ex::tile_origin(p, t["tile"][0].get<int>(), t["tile"][1].get<int>());
    EXPECT_EQ(t["origin"][0].get<double>(), to.x_m);
    EXPECT_EQ(t["origin"][1].get<double>(), to.y_m);
    EXPECT_NE(text.find(t["flags"].get<std::string>()), std::string::npos) << text;
  }
  // Region (0, 1) lies a whole region (128 samples of 8 m) south of region (0, 0).
  EXPECT_EQ(j["cook_back"]["tiles"][0]["origin"][1].get<double>() - j["cook_back"]["tiles"][2]["origin"][1].get<double>(),
            128 * 8.0);
  const RoundTrip rt = cook_back_every_tile(reader, p, j, [](double h) { return std::fabs(h) * std::ldexp(1.0, -24); });
  EXPECT_EQ(rt.tiles, 4u);
  EXPECT_EQ(rt.samples + rt.all_hole_tiles * 128 * 128, r.samples);
  EXPECT_GT(rt.holes, 0u);
  EXPECT_EQ(rt.hole_mismatches, 0u);
  EXPECT_LE(rt.worst_excess, 0.0);
  EXPECT_LE(rt.max_node_error, 0.02);
  std::printf("godot 2x2 regions: %zu samples, %zu holes, worst |original - cooked back| %.5f m, node error <= %.5f m\n",
              rt.samples, rt.holes, rt.worst, rt.max_node_error);
}

TEST_F(Jacksboro, RoundTripUnrealOneHeightmap) {
  ex::Options o;
  o.out_dir = kScratch + "/rt_unreal";
  o.level = 4;
  const double east = reader.world().extent_max_x_m;
  o.rect = ex::Rect{east - 8.0 * 150, cy(), east + 8.0 * 20, cy() + 8.0 * 100};
  const ex::Plan p = plan_for(o);
  ASSERT_FALSE(p.tiled);
  ASSERT_EQ(p.tile_size, 253);
  const ex::Result r = run(p);
  ASSERT_GT(r.hole_samples, r.samples / 3);  // the padding to 253 x 253 and the data's edge: 41 %
  const nlohmann::json j = read_json(o.out_dir + "/terrain.json");
  ASSERT_EQ(j["cook_back"]["tiles"].size(), 1u);
  EXPECT_EQ(j["cook_back"]["origin"], j["cook_back"]["tiles"][0]["origin"]);
  EXPECT_EQ(j["cook_back"]["nodata_value"].get<int>(), 0);
  EXPECT_NE(ex::import_instructions(p, r).find(j["cook_back"]["tiles"][0]["flags"].get<std::string>()), std::string::npos);
  // No height is written as the hole value.
  int w = 0, h = 0, ch = 0;
  const auto px = read_image<uint16_t>(o.out_dir + "/terrain.png", OIIO::TypeDesc::UINT16, w, h, ch);
  const auto vis = read_image<uint8_t>(o.out_dir + "/terrain_visibility.png", OIIO::TypeDesc::UINT8, w, h, ch);
  ASSERT_EQ(px.size(), vis.size());
  for (size_t k = 0; k < px.size(); ++k) ASSERT_EQ(px[k] == ex::kUnrealHoleValue, vis[k] == 255) << k;
  const double half_step = r.unreal.step_m / 2;
  const RoundTrip rt = cook_back_every_tile(reader, p, j, [&](double) { return half_step; });
  EXPECT_EQ(rt.samples, r.samples);
  EXPECT_EQ(rt.holes, r.hole_samples);
  EXPECT_EQ(rt.hole_mismatches, 0u);
  EXPECT_LE(rt.worst_excess, 0.0);
  EXPECT_LE(rt.max_node_error, 0.02);
  std::printf("unreal 253 x 253: %zu samples, %zu holes, worst |original - cooked back| %.5f m, bound step/2 %.5f + node "
              "error <= %.5f m\n", rt.samples, rt.holes, rt.worst, half_step, rt.max_node_error);
}

TEST_F(Jacksboro, RoundTripUnrealTiles) {
  ex::Options o;
  o.out_dir = kScratch + "/rt_unreal_tiles";
  o.level = 4;
  o.tile_size = 127;
  const double east = reader.world().extent_max_x_m;
  o.rect = ex::Rect{east - 8.0 * 250, cy(), east + 8.0 * 20, cy() + 8.0 * 200};
  const ex::Plan p = plan_for(o);
  ASSERT_EQ(p.tiles_x, 3);
  ASSERT_EQ(p.tiles_y, 2);
  const ex::Result r = run(p);
  const nlohmann::json j = read_json(o.out_dir + "/terrain.json");
  ASSERT_EQ(j["cook_back"]["tiles"].size(), 6u);
  EXPECT_FALSE(j["cook_back"].contains("origin"));
  const std::string text = ex::import_instructions(p, r);
  for (const nlohmann::json& t : j["cook_back"]["tiles"])  // a tile of holes only is said to be one
    EXPECT_NE(text.find(t["hole_samples"].get<int>() == 127 * 127 ? t["file"].get<std::string>() + ": all holes"
                                                                    : t["flags"].get<std::string>()),
              std::string::npos) << text;
  // Tiles share their edge rows: tile (0, 1) starts 126 samples south of tile (0, 0).
  EXPECT_EQ(j["cook_back"]["tiles"][0]["origin"][1].get<double>() - j["cook_back"]["tiles"][3]["origin"][1].get<double>(),
            126 * 8.0);
  const double half_step = r.unreal.step_m / 2;
  const RoundTrip rt = cook_back_every_tile(reader, p, j, [&](double) { return half_step; });
  EXPECT_EQ(rt.tiles, 6u);
  EXPECT_GT(rt.holes, 0u);
  EXPECT_EQ(rt.hole_mismatches, 0u);
  EXPECT_LE(rt.worst_excess, 0.0);
  EXPECT_LE(rt.max_node_error, 0.02);
  std::printf("unreal 3x2 tiles of 127: %zu samples (%zu all-hole tiles), %zu holes, worst %.5f m, step/2 %.5f m\n",
              rt.samples, rt.all_hole_tiles, rt.holes, rt.worst, half_step);
}
