// The GDAL reader on the shared real DEMs (issue 13): the same Raster as the libgeotiff reader,
// bit for bit, and a VRT of 16 tiles cut from a DEM cooks to the uncut DEM's node payloads.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fmt/format.h>

#include "cooker_test_util.h"
#include "inputs/inputs.h"
#include "inputs/source_raster.h"
#include "test_data.h"

using namespace terrain;
using namespace terrain::test;
namespace fs = std::filesystem;

class SharedGeoTiff : public ::testing::TestWithParam<const char*> {};

TEST_P(SharedGeoTiff, GdalReaderEqualsTheLibgeotiffReader) {
  const fs::path path = data_file(GetParam());
  TERRAIN_REQUIRE_DATA(path);
  cook::ReadOptions ro;
  cook::Raster old_r, new_r;
  ASSERT_TRUE(cook::read_geotiff(path.string(), ro, old_r).ok());
  std::unique_ptr<cook::SourceRaster> src;
  ASSERT_TRUE(cook::open_gdal_source(path.string(), ro, src).ok());
  ASSERT_TRUE(cook::read_whole_source(*src, ro, new_r).ok());
  expect_same_raster(old_r, new_r);
  // Bytes asked of the driver: every sample once.
  EXPECT_GE(src->info().bytes_read, uint64_t(new_r.width) * uint64_t(new_r.height));
}

INSTANTIATE_TEST_SUITE_P(SharedData, SharedGeoTiff,
                         ::testing::Values("kilauea_utm5n.tif", "srtm_oetztal.tif", "slovenia_TM1_564_146.tif",
                                           "tahoe_lidar_bareearth.tif", "tahoe_lidar_highesthit.tif"),
                         [](const auto& p) {
                           std::string n = p.param;
                           return n.substr(0, n.find('.'));
                         });

// Kilauea (857 x 793, Int16, nodata -32768) cut into 4 x 4 tiles of unequal sizes with
// gdal_translate -srcwin, listed in a VRT by gdalbuildvrt: the mosaic cooks to the same nodes and
// node payloads, byte for byte, as the uncut file.
TEST(GdalMosaic, VrtOf16TilesCooksToTheUncutPayloads) {
  const fs::path dem = data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(dem);
  const fs::path dir = scratch_dir("gdal_vrt16");
  const int w = 857, h = 793, tw = 215, th = 199;
  std::string list;
  for (int ty = 0; ty < 4; ++ty)
    for (int tx = 0; tx < 4; ++tx) {
      const int x0 = tx * tw, y0 = ty * th;
      const int cw = tx == 3 ? w - x0 : tw, ch = ty == 3 ? h - y0 : th;
      const fs::path tile = dir / fmt::format("t{}{}.tif", ty, tx);
      const std::string cmd = fmt::format("gdal_translate -q -srcwin {} {} {} {} '{}' '{}'", x0, y0, cw, ch,
                                          dem.string(), tile.string());
      ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
      list += " '" + tile.string() + "'";
    }
  const fs::path vrt = dir / "mosaic.vrt";
  ASSERT_EQ(std::system(fmt::format("gdalbuildvrt -q '{}'{}", vrt.string(), list).c_str()), 0);

  cook::CookOptions a, b;
  a.inputs = {dem.string()};
  a.output = (dir / "uncut.terrain").string();
  a.threads = 2;
  b = a;
  b.inputs = {vrt.string()};
  b.output = (dir / "mosaic.terrain").string();
  cook::CookReport ra, rb;
  ASSERT_TRUE(cook::cook(a, {}, ra).ok());
  ASSERT_TRUE(cook::cook(b, {}, rb).ok());
  ArchiveReader ua, ub;
  ASSERT_TRUE(ua.open(a.output).ok());
  ASSERT_TRUE(ub.open(b.output).ok());
  ASSERT_EQ(ua.nodes().size(), ub.nodes().size());
  ASSERT_GT(ua.nodes().size(), 10u);
  size_t differing = 0;
  std::vector<uint8_t> pa, pb;
  for (size_t i = 0; i < ua.nodes().size(); ++i) {
    const NodeRecord& na = ua.nodes()[i];
    const int64_t j = ub.find(na.key);
    ASSERT_GE(j, 0) << "node missing from the mosaic's cook";
    ASSERT_TRUE(ua.read_payload(i, pa).ok());
    ASSERT_TRUE(ub.read_payload(size_t(j), pb).ok());
    if (pa != pb) ++differing;
  }
  EXPECT_EQ(differing, 0u) << "of " << ua.nodes().size() << " nodes";
}
