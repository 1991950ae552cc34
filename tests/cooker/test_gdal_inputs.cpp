// Inputs read through GDAL (issue 13): windows, scale/offset, nodata, PixelIsPoint parity with the
// libgeotiff reader, directories, broken VRTs, and web elevation tiles (terrarium, Mapbox
// terrain-RGB) written at test time with known heights.
#include <gtest/gtest.h>

#include <cpl_minixml.h>
#include <gdal_priv.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <fmt/format.h>

#include "session/cook_session.h"
#include "cooker_test_util.h"
#include "inputs/inputs.h"
#include "inputs/source_raster.h"
#include "test_data.h"
#include "inputs/gdal/vrt_stream.h"
#include "inputs/gdal/vrt_xml.h"
#include "inputs/web_tiles.h"

using namespace terrain;
using namespace terrain::test;
namespace fs = std::filesystem;

namespace {

constexpr double kR = 6378137.0;  // EPSG:3857 sphere radius

// Writes a 3-band byte PNG through GDAL (MEM, then CreateCopy), rgb[band][row * size + col].
void write_rgb_png(const fs::path& path, int size, const std::vector<std::vector<uint8_t>>& rgb) {
  GDALAllRegister();
  fs::create_directories(path.parent_path());
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  GDALDriver* png = GetGDALDriverManager()->GetDriverByName("PNG");
  ASSERT_TRUE(mem && png);
  std::unique_ptr<GDALDataset> ds(mem->Create("", size, size, 3, GDT_Byte, nullptr));
  for (int b = 0; b < 3; ++b)
    ASSERT_EQ(ds->GetRasterBand(b + 1)->RasterIO(GF_Write, 0, 0, size, size, const_cast<uint8_t*>(rgb[size_t(b)].data()),
                                                size, size, GDT_Byte, 0, 0, nullptr),
              CE_None);
  std::unique_ptr<GDALDataset> out(png->CreateCopy(path.c_str(), ds.get(), FALSE, nullptr, nullptr, nullptr));
  ASSERT_TRUE(out);
}

cook::CookOptions options_for(const std::vector<std::string>& inputs) {
  cook::CookOptions o;
  o.inputs = inputs;
  return o;
}

Status read_through_gdal(const std::string& path, cook::Raster& r) {
  std::unique_ptr<cook::SourceRaster> src;
  cook::ReadOptions ro;
  TERRAIN_TRY(cook::open_gdal_source(path, ro, src));
  return cook::read_whole_source(*src, ro, r);
}

// A web tile through its reader (load_inputs refuses EPSG:3857 until the "any CRS" work lands).
Status read_tile(const std::string& path, const std::string& flag, cook::Raster& r) {
  cook::TileAddress t;
  if (!cook::parse_tile_address(path, t)) return Status::failure(Error::invalid_argument, "not a z/x/y path");
  cook::TileEncoding enc = cook::TileEncoding::none;
  TERRAIN_TRY(cook::tile_encoding_of(path, flag, enc));
  std::unique_ptr<cook::SourceRaster> src;
  TERRAIN_TRY(cook::open_web_tile(path, t, enc, src));
  return cook::read_whole_source(*src, {}, r);
}

SyntheticDem small_dem(bool point, bool int16) {
  SyntheticDem d;
  d.width = 37;
  d.height = 23;
  d.values.resize(size_t(d.width) * d.height);
  for (int row = 0; row < d.height; ++row)
    for (int col = 0; col < d.width; ++col) d.at(col, row) = 100.0 + 3.0 * col - 2.0 * row + (col * row % 7);
  d.at(5, 5) = NAN;
  d.nodata = -32768;
  d.int16 = int16;
  d.point = point;
  d.x0 = 500012.5;
  d.y0 = 5000987.5;
  d.dx = d.dy = 25;
  d.epsg_projected = 32633;
  return d;
}

}  // namespace

TEST(WebTiles, DecodingFormulas) {
  EXPECT_EQ(cook::terrarium_height(128, 0, 0), 0.0);
  EXPECT_EQ(cook::terrarium_height(0, 0, 0), -32768.0);
  EXPECT_EQ(cook::terrarium_height(127, 255, 128), -0.5);  // 32512 + 255 + 0.5 - 32768
  EXPECT_EQ(cook::terrarium_height(139, 34, 64), 2850.25);  // 35584 + 34 + 0.25 - 32768
  EXPECT_EQ(cook::mapbox_height(0, 0, 0), -10000.0);
  EXPECT_NEAR(cook::mapbox_height(1, 134, 160), 0.0, 1e-9);  // 100000 * 0.1 - 10000
  EXPECT_NEAR(cook::mapbox_height(1, 251, 208), 3000.0, 1e-9);  // 65536 + 64256 + 208 = 130000
}

TEST(WebTiles, AddressAndEncodingFromThePath) {
  cook::TileAddress t;
  ASSERT_TRUE(cook::parse_tile_address("/data/terrarium/12/654/1583.png", t));
  EXPECT_EQ(t.z, 12);
  EXPECT_EQ(t.x, 654);
  EXPECT_EQ(t.y, 1583);
  EXPECT_TRUE(cook::parse_tile_address("tiles/0/0/0.webp", t));
  EXPECT_FALSE(cook::parse_tile_address("tiles/12/4096/1.png", t));  // x beyond 2^12 - 1
  EXPECT_FALSE(cook::parse_tile_address("maps/heightmap.png", t));
  EXPECT_FALSE(cook::parse_tile_address("tiles/12/654/1583.tif", t));
  cook::TileEncoding e = cook::TileEncoding::none;
  EXPECT_TRUE(cook::tile_encoding_of("/d/terrarium/1/0/0.png", "", e).ok());
  EXPECT_EQ(e, cook::TileEncoding::terrarium);
  EXPECT_TRUE(cook::tile_encoding_of("/d/mapbox.terrain-rgb/1/0/0.png", "", e).ok());
  EXPECT_EQ(e, cook::TileEncoding::mapbox);
  EXPECT_TRUE(cook::tile_encoding_of("/d/terrarium/1/0/0.png", "mapbox", e).ok());  // the flag wins
  EXPECT_EQ(e, cook::TileEncoding::mapbox);
  expect_refusal(cook::tile_encoding_of("/d/tiles/1/0/0.png", "", e), Error::invalid_argument, {"--tile-encoding"});
}

TEST(WebTiles, GeoreferencingFromTheAddress) {
  // z0: the whole EPSG:3857 square, pi * R either side of 0.
  const cook::SampleGeo g0 = cook::web_tile_geo({0, 0, 0}, 256);
  const double half = M_PI * kR;
  EXPECT_NEAR(g0.c[0] - 0.5 * g0.c[1], -half, 1e-6);
  EXPECT_NEAR(g0.c[3] - 0.5 * g0.c[5], half, 1e-6);
  EXPECT_NEAR(g0.c[1] * 256, 2 * half, 1e-6);
  EXPECT_EQ(g0.c[2], 0.0);
  EXPECT_EQ(g0.c[4], 0.0);
  EXPECT_FALSE(g0.point_samples);
  // z12/654/1583: west edge at longitude 654/4096*360-180 = -122.51953125 deg; north edge at the
  // latitude of y = 1583 (the slippy-map formula), both to metres on the sphere.
  const cook::SampleGeo g = cook::web_tile_geo({12, 654, 1583}, 512);
  const double west_lon = 654.0 / 4096.0 * 360.0 - 180.0;
  const double north_lat = std::atan(std::sinh(M_PI * (1 - 2.0 * 1583 / 4096.0)));
  EXPECT_NEAR(g.c[0] - 0.5 * g.c[1], west_lon * M_PI / 180.0 * kR, 1e-6);
  EXPECT_NEAR(g.c[3] - 0.5 * g.c[5], kR * std::log(std::tan(M_PI / 4 + north_lat / 2)), 1e-6);
  EXPECT_NEAR(g.c[1], 2 * half / 4096.0 / 512.0, 1e-9);
  EXPECT_NEAR(g.c[5], -2 * half / 4096.0 / 512.0, 1e-9);
  // The CRS a 3857 GeoTIFF gets from the GDAL reader.
  const cook::SourceCrs crs = cook::web_mercator_crs();
  EXPECT_EQ(crs.epsg, 3857);
  EXPECT_EQ(crs.kind, cook::CrsKind::projected);  // through PROJ; the frame choice decides whether it is kept
  EXPECT_NE(crs.name.find("Pseudo-Mercator"), std::string::npos) << crs.name;
}

// Terrarium and Mapbox tiles with known heights, read through load_inputs like any other input.
TEST(WebTiles, GeneratedTilesDecodeToTheirHeights) {
  const fs::path dir = scratch_dir("gdal_web_tiles");
  const int n = 256;
  std::vector<std::vector<uint8_t>> terr(3, std::vector<uint8_t>(size_t(n) * n)), mb = terr;
  std::vector<double> h_terr(size_t(n) * n), h_mb(size_t(n) * n);
  for (int row = 0; row < n; ++row)
    for (int col = 0; col < n; ++col) {
      const size_t i = size_t(row) * n + size_t(col);
      // Terrarium: multiples of 1/256 m from -420.5 to about 4400 m (exactly representable).
      const double h = -420.5 + col * 12.25 + row * 6.5 + (col % 5) / 256.0;
      const double v = h + 32768.0;
      terr[0][i] = uint8_t(int(v) / 256);
      terr[1][i] = uint8_t(int(v) % 256);
      terr[2][i] = uint8_t((v - std::floor(v)) * 256.0);
      h_terr[i] = h;
      // Mapbox: integer decimetres from -11 m.
      const uint32_t code = uint32_t(99890 + col * 97 + row * 41);
      mb[0][i] = uint8_t(code >> 16);
      mb[1][i] = uint8_t((code >> 8) & 255);
      mb[2][i] = uint8_t(code & 255);
      h_mb[i] = -10000.0 + code * 0.1;
    }
  const fs::path terr_path = dir / "terrarium" / "12" / "654" / "1583.png";
  const fs::path mb_path = dir / "tiles" / "12" / "655" / "1583.png";
  ASSERT_NO_FATAL_FAILURE(write_rgb_png(terr_path, n, terr));
  ASSERT_NO_FATAL_FAILURE(write_rgb_png(mb_path, n, mb));

  std::vector<cook::Raster> rasters;
  // The Mapbox tile's path does not name its encoding: refused before anything is read.
  expect_refusal(cook::load_inputs(cook::input_options(options_for({mb_path.string()})), rasters),
                 Error::invalid_argument,
                 {"--tile-encoding"});
  cook::Raster r;
  ASSERT_TRUE(read_tile(terr_path.string(), "", r).ok());
  for (size_t i = 0; i < h_terr.size(); ++i) ASSERT_EQ(r.values[i], float(h_terr[i])) << i;
  ASSERT_TRUE(read_tile(terr_path.string(), "mapbox", r).ok());  // the flag wins over the path
  EXPECT_NE(r.values[0], float(h_terr[0]));
  ASSERT_TRUE(read_tile(mb_path.string(), "mapbox", r).ok());
  for (size_t i = 0; i < h_mb.size(); ++i) ASSERT_EQ(r.values[i], float(h_mb[i])) << i;
  const cook::SampleGeo g = cook::web_tile_geo({12, 655, 1583}, n);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(r.geo.c[i], g.c[i]);
  EXPECT_EQ(r.crs.epsg, 3857);
  EXPECT_NE(r.description.find("Mapbox"), std::string::npos) << r.description;
}

// --tile-encoding on a PNG not under a z/x/y path (issue 48): a cut of the Oetztal SRTM DEM encoded
// as terrarium RGB (h = R*256 + G + B/256 - 32768) decodes to the DEM's heights, placed by the PNG's
// own georeferencing (.aux.xml) or by --spacing/--crs. Before, the PNG was read as a grey heightmap
// and its red channel cooked as metres (129 .. 142 m here). A grey PNG with the flag, and the flag
// with no PNG input, are refused.
TEST(WebTiles, TerrariumImageOutsideZxyDecodesToTheDemsHeights) {
  const fs::path dem_path = data_file("srtm_oetztal.tif");
  TERRAIN_REQUIRE_DATA(dem_path);
  const fs::path dir = scratch_dir("gdal_terrarium_image");
  GDALAllRegister();
  std::unique_ptr<GDALDataset> dem(GDALDataset::Open(dem_path.c_str(), GA_ReadOnly));
  ASSERT_TRUE(dem);
  const int w = 160, h = 120, x0 = 300, y0 = 200;  // the cut: columns 300..459, rows 200..319
  std::vector<float> heights(size_t(w) * h);
  ASSERT_EQ(dem->GetRasterBand(1)->RasterIO(GF_Read, x0, y0, w, h, heights.data(), w, h, GDT_Float32, 0, 0, nullptr),
            CE_None);
  double gt[6];
  ASSERT_EQ(dem->GetGeoTransform(gt), CE_None);
  const double cut_gt[6] = {gt[0] + x0 * gt[1], gt[1], 0, gt[3] + y0 * gt[5], 0, gt[5]};
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  GDALDriver* png = GetGDALDriverManager()->GetDriverByName("PNG");
  ASSERT_TRUE(mem && png);
  std::unique_ptr<GDALDataset> rgb(mem->Create("", w, h, 3, GDT_Byte, nullptr));
  std::vector<std::vector<uint8_t>> band(3, std::vector<uint8_t>(heights.size()));
  float lo = 1e9f, hi = -1e9f;
  for (size_t i = 0; i < heights.size(); ++i) {
    const double v = double(heights[i]) + 32768.0;
    band[0][i] = uint8_t(int(std::floor(v)) / 256);
    band[1][i] = uint8_t(int(std::floor(v)) % 256);
    band[2][i] = uint8_t(std::lround((v - std::floor(v)) * 256.0));
    lo = std::min(lo, heights[i]);
    hi = std::max(hi, heights[i]);
  }
  ASSERT_GT(hi - lo, 500.0f);  // real relief: a red channel read as metres could not pass
  for (int b = 0; b < 3; ++b)
    ASSERT_EQ(rgb->GetRasterBand(b + 1)->RasterIO(GF_Write, 0, 0, w, h, band[size_t(b)].data(), w, h, GDT_Byte, 0, 0, nullptr),
              CE_None);
  // Without georeferencing, then with the DEM's (GDAL writes it to cut.png.aux.xml).
  const std::string plain = (dir / "plain.png").string(), placed = (dir / "cut.png").string();
  { std::unique_ptr<GDALDataset> out(png->CreateCopy(plain.c_str(), rgb.get(), FALSE, nullptr, nullptr, nullptr)); ASSERT_TRUE(out); }
  rgb->SetGeoTransform(const_cast<double*>(cut_gt));
  rgb->SetSpatialRef(dem->GetSpatialRef());
  { std::unique_ptr<GDALDataset> out(png->CreateCopy(placed.c_str(), rgb.get(), FALSE, nullptr, nullptr, nullptr)); ASSERT_TRUE(out); }
  ASSERT_TRUE(fs::exists(placed + ".aux.xml"));

  cook::Raster reference;
  {
    std::vector<cook::Raster> r;
    ASSERT_TRUE(cook::load_inputs(cook::input_options(options_for({dem_path.string()})), r).ok());
    reference = std::move(r[0]);
  }
  // Placed by its .aux.xml: the DEM's heights, sample positions and CRS.
  {
    cook::CookOptions o = options_for({placed});
    o.tile_encoding = "terrarium";
    std::vector<cook::Raster> r;
    const Status st = cook::load_inputs(cook::input_options(o), r);
    ASSERT_TRUE(st.ok()) << st.message;
    ASSERT_EQ(r[0].width, w);
    ASSERT_EQ(r[0].height, h);
    for (size_t i = 0; i < heights.size(); ++i) ASSERT_EQ(r[0].values[i], heights[i]) << i;
    EXPECT_NEAR(r[0].geo.c[0], reference.geo.c[0] + x0 * reference.geo.c[1], 1e-9);
    EXPECT_NEAR(r[0].geo.c[3], reference.geo.c[3] + y0 * reference.geo.c[5], 1e-9);
    EXPECT_DOUBLE_EQ(r[0].geo.c[1], reference.geo.c[1]);
    EXPECT_DOUBLE_EQ(r[0].geo.c[5], reference.geo.c[5]);
    EXPECT_EQ(r[0].crs.kind, reference.crs.kind);
    EXPECT_EQ(r[0].crs.epsg, reference.crs.epsg);
    EXPECT_NE(r[0].description.find("terrarium"), std::string::npos) << r[0].description;
  }
  // No georeferencing: --spacing and --crs place it (a vertex grid, as heightmap images are).
  {
    cook::CookOptions o = options_for({plain});
    o.tile_encoding = "terrarium";
    o.spacing = std::array<double, 2>{90.0, 90.0};
    o.crs = "local";
    std::vector<cook::Raster> r;
    const Status st = cook::load_inputs(cook::input_options(o), r);
    ASSERT_TRUE(st.ok()) << st.message;
    for (size_t i = 0; i < heights.size(); ++i) ASSERT_EQ(r[0].values[i], heights[i]) << i;
    EXPECT_EQ(r[0].geo.c[1], 90.0);
    EXPECT_TRUE(r[0].geo.point_samples);
    // Without --spacing it has no place: the usual message.
    o.spacing.reset();
    expect_refusal(cook::load_inputs(cook::input_options(o), r),
                   Error::invalid_argument, {"plain.png", "no georeferencing", "--spacing"});
  }
  // The same image cooked end to end: the archive's heights are the DEM's, not 129 .. 142 m.
  {
    cook::CookOptions o = options_for({placed});
    o.tile_encoding = "terrarium";
    o.output = (dir / "cut.terrain").string();
    o.heights_only = true;
    cook::CookReport report;
    const Status st = cook::cook(o, {}, report);
    ASSERT_TRUE(st.ok()) << st.message;
    CookedArchive a;
    ASSERT_TRUE(a.open(o.output).ok());
    float amin = 1e9f, amax = -1e9f;
    for (const terrain::NodeRecord& n : a.reader.nodes()) {
      amin = std::min(amin, float(terrain::units_to_metres(n.min_height)));
      amax = std::max(amax, float(terrain::units_to_metres(n.max_height)));
    }
    EXPECT_NEAR(amin, lo, 30.0);
    EXPECT_NEAR(amax, hi, 30.0);
  }
  // A grey PNG with the flag is refused by name (not read as a heightmap).
  const fs::path grey = dir / "grey.png";
  {
    std::unique_ptr<GDALDataset> g(mem->Create("", 16, 16, 1, GDT_Byte, nullptr));
    std::unique_ptr<GDALDataset> out(png->CreateCopy(grey.c_str(), g.get(), FALSE, nullptr, nullptr, nullptr));
    ASSERT_TRUE(out);
  }
  cook::CookOptions o = options_for({grey.string()});
  o.tile_encoding = "terrarium";
  o.spacing = std::array<double, 2>{1.0, 1.0};
  o.crs = "local";
  std::vector<cook::Raster> r;
  expect_refusal(cook::load_inputs(cook::input_options(o), r),
                 Error::unsupported_input, {"grey.png", "1 band(s)", "--tile-encoding terrarium"});
  // The flag with no PNG / WebP input would change nothing: refused.
  o = options_for({dem_path.string()});
  o.tile_encoding = "mapbox";
  expect_refusal(cook::load_inputs(cook::input_options(o), r),
                 Error::invalid_argument, {"--tile-encoding mapbox", "none of the inputs"});
}

// A tile and a GeoTIFF in EPSG:3857 over the same pixels are the same input to the cooker; the
// cook runs once a 3857 frame is possible (the "any CRS" part of issue 13).
TEST(WebTiles, SameAsA3857GeoTiffAndCooksOnceTheFrameAllowsIt) {
  const fs::path dir = scratch_dir("gdal_web_tile_3857");
  const int n = 256;
  std::vector<std::vector<uint8_t>> rgb(3, std::vector<uint8_t>(size_t(n) * n));
  for (int row = 0; row < n; ++row)
    for (int col = 0; col < n; ++col) {
      const int v = 32768 + 1000 + 3 * col + 2 * row;  // 1000 .. 1765 m
      rgb[0][size_t(row) * n + size_t(col)] = uint8_t(v / 256);
      rgb[1][size_t(row) * n + size_t(col)] = uint8_t(v % 256);
    }
  const fs::path tile = dir / "terrarium" / "12" / "654" / "1583.png";
  ASSERT_NO_FATAL_FAILURE(write_rgb_png(tile, n, rgb));
  const fs::path tif = dir / "same.tif";
  const cook::SampleGeo g = cook::web_tile_geo({12, 654, 1583}, n);
  const std::string cmd =
      fmt::format("gdal_translate -q -of GTiff -b 1 -a_srs EPSG:3857 -a_ullr {:.17g} {:.17g} {:.17g} {:.17g} '{}' '{}'",
                  g.c[0] - 0.5 * g.c[1], g.c[3] - 0.5 * g.c[5], g.c[0] + (n - 0.5) * g.c[1], g.c[3] + (n - 0.5) * g.c[5],
                  tile.string(), tif.string());
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  cook::Raster t, r;
  ASSERT_TRUE(read_tile(tile.string(), "", t).ok());
  ASSERT_TRUE(read_through_gdal(tif.string(), r).ok());
  EXPECT_EQ(t.width, r.width);
  EXPECT_EQ(t.height, r.height);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(t.geo.c[i], r.geo.c[i], 1e-6 * std::max(1.0, std::fabs(r.geo.c[i])));
  EXPECT_EQ(t.crs.kind, r.crs.kind);
  EXPECT_EQ(t.crs.epsg, r.crs.epsg);
  EXPECT_EQ(t.crs.name, r.crs.name);
  EXPECT_EQ(t.crs.projection, r.crs.projection);
  // The tile's centre, for the gdalwarp hint: lon -122.475 (tile 654.5 of 4096), lat 37.77.
  EXPECT_NEAR(t.crs.center_lon, 654.5 / 4096 * 360 - 180, 1e-9);
  EXPECT_NEAR(t.crs.center_lat, std::atan(std::sinh(M_PI * (1 - 2.0 * 1583.5 / 4096.0))) * 180 / M_PI, 1e-9);

  cook::CookOptions o = options_for({tile.string()});
  o.output = (dir / "tile.terrain").string();
  cook::CookReport report;
  const Status st = cook::cook(o, {}, report);
  ASSERT_TRUE(st.ok()) << st.message;
  // Web Mercator at 37.8 N scales by 1.27: the frame is a Transverse Mercator centred on the tile.
  EXPECT_EQ(report.frame.kind, terrain::ProjectionKind::transverse_mercator) << report.frame_reason;
  CookedArchive a;
  ASSERT_TRUE(a.open(o.output).ok());
  EXPECT_TRUE(a.reader.verify().ok());
}

TEST(GdalInputs, PixelIsPointAndAreaMatchTheLibgeotiffReader) {
  const fs::path dir = scratch_dir("gdal_parity");
  for (bool point : {false, true})
    for (bool int16 : {false, true})
      for (bool tiled : {false, true}) {
        SCOPED_TRACE(fmt::format("point {} int16 {} tiled {}", point, int16, tiled));
        const std::string path = (dir / fmt::format("d{}{}{}.tif", point, int16, tiled)).string();
        std::string err;
        ASSERT_TRUE(write_geotiff(path, small_dem(point, int16), tiled, err)) << err;
        cook::Raster old_r, new_r;
        ASSERT_TRUE(cook::read_geotiff(path, {}, old_r).ok());
        ASSERT_TRUE(read_through_gdal(path, new_r).ok());
        expect_same_raster(old_r, new_r);
        EXPECT_TRUE(std::isnan(new_r.at(5, 5)));
        EXPECT_EQ(new_r.at(0, 0), 100.0f);
      }
}

TEST(GdalInputs, WindowsScaleAndOffset) {
  const fs::path dir = scratch_dir("gdal_windows");
  const std::string plain = (dir / "plain.tif").string(), scaled = (dir / "scaled.tif").string();
  std::string err;
  ASSERT_TRUE(write_geotiff(plain, small_dem(false, true), true, err)) << err;
  ASSERT_EQ(std::system(fmt::format("gdal_translate -q -a_scale 0.5 -a_offset 100 '{}' '{}'", plain, scaled).c_str()), 0);
  cook::ReadOptions ro;
  std::unique_ptr<cook::SourceRaster> a, b;
  ASSERT_TRUE(cook::open_gdal_source(plain, ro, a).ok());
  ASSERT_TRUE(cook::open_gdal_source(scaled, ro, b).ok());
  EXPECT_EQ(b->info().scale, 0.5);
  EXPECT_EQ(b->info().offset, 100.0);
  cook::Raster whole;
  ASSERT_TRUE(cook::read_whole_source(*a, ro, whole).ok());
  // A window inside the raster, the nodata sample (5, 5) included.
  const int x0 = 3, y0 = 4, w = 11, h = 7;
  std::vector<float> wa(size_t(w) * h), wb(size_t(w) * h);
  ASSERT_TRUE(a->read_window(x0, y0, w, h, wa.data()).ok());
  ASSERT_TRUE(b->read_window(x0, y0, w, h, wb.data()).ok());
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const float v = whole.at(x0 + c, y0 + r), va = wa[size_t(r) * w + size_t(c)], vb = wb[size_t(r) * w + size_t(c)];
      if (std::isnan(v)) {
        EXPECT_TRUE(std::isnan(va) && std::isnan(vb)) << c << "," << r;
        continue;
      }
      EXPECT_EQ(va, v);
      EXPECT_EQ(vb, float(v * 0.5 + 100.0));
    }
  EXPECT_TRUE(std::isnan(wa[size_t(5 - y0) * w + size_t(5 - x0)]));
  expect_refusal(a->read_window(30, 0, 11, 2, wa.data()), Error::invalid_argument, {"outside"});
  // Float64 (read through a band of doubles, not in place): the same heights and nodata.
  const std::string f64 = (dir / "f64.tif").string();
  ASSERT_EQ(std::system(fmt::format("gdal_translate -q -ot Float64 '{}' '{}'", plain, f64).c_str()), 0);
  std::unique_ptr<cook::SourceRaster> c;
  ASSERT_TRUE(cook::open_gdal_source(f64, ro, c).ok());
  EXPECT_EQ(c->info().sample_type, "Float64");
  cook::Raster whole64;
  ASSERT_TRUE(cook::read_whole_source(*c, ro, whole64).ok());
  ASSERT_EQ(whole64.values.size(), whole.values.size());
  EXPECT_EQ(std::memcmp(whole64.values.data(), whole.values.data(), whole.values.size() * sizeof(float)), 0);
  EXPECT_TRUE(std::isnan(whole64.at(5, 5)));
}

TEST(GdalInputs, DirectoryInputIsEveryRasterInPathOrder) {
  const fs::path dir = scratch_dir("gdal_directory");
  SyntheticDem west = small_dem(false, false), east = small_dem(false, false);
  east.x0 += east.width * east.dx;
  for (double& v : east.values) v += 1000;
  std::string err;
  fs::create_directories(dir / "in" / "sub");
  ASSERT_TRUE(write_geotiff((dir / "in" / "b_west.tif").string(), west, false, err)) << err;
  ASSERT_TRUE(write_geotiff((dir / "in" / "sub" / "a_east.tif").string(), east, false, err)) << err;
  std::ofstream(dir / "in" / "README.txt") << "not a raster\n";
  std::vector<cook::Raster> rasters;
  ASSERT_TRUE(cook::load_inputs(cook::input_options(options_for({(dir / "in").string()})), rasters).ok());
  ASSERT_EQ(rasters.size(), 2u);
  EXPECT_EQ(rasters[0].path, (dir / "in" / "b_west.tif").string());  // "b_west.tif" < "sub/..."
  EXPECT_EQ(rasters[1].path, (dir / "in" / "sub" / "a_east.tif").string());
  EXPECT_EQ(rasters[1].at(0, 0), 1100.0f);
  fs::create_directories(dir / "empty");
  expect_refusal(cook::load_inputs(cook::input_options(options_for({(dir / "empty").string()})), rasters),
                 Error::unsupported_input,
                 {"no raster files"});
}

TEST(GdalInputs, BrokenVrtsAreNamedErrors) {
  const fs::path dir = scratch_dir("gdal_bad_vrt");
  SyntheticDem west = small_dem(false, false), east = small_dem(false, false);
  east.x0 += east.width * east.dx;
  std::string err;
  const std::string a = (dir / "a.tif").string(), b = (dir / "b.tif").string(), vrt = (dir / "m.vrt").string();
  ASSERT_TRUE(write_geotiff(a, west, false, err)) << err;
  ASSERT_TRUE(write_geotiff(b, east, false, err)) << err;
  ASSERT_EQ(std::system(fmt::format("gdalbuildvrt -q '{}' '{}' '{}'", vrt, a, b).c_str()), 0);
  std::vector<cook::Raster> rasters;
  ASSERT_TRUE(cook::load_inputs(cook::input_options(options_for({vrt})), rasters).ok());
  EXPECT_EQ(rasters[0].width, 2 * west.width);
  EXPECT_EQ(rasters[0].at(west.width, 0), 100.0f);
  // A tile GDAL cannot read: garbage where the TIFF was.
  std::ofstream(b, std::ios::binary | std::ios::trunc) << std::string(4096, 'x');
  expect_refusal(cook::load_inputs(cook::input_options(options_for({vrt})), rasters),
                 Error::io_read, {"m.vrt", "cannot read rows"});
  // A missing tile.
  fs::remove(b);
  expect_refusal(cook::load_inputs(cook::input_options(options_for({vrt})), rasters), Error::io_read,
                 {"m.vrt", "cannot read rows", "b.tif", "No such file or directory"});
  // Not a raster at all.
  const std::string text = (dir / "notes.dat").string();
  std::ofstream(text) << "hello\n";
  expect_refusal(cook::load_inputs(cook::input_options(options_for({text})), rasters),
                 Error::unsupported_input, {"unknown input format"});
}

// vrt_xml.h's reading of relativeToVRT against GDAL's VRT driver, spelling by spelling: a tile of
// the same name lies beside the VRT and in the working directory, so the file GDAL lists (its
// GetFileList names a source only where it exists) shows which way GDAL resolved the name.
TEST(VrtXml, SourceFilesResolveAsGdalResolvesThem) {
  const fs::path dir = fs::absolute(scratch_dir("vrt_relative"));
  fs::create_directories(dir / "sub");
  const SyntheticDem dem = small_dem(false, false);
  std::string err;
  ASSERT_TRUE(write_geotiff((dir / "t.tif").string(), dem, false, err)) << err;
  ASSERT_TRUE(write_geotiff((dir / "sub" / "t.tif").string(), dem, false, err)) << err;
  struct InDir {  // back to the test's working directory however the test ends
    fs::path before = fs::current_path();
    explicit InDir(const fs::path& d) { fs::current_path(d); }
    ~InDir() { fs::current_path(before); }
  } in_dir(dir);
  GDALAllRegister();
  int relative = 0, not_relative = 0;
  for (const char* attr : {"1", "0", "TRUE", "true", "yes", "2", "-1", "01", " 1", "1x", ""}) {
    SCOPED_TRACE(fmt::format("relativeToVRT=\"{}\"", attr));
    const std::string vrt = "sub/m.vrt";
    std::ofstream(vrt, std::ios::trunc) << fmt::format(
        "<VRTDataset rasterXSize=\"{0}\" rasterYSize=\"{1}\">\n <VRTRasterBand dataType=\"Float32\" band=\"1\">\n"
        "  <SimpleSource>\n   <SourceFilename relativeToVRT=\"{2}\">t.tif</SourceFilename>\n"
        "   <SourceBand>1</SourceBand>\n   <SrcRect xOff=\"0\" yOff=\"0\" xSize=\"{0}\" ySize=\"{1}\"/>\n"
        "   <DstRect xOff=\"0\" yOff=\"0\" xSize=\"{0}\" ySize=\"{1}\"/>\n  </SimpleSource>\n"
        " </VRTRasterBand>\n</VRTDataset>\n",
        dem.width, dem.height, attr);
    std::string gdal_file;
    {
      std::unique_ptr<GDALDataset> ds(GDALDataset::Open(vrt.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
      ASSERT_TRUE(ds);
      char** files = ds->GetFileList();
      for (int i = 0; files && files[i]; ++i)
        if (fs::path(files[i]).filename() == "t.tif") gdal_file = files[i];
      CSLDestroy(files);
    }
    ASSERT_FALSE(gdal_file.empty()) << "GDAL lists no source";
    CPLXMLNode* root = CPLParseXMLFile(vrt.c_str());
    ASSERT_TRUE(root);
    const CPLXMLNode* name = CPLGetXMLNode(root, "VRTRasterBand.SimpleSource.SourceFilename");
    ASSERT_TRUE(name);
    const std::string ours = cook::vrt_source_file(name, cook::vrt_folder(vrt));
    const bool ours_relative = cook::vrt_name_is_relative(name);
    CPLDestroyXMLNode(root);
    EXPECT_EQ(fs::weakly_canonical(ours), fs::weakly_canonical(gdal_file)) << "ours " << ours << ", GDAL's " << gdal_file;
    EXPECT_EQ(ours_relative, fs::weakly_canonical(gdal_file) == fs::weakly_canonical(dir / "sub" / "t.tif"));
    (ours_relative ? relative : not_relative) += 1;
  }
  // Both readings occur among the spellings (else the test could not tell them apart).
  EXPECT_GE(relative, 3);
  EXPECT_GE(not_relative, 3);
}

namespace {

// A node alone, serialized (CPLSerializeXMLTree also writes the siblings that follow it).
std::string serialized_alone(CPLXMLNode* node) {
  CPLXMLNode* next = node->psNext;
  node->psNext = nullptr;
  char* text = CPLSerializeXMLTree(node);
  node->psNext = next;
  std::string s = text ? text : "";
  CPLFree(text);
  return s;
}

}  // namespace

// vrt_stream.h against the whole-file tree it replaces (CPLParseXMLFile): the same sources, in the
// same order and bands, and the same dataset without them, whatever the chunk size (1 byte splits
// every tag and entity across chunks); a source as an empty element, entities, CDATA holding a
// tag's text, comments, a prolog and a band's <Overview> (not a source) on the way.
TEST(VrtStream, SourcesAndHeaderAreTheWholeTreesAtAnyChunkSize) {
  const fs::path dir = fs::absolute(scratch_dir("vrt_stream"));
  fs::create_directories(dir);
  const std::string vrt = (dir / "m.vrt").string();
  std::ofstream(vrt, std::ios::trunc)
      << "<?xml version=\"1.0\"?>\n<!-- made by hand -->\n"
         "<VRTDataset rasterXSize=\"20\" rasterYSize=\"10\">\n"
         " <GeoTransform>0, 1, 0, 10, 0, -1</GeoTransform>\n"
         " <Metadata><MDI key=\"note\"><![CDATA[<SimpleSource>not a source</SimpleSource>]]></MDI></Metadata>\n"
         " <VRTRasterBand dataType=\"Float32\" band=\"1\">\n"
         "  <NoDataValue>-9999</NoDataValue>\n"
         "  <ComplexSource>\n   <SourceFilename relativeToVRT=\"1\">a&amp;b.tif</SourceFilename>\n"
         "   <SourceBand>1</SourceBand>\n   <SrcRect xOff=\"0\" yOff=\"0\" xSize=\"10\" ySize=\"10\"/>\n"
         "   <DstRect xOff=\"0\" yOff=\"0\" xSize=\"10\" ySize=\"10\"/>\n   <NODATA>-9999</NODATA>\n  </ComplexSource>\n"
         "  <!-- between two sources -->\n"
         "  <SimpleSource/>\n"
         "  <Overview><SourceFilename relativeToVRT=\"1\">m.ovr</SourceFilename><SourceBand>1</SourceBand></Overview>\n"
         "  <KernelFilteredSource><SourceFilename relativeToVRT=\"0\">/abs/c.tif</SourceFilename>"
         "<Kernel><Size>3</Size><Coefs>0 0 0 0 1 0 0 0 0</Coefs></Kernel></KernelFilteredSource>\n"
         " </VRTRasterBand>\n"
         " <VRTRasterBand dataType=\"Float32\" band=\"2\">\n"
         "  <SimpleSource><SourceFilename relativeToVRT=\"1\">d.tif</SourceFilename>"
         "<DstRect xOff=\"10\" yOff=\"0\" xSize=\"10\" ySize=\"10\"/></SimpleSource>\n"
         " </VRTRasterBand>\n"
         "</VRTDataset>\n<!-- after -->\n";
  // The reference: the whole tree, its sources serialized one by one, then removed.
  std::vector<std::pair<int, std::string>> want;
  std::string want_header;
  {
    CPLXMLNode* root = CPLParseXMLFile(vrt.c_str());
    ASSERT_TRUE(root);
    CPLXMLNode* ds = CPLGetXMLNode(root, "=VRTDataset");
    ASSERT_TRUE(ds);
    int band = -1;
    for (CPLXMLNode* b = ds->psChild; b; b = b->psNext) {
      if (b->eType != CXT_Element || !EQUAL(b->pszValue, "VRTRasterBand")) continue;
      ++band;
      CPLXMLNode** link = &b->psChild;
      while (CPLXMLNode* c = *link) {
        if (!cook::is_vrt_source(c)) {
          link = &c->psNext;
          continue;
        }
        want.emplace_back(band, serialized_alone(c));
        *link = c->psNext;
        c->psNext = nullptr;
        CPLDestroyXMLNode(c);
      }
    }
    want_header = serialized_alone(ds);
    CPLDestroyXMLNode(root);
  }
  ASSERT_EQ(want.size(), 4u);
  std::string file;
  {
    std::ifstream in(vrt, std::ios::binary);
    file.assign(std::istreambuf_iterator<char>(in), {});
  }
  for (size_t chunk : {size_t(1), size_t(2), size_t(3), size_t(7), size_t(64), size_t(1) << 20}) {
    SCOPED_TRACE(fmt::format("chunk {}", chunk));
    std::vector<std::pair<int, std::string>> got;
    cook::VrtStream stream;
    const cook::VrtRead read = cook::read_vrt_stream(
        vrt, stream,
        [&](const cook::VrtSourceVisit& v) {
          got.emplace_back(v.band, serialized_alone(const_cast<CPLXMLNode*>(v.node)));
          // Its bytes in the file are the element itself.
          CPLXMLNode* again = CPLParseXMLString(file.substr(size_t(v.begin), size_t(v.end - v.begin)).c_str());
          EXPECT_TRUE(again);
          if (again) {
            EXPECT_EQ(serialized_alone(again), got.back().second);
          }
          CPLDestroyXMLNode(again);
          return true;
        },
        chunk);
    ASSERT_EQ(read, cook::VrtRead::ok);
    EXPECT_EQ(got, want);
    ASSERT_TRUE(stream.header.starts_with("<VRTDataset"));  // what GDAL's VRT driver opens as text
    CPLXMLNode* header = CPLParseXMLString(stream.header.c_str());
    ASSERT_TRUE(header);
    EXPECT_EQ(serialized_alone(header), want_header);
    CPLDestroyXMLNode(header);
    ASSERT_EQ(stream.band_sources_at.size(), 2u);
    // Where band 1's first source stood: after its NoDataValue, before the comment that followed it.
    EXPECT_TRUE(stream.header.substr(0, stream.band_sources_at[0]).ends_with("</NoDataValue>\n  "));
  }
  // A reader that stops, a document that is not a VRT, a truncated one and a missing one.
  cook::VrtStream stream;
  int visits = 0;
  EXPECT_EQ(cook::read_vrt_stream(vrt, stream, [&](const cook::VrtSourceVisit&) { return ++visits < 2; }), cook::VrtRead::stopped);
  EXPECT_EQ(visits, 2);
  const std::string other = (dir / "other.vrt").string(), cut = (dir / "cut.vrt").string();
  std::ofstream(other, std::ios::trunc) << "<?xml version=\"1.0\"?><VRTDatasetX><VRTRasterBand/></VRTDatasetX>";
  std::ofstream(cut, std::ios::trunc) << file.substr(0, file.size() / 2);
  EXPECT_EQ(cook::read_vrt_stream(other, stream, {}), cook::VrtRead::not_vrt);
  EXPECT_EQ(cook::read_vrt_stream(cut, stream, {}), cook::VrtRead::unreadable);
  EXPECT_EQ(cook::read_vrt_stream((dir / "none.vrt").string(), stream, {}), cook::VrtRead::unreadable);
  // GDAL opens the header as the VRT without its sources.
  EXPECT_EQ(cook::vrt_without_sources(vrt).substr(0, 11), "<VRTDataset");
}
