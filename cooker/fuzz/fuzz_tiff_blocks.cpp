// libFuzzer target (CMake option TERRAIN_FUZZ, clang): arbitrary bytes as a GeoTIFF for the
// cooker's own block reader (cooker/src/inputs/tiff_blocks.h), without GDAL. Whatever the layout and the
// blocks say, open() either refuses or gives a reader whose windows decode or return false: no
// read outside the file or a block, no crash, and where libtiff decodes every block too, its
// samples (GDAL reads GeoTIFFs through libtiff). The first corpus directory, when empty, is filled
// with seeds written by libtiff (Float32 zstd predictor 3 tiles, Int16 deflate predictor 2 strips,
// UInt16 zstd tiles, Float32 LZW predictor 3 tiles, Int16 LZW predictor 2 strips).
#include <tiffio.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstdarg>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "inputs/tiff_blocks.h"

namespace {

std::string g_file;  // this process's scratch file

void quiet(const char*, const char*, va_list) {}

std::vector<uint8_t> slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

// A w x h seed: tiles of t x t (0: strips of 3 rows), compression and predictor as given.
std::vector<uint8_t> seed(int w, int h, int t, int bits, int format, int compression, int predictor) {
  TIFF* tif = TIFFOpen(g_file.c_str(), "w");
  if (!tif) return {};
  TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, w);
  TIFFSetField(tif, TIFFTAG_IMAGELENGTH, h);
  TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, 1);
  TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, bits);
  TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, format);
  TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
  TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
  TIFFSetField(tif, TIFFTAG_COMPRESSION, compression);
  TIFFSetField(tif, TIFFTAG_PREDICTOR, predictor);
  const int bps = bits / 8;
  auto value = [&](int x, int y, uint8_t* out) {
    const double z = 100 + 40 * std::sin(x * 0.3) * std::cos(y * 0.2) + x * 0.5;
    if (format == SAMPLEFORMAT_IEEEFP) {
      const float f = float(z);
      std::memcpy(out, &f, 4);
    } else {
      const uint16_t v = uint16_t(int(z * 10));
      std::memcpy(out, &v, 2);
    }
  };
  if (t > 0) {
    TIFFSetField(tif, TIFFTAG_TILEWIDTH, t);
    TIFFSetField(tif, TIFFTAG_TILELENGTH, t);
    std::vector<uint8_t> tile(size_t(t) * size_t(t) * size_t(bps));
    for (int ty = 0; ty < h; ty += t)
      for (int tx = 0; tx < w; tx += t) {
        for (int y = 0; y < t; ++y)
          for (int x = 0; x < t; ++x) value(tx + x, ty + y, &tile[(size_t(y) * size_t(t) + size_t(x)) * size_t(bps)]);
        TIFFWriteTile(tif, tile.data(), uint32_t(tx), uint32_t(ty), 0, 0);
      }
  } else {
    TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, 3);
    std::vector<uint8_t> row(size_t(w) * size_t(bps));
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) value(x, y, &row[size_t(x) * size_t(bps)]);
      TIFFWriteScanline(tif, row.data(), uint32_t(y), 0);
    }
  }
  TIFFClose(tif);
  return slurp(g_file);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
  g_file = (std::filesystem::current_path() / ("fuzz-tiff-" + std::to_string(getpid()) + ".tif")).string();
  TIFFSetErrorHandler(quiet);
  TIFFSetWarningHandler(quiet);
  for (int i = 1; i < *argc; ++i) {
    const std::filesystem::path corpus = (*argv)[i];
    if ((*argv)[i][0] == '-' || !std::filesystem::is_directory(corpus)) continue;
    if (std::filesystem::is_empty(corpus)) {
      const std::vector<std::vector<uint8_t>> seeds = {
          seed(40, 37, 16, 32, SAMPLEFORMAT_IEEEFP, COMPRESSION_ZSTD, PREDICTOR_FLOATINGPOINT),
          seed(33, 20, 0, 16, SAMPLEFORMAT_INT, COMPRESSION_ADOBE_DEFLATE, PREDICTOR_HORIZONTAL),
          seed(50, 50, 32, 16, SAMPLEFORMAT_UINT, COMPRESSION_ZSTD, PREDICTOR_NONE),
          seed(45, 40, 16, 32, SAMPLEFORMAT_IEEEFP, COMPRESSION_LZW, PREDICTOR_FLOATINGPOINT),
          seed(37, 21, 0, 16, SAMPLEFORMAT_INT, COMPRESSION_LZW, PREDICTOR_HORIZONTAL)};
      int k = 0;
      for (const auto& s : seeds) {
        std::ofstream f(corpus / ("seed" + std::to_string(k++)), std::ios::binary);
        f.write(reinterpret_cast<const char*>(s.data()), std::streamsize(s.size()));
      }
    }
    break;
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  {
    std::ofstream f(g_file, std::ios::binary | std::ios::trunc);
    f.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  // The size GDAL would report: the first image's, from libtiff.
  uint32_t w = 0, h = 0;
  uint16_t bits = 0;
  if (TIFF* tif = TIFFOpen(g_file.c_str(), "r")) {
    TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &w);
    TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &h);
    TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &bits);
    TIFFClose(tif);
  }
  if (w == 0 || h == 0 || w > 4096 || h > 4096) return 0;
  std::unique_ptr<terrain::cook::TiffBlockReader> reader;
  if (!terrain::cook::TiffBlockReader::open(g_file, int(w), int(h), bits / 8, reader).ok()) return 0;
  terrain::cook::set_tiff_block_cache_bytes(uint64_t(1) << 20);
  std::vector<uint8_t> slots(size_t(w) * size_t(h) * 4);
  const bool ours = reader->read_window(0, 0, int(w), int(h), slots.data(), 2);
  std::vector<uint8_t> part(slots.size());
  reader->read_window(int(w) / 2, int(h) / 3, int(w) - int(w) / 2, int(h) - int(h) / 3, part.data(), 1);
  // Where libtiff decodes every block too, the samples must be libtiff's (GDAL reads through it).
  const terrain::cook::TiffBlockLayout& l = reader->layout();
  if (!ours || uint64_t(l.block_w) * uint64_t(l.block_h) > (uint64_t(1) << 22)) return 0;
  TIFF* tif = TIFFOpen(g_file.c_str(), "r");
  if (!tif) return 0;
  const size_t bps = size_t(l.bytes_per_sample), block_bytes = size_t(l.block_w) * size_t(l.block_h) * bps;
  std::vector<uint8_t> block(block_bytes);
  const int across = (l.width + l.block_w - 1) / l.block_w;
  bool same = true, decoded = true;
  for (size_t i = 0; i < l.offsets.size() && decoded; ++i) {
    const int bx = int(i % size_t(across)), by = int(i / size_t(across));
    const int rows = l.tiled ? l.block_h : std::min(l.block_h, l.height - by * l.block_h);
    const tmsize_t want = tmsize_t(size_t(rows) * size_t(l.block_w) * bps);
    const tmsize_t got = l.tiled ? TIFFReadEncodedTile(tif, uint32_t(i), block.data(), tmsize_t(block_bytes))
                                 : TIFFReadEncodedStrip(tif, uint32_t(i), block.data(), want);
    if (got != want) {
      decoded = false;
      break;
    }
    for (int r = 0; r < rows && by * l.block_h + r < l.height; ++r)
      for (int c = 0; c < l.block_w && bx * l.block_w + c < l.width; ++c) {
        const size_t at = (size_t(by * l.block_h + r) * size_t(w) + size_t(bx * l.block_w + c)) * 4;
        same = same && std::memcmp(&slots[at], &block[(size_t(r) * size_t(l.block_w) + size_t(c)) * bps], bps) == 0;
      }
  }
  TIFFClose(tif);
  if (decoded && !same) {
    std::fprintf(stderr, "fuzz_tiff_blocks: samples differ from libtiff's\n");
    std::abort();
  }
  return 0;
}
