// The cooker's own decoding of plain GeoTIFF blocks (cooker/src/inputs/tiff_blocks.h): the predictors'
// undo against the TIFF rules written out here, every window of every supported layout bit for bit
// GDAL's, what it leaves to GDAL (and that the source then reads the same samples), and archives
// equal with the reader on and off.
#include <gtest/gtest.h>

#include <gdal_priv.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <iostream>
#include <optional>
#include <random>
#include <set>
#include <thread>

#include "cooker_test_util.h"
#include "inputs/inputs.h"
#include "base/slab_pool.h"
#include "inputs/source_raster.h"
#include "test_data.h"
#include "inputs/tiff_blocks.h"
#include "inputs/gdal/vrt_tiles.h"

using namespace terrain;
using namespace terrain::test;
namespace fs = std::filesystem;

namespace {

// TERRAIN_TIFF_DIRECT for one scope.
struct DirectSwitch {
  explicit DirectSwitch(bool on) { ::setenv("TERRAIN_TIFF_DIRECT", on ? "1" : "0", 1); }
  ~DirectSwitch() { ::unsetenv("TERRAIN_TIFF_DIRECT"); }
};

// TIFF predictor 2 (horizontal differencing) of one row, as a writer applies it.
void difference_row(uint8_t* row, int samples, int bps) {
  for (int i = samples - 1; i >= 1; --i) {
    uint32_t a = 0, b = 0;
    std::memcpy(&a, row + size_t(i - 1) * size_t(bps), size_t(bps));
    std::memcpy(&b, row + size_t(i) * size_t(bps), size_t(bps));
    b -= a;
    std::memcpy(row + size_t(i) * size_t(bps), &b, size_t(bps));
  }
}

// TIFF predictor 3 (Adobe's floating-point predictor) of one row of little-endian floats: the
// bytes split into planes, most significant first, then differenced byte by byte along the row.
std::vector<uint8_t> float_predict_row(const std::vector<float>& v) {
  const size_t n = v.size();
  std::vector<uint8_t> out(4 * n);
  for (size_t i = 0; i < n; ++i) {
    uint32_t u;
    std::memcpy(&u, &v[i], 4);
    for (int b = 0; b < 4; ++b) out[size_t(b) * n + i] = uint8_t(u >> (8 * (3 - b)));
  }
  for (size_t i = out.size() - 1; i >= 1; --i) out[i] = uint8_t(out[i] - out[i - 1]);
  return out;
}

TEST(TiffBlocks, PredictorsUndoWhatAWriterDid) {
  std::mt19937 rng(7);
  // Row lengths around the 16-byte vectors, odd tails included, and a 512-sample tile row.
  for (int samples : {1, 2, 3, 7, 15, 16, 17, 31, 33, 100, 257, 512, 1000}) {
    for (int bps : {1, 2, 4}) {
      std::vector<uint8_t> original(size_t(samples) * size_t(bps));
      for (uint8_t& b : original) b = uint8_t(rng());
      for (bool scalar : {false, true}) {
        std::vector<uint8_t> row = original;
        difference_row(row.data(), samples, bps);
        cook::undo_horizontal_predictor(row.data(), samples, bps, scalar);
        EXPECT_EQ(row, original) << samples << " samples of " << bps << " bytes, scalar " << scalar;
      }
    }
    std::vector<float> v(static_cast<size_t>(samples));
    std::normal_distribution<float> z(800.0f, 300.0f);
    for (float& f : v) f = z(rng);
    if (samples > 3) v[2] = -0.0f, v[3] = NAN;
    for (bool scalar : {false, true}) {
      std::vector<uint8_t> row = float_predict_row(v), out(4 * size_t(samples));
      cook::undo_float_predictor(row.data(), samples, out.data(), scalar);
      EXPECT_EQ(std::memcmp(out.data(), v.data(), out.size()), 0) << samples << " floats, scalar " << scalar;
    }
  }
}

struct Layout {
  GDALDataType type;
  std::vector<std::string> options;  // GTiff creation options
};

// A w x h raster of `type` with relief, noise, a nodata patch and negative values where signed.
fs::path write_tiff(const fs::path& dir, const std::string& name, int w, int h, const Layout& l) {
  GDALAllRegister();
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  GDALDriver* gtiff = GetGDALDriverManager()->GetDriverByName("GTiff");
  std::unique_ptr<GDALDataset> ds(mem->Create("", w, h, 1, GDT_Float64, nullptr));
  std::vector<double> v(size_t(w) * size_t(h));
  std::mt19937 rng(uint32_t(w * 31 + h));
  std::uniform_real_distribution<double> noise(-3.0, 3.0);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      double z = 120.0 + 60.0 * std::sin(c * 0.013) * std::cos(r * 0.021) + noise(rng);
      if (l.type == GDT_Float32) z = z * 13.7 - 400.0;  // negative heights, fractions
      if (l.type == GDT_Int16 || l.type == GDT_Int32) z = z * 50.0 - 3000.0;
      if (l.type == GDT_UInt16) z *= 200.0;
      if (c > w / 3 && c < w / 3 + 20 && r > h / 2 && r < h / 2 + 9) z = l.type == GDT_Byte ? 0 : -9999;  // nodata
      v[size_t(r) * size_t(w) + size_t(c)] = z;
    }
  EXPECT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, w, h, v.data(), w, h, GDT_Float64, 0, 0, nullptr), CE_None);
  std::unique_ptr<GDALDataset> typed(mem->Create("", w, h, 1, l.type, nullptr));
  EXPECT_EQ(typed->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, w, h, v.data(), w, h, GDT_Float64, 0, 0, nullptr), CE_None);
  if (l.type != GDT_Byte) typed->GetRasterBand(1)->SetNoDataValue(-9999);
  std::vector<const char*> opts;
  for (const std::string& o : l.options) opts.push_back(o.c_str());
  opts.push_back(nullptr);
  const fs::path path = dir / (name + ".tif");
  std::unique_ptr<GDALDataset> out(
      gtiff->CreateCopy(path.c_str(), typed.get(), FALSE, const_cast<char**>(opts.data()), nullptr, nullptr));
  EXPECT_TRUE(out) << path;
  return path;
}

// GDAL's window in 4-byte slots, as GdalSource asks for it.
std::vector<uint8_t> gdal_window(GDALDataset& ds, int x0, int y0, int w, int h) {
  GDALRasterBand* b = ds.GetRasterBand(1);
  std::vector<uint8_t> slots(size_t(w) * size_t(h) * 4, 0);
  EXPECT_EQ(b->RasterIO(GF_Read, x0, y0, w, h, slots.data(), w, h, b->GetRasterDataType(), 4, GSpacing(w) * 4, nullptr),
            CE_None);
  return slots;
}

// Slots compared on their first `bps` bytes (the rest is not written by either reader).
bool same_samples(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b, int bps) {
  for (size_t i = 0; i < a.size(); i += 4)
    if (std::memcmp(&a[i], &b[i], size_t(bps)) != 0) return false;
  return true;
}

TEST(TiffBlocks, EveryWindowIsGdalsBitForBit) {
  const fs::path dir = scratch_dir("TiffBlocks.EveryWindowIsGdalsBitForBit");
  const int w = 1001, h = 777;  // partial tiles and a short last strip on both edges
  const std::vector<std::pair<std::string, Layout>> layouts = {
      {"f32_zstd_p3_tiles", {GDT_Float32, {"TILED=YES", "COMPRESS=ZSTD", "PREDICTOR=3", "BLOCKXSIZE=256", "BLOCKYSIZE=128"}}},
      {"f32_deflate_p3_strips", {GDT_Float32, {"COMPRESS=DEFLATE", "PREDICTOR=3", "BLOCKYSIZE=5"}}},
      {"f32_deflate_p1_tiles", {GDT_Float32, {"TILED=YES", "COMPRESS=DEFLATE", "BLOCKXSIZE=512", "BLOCKYSIZE=512"}}},
      {"f32_zstd_p3_small_tiles", {GDT_Float32, {"TILED=YES", "COMPRESS=ZSTD", "PREDICTOR=3", "BLOCKXSIZE=16", "BLOCKYSIZE=16"}}},
      {"f32_zstd_p2_strips", {GDT_Float32, {"COMPRESS=ZSTD", "PREDICTOR=2", "BLOCKYSIZE=16"}}},
      {"i16_deflate_p2_strips", {GDT_Int16, {"COMPRESS=DEFLATE", "PREDICTOR=2", "BLOCKYSIZE=7"}}},
      {"i16_zstd_p2_tiles", {GDT_Int16, {"TILED=YES", "COMPRESS=ZSTD", "PREDICTOR=2", "BLOCKXSIZE=128", "BLOCKYSIZE=256"}}},
      {"u16_zstd_p1_tiles", {GDT_UInt16, {"TILED=YES", "COMPRESS=ZSTD", "BLOCKXSIZE=256", "BLOCKYSIZE=256"}}},
      {"i32_zstd_p1_strips", {GDT_Int32, {"COMPRESS=ZSTD", "BLOCKYSIZE=100"}}},
      {"i32_deflate_p2_tiles", {GDT_Int32, {"TILED=YES", "COMPRESS=DEFLATE", "PREDICTOR=2"}}},
      {"u8_deflate_p2_strips", {GDT_Byte, {"COMPRESS=DEFLATE", "PREDICTOR=2"}}},
      {"f32_lzw_p3_tiles", {GDT_Float32, {"TILED=YES", "COMPRESS=LZW", "PREDICTOR=3", "BLOCKXSIZE=256", "BLOCKYSIZE=256"}}},
      {"f32_lzw_p1_strips", {GDT_Float32, {"COMPRESS=LZW", "BLOCKYSIZE=9"}}},
      {"i16_lzw_p2_tiles", {GDT_Int16, {"TILED=YES", "COMPRESS=LZW", "PREDICTOR=2", "BLOCKXSIZE=512", "BLOCKYSIZE=512"}}},
      {"u8_lzw_p1_strips", {GDT_Byte, {"COMPRESS=LZW"}}},
  };
  std::mt19937 rng(11);
  for (const auto& [name, layout] : layouts) {
    SCOPED_TRACE(name);
    const fs::path path = write_tiff(dir, name, w, h, layout);
    const int bps = GDALGetDataTypeSizeBytes(layout.type);
    std::unique_ptr<cook::TiffBlockReader> reader;
    const Status opened = cook::TiffBlockReader::open(path.string(), w, h, bps, reader);
    ASSERT_TRUE(opened.ok() && reader) << opened.to_string();
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    ASSERT_TRUE(ds);
    // Whole, one sample, the corners, and random windows; a cache of one block for half of them.
    std::vector<std::array<int, 4>> windows = {{0, 0, w, h}, {0, 0, 1, 1}, {w - 1, h - 1, 1, 1}, {w - 300, 0, 300, 64},
                                               {0, h - 33, 77, 33}};
    for (int i = 0; i < 40; ++i) {
      const int ww = 1 + int(rng() % uint32_t(w)), wh = 1 + int(rng() % 300u);
      windows.push_back({int(rng() % uint32_t(w - ww + 1)), int(rng() % uint32_t(h - wh + 1)), ww, wh});
    }
    int k = 0;
    for (const auto& [x0, y0, ww, wh] : windows) {
      cook::set_tiff_block_cache_bytes(k++ % 2 ? uint64_t(1) : uint64_t(64) << 20);
      std::vector<uint8_t> slots(size_t(ww) * size_t(wh) * 4, 0);
      ASSERT_TRUE(reader->read_window(x0, y0, ww, wh, slots.data(), 1 + k % 3));
      ASSERT_TRUE(same_samples(slots, gdal_window(*ds, x0, y0, ww, wh), bps))
          << "window " << ww << "x" << wh << " at " << x0 << "," << y0;
    }
  }
  cook::set_tiff_block_cache_bytes(uint64_t(64) << 20);
}

TEST(TiffBlocks, LeavesOtherLayoutsToGdal) {
  const fs::path dir = scratch_dir("TiffBlocks.LeavesOtherLayoutsToGdal");
  struct Case {
    std::string name;
    Layout layout;
    std::string why;
  };
  const std::vector<Case> cases = {
      {"lerc", {GDT_Float32, {"COMPRESS=LERC"}}, "compression 34887"},
      {"packbits", {GDT_Int16, {"COMPRESS=PACKBITS"}}, "compression 32773"},
      {"f64", {GDT_Float64, {"COMPRESS=ZSTD"}}, "64-bit"},
      {"none", {GDT_Float32, {"TILED=YES"}}, "no compression"},
  };
  for (const Case& c : cases) {
    const fs::path path = write_tiff(dir, c.name, 300, 200, c.layout);
    std::unique_ptr<cook::TiffBlockReader> reader;
    const Status st = cook::TiffBlockReader::open(path.string(), 300, 200, GDALGetDataTypeSizeBytes(c.layout.type), reader);
    EXPECT_EQ(st.code, Error::unsupported_input) << c.name;
    EXPECT_FALSE(reader) << c.name;
    EXPECT_NE(st.message.find(c.why), std::string::npos) << c.name << ": " << st.message;
  }
  const fs::path plain = write_tiff(dir, "plain", 300, 200, {GDT_Float32, {"COMPRESS=ZSTD", "PREDICTOR=3"}});
  std::unique_ptr<cook::TiffBlockReader> reader;
  EXPECT_EQ(cook::TiffBlockReader::open(plain.string(), 301, 200, 4, reader).message,
            "its first image is not the one GDAL reads") << "another size than GDAL's";
  EXPECT_FALSE(reader);
  {
    DirectSwitch off(false);
    const Status st = cook::TiffBlockReader::open(plain.string(), 300, 200, 4, reader);
    EXPECT_EQ(st.code, Error::unsupported_input);
    EXPECT_EQ(st.message, "TERRAIN_TIFF_DIRECT=0");
    EXPECT_FALSE(reader);
  }
  const Status st = cook::TiffBlockReader::open(plain.string(), 300, 200, 4, reader);
  EXPECT_TRUE(st.ok() && reader) << st.to_string();
}

// A source's window read through the cooker's GDAL source, with the direct reader on or off.
std::vector<float> source_window(const fs::path& path, bool direct, int x0, int y0, int w, int h, Status& st) {
  DirectSwitch sw(direct);
  std::unique_ptr<cook::SourceRaster> src;
  cook::ReadOptions ro;
  std::vector<float> out(size_t(w) * size_t(h));
  st = cook::open_gdal_source(path.string(), ro, src);
  if (st.ok()) st = src->read_window(x0, y0, w, h, out.data());
  return out;
}

bool same_floats(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

// A window read with the direct reader on and off: both reads succeed and give the same bits;
// the direct read is returned.
std::vector<float> expect_same_both_ways(const fs::path& path, int x0, int y0, int w, int h) {
  Status on, off;
  const std::vector<float> direct = source_window(path, true, x0, y0, w, h, on);
  const std::vector<float> gdal = source_window(path, false, x0, y0, w, h, off);
  EXPECT_TRUE(on.ok()) << on.message;
  EXPECT_TRUE(off.ok()) << off.message;
  EXPECT_TRUE(same_floats(direct, gdal)) << path;
  return direct;
}

TEST(TiffBlocks, SparseAndDamagedBlocksAreReadByGdal) {
  const fs::path dir = scratch_dir("TiffBlocks.SparseAndDamagedBlocksAreReadByGdal");
  GDALAllRegister();
  // Sparse: two of four 128 x 128 tiles written, the others absent from the file.
  const fs::path sparse = dir / "sparse.tif";
  {
    const char* opts[] = {"TILED=YES", "BLOCKXSIZE=128", "BLOCKYSIZE=128", "COMPRESS=ZSTD", "PREDICTOR=3",
                          "SPARSE_OK=TRUE", nullptr};
    std::unique_ptr<GDALDataset> ds(GetGDALDriverManager()->GetDriverByName("GTiff")->Create(
        sparse.c_str(), 256, 256, 1, GDT_Float32, const_cast<char**>(opts)));
    ASSERT_TRUE(ds);
    ds->GetRasterBand(1)->SetNoDataValue(-9999);
    std::vector<float> tile(128 * 128);
    for (size_t i = 0; i < tile.size(); ++i) tile[i] = 500.0f + float(i % 97) * 0.25f;
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 128, 128, tile.data(), 128, 128, GDT_Float32, 0, 0, nullptr),
              CE_None);
    ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 128, 128, 128, 128, tile.data(), 128, 128, GDT_Float32, 0, 0,
                                             nullptr),
              CE_None);
  }
  std::unique_ptr<cook::TiffBlockReader> reader;
  ASSERT_TRUE(cook::TiffBlockReader::open(sparse.string(), 256, 256, 4, reader).ok());
  std::vector<uint8_t> slots(256 * 256 * 4);
  EXPECT_TRUE(reader->read_window(0, 0, 128, 128, slots.data(), 1)) << "a written tile";
  EXPECT_FALSE(reader->read_window(0, 0, 256, 256, slots.data(), 1)) << "a window over an absent tile";
  const std::vector<float> on = expect_same_both_ways(sparse, 60, 60, 150, 150);
  EXPECT_TRUE(std::isnan(on[size_t(149) * 150]) && on[0] == 500.0f + float((60 * 128 + 60) % 97) * 0.25f)
      << "absent tiles are nodata, written ones their heights";

  // Damaged: tile 1's zstd frame header overwritten. Neither reader makes up samples: the window
  // fails with GDAL's message naming the file.
  const fs::path damaged = write_tiff(dir, "damaged", 600, 400, {GDT_Float32, {"TILED=YES", "COMPRESS=ZSTD", "PREDICTOR=3"}});
  std::unique_ptr<cook::TiffBlockReader> good;
  ASSERT_TRUE(cook::TiffBlockReader::open(damaged.string(), 600, 400, 4, good).ok());
  {
    std::fstream f(damaged, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(std::streamoff(good->layout().offsets[1]));
    const std::string junk(8, '\x5a');
    f.write(junk.data(), std::streamsize(junk.size()));
  }
  // A reader opened before the change no longer reads the file (its layout may be stale): GDAL,
  // which holds the file it opened, reads instead.
  fs::last_write_time(damaged, fs::last_write_time(damaged) + std::chrono::seconds(2));
  std::vector<uint8_t> corner(256 * 256 * 4);
  EXPECT_FALSE(good->read_window(0, 0, 256, 256, corner.data(), 1)) << "the file changed since its layout was read";
  std::unique_ptr<cook::TiffBlockReader> reopened;
  ASSERT_TRUE(cook::TiffBlockReader::open(damaged.string(), 600, 400, 4, reopened).ok());
  std::vector<uint8_t> wide(600 * 400 * 4);
  EXPECT_TRUE(reopened->read_window(0, 0, 256, 256, wide.data(), 1)) << "tile 0 is intact";
  EXPECT_FALSE(reopened->read_window(0, 0, 600, 400, wide.data(), 2)) << "tile 1 is not";
  Status st;
  source_window(damaged, true, 0, 0, 600, 400, st);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message.find("damaged.tif"), std::string::npos) << st.message;
}

// --- VRT mosaics read through their tiles (cooker/src/inputs/gdal/vrt_tiles.h) ---

// A w x h Float32 tile whose samples come from f(c, r) (NaN allowed), zstd with predictor 3.
template <class F>
fs::path write_float_tile(const fs::path& dir, const std::string& name, int w, int h, F f) {
  GDALAllRegister();
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  std::unique_ptr<GDALDataset> ds(mem->Create("", w, h, 1, GDT_Float32, nullptr));
  std::vector<float> v(size_t(w) * size_t(h));
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) v[size_t(r) * size_t(w) + size_t(c)] = f(c, r);
  EXPECT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, w, h, v.data(), w, h, GDT_Float32, 0, 0, nullptr), CE_None);
  const char* opts[] = {"TILED=YES", "BLOCKXSIZE=128", "BLOCKYSIZE=128", "COMPRESS=ZSTD", "PREDICTOR=3", nullptr};
  const fs::path path = dir / (name + ".tif");
  std::unique_ptr<GDALDataset> out(GetGDALDriverManager()->GetDriverByName("GTiff")->CreateCopy(
      path.c_str(), ds.get(), FALSE, const_cast<char**>(opts), nullptr, nullptr));
  EXPECT_TRUE(out) << path;
  return path;
}

struct VrtPlace {
  fs::path tile;
  int tw, th;          // the tile's size
  int sx, sy, dx, dy;  // SrcRect and DstRect corners
  int w, h;            // both rectangles' size (DstRect's differs when dw > 0)
  std::optional<std::string> nodata;  // a ComplexSource's NODATA; none: a SimpleSource
  std::string extra = {};             // more XML inside the source
  int dw = 0, dh = 0;                 // DstRect's size when resampled
};

fs::path write_vrt(const fs::path& dir, const std::string& name, int w, int h, const std::string& type,
                   const std::optional<std::string>& band_nodata, const std::vector<VrtPlace>& places) {
  std::string xml = fmt::format("<VRTDataset rasterXSize=\"{}\" rasterYSize=\"{}\">\n", w, h);
  xml += fmt::format("  <VRTRasterBand dataType=\"{}\" band=\"1\">\n", type);
  if (band_nodata) xml += fmt::format("    <NoDataValue>{}</NoDataValue>\n", *band_nodata);
  for (const VrtPlace& p : places) {
    const char* kind = p.nodata ? "ComplexSource" : "SimpleSource";
    xml += fmt::format("    <{}>\n      <SourceFilename relativeToVRT=\"1\">{}</SourceFilename>\n", kind,
                       p.tile.filename().string());
    xml += "      <SourceBand>1</SourceBand>\n";
    xml += fmt::format("      <SourceProperties RasterXSize=\"{}\" RasterYSize=\"{}\" DataType=\"{}\" />\n", p.tw, p.th,
                       type);
    xml += fmt::format("      <SrcRect xOff=\"{}\" yOff=\"{}\" xSize=\"{}\" ySize=\"{}\" />\n", p.sx, p.sy, p.w, p.h);
    xml += fmt::format("      <DstRect xOff=\"{}\" yOff=\"{}\" xSize=\"{}\" ySize=\"{}\" />\n", p.dx, p.dy,
                       p.dw ? p.dw : p.w, p.dh ? p.dh : p.h);
    if (p.nodata) xml += fmt::format("      <NODATA>{}</NODATA>\n", *p.nodata);
    xml += p.extra;
    xml += fmt::format("    </{}>\n", kind);
  }
  xml += "  </VRTRasterBand>\n</VRTDataset>\n";
  const fs::path path = dir / (name + ".vrt");
  std::ofstream(path) << xml;
  return path;
}

// Every window (the whole raster and 40 random ones) read by the reader equals GDAL's VRT read
// bit for bit; `tiles_refused`: windows that touch a tile the block reader leaves to GDAL fail.
void expect_windows_are_gdals(const fs::path& vrt, int bps, int* composed_reads = nullptr) {
  SCOPED_TRACE(vrt.filename().string());
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(vrt.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  ASSERT_TRUE(ds);
  const int W = ds->GetRasterXSize(), H = ds->GetRasterYSize();
  std::unique_ptr<cook::VrtTileReader> reader;
  const Status opened = cook::VrtTileReader::open(vrt.string(), W, H, reader);
  ASSERT_TRUE(opened.ok() && reader) << opened.to_string();
  std::mt19937 rng(11);
  int checked = 0;
  for (int k = 0; k < 41; ++k) {
    int x0 = 0, y0 = 0, w = W, h = H;
    if (k > 0) {
      x0 = int(rng() % uint32_t(W));
      y0 = int(rng() % uint32_t(H));
      w = 1 + int(rng() % uint32_t(W - x0));
      h = 1 + int(rng() % uint32_t(H - y0));
    }
    std::vector<uint8_t> mine(size_t(w) * size_t(h) * 4, 0xAB);
    ASSERT_TRUE(reader->read_window(x0, y0, w, h, mine.data(), 2)) << x0 << "," << y0 << " " << w << "x" << h;
    EXPECT_TRUE(same_samples(mine, gdal_window(*ds, x0, y0, w, h), bps))
        << "window " << w << "x" << h << " at (" << x0 << ", " << y0 << ")";
    ++checked;
  }
  EXPECT_EQ(checked, 41);
  if (composed_reads) *composed_reads = checked;
}

// Each case twice: with the default number of open tile readers, and with one (each tile is
// closed and opened again within a read and between reads: the same samples).
TEST(TiffBlocks, VrtWindowsAreGdalsBitForBit) {
  const fs::path dir = scratch_dir("TiffBlocks.VrtWindowsAreGdalsBitForBit");
  GDALAllRegister();
  for (const size_t limit : {size_t(16384), size_t(1)}) {
    SCOPED_TRACE(fmt::format("{} open tile readers", limit));
    const size_t before = cook::VrtTileReader::set_open_tile_limit(limit);
    const Layout f32{GDT_Float32, {"TILED=YES", "BLOCKXSIZE=128", "BLOCKYSIZE=128", "COMPRESS=ZSTD", "PREDICTOR=3"}};
    const fs::path a = write_tiff(dir, "a", 300, 200, f32), b = write_tiff(dir, "b", 300, 200, f32),
                   c = write_tiff(dir, "c", 300, 200, f32);
    // gdalbuildvrt's layout: tiles side by side, ComplexSource NODATA = the band's nodata, a gap
    // (the fourth quarter) left at the band's nodata.
    expect_windows_are_gdals(write_vrt(dir, "side_by_side", 600, 400, "Float32", "-9999",
                                       {{a, 300, 200, 0, 0, 0, 0, 300, 200, "-9999"},
                                        {b, 300, 200, 0, 0, 300, 0, 300, 200, "-9999"},
                                        {c, 300, 200, 0, 0, 0, 200, 300, 200, "-9999"}}),
                             4);
    // Overlaps: a tile of exact nodata, values a few ulps from it (GDAL's ARE_REAL_EQUAL counts them
    // as nodata), values just beyond, NaN and data, drawn over others with NODATA -9999, with NaN
    // as NODATA, and as a SimpleSource (drawn whole); part of a tile (SrcRect inside it).
    const fs::path odd = write_float_tile(dir, "odd", 200, 150, [](int col, int row) {
      switch ((col / 7 + row / 5) % 6) {
        case 0: return -9999.0f;
        case 1: return std::nextafter(std::nextafter(-9999.0f, 0.0f), 0.0f);  // 2 ulps off: nodata to GDAL
        case 2: return -9998.99f;                                              // data
        case 3: return NAN;
        default: return float(col * 0.25 - row * 1.5);
      }
    });
    expect_windows_are_gdals(write_vrt(dir, "overlaps", 600, 400, "Float32", "-9999",
                                       {{a, 300, 200, 0, 0, 0, 0, 300, 200, "-9999"},
                                        {odd, 200, 150, 0, 0, 200, 100, 200, 150, "-9999"},
                                        {b, 300, 200, 0, 0, 300, 0, 300, 200, "-9999"},
                                        {odd, 200, 150, 0, 0, 350, 150, 200, 150, "nan"},
                                        {c, 300, 200, 50, 40, 20, 220, 250, 160, std::nullopt},
                                        {odd, 200, 150, 10, 10, 380, 300, 150, 100, "-9999"}}),
                             4);
    // No band nodata (the window starts at 0), NaN nodata where nothing lies under the tile, sources
    // reaching past the raster's edges (clipped) and one wholly outside it.
    expect_windows_are_gdals(write_vrt(dir, "zero_fill", 500, 300, "Float32", std::nullopt,
                                       {{odd, 200, 150, 0, 0, 0, 0, 200, 150, "nan"},
                                        {odd, 200, 150, 0, 0, 210, 100, 200, 150, "-9999"},
                                        {odd, 200, 150, 0, 0, -60, 220, 200, 150, "-9999"},
                                        {odd, 200, 150, 0, 0, 420, -40, 200, 150, std::nullopt},
                                        {odd, 200, 150, 0, 0, 900, 900, 200, 150, std::nullopt}}),
                             4);
    // 16-bit tiles: Int16 (deflate, predictor 2) with NODATA, UInt16 (LZW) as SimpleSources.
    const Layout i16{GDT_Int16, {"TILED=YES", "BLOCKXSIZE=128", "BLOCKYSIZE=128", "COMPRESS=DEFLATE", "PREDICTOR=2"}};
    const fs::path i1 = write_tiff(dir, "i1", 300, 200, i16), i2 = write_tiff(dir, "i2", 300, 200, i16);
    expect_windows_are_gdals(write_vrt(dir, "int16", 500, 350, "Int16", "-9999",
                                       {{i1, 300, 200, 0, 0, 0, 0, 300, 200, "-9999"},
                                        {i2, 300, 200, 0, 0, 150, 120, 300, 200, "-9999"}}),
                             2);
    const Layout u16{GDT_UInt16, {"COMPRESS=LZW", "PREDICTOR=2"}};
    const fs::path u1 = write_tiff(dir, "u1", 300, 200, u16), u2 = write_tiff(dir, "u2", 300, 200, u16);
    expect_windows_are_gdals(write_vrt(dir, "uint16", 600, 200, "UInt16", std::nullopt,
                                       {{u1, 300, 200, 0, 0, 0, 0, 300, 200, std::nullopt},
                                        {u2, 300, 200, 0, 0, 250, 0, 300, 200, std::nullopt}}),
                             2);
    cook::VrtTileReader::set_open_tile_limit(before);
  }
}

// What the VRT reader leaves to GDAL: sources with arithmetic or resampling are refused at open;
// a tile the block reader does not decode, or one not of the type the VRT says, makes the windows
// over it GDAL's. Either way the
// cooker's source reads what GDAL reads.
TEST(TiffBlocks, VrtsBeyondThePlainCaseAreReadByGdal) {
  const fs::path dir = scratch_dir("TiffBlocks.VrtsBeyondThePlainCaseAreReadByGdal");
  GDALAllRegister();
  const Layout f32{GDT_Float32, {"TILED=YES", "BLOCKXSIZE=128", "BLOCKYSIZE=128", "COMPRESS=ZSTD", "PREDICTOR=3"}};
  const fs::path a = write_tiff(dir, "a", 300, 200, f32);
  const fs::path raw = write_tiff(dir, "raw", 300, 200, {GDT_Float32, {}});  // uncompressed: left to GDAL
  // Int32 samples (as 4 bytes as Float32's) behind a VRT that says Float32: GDAL converts them.
  const fs::path ints = write_tiff(dir, "ints", 300, 200, {GDT_Int32, {"COMPRESS=ZSTD"}});
  struct Case {
    const char* name;
    std::vector<VrtPlace> places;
    bool refused;
  };
  const std::vector<Case> cases = {
      {"scaled", {{a, 300, 200, 0, 0, 0, 0, 300, 200, "-9999", "      <ScaleRatio>2</ScaleRatio>\n"}}, true},
      {"resampled", {{a, 300, 200, 0, 0, 0, 0, 300, 200, "-9999", "", 150, 100}}, true},
      {"uncompressed_tile", {{a, 300, 200, 0, 0, 0, 0, 300, 200, "-9999"}, {raw, 300, 200, 0, 0, 300, 0, 300, 200, "-9999"}},
       false},
      {"tile_of_another_type",
       {{a, 300, 200, 0, 0, 0, 0, 300, 200, "-9999"}, {ints, 300, 200, 0, 0, 300, 0, 300, 200, "-9999"}},
       false}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const fs::path vrt = write_vrt(dir, c.name, 600, 200, "Float32", "-9999", c.places);
    std::unique_ptr<cook::VrtTileReader> reader;
    const Status opened = cook::VrtTileReader::open(vrt.string(), 600, 200, reader);
    const std::string& why = opened.message;
    EXPECT_EQ(!opened.ok(), c.refused) << why;
    EXPECT_EQ(!reader, c.refused) << why;
    EXPECT_EQ(opened.code, c.refused ? Error::unsupported_input : Error::ok) << why;
    {  // The report says who decodes, and why not the cooker.
      std::unique_ptr<cook::SourceRaster> src;
      ASSERT_TRUE(cook::open_gdal_source(vrt.string(), cook::ReadOptions{}, src).ok());
      const std::string& d = src->info().decoder;
      EXPECT_EQ(d.find("read by GDAL's VRT driver"), c.refused ? 0u : std::string::npos) << d;
      if (c.refused) {
        EXPECT_NE(d.find(why), std::string::npos) << d;
      }
    }
    if (reader) {
      std::vector<uint8_t> slots(600 * 200 * 4);
      EXPECT_TRUE(reader->read_window(0, 0, 300, 200, slots.data(), 1));    // a's tile alone
      EXPECT_FALSE(reader->read_window(250, 0, 100, 50, slots.data(), 1));  // touches the tile left to GDAL
    }
    expect_same_both_ways(vrt, 0, 0, 600, 200);
  }
}

// The same archive whichever reader decodes the blocks: a 1 m Float32 square (zstd, predictor 3,
// the layout of 1 m lidar DEMs) made from a shared DEM when there is one, else a synthetic one.
TEST(TiffBlocks, ArchivesAreTheSameWithGdalDecoding) {
  const fs::path dir = scratch_dir("TiffBlocks.ArchivesAreTheSameWithGdalDecoding");
  fs::path input;
  const fs::path real = data_file("kilauea_utm5n.tif");
  if (fs::exists(real)) {
    // As Float32 with the floating-point predictor: the layout of 1 m lidar DEMs.
    input = dir / "kilauea_f32_zstd_p3.tif";
    std::string out;
    ASSERT_TRUE(run_command(fmt::format("gdal_translate -q -ot Float32 -co TILED=YES -co COMPRESS=ZSTD -co PREDICTOR=3 "
                                        "-co BLOCKXSIZE=256 -co BLOCKYSIZE=256 '{}' '{}' 2>&1",
                                        real.string(), input.string()),
                            out))
        << out;
  } else {
    std::cout << "[ note ] " << real << " not found: a synthetic square instead\n";
    input = write_tiff(dir, "synthetic", 1500, 1300,
                       {GDT_Float32, {"TILED=YES", "COMPRESS=ZSTD", "PREDICTOR=3", "BLOCKXSIZE=256", "BLOCKYSIZE=256"}});
  }
  {
    GDALAllRegister();
    std::unique_ptr<GDALDataset> ds(GDALDataset::Open(input.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    ASSERT_TRUE(ds) << input;
    std::unique_ptr<cook::TiffBlockReader> reader;
    const Status st = cook::TiffBlockReader::open(input.string(), ds->GetRasterXSize(), ds->GetRasterYSize(), 4, reader);
    ASSERT_TRUE(st.ok()) << st.to_string();
  }
  std::vector<std::vector<uint8_t>> bytes;
  for (bool direct : {true, false}) {
    DirectSwitch sw(direct);
    cook::CookOptions o;
    o.inputs = {input.string()};
    if (!fs::exists(real)) {  // the synthetic square has no georeferencing: 1 m samples, a local frame
      o.spacing = std::array<double, 2>{1.0, 1.0};
      o.crs = "local";
    }
    o.output = (dir / (direct ? "direct.terrain" : "gdal.terrain")).string();
    o.threads = 2;
    cook::CookReport r;
    const Status st = cook::cook(o, nullptr, r);
    ASSERT_TRUE(st.ok()) << st.message;
    std::ifstream f(o.output, std::ios::binary);
    bytes.emplace_back(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  }
  ASSERT_GT(bytes[0].size(), 1000u);
  EXPECT_TRUE(bytes[0] == bytes[1]) << "archives differ";
}

// The decoded blocks' slab pool (cooker/src/base/slab_pool.h): slots never overlap and keep what is
// written into them, come back for reuse, and return their slabs to the system once free. Sizes:
// 1 MB + 16 is a 512 x 512 Float32 tile with the LZW decoder's slack; a slab holds 16 slots of 64-byte
// aligned size within 2-16 MB, so 15 such tiles per 16 MB slab, and small slots share one of 2 MB.
TEST(SlabPool, SlotsAreDisjointReusedAndReturned) {
  cook::SlabPool pool;
  const size_t tile = (size_t(1) << 20) + 16, small = 4000;
  std::vector<uint8_t*> tiles, smalls;
  for (int i = 0; i < 20; ++i) tiles.push_back(pool.take(tile));
  for (int i = 0; i < 9; ++i) smalls.push_back(pool.take(small));
  struct Span {
    uintptr_t begin, end;
  };
  std::vector<Span> spans;
  for (uint8_t* p : tiles) spans.push_back({uintptr_t(p), uintptr_t(p) + tile});
  for (uint8_t* p : smalls) spans.push_back({uintptr_t(p), uintptr_t(p) + small});
  std::sort(spans.begin(), spans.end(), [](const Span& a, const Span& b) { return a.begin < b.begin; });
  for (size_t i = 0; i < spans.size(); ++i) {
    ASSERT_NE(spans[i].begin, 0u);
    EXPECT_EQ(spans[i].begin % 64, 0u);
    if (i > 0) {
      EXPECT_LE(spans[i - 1].end, spans[i].begin) << "slots overlap";
    }
  }
  // Every byte of every slot written with its slot's number, then read back.
  auto fill = [](std::vector<uint8_t*>& v, size_t n, int salt) {
    for (size_t i = 0; i < v.size(); ++i) std::memset(v[i], int(i * 7 + size_t(salt)) & 0xff, n);
  };
  auto intact = [](std::vector<uint8_t*>& v, size_t n, int salt) {
    for (size_t i = 0; i < v.size(); ++i)
      for (size_t k = 0; k < n; ++k)
        if (v[i][k] != uint8_t((i * 7 + size_t(salt)) & 0xff)) return false;
    return true;
  };
  fill(tiles, tile, 1);
  fill(smalls, small, 2);
  EXPECT_TRUE(intact(tiles, tile, 1));
  EXPECT_TRUE(intact(smalls, small, 2));
  // 20 tiles: two slabs of 16 MB; 9 small slots: one of 2 MB. Touched: the slots handed out, in pages.
  EXPECT_EQ(pool.reserved_bytes(), uint64_t(34) << 20);
  const uint64_t tile_slot = tile + 48, small_slot = 4032;
  auto pages = [](uint64_t b) { return (b + 4095) / 4096 * 4096; };
  EXPECT_EQ(pool.touched_bytes(), pages(15 * tile_slot) + pages(5 * tile_slot) + pages(9 * small_slot));
  // Given back (all but one per slab, which keeps the slabs) and taken again: the same
  // addresses, no new slab. (The lowest and the highest address lie in different slabs.)
  std::sort(tiles.begin(), tiles.end());
  const std::set<uint8_t*> before(tiles.begin() + 1, tiles.end() - 1);
  for (size_t i = 1; i + 1 < tiles.size(); ++i) pool.give(tiles[i]);
  tiles = {tiles.front(), tiles.back()};
  for (int i = 0; i < 18; ++i) tiles.push_back(pool.take(tile));
  EXPECT_EQ(std::set<uint8_t*>(tiles.begin() + 2, tiles.end()), before);
  EXPECT_EQ(pool.reserved_bytes(), uint64_t(34) << 20);
  // A slab whose slots are all free goes back to the system.
  for (uint8_t* p : smalls) pool.give(p);
  EXPECT_EQ(pool.reserved_bytes(), uint64_t(32) << 20);
  for (uint8_t* p : tiles) pool.give(p);
  EXPECT_EQ(pool.reserved_bytes(), 0u);
  EXPECT_EQ(pool.touched_bytes(), 0u);
}

// Threads taking, writing, checking and giving slots at once (run under TSan and ASan in CI): no
// slot is handed to two threads.
TEST(SlabPool, ThreadsNeverShareASlot) {
  cook::SlabPool pool;
  std::atomic<int> clobbered{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      std::mt19937 rng{uint32_t(t)};
      std::vector<uint8_t*> held;
      for (int i = 0; i < 400; ++i) {
        if (held.size() < 12 && (held.empty() || rng() % 3)) {
          uint8_t* p = pool.take(70000);
          std::memset(p, t + 1, 70000);
          held.push_back(p);
        } else {
          const size_t k = rng() % held.size();
          for (size_t b = 0; b < 70000; b += 997)
            if (held[k][b] != uint8_t(t + 1)) ++clobbered;
          pool.give(held[k]);
          held.erase(held.begin() + std::ptrdiff_t(k));
        }
      }
      for (uint8_t* p : held) pool.give(p);
    });
  for (std::thread& th : threads) th.join();
  EXPECT_EQ(clobbered.load(), 0);
  EXPECT_EQ(pool.reserved_bytes(), 0u);
}

// A real DEM cut into 4 compressed tiles (Kilauea: 857 x 793 Int16, so the quarters are unequal) and
// mosaicked by gdalbuildvrt: the same archive whether the VRT is composed from the tiles' blocks or
// read by GDAL's VRT driver, and the report says which.
TEST(TiffBlocks, VrtArchivesAreTheSameWithGdalDecoding) {
  const fs::path real = data_file("kilauea_utm5n.tif");
  TERRAIN_REQUIRE_DATA(real);
  const fs::path dir = scratch_dir("TiffBlocks.VrtArchivesAreTheSameWithGdalDecoding");
  std::string out, list;
  const int w = 857, h = 793, hw = w / 2, hh = h / 2;
  int n = 0;
  for (int x : {0, hw})
    for (int y : {0, hh}) {
      const fs::path tile = dir / fmt::format("tile_{}.tif", n++);
      ASSERT_TRUE(run_command(fmt::format("gdal_translate -q -srcwin {} {} {} {} -co TILED=YES -co COMPRESS=ZSTD "
                                          "-co PREDICTOR=2 '{}' '{}' 2>&1",
                                          x, y, x ? w - hw : hw, y ? h - hh : hh, real.string(), tile.string()),
                              out))
          << out;
      list += " '" + tile.string() + "'";
    }
  const fs::path vrt = dir / "kilauea.vrt";
  ASSERT_TRUE(run_command(fmt::format("gdalbuildvrt -q '{}'{} 2>&1", vrt.string(), list), out)) << out;
  std::vector<std::vector<uint8_t>> bytes;
  for (bool direct : {true, false}) {
    DirectSwitch sw(direct);
    cook::CookOptions o;
    o.inputs = {vrt.string()};
    o.output = (dir / (direct ? "direct.terrain" : "gdal.terrain")).string();
    o.threads = 2;
    cook::CookReport r;
    const Status st = cook::cook(o, nullptr, r);
    ASSERT_TRUE(st.ok()) << st.message;
    ASSERT_EQ(r.input_descriptions.size(), 1u);
    EXPECT_NE(r.input_descriptions[0].find(direct ? "4 tile sources composed by the cooker" : "read by GDAL's VRT driver"),
              std::string::npos)
        << r.input_descriptions[0];
    std::ifstream f(o.output, std::ios::binary);
    bytes.emplace_back(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  }
  ASSERT_GT(bytes[0].size(), 1000u);
  EXPECT_TRUE(bytes[0] == bytes[1]) << "archives differ";
}

}  // namespace
