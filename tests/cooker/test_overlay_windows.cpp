// The overlays (--albedo, --holes, --landcover) read by windows, block by block (issue 13): a cook
// in blocks of one root, in a shuffled order, must give the archive of the one-block cook byte for
// byte, and each window must follow the block, not the raster. The overlays are made by GDAL's
// command-line tools from a synthetic DEM, in other CRSs than the DEM's (anchored mappings), tiled
// and striped, covering a part of the DEM that crosses several root edges.
#include <gtest/gtest.h>
#include <tiffio.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <fmt/format.h>

#include "cooker_test_util.h"
#include "inputs/inputs.h"
#include "overlays/overlays.h"
#include "inputs/raster.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;
namespace fs = std::filesystem;

namespace {

std::string file_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

bool have_gdal() { return std::system("gdal_translate --version > /dev/null 2>&1") == 0; }

void run(const std::string& cmd) { ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd; }

// Single-quoted for the shell (the scratch paths hold no quotes).
std::string q(const fs::path& p) { return fmt::format("'{}'", p.string()); }

// Smooth hills with a ridge (a colourful relief), UTM 32N, 4 m samples, 5.6 x 4.4 km: frame x
// 500000 .. 505600 crosses root edges at 501760 and 503808, y 5195604 .. 5200004 at 5195776,
// 5197824 and 5199872.
SyntheticDem hills() {
  SyntheticDem d;
  d.width = 1400;
  d.height = 1100;
  d.dx = d.dy = 4.0;
  d.x0 = 500002.0;
  d.y0 = 5200002.0;
  d.epsg_projected = 32632;
  d.values.resize(size_t(d.width) * size_t(d.height));
  for (int r = 0; r < d.height; ++r)
    for (int c = 0; c < d.width; ++c) {
      const double x = c * 4.0, y = r * 4.0;
      d.at(c, r) = 600 + 300 * std::sin(x / 900.0) * std::cos(y / 700.0) + 25 * std::sin(x / 41.0 + y / 67.0);
    }
  return d;
}

// The part of the DEM the overlays cover (UTM 32N): x 500800 .. 504800, y 5196200 .. 5199000,
// across the root edges x 501760, 503808 and y 5197824.
constexpr const char* kProjWin = "-projwin 500800 5199000 504800 5196200";

struct Overlays {
  fs::path photo, photo16, mask, classes, table;
};

// photo: RGBA colour relief (alpha 0 where the relief has no colour), EPSG:4326, 64 x 64 tiles.
// photo16: its RGB scaled to 16 bits (100 .. 65500: not multiples of 257), UTM, strips of 8 rows.
// mask: 255 above 750 m, EPSG:4326, strips. classes: 10 / 20 / 30 by height, UTM 33N, 32 x 32 tiles.
void make_overlays(const fs::path& dir, const fs::path& dem, Overlays& o) {
  std::ofstream(dir / "ramp.txt") << "300 0 0 0 0\n420 30 90 160 255\n600 60 140 70 255\n750 150 170 90 255\n"
                                     "900 240 235 230 255\n";
  run(fmt::format("gdaldem color-relief -q -alpha {} {} {}", q(dem), q(dir / "ramp.txt"), q(dir / "relief.tif")));
  run(fmt::format("gdal_translate -q {} {} {}", kProjWin, q(dir / "relief.tif"), q(dir / "relief_cut.tif")));
  o.photo = dir / "photo_4326.tif";
  run(fmt::format("gdalwarp -q -overwrite -t_srs EPSG:4326 -r bilinear -co TILED=YES -co BLOCKXSIZE=64 "
                  "-co BLOCKYSIZE=64 {} {}", q(dir / "relief_cut.tif"), q(o.photo)));
  o.photo16 = dir / "photo16.tif";
  run(fmt::format("gdal_translate -q -ot UInt16 -scale 0 255 100 65500 -b 1 -b 2 -b 3 -co PHOTOMETRIC=RGB "
                  "-co BLOCKYSIZE=8 {} {}", q(dir / "relief_cut.tif"), q(o.photo16)));
  std::ofstream(dir / "mask.txt") << "0 0 0 0\n749.99 0 0 0\n750 255 255 255\n2000 255 255 255\n";
  run(fmt::format("gdaldem color-relief -q -nearest_color_entry {} {} {}", q(dem), q(dir / "mask.txt"),
                  q(dir / "mask_utm.tif")));
  run(fmt::format("gdal_translate -q -b 1 {} {} {}", kProjWin, q(dir / "mask_utm.tif"), q(dir / "mask_cut.tif")));
  o.mask = dir / "mask_4326.tif";
  run(fmt::format("gdalwarp -q -overwrite -t_srs EPSG:4326 -r near {} {}", q(dir / "mask_cut.tif"), q(o.mask)));
  std::ofstream(dir / "classes.txt") << "0 10 10 10\n449.99 10 10 10\n450 20 20 20\n699.99 20 20 20\n700 30 30 30\n"
                                        "2000 30 30 30\n";
  run(fmt::format("gdaldem color-relief -q -nearest_color_entry {} {} {}", q(dem), q(dir / "classes.txt"),
                  q(dir / "lc_utm.tif")));
  run(fmt::format("gdal_translate -q -b 1 {} {} {}", kProjWin, q(dir / "lc_utm.tif"), q(dir / "lc_cut.tif")));
  o.classes = dir / "lc_32633.tif";
  run(fmt::format("gdalwarp -q -overwrite -t_srs EPSG:32633 -r near -co TILED=YES -co BLOCKXSIZE=32 "
                  "-co BLOCKYSIZE=32 {} {}", q(dir / "lc_cut.tif"), q(o.classes)));
  o.table = dir / "table.json";
  std::ofstream(o.table) << R"({"classes": {"10": "snow", "20": "sand", "30": "scree"}})";
}

uint64_t raster_samples(const fs::path& path) {
  cook::ReadOptions ro;
  ro.header_only = true;
  cook::Raster r;
  EXPECT_TRUE(cook::read_geotiff(path.string(), ro, r).ok()) << path;
  return uint64_t(r.width) * uint64_t(r.height);
}

struct Cooked {
  std::string bytes;
  cook::CookReport report;
  cook::OverlayWindowStats windows;
};

void cook_to(cook::CookOptions o, uint32_t block_roots, uint64_t order, const std::string& suffix, Cooked& out) {
  o.block_roots = block_roots;
  o.block_order = order;
  o.output += suffix;
  cook::reset_overlay_window_stats();
  const Status st = cook::cook(o, nullptr, out.report);
  ASSERT_TRUE(st.ok()) << st.to_string();
  out.windows = cook::overlay_window_stats();
  out.bytes = file_bytes(o.output);
  ASSERT_GT(out.bytes.size(), 1000u);
}

class OverlayWindows : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!have_gdal()) GTEST_SKIP() << "GDAL command-line tools (gdal-bin) not found";
    dir_ = scratch_dir("overlay-windows");
    ASSERT_NO_FATAL_FAILURE(write_cook_input(dir_, "hills", hills(), true, base_));
    base_.threads = 2;
    base_.finest_level = 4;
    base_.tolerance_m = 2.0;
    ASSERT_NO_FATAL_FAILURE(make_overlays(dir_, dir_ / "hills.tif", ov_));
  }
  fs::path dir_;
  cook::CookOptions base_;
  Overlays ov_;
};

TEST_F(OverlayWindows, PhotoMaskAndClassesInOneRootBlocksGiveTheOneBlockBytes) {
  cook::CookOptions o = base_;
  Cooked plain;
  ASSERT_NO_FATAL_FAILURE(cook_to(o, 4096, 0, ".plain", plain));
  o.albedo_path = ov_.photo.string();
  o.holes_path = ov_.mask.string();
  o.landcover_path = ov_.classes.string();
  o.landcover_table_path = ov_.table.string();
  Cooked whole, split;
  ASSERT_NO_FATAL_FAILURE(cook_to(o, 4096, 0, ".whole", whole));
  ASSERT_NO_FATAL_FAILURE(cook_to(o, 1, 7, ".b1s7", split));
  EXPECT_EQ(whole.report.blocks, 1u);
  EXPECT_GE(split.report.blocks, 6u);
  // The overlays change the archive (so equal bytes below mean equal overlay samples).
  EXPECT_NE(plain.bytes, whole.bytes);
  EXPECT_TRUE(split.bytes == whole.bytes) << "blocks of one root in order 7 differ from the one-block cook";
  EXPECT_EQ(whole.windows.misses, 0u);
  EXPECT_EQ(split.windows.misses, 0u);
  // One block covers every overlay: its windows are the whole rasters (3 windows). Blocks of one
  // root read a window per block and overlay, each at most a 2176 m square of the 4000 x 2800 m
  // the overlays cover: well under 60 % of the largest raster.
  const uint64_t photo = raster_samples(ov_.photo), mask = raster_samples(ov_.mask),
                 classes = raster_samples(ov_.classes);
  EXPECT_EQ(whole.windows.largest_window_samples, std::max({photo, mask, classes}));
  EXPECT_EQ(whole.windows.windows, 3u);
  EXPECT_GT(split.windows.windows, 3u);
  EXPECT_LT(double(split.windows.largest_window_samples), 0.6 * double(std::max({photo, mask, classes})));
  std::printf("overlay windows: one block %llu samples largest (%llu windows); one-root blocks %llu (%llu windows), "
              "rasters %llu / %llu / %llu samples\n",
              (unsigned long long)whole.windows.largest_window_samples, (unsigned long long)whole.windows.windows,
              (unsigned long long)split.windows.largest_window_samples, (unsigned long long)split.windows.windows,
              (unsigned long long)photo, (unsigned long long)mask, (unsigned long long)classes);
}

TEST_F(OverlayWindows, SixteenBitStripedPhotoInOneRootBlocksGivesTheOneBlockBytes) {
  cook::CookOptions o = base_;
  Cooked plain;
  ASSERT_NO_FATAL_FAILURE(cook_to(o, 4096, 0, ".plain16", plain));
  o.albedo_path = ov_.photo16.string();
  Cooked whole, split;
  ASSERT_NO_FATAL_FAILURE(cook_to(o, 4096, 0, ".whole16", whole));
  ASSERT_NO_FATAL_FAILURE(cook_to(o, 1, 3, ".b1s3", split));
  EXPECT_GE(split.report.blocks, 6u);
  EXPECT_NE(plain.bytes, whole.bytes);
  EXPECT_TRUE(split.bytes == whole.bytes) << "16-bit photo: blocks of one root in order 3 differ";
  EXPECT_EQ(split.windows.misses, 0u);
  EXPECT_LT(double(split.windows.largest_window_samples), 0.6 * double(raster_samples(ov_.photo16)));
}

// An orthophoto whose Orientation tag is not top-left: only libtiff's oriented whole-image read
// turns it, so its window is the whole raster, read once, in every block.
TEST_F(OverlayWindows, PhotoNotStoredTopLeftIsReadWholeOnce) {
  const fs::path flipped = dir_ / "photo_botleft.tif";
  fs::copy_file(ov_.photo, flipped, fs::copy_options::overwrite_existing);
  {
    TIFF* t = TIFFOpen(flipped.string().c_str(), "r+");
    ASSERT_NE(t, nullptr);
    ASSERT_EQ(TIFFSetField(t, TIFFTAG_ORIENTATION, ORIENTATION_BOTLEFT), 1);
    ASSERT_EQ(TIFFRewriteDirectory(t), 1);
    TIFFClose(t);
  }
  cook::CookOptions o = base_;
  o.albedo_path = flipped.string();
  Cooked whole, split;
  ASSERT_NO_FATAL_FAILURE(cook_to(o, 4096, 0, ".flipwhole", whole));
  ASSERT_NO_FATAL_FAILURE(cook_to(o, 1, 5, ".flipb1s5", split));
  EXPECT_TRUE(split.bytes == whole.bytes) << "bottom-left photo: blocks of one root in order 5 differ";
  EXPECT_EQ(split.windows.windows, 1u);
  EXPECT_EQ(split.windows.largest_window_samples, raster_samples(flipped));
  EXPECT_EQ(split.windows.misses, 0u);
  // The flip is real: the archive differs from the top-left photo's.
  o.albedo_path = ov_.photo.string();
  Cooked upright;
  ASSERT_NO_FATAL_FAILURE(cook_to(o, 4096, 0, ".upright", upright));
  EXPECT_NE(upright.bytes, whole.bytes);
}

// A window is checked against --memory-limit before it is read: a 1 m photo (4000 x 2800 samples,
// 45 MB as one window) is refused under a 40 MB limit in one block, with the way out named, and
// cooks in blocks of one root (windows of at most 2176 x 2176 m: 19 MB).
TEST_F(OverlayWindows, AWindowOverTheMemoryLimitIsRefusedAndSmallerBlocksFit) {
  const fs::path fine = dir_ / "photo_1m.tif";
  run(fmt::format("gdal_translate -q -r bilinear -tr 1 1 -co TILED=YES {} {}", q(dir_ / "relief_cut.tif"), q(fine)));
  ASSERT_EQ(raster_samples(fine), uint64_t(4000) * 2800);
  cook::CookOptions o = base_;
  o.albedo_path = fine.string();
  o.memory_limit_bytes = uint64_t(40) << 20;
  o.block_roots = 4096;
  o.output += ".limit";
  cook::CookReport report;
  const Status refused = cook::cook(o, nullptr, report);
  expect_refusal(refused, Error::unsupported_input, {"--albedo", "photo_1m.tif", "11.2 M samples", "--block-roots"});
  EXPECT_FALSE(fs::exists(o.output));
  o.block_roots = 1;
  cook::reset_overlay_window_stats();
  const Status st = cook::cook(o, nullptr, report);
  ASSERT_TRUE(st.ok()) << st.to_string();
  EXPECT_EQ(cook::overlay_window_stats().misses, 0u);
  EXPECT_LE(cook::overlay_window_stats().largest_window_samples * 4, uint64_t(40) << 20);
}

}  // namespace
