// The windowed mosaic reader (cooker/src/mosaic/mosaic_source.h, issue 13): any window of the mosaic,
// inside, across the edges or outside it, is bit-identical to the same rectangle of the whole read,
// and the whole read is bit-identical to what load_inputs + mosaic gave before MosaicSource existed
// (hashes recorded from that code, commit 91de528, on the shared DEMs).
#include <gtest/gtest.h>

#include <gdal.h>

#include <cstdlib>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <random>

#include "session/cook_session.h"
#include "cooker_test_util.h"
#include "inputs/inputs.h"
#include "mosaic/mosaic.h"
#include "mosaic/mosaic_source.h"
#include "mosaic/precedence.h"
#include "inputs/raster.h"
#include "inputs/source_raster.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;
namespace fs = std::filesystem;

namespace {

uint64_t fnv(uint64_t h, const void* p, size_t n) {
  const uint8_t* b = static_cast<const uint8_t*>(p);
  for (size_t i = 0; i < n; ++i) {
    h ^= b[i];
    h *= 1099511628211ull;
  }
  return h;
}

// Size, georeferencing and the bits of every value.
uint64_t raster_hash(const cook::Raster& r) {
  uint64_t h = 1469598103934665603ull;
  h = fnv(h, &r.width, sizeof r.width);
  h = fnv(h, &r.height, sizeof r.height);
  h = fnv(h, r.geo.c, sizeof r.geo.c);
  return fnv(h, r.values.data(), r.values.size() * sizeof(float));
}

// The whole mosaic through one read() of its full rectangle.
cook::Raster read_whole(cook::MosaicSource& src) {
  cook::Raster r = src.header();
  r.values.resize(size_t(r.width) * size_t(r.height));
  EXPECT_TRUE(src.read(0, 0, r.width, r.height, r.values.data()).ok());
  return r;
}

// The same rectangle cut from a whole raster (NaN outside it).
std::vector<float> cut(const cook::Raster& whole, int c0, int r0, int w, int h) {
  std::vector<float> v(size_t(w) * size_t(h), NAN);
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) {
      const int c = c0 + col, r = r0 + row;
      if (c >= 0 && r >= 0 && c < whole.width && r < whole.height) v[size_t(row) * size_t(w) + size_t(col)] = whole.at(c, r);
    }
  return v;
}

// Random windows of `src` (sizes 1..maxsize, positions reaching 40 samples beyond every edge, so
// some cross an edge and some lie wholly outside) equal the rectangles of `whole`, bit for bit.
void expect_windows_equal(cook::MosaicSource& src, const cook::Raster& whole, int count, int max_size, uint32_t seed) {
  std::mt19937 rng(seed);
  int crossing = 0;
  for (int k = 0; k < count; ++k) {
    const int w = std::uniform_int_distribution<int>(1, max_size)(rng);
    const int h = std::uniform_int_distribution<int>(1, max_size)(rng);
    const int c0 = std::uniform_int_distribution<int>(-40 - w / 2, whole.width + 40 - w / 2)(rng);
    const int r0 = std::uniform_int_distribution<int>(-40 - h / 2, whole.height + 40 - h / 2)(rng);
    if (c0 < 0 || r0 < 0 || c0 + w > whole.width || r0 + h > whole.height) ++crossing;
    std::vector<float> got(size_t(w) * size_t(h), 12345.0f);
    ASSERT_TRUE(src.read(c0, r0, w, h, got.data()).ok());
    const std::vector<float> want = cut(whole, c0, r0, w, h);
    ASSERT_EQ(std::memcmp(got.data(), want.data(), got.size() * sizeof(float)), 0)
        << whole.path << ": window " << w << "x" << h << " at (" << c0 << ", " << r0 << ")";
  }
  EXPECT_GT(crossing, count / 10);  // the edges were exercised
}

cook::CookOptions options_for(const std::vector<std::string>& inputs) {
  cook::CookOptions o;
  o.inputs = inputs;
  return o;
}

// Bytes this process has asked the kernel to read (/proc/self/io rchar); -1 when unknown.
int64_t process_read_bytes() {
  std::ifstream io("/proc/self/io");
  std::string key;
  int64_t v = 0;
  while (io >> key >> v)
    if (key == "rchar:") return v;
  return -1;
}

struct LegacyCase {
  const char* name;
  std::vector<std::string> inputs;  // names under the data dir (or absolute)
  const char* crs;
  double height_scale, height_offset;
  std::array<double, 2> valid_range;
  int width, height;
  uint64_t hash;                        // load_inputs + mosaic before MosaicSource (commit 91de528; n19_kilauea: see there)
  std::vector<uint64_t> out_of_range;   // per input, from the same code
};

const char* const kJacksboro = "/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz";

std::vector<LegacyCase> legacy_cases() {
  const std::array<double, 2> dv{-12000, 9000};
  return {
      {"kilauea", {"kilauea_utm5n.tif"}, "", 1, 0, dv, 857, 793, 0xa47b33c820243021ull, {0}},
      {"oetztal", {"srtm_oetztal.tif"}, "", 1, 0, dv, 582, 444, 0x63df1ef4ac20080dull, {0}},
      {"slovenia", {"slovenia_TM1_564_146.tif"}, "", 1, 0, dv, 1000, 1000, 0x00ab0fa91ea54bb7ull, {0}},
      {"tahoe_be", {"tahoe_lidar_bareearth.tif"}, "", 1, 0, dv, 400, 400, 0x60e779571b563a8cull, {0}},
      {"tahoe_hh", {"tahoe_lidar_highesthit.tif"}, "", 1, 0, dv, 400, 400, 0xb21198b34abf4284ull, {0}},
      {"n19", {"N19W155.hgt.zip"}, "", 1, 0, dv, 1201, 1201, 0x2cdf10a2818a4086ull, {0}},
      {"n22", {"N22W160.hgt.zip"}, "", 1, 0, dv, 1201, 1201, 0xda253d15e7a711a4ull, {0}},
      {"s46", {"S46W066.hgt.gz"}, "", 1, 0, dv, 3601, 3601, 0xc63336f5d79a8090ull, {0}},
      {"jacksboro", {kJacksboro}, "EPSG:4326", 1, 0, dv, 403, 344, 0x740e6bb9465e3ce1ull, {0}},
      // --height-scale 0.5 --height-offset 10 --valid-range 0,500: a third of Kilauea is implausible.
      {"kilauea_rules", {"kilauea_utm5n.tif"}, "", 0.5, 10, {0, 500}, 857, 793, 0x74b72fa1dca70a24ull, {194421}},
      // Two inputs on one grid: the first wins, the second fills its voids.
      {"tahoe_pair", {"tahoe_lidar_highesthit.tif", "tahoe_lidar_bareearth.tif"}, "", 1, 0, dv, 400, 400,
       0xb21198b34abf4284ull, {0, 0}},
      // An HGT tile and a UTM GeoTIFF resampled onto its grid, with a gap between them. The hash is
      // of the windowed resampling (resample_inputs.h, anchors + tent filter); against gdalwarp -r
      // bilinear onto the same grid it differs by a median 0.09 m, p99 1.8 m, max 12 m (on the
      // cliffs, 30 m samples onto 90 m), and has data in 4521 fewer samples at nodata edges.
      {"n19_kilauea", {"N19W155.hgt.zip", "kilauea_utm5n.tif"}, "", 1, 0, dv, 1610, 1201, 0x8caaf66df96dbc75ull, {0, 0}},
  };
}

class MosaicLegacy : public ::testing::TestWithParam<size_t> {};

// Every shared DEM (and two mosaics): the whole read equals the old load_inputs + mosaic, the
// implausible counts of a counting pass equal the old ones, and random windows equal the whole.
TEST_P(MosaicLegacy, WindowsEqualTheWholeReadWhichEqualsTheOldMosaic) {
  const LegacyCase c = legacy_cases()[GetParam()];
  cook::CookOptions o;
  for (const std::string& n : c.inputs) {
    const fs::path p = n.front() == '/' ? fs::path(n) : data_file(n);
    TERRAIN_REQUIRE_DATA(p);
    o.inputs.push_back(p.string());
  }
  o.crs = c.crs;
  o.height_scale = c.height_scale;
  o.height_offset = c.height_offset;
  o.valid_range_m = c.valid_range;
  o.overlap = cook::OverlapRule::list;  // the old mosaic's rule (n19_kilauea: the finer Kilauea would win)

  cook::MosaicSource src;
  ASSERT_TRUE(cook::open_mosaic_source(cook::input_options(o), UINT64_MAX, src).ok());
  ASSERT_EQ(src.header().width, c.width);
  ASSERT_EQ(src.header().height, c.height);
  EXPECT_TRUE(src.header().values.empty());
  src.set_count_implausible(true);  // one pass over every sample
  const cook::Raster whole = read_whole(src);
  src.set_count_implausible(false);
  EXPECT_EQ(raster_hash(whole), c.hash) << c.name;
  ASSERT_EQ(src.inputs().size(), c.inputs.size());
  for (size_t i = 0; i < c.inputs.size(); ++i) {
    EXPECT_EQ(src.inputs()[i].implausible.out_of_range, c.out_of_range[i]) << c.name << " input " << i;
    EXPECT_EQ(src.inputs()[i].implausible.sentinel, 0u);
  }
  if (c.out_of_range[0]) {
    EXPECT_DOUBLE_EQ(src.inputs()[0].implausible.highest, 762.5);  // Kilauea's highest sample 1505 * 0.5 + 10
  }
  // Today's entry points: the same raster (they are this reader's whole window).
  std::vector<cook::Raster> rasters;
  ASSERT_TRUE(cook::load_inputs(cook::input_options(o), rasters).ok());
  ASSERT_EQ(rasters.size(), c.inputs.size());
  for (size_t i = 0; i < rasters.size(); ++i) {
    EXPECT_EQ(rasters[i].implausible.out_of_range, c.out_of_range[i]);
    EXPECT_EQ(rasters[i].description, src.inputs()[i].description);
  }
  cook::Raster m;
  ASSERT_TRUE(cook::mosaic(rasters, m).ok());
  EXPECT_EQ(raster_hash(m), c.hash);
  EXPECT_EQ(m.description, src.header().description);
  EXPECT_EQ(m.nodata_declared, src.header().nodata_declared);
  EXPECT_EQ(m.geo.point_samples, src.header().geo.point_samples);

  const int max_size = std::max(8, std::min(c.width, c.height) / 3);
  expect_windows_equal(src, whole, 60, max_size, uint32_t(GetParam()) + 7);
  // Windows wholly outside and empty ones.
  std::vector<float> out(16, 0.0f);
  ASSERT_TRUE(src.read(-10, -10, 4, 4, out.data()).ok());
  for (float v : out) EXPECT_TRUE(std::isnan(v));
  EXPECT_TRUE(src.read(c.width + 3, 0, 0, 0, out.data()).ok());
}

INSTANTIATE_TEST_SUITE_P(SharedData, MosaicLegacy, ::testing::Range<size_t>(0, 12),
                         [](const auto& p) { return std::string(legacy_cases()[p.param].name); });

// Kilauea cut into 4 x 4 tiles (gdal_translate -srcwin), given as one VRT and as 16 inputs: windows
// equal those of the uncut DEM, and only the tiles a window touches are read.
TEST(MosaicSource, SixteenTilesAsVrtAndAsInputsEqualTheUncutDem) {
  const fs::path dem = data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(dem);
  const fs::path dir = scratch_dir("mosaic_source_16");
  const int w = 857, h = 793, tw = 215, th = 199;
  std::vector<std::string> tiles;
  std::string list;
  for (int ty = 0; ty < 4; ++ty)
    for (int tx = 0; tx < 4; ++tx) {
      const int x0 = tx * tw, y0 = ty * th;
      const int cw = tx == 3 ? w - x0 : tw, ch = ty == 3 ? h - y0 : th;
      const fs::path tile = dir / fmt::format("t{}{}.tif", ty, tx);
      const std::string cmd = fmt::format("gdal_translate -q -srcwin {} {} {} {} '{}' '{}'", x0, y0, cw, ch,
                                          dem.string(), tile.string());
      ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
      tiles.push_back(tile.string());
      list += " '" + tile.string() + "'";
    }
  const fs::path vrt = dir / "mosaic.vrt";
  ASSERT_EQ(std::system(fmt::format("gdalbuildvrt -q '{}'{}", vrt.string(), list).c_str()), 0);

  cook::MosaicSource uncut, by_vrt, by_inputs;
  ASSERT_TRUE(cook::open_mosaic_source(cook::input_options(options_for({dem.string()})), UINT64_MAX, uncut).ok());
  ASSERT_TRUE(cook::open_mosaic_source(cook::input_options(options_for({vrt.string()})), UINT64_MAX, by_vrt).ok());
  ASSERT_TRUE(cook::open_mosaic_source(cook::input_options(options_for(tiles)), UINT64_MAX, by_inputs).ok());
  const cook::Raster whole = read_whole(uncut);
  EXPECT_EQ(raster_hash(whole), 0xa47b33c820243021ull);
  for (cook::MosaicSource* s : {&by_vrt, &by_inputs}) {
    ASSERT_EQ(s->header().width, w);
    ASSERT_EQ(s->header().height, h);
    for (int k = 0; k < 6; ++k) EXPECT_EQ(s->header().geo.c[k], whole.geo.c[k]);
  }
  ASSERT_EQ(by_inputs.inputs().size(), 16u);
  // One 100 x 100 window inside tile (1, 1) (columns 215..429, rows 199..397): with its ring, only
  // that input is read.
  std::vector<float> win(100 * 100);
  ASSERT_TRUE(by_inputs.read(250, 250, 100, 100, win.data()).ok());
  for (size_t i = 0; i < 16; ++i) {
    if (i == 5)
      EXPECT_GE(by_inputs.inputs()[i].bytes_read, uint64_t(100 * 100 * 2));
    else
      EXPECT_EQ(by_inputs.inputs()[i].bytes_read, 0u) << "tile " << i << " read for a window outside it";
  }
  expect_windows_equal(by_vrt, whole, 80, 300, 11);
  expect_windows_equal(by_inputs, whole, 80, 300, 12);
  // Windows along the tile seams (the 1-sample ring crosses into the neighbours).
  for (int x : {tw - 1, tw, 2 * tw - 1})
    for (int y : {th - 1, th, 3 * th}) {
      std::vector<float> a(7 * 5), b(7 * 5);
      ASSERT_TRUE(by_inputs.read(x - 3, y - 2, 7, 5, a.data()).ok());
      ASSERT_TRUE(by_vrt.read(x - 3, y - 2, 7, 5, b.data()).ok());
      const std::vector<float> want = cut(whole, x - 3, y - 2, 7, 5);
      EXPECT_EQ(std::memcmp(a.data(), want.data(), a.size() * 4), 0);
      EXPECT_EQ(std::memcmp(b.data(), want.data(), b.size() * 4), 0);
    }
}

// Undeclared -9999 voids near window edges: every window gets the whole read's answer, which is the
// rule's (a lone -9999 patch on land is a void; a -9999 beside -9500 m is a real depth), and a
// counting pass of tiling windows counts each void sample once.
TEST(MosaicSource, SentinelRuleAtWindowEdgesAsWhole) {
  const fs::path dir = scratch_dir("mosaic_source_sentinel");
  SyntheticDem d;
  d.width = 61;
  d.height = 47;
  d.x0 = 500000;
  d.y0 = 5000000;
  d.dx = d.dy = 10;
  d.epsg_projected = 32632;
  d.values.assign(size_t(d.width) * size_t(d.height), 0.0);
  for (int r = 0; r < d.height; ++r)
    for (int c = 0; c < d.width; ++c) d.at(c, r) = 300 + 2.0 * c + 3.0 * r;
  // Voids: a 3x2 patch, single samples on rows/columns 0 and the last (the raster's edge), and a
  // patch straddling many window edges.
  int voids = 0;
  auto hole = [&](int c, int r) {
    d.at(c, r) = -9999;
    ++voids;
  };
  for (int r = 12; r < 14; ++r)
    for (int c = 20; c < 23; ++c) hole(c, r);
  hole(0, 0);
  hole(60, 46);
  hole(30, 0);
  for (int r = 30; r < 37; ++r)
    for (int c = 39; c < 45; ++c) hole(c, r);
  // A real trench: -9999 beside -9500 (kept).
  d.at(10, 40) = -9500;
  d.at(11, 40) = -9999;
  d.at(12, 40) = -9999;  // beside -9999 and land only: but (11, 40)'s neighbour -9500 does not reach it
  ++voids;
  cook::CookOptions o;
  write_cook_input(dir, "sentinel", d, true, o);
  o.valid_range_m = {-12000, 9000};

  std::vector<cook::Raster> rasters;
  ASSERT_TRUE(cook::load_inputs(cook::input_options(o), rasters).ok());
  ASSERT_EQ(rasters.size(), 1u);
  EXPECT_EQ(rasters[0].implausible.sentinel, uint64_t(voids));
  EXPECT_TRUE(std::isnan(rasters[0].at(0, 0)));
  EXPECT_TRUE(std::isnan(rasters[0].at(21, 12)));
  EXPECT_EQ(rasters[0].at(11, 40), -9999.0f);
  EXPECT_TRUE(std::isnan(rasters[0].at(12, 40)));
  EXPECT_EQ(rasters[0].at(1, 0), 302.0f);

  cook::MosaicSource src;
  ASSERT_TRUE(cook::open_mosaic_source(cook::input_options(o), UINT64_MAX, src).ok());
  EXPECT_TRUE(src.inputs()[0].windowed);
  // Counting pass: 7 x 5 windows tiling the raster (their edges cut through the voids).
  src.set_count_implausible(true);
  cook::Raster tiled = src.header();
  tiled.values.assign(size_t(d.width) * size_t(d.height), 0.0f);
  for (int r = 0; r < d.height; r += 5)
    for (int c = 0; c < d.width; c += 7) {
      const int w = std::min(7, d.width - c), h = std::min(5, d.height - r);
      std::vector<float> v(size_t(w) * size_t(h));
      ASSERT_TRUE(src.read(c, r, w, h, v.data()).ok());
      for (int y = 0; y < h; ++y)
        std::memcpy(&tiled.values[size_t(r + y) * size_t(d.width) + size_t(c)], &v[size_t(y) * size_t(w)], size_t(w) * 4);
    }
  src.set_count_implausible(false);
  EXPECT_EQ(src.inputs()[0].implausible.sentinel, uint64_t(voids));
  ASSERT_EQ(tiled.values.size(), rasters[0].values.size());
  EXPECT_EQ(std::memcmp(tiled.values.data(), rasters[0].values.data(), tiled.values.size() * 4), 0);
  // Every 1..4-sample window around each void sample.
  for (int r = 0; r < d.height; ++r)
    for (int c = 0; c < d.width; ++c) {
      if (d.at(c, r) != -9999) continue;
      for (int dy = -3; dy <= 0; ++dy)
        for (int dx = -3; dx <= 0; ++dx) {
          std::vector<float> v(16);
          ASSERT_TRUE(src.read(c + dx, r + dy, 4, 4, v.data()).ok());
          const std::vector<float> want = cut(rasters[0], c + dx, r + dy, 4, 4);
          ASSERT_EQ(std::memcmp(v.data(), want.data(), 64), 0) << "void at (" << c << ", " << r << ")";
        }
    }
  EXPECT_EQ(src.inputs()[0].implausible.sentinel, uint64_t(voids));  // not counted while off
}

// A window reads what it needs, not the file: a 100 x 100 window of Kilauea (857 x 793 Int16 in
// 256 x 256 deflate tiles) asks GDAL for under a quarter of the samples' bytes and reads under a
// quarter of the file; a whole read asks for all of them.
TEST(MosaicSource, BytesReadGrowWithTheWindowNotTheFile) {
  const fs::path dem = data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(dem);
  const uint64_t samples = 857ull * 793ull;
  const uint64_t file_bytes = fs::file_size(dem);
  cook::MosaicSource src;
  ASSERT_TRUE(cook::open_mosaic_source(cook::input_options(options_for({dem.string()})), UINT64_MAX, src).ok());
  ASSERT_TRUE(src.inputs()[0].windowed);
  EXPECT_EQ(src.inputs()[0].bytes_read, 0u);  // open reads no samples
  std::vector<float> win(100 * 100);
  const int64_t before = process_read_bytes();
  ASSERT_TRUE(src.read(400, 300, 100, 100, win.data()).ok());  // inside tile (1, 1)
  const int64_t after = process_read_bytes();
  const uint64_t asked = src.inputs()[0].bytes_read;
  EXPECT_GE(asked, uint64_t(100 * 100 * 2));
  EXPECT_LT(asked, samples * 4 / 4);
  if (before >= 0) {
    EXPECT_LT(uint64_t(after - before), file_bytes / 4) << "bytes read from the file for one window";
    fmt::print("100x100 window: {} B asked of GDAL, {} B read from the {} B file\n", asked, after - before, file_bytes);
  }
  // What it holds: the window, its ring and GDAL's cache of the one tile, far from the whole raster.
  EXPECT_LT(src.resident_bytes(), samples * 4 / 4);
  EXPECT_GT(src.resident_bytes(), uint64_t(100 * 100 * 4));
  // The whole raster: every sample asked for.
  std::vector<float> all(samples);
  ASSERT_TRUE(src.read(0, 0, 857, 793, all.data()).ok());
  EXPECT_GE(src.inputs()[0].bytes_read - asked, samples * 2);

  // An input only our own readers take (.npz) is held whole.
  if (fs::exists(kJacksboro)) {
    cook::CookOptions o = options_for({kJacksboro});
    o.crs = "EPSG:4326";
    cook::MosaicSource npz;
    ASSERT_TRUE(cook::open_mosaic_source(cook::input_options(o), UINT64_MAX, npz).ok());
    EXPECT_FALSE(npz.inputs()[0].windowed);
    EXPECT_GE(npz.resident_bytes(), 403ull * 344ull * 4);
    // ... within the budget it is given.
    expect_refusal(cook::open_mosaic_source(cook::input_options(o), 100000, npz),
                   Error::unsupported_input, {"jacksboro_fault_dem.npz", "memory-limit"});
  }
}

// The GDAL block cache follows the budget it is given (unless GDAL_CACHEMAX says otherwise).
// SRTM HGT tiles are read by windows too (a mosaic of thousands holds none of them): a plain tile
// in place, a gzip inflated once into an unlinked file in $TMPDIR, which leaves nothing behind.
TEST(MosaicSource, HgtTilesAreReadByWindowsNotHeld) {
  const fs::path dir = scratch_dir("mosaic_source_hgt");
  const fs::path tmp = dir / "tmp";
  fs::create_directories(tmp);
  constexpr int n = 1201;
  std::vector<uint8_t> bytes(size_t(n) * n * 2);
  std::vector<float> expect(size_t(n) * n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      int16_t v = int16_t(100 + (r * 7 + c * 3) % 2000 - 600);
      if ((r - 600) * (r - 600) + (c - 300) * (c - 300) < 25) v = -32768;  // an enclosed void
      const size_t i = size_t(r) * n + size_t(c);
      bytes[2 * i] = uint8_t(uint16_t(v) >> 8);
      bytes[2 * i + 1] = uint8_t(uint16_t(v) & 0xff);
      expect[i] = v == -32768 ? NAN : float(v);
    }
  const fs::path plain = dir / "N10E020.hgt", gz = dir / "N10E021.hgt.gz";
  {
    std::ofstream f(plain, std::ios::binary);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
  }
  ASSERT_EQ(std::system(fmt::format("gzip -n -c '{}' > '{}'", plain.string(), gz.string()).c_str()), 0);
  const char* old_tmp = std::getenv("TMPDIR");
  const std::string saved = old_tmp ? old_tmp : "";
  setenv("TMPDIR", tmp.c_str(), 1);
  for (const fs::path& p : {plain, gz}) {
    SCOPED_TRACE(p.string());
    cook::CookOptions o;
    o.inputs = {p.string()};
    cook::MosaicSource src;
    const Status st = cook::open_mosaic_source(cook::input_options(o), UINT64_MAX, src);
    ASSERT_TRUE(st.ok()) << st.message;
    EXPECT_TRUE(src.inputs()[0].windowed);
    EXPECT_EQ(src.held_input_bytes(), 0u);
    EXPECT_TRUE(fs::is_empty(tmp)) << "the inflated tile must be unlinked";
    // A window reads its rows only, and gives the stored values (voids as NaN).
    std::vector<float> out(size_t(40) * 30);
    ASSERT_TRUE(src.read(590, 280, 40, 30, out.data()).ok());
    EXPECT_EQ(src.inputs()[0].bytes_read, uint64_t(40) * 30 * 2);
    for (int r = 0; r < 30; ++r)
      for (int c = 0; c < 40; ++c) {
        const float e = expect[size_t(280 + r) * n + size_t(590 + c)], g = out[size_t(r) * 40 + size_t(c)];
        ASSERT_TRUE(std::isnan(e) ? std::isnan(g) : g == e) << c << "," << r;
      }
    // The whole tile through read_hgt (tools and tests) is the same reader.
    cook::Raster whole;
    ASSERT_TRUE(cook::read_hgt(p.string(), {}, whole).ok());
    ASSERT_EQ(whole.values.size(), expect.size());
    EXPECT_TRUE(std::equal(whole.values.begin(), whole.values.end(), expect.begin(),
                           [](float a, float b) { return (std::isnan(a) && std::isnan(b)) || a == b; }));
  }
  // Nowhere to inflate into: a named error.
  setenv("TMPDIR", (dir / "missing").c_str(), 1);
  {
    cook::CookOptions o;
    o.inputs = {gz.string()};
    cook::MosaicSource src;
    const Status st = cook::open_mosaic_source(cook::input_options(o), UINT64_MAX, src);
    EXPECT_FALSE(st.ok());
    EXPECT_NE(st.message.find("temporary file"), std::string::npos) << st.message;
    EXPECT_NE(st.message.find("N10E021.hgt.gz"), std::string::npos) << st.message;
  }
  if (old_tmp) setenv("TMPDIR", saved.c_str(), 1);
  else unsetenv("TMPDIR");
}

TEST(MosaicSource, GdalCacheSize) {
  if (std::getenv("GDAL_CACHEMAX")) GTEST_SKIP() << "GDAL_CACHEMAX is set";
  cook::set_gdal_cache_bytes(uint64_t(24) << 20);
  EXPECT_EQ(GDALGetCacheMax64(), GIntBig(24) << 20);
  cook::set_gdal_cache_bytes(uint64_t(64) << 20);
  EXPECT_EQ(GDALGetCacheMax64(), GIntBig(64) << 20);
}

// Refusals at open: a VRT naming a missing tile (before any window reaches it), and load_inputs'
// The rule "finer wins" (precedence.h): by ground spacing in metres across CRSs; tiles of one grid
// family keep list order among themselves at any latitude; and any order of the same inputs gives
// the same precedence (their paths in the same order).
TEST(Precedence, FinerFirstTilesInListOrderAndAnyInputOrder) {
  auto raster = [](const char* path, cook::CrsKind kind, double dx, double dy, double x0, double y0) {
    cook::Raster r;
    r.path = path;
    r.crs.kind = kind;  // local: same_crs needs nothing more; geographic: the default ellipsoid fields
    r.width = r.height = 100;
    r.geo.c[0] = x0;
    r.geo.c[1] = dx;
    r.geo.c[3] = y0;
    r.geo.c[5] = -dy;
    r.geo.valid = true;
    return r;
  };
  using cook::CrsKind;
  // Ground spacings: 1" of arc is 30.887 m on the mean sphere; at the tiles' centres (0.486 N and
  // 60.486 N) 30.887 m and 30.887 x sqrt(cos 60.486) = 21.68 m; 25 m local; 1 m local.
  const cook::Raster tile_equator = raster("tile_eq", CrsKind::geographic, 1 / 3600.0, 1 / 3600.0, 10, 0.5);
  const cook::Raster tile_north = raster("tile_60n", CrsKind::geographic, 1 / 3600.0, 1 / 3600.0, 10, 60.5);
  const cook::Raster dem25 = raster("dem25", CrsKind::local, 25, 25, 0, 0);
  const cook::Raster lidar = raster("lidar", CrsKind::local, 1, 1, 100, 100);
  const double arc_second_m = 6371008.8 * M_PI / 180 / 3600;
  EXPECT_NEAR(cook::ground_spacing_m(tile_equator), arc_second_m * std::sqrt(std::cos(0.48625 * M_PI / 180)), 1e-9);
  EXPECT_NEAR(cook::ground_spacing_m(tile_north), arc_second_m * std::sqrt(std::cos(60.48625 * M_PI / 180)), 1e-9);
  EXPECT_NEAR(cook::ground_spacing_m(tile_north), 21.68, 0.01);
  EXPECT_DOUBLE_EQ(cook::ground_spacing_m(dem25), 25.0);
  auto order_of = [](std::vector<const cook::Raster*> rs) {
    std::vector<std::string> paths;
    for (size_t i : cook::finer_first_order(rs)) paths.push_back(rs[i]->path);
    return paths;
  };
  // The tiles share the family key of the finest of them (21.7 m, finer than 25 m) and keep list order.
  const std::vector<std::string> expected = {"lidar", "tile_eq", "tile_60n", "dem25"};
  EXPECT_EQ(order_of({&tile_equator, &tile_north, &dem25, &lidar}), expected);
  EXPECT_EQ(order_of({&dem25, &lidar, &tile_equator, &tile_north}), expected);
  EXPECT_EQ(order_of({&tile_equator, &dem25, &tile_north, &lidar}), expected);
  EXPECT_EQ(order_of({&tile_north, &tile_equator, &lidar, &dem25}),
            (std::vector<std::string>{"lidar", "tile_60n", "tile_eq", "dem25"}));  // tiles: list order
  // Two rasters of one family (same CRS and spacing, another origin) keep list order either way.
  const cook::Raster dem25b = raster("dem25b", CrsKind::local, 25, 25, 2500, 0);
  EXPECT_EQ(order_of({&dem25b, &lidar, &dem25}), (std::vector<std::string>{"lidar", "dem25b", "dem25"}));
  EXPECT_EQ(order_of({&dem25, &dem25b, &lidar}), (std::vector<std::string>{"lidar", "dem25", "dem25b"}));
}

// own errors.
TEST(MosaicSource, OpenRefusesWhatLoadInputsRefuses) {
  const fs::path dir = scratch_dir("mosaic_source_refusals");
  SyntheticDem west;
  west.width = 20;
  west.height = 10;
  west.values.assign(200, 100.0);
  west.x0 = 500000;
  west.y0 = 5000000;
  west.dx = west.dy = 10;
  west.epsg_projected = 32632;
  SyntheticDem east = west;
  east.x0 += east.width * east.dx;
  std::string err;
  const std::string a = (dir / "a.tif").string(), b = (dir / "b.tif").string(), vrt = (dir / "m.vrt").string();
  ASSERT_TRUE(write_geotiff(a, west, false, err)) << err;
  ASSERT_TRUE(write_geotiff(b, east, false, err)) << err;
  ASSERT_EQ(std::system(fmt::format("gdalbuildvrt -q '{}' '{}' '{}'", vrt, a, b).c_str()), 0);
  cook::MosaicSource src;
  ASSERT_TRUE(cook::open_mosaic_source(cook::input_options(options_for({vrt})), UINT64_MAX, src).ok());
  EXPECT_EQ(src.header().width, 40);
  fs::remove(b);
  expect_refusal(cook::open_mosaic_source(cook::input_options(options_for({vrt})), UINT64_MAX, src), Error::io_read,
                 {"m.vrt", "b.tif", "No such file or directory"});
  expect_refusal(cook::open_mosaic_source(cook::input_options(options_for({(dir / "nope.tif").string()})), UINT64_MAX, src),
                 Error::io_open,
                 {"nope.tif"});
  // No CRS: the npz without --crs.
  if (fs::exists(kJacksboro))
    expect_refusal(cook::open_mosaic_source(cook::input_options(options_for({kJacksboro})), UINT64_MAX, src),
                   Error::invalid_argument,
                   {"has no CRS"});
  expect_refusal(cook::open_mosaic_source(cook::input_options(options_for({})), UINT64_MAX, src),
                 Error::invalid_argument,
                 {"no input files"});
}

}  // namespace

namespace {

// The tent filter of resample_inputs.h at input position (a, b) of `dem`, in doubles: taps with
// |p - k| < rad weigh 1 - |p - k| / rad; NaN when a tap is outside the input or a hole.
double tent_reference(const SyntheticDem& dem, double a, double b, double rad) {
  double sum = 0, wsum = 0;
  for (int kb = int(std::floor(b - rad)) + 1; kb <= int(std::ceil(b + rad)) - 1; ++kb)
    for (int ka = int(std::floor(a - rad)) + 1; ka <= int(std::ceil(a + rad)) - 1; ++ka) {
      const double w = (1 - std::fabs(a - ka) / rad) * (1 - std::fabs(b - kb) / rad);
      if (!(w > 0)) continue;
      if (ka < 0 || kb < 0 || ka >= dem.width || kb >= dem.height) return NAN;
      const double z = dem.values[size_t(kb) * size_t(dem.width) + size_t(ka)];
      if (std::isnan(z)) return NAN;
      sum += w * z;
      wsum += w;
    }
  return wsum > 0 ? sum / wsum : NAN;
}

// `second` seen on `first`'s grid (--overlap list: the first listed sets the grid), read whole, is
// the tent reference at each sample's exact position in `second` within `bound_m`, wherever
// `first` has no data (first's box); NaN exactly where the reference is. Any window of the mosaic is
// bit-identical to the same rectangle of the whole read. Returns the samples compared, and the
// holes among them.
void expect_resampled_matches_reference(const fs::path& dir, const SyntheticDem& first, const SyntheticDem& second,
                                        double rad, double bound_m, uint64_t& compared, uint64_t& holes) {
  std::string error;
  ASSERT_TRUE(write_geotiff((dir / "first.tif").string(), first, true, error)) << error;
  ASSERT_TRUE(write_geotiff((dir / "second.tif").string(), second, true, error)) << error;
  cook::InputOptions io = cook::input_options(options_for({(dir / "first.tif").string(), (dir / "second.tif").string()}));
  io.finer_wins = false;
  cook::MosaicSource src;
  const Status st = cook::open_mosaic_source(io, UINT64_MAX, src);
  ASSERT_TRUE(st.ok()) << st.message;
  const cook::Raster& h = src.header();
  std::vector<float> whole(size_t(h.width) * size_t(h.height));
  ASSERT_TRUE(src.read(0, 0, h.width, h.height, whole.data()).ok());
  compared = holes = 0;
  double worst = 0;
  for (int r = 0; r < h.height; ++r)
    for (int c = 0; c < h.width; ++c) {
      const double x = h.geo.c[0] + h.geo.c[1] * c, y = h.geo.c[3] + h.geo.c[5] * r;
      const double fa = (x - first.x0) / first.dx, fb = (first.y0 - y) / first.dy;
      if (fa > -0.5 && fb > -0.5 && fa < first.width - 0.5 && fb < first.height - 0.5) continue;  // first's own
      const double ref = tent_reference(second, (x - second.x0) / second.dx, (second.y0 - y) / second.dy, rad);
      const float got = whole[size_t(r) * size_t(h.width) + size_t(c)];
      ASSERT_EQ(std::isnan(ref), std::isnan(got)) << "sample " << c << ", " << r << ": reference " << ref << ", got "
                                                  << got;
      ++compared;
      if (std::isnan(ref)) {
        ++holes;
        continue;
      }
      worst = std::max(worst, std::fabs(got - ref));
    }
  EXPECT_LE(worst, bound_m);
  std::mt19937 rng(7);
  for (int k = 0; k < 24; ++k) {
    const int w = 1 + int(rng() % 700), hh = 1 + int(rng() % 300);
    const int c0 = int(rng() % uint32_t(h.width + 40)) - 20, r0 = int(rng() % uint32_t(h.height + 40)) - 20;
    std::vector<float> part(size_t(w) * size_t(hh));
    ASSERT_TRUE(src.read(c0, r0, w, hh, part.data()).ok());
    for (int j = 0; j < hh; ++j)
      for (int i = 0; i < w; ++i) {
        const int c = c0 + i, r = r0 + j;
        const float want = c < 0 || r < 0 || c >= h.width || r >= h.height ? NAN : whole[size_t(r) * size_t(h.width) + size_t(c)];
        const float got = part[size_t(j) * size_t(w) + size_t(i)];
        ASSERT_TRUE((std::isnan(want) && std::isnan(got)) || std::memcmp(&want, &got, sizeof(float)) == 0)
            << "window " << k << " at " << c << ", " << r;
      }
  }
}

SyntheticDem wavy_dem(int width, int height, double x0, double y0, double spacing, int hole_col, int hole_row) {
  SyntheticDem d;
  d.width = width;
  d.height = height;
  d.x0 = x0;
  d.y0 = y0;
  d.dx = d.dy = spacing;
  d.epsg_projected = 32633;
  d.nodata = -9999;
  d.values.resize(size_t(width) * size_t(height));
  for (int r = 0; r < height; ++r)
    for (int c = 0; c < width; ++c) d.at(c, r) = 300 + 200 * std::sin(c * 0.37) * std::cos(r * 0.23) - 0.5 * r;
  d.at(hole_col, hole_row) = NAN;
  return d;
}

}  // namespace

// A 30 m DEM seen on a 1 m grid of the same CRS (a lidar tile's, listed first): the tent of radius
// one (bilinear) at each sample's exact position, within 1e-4 m (float32 output of values up to
// 700 m: half an ulp is 3e-5 m); a 30 m hole makes exactly the 1 m samples within one 30 m sample of
// it holes; every window gives the same bits.
TEST(ResampledGrid, ACoarserInputIsBilinearAtItsExactPositions) {
  const fs::path dir = scratch_dir("resampled_coarser");
  SyntheticDem fine;
  fine.width = fine.height = 40;
  fine.x0 = 500600.5;
  fine.y0 = 4990399.5 - 600;
  fine.epsg_projected = 32633;
  fine.values.assign(40 * 40, 50.0);
  const SyntheticDem coarse = wavy_dem(40, 30, 500015 + 3.25, 4990385 - 7.5, 30, 21, 12);
  uint64_t compared = 0, holes = 0;
  ASSERT_NO_FATAL_FAILURE(expect_resampled_matches_reference(dir, fine, coarse, 1.0, 1e-4, compared, holes));
  EXPECT_GT(compared, uint64_t(1000000));
  EXPECT_GT(holes, uint64_t(59 * 59 - 1));  // the hole's (2 x 30 - 1)^2 samples at least, plus the margins
}

// A 0.5 m input seen on a 2 m grid (a coarser input listed first): the area filter, a tent of
// radius 4 input samples, within 1e-4 m; a 0.5 m hole removes the 2 m samples whose tent reaches it.
TEST(ResampledGrid, AFinerInputIsTheTentAreaFilter) {
  const fs::path dir = scratch_dir("resampled_finer");
  SyntheticDem grid;
  grid.width = grid.height = 10;
  grid.x0 = 500001;
  grid.y0 = 4990399;
  grid.dx = grid.dy = 2;
  grid.epsg_projected = 32633;
  grid.values.assign(100, 50.0);
  const SyntheticDem fine = wavy_dem(600, 500, 500000.25 + 0.125, 4990399.75 - 0.5, 0.5, 300, 250);
  uint64_t compared = 0, holes = 0;
  ASSERT_NO_FATAL_FAILURE(expect_resampled_matches_reference(dir, grid, fine, 4.0, 1e-4, compared, holes));
  EXPECT_GT(compared, uint64_t(18000));  // 300 x 250 m: 150 x 125 samples of 2 m, plus the margins
  EXPECT_GE(holes, uint64_t(16));  // 2 m samples within 2 m of the hole on both axes: 4 x 4
}
