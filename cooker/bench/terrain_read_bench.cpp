// terrain-read-bench: decoding a GeoTIFF source as the cook reads it, by the cooker's own block
// reader (cooker/src/inputs/tiff_blocks.h) against GDAL (the baseline it replaces; TERRAIN_TIFF_DIRECT=0)
// and against inflating the same blocks alone (libzstd / libdeflate / the LZW decoder on bytes
// already in memory: the floor any reader pays). Two read patterns: the first pass's (rows of 64 samples across the
// whole width) and the blocks' (2048 x 2048 windows). One decoding thread, so CPU seconds compare
// like with like; medians of --runs. Every read's samples are compared with GDAL's.
//
//   terrain-read-bench DEM.tif... [--runs 5]
#include <libdeflate.h>
#include <sys/resource.h>
#include <zstd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fmt/format.h>
#include <fstream>
#include <vector>

#include "inputs/inputs.h"
#include "inputs/source_raster.h"
#include "inputs/tiff_blocks.h"

using namespace terrain;

namespace {

double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

// The whole source read in `pattern` (0: rows of 64 across the width, 1: 2048 x 2048 windows) by
// the cooker's source with the direct reader on or off; its CPU seconds, and the samples.
double read_source(const std::string& path, bool direct, int pattern, std::vector<float>& all, std::string& error) {
  ::setenv("TERRAIN_TIFF_DIRECT", direct ? "1" : "0", 1);
  std::unique_ptr<cook::SourceRaster> src;
  cook::ReadOptions ro;
  if (Status st = cook::open_gdal_source(path, ro, src); !st.ok()) {
    error = st.message;
    return -1;
  }
  const int w = src->info().width, h = src->info().height;
  all.assign(size_t(w) * size_t(h), 0.0f);
  std::vector<float> win;
  const double c0 = cpu_seconds();
  const int bw = pattern == 0 ? w : 2048, bh = pattern == 0 ? 64 : 2048;
  for (int y = 0; y < h; y += bh)
    for (int x = 0; x < w; x += bw) {
      const int ww = std::min(bw, w - x), wh = std::min(bh, h - y);
      win.resize(size_t(ww) * size_t(wh));
      if (Status st = src->read_window(x, y, ww, wh, win.data()); !st.ok()) {
        error = st.message;
        return -1;
      }
      for (int r = 0; r < wh; ++r)
        std::memcpy(&all[size_t(y + r) * size_t(w) + size_t(x)], &win[size_t(r) * size_t(ww)], size_t(ww) * 4);
    }
  const double cpu = cpu_seconds() - c0;
  ::unsetenv("TERRAIN_TIFF_DIRECT");
  return cpu;
}

// Inflating every block from memory (no predictor, no copy): CPU seconds, or -1 when the file is
// not one the direct reader takes.
double inflate_only(const std::string& path, int w, int h, int bps, std::string& why) {
  std::unique_ptr<cook::TiffBlockReader> reader;
  if (Status st = cook::TiffBlockReader::open(path, w, h, bps, reader); !st.ok()) {
    why = st.message;
    return -1;
  }
  const cook::TiffBlockLayout& l = reader->layout();
  std::ifstream f(path, std::ios::binary);
  std::vector<std::vector<uint8_t>> raw(l.offsets.size());
  for (size_t i = 0; i < raw.size(); ++i) {
    raw[i].resize(l.byte_counts[i]);
    f.seekg(std::streamoff(l.offsets[i]));
    f.read(reinterpret_cast<char*>(raw[i].data()), std::streamsize(raw[i].size()));
  }
  const size_t need = size_t(l.block_w) * size_t(l.block_h) * size_t(l.bytes_per_sample);
  std::vector<uint8_t> out(need + 16);
  ZSTD_DCtx* z = ZSTD_createDCtx();
  libdeflate_decompressor* d = libdeflate_alloc_decompressor();
  const double c0 = cpu_seconds();
  for (const auto& r : raw) {
    // (Strips: the last one is shorter; decoding it against a whole block's size fails early,
    // which understates the floor by at most one strip.)
    if (l.compression == 50000) {
      ZSTD_decompressDCtx(z, out.data(), need, r.data(), r.size());
    } else if (l.compression == 5) {
      cook::lzw_decode(r.data(), r.size(), out.data(), need);
    } else {
      size_t n = 0;
      libdeflate_zlib_decompress(d, r.data(), r.size(), out.data(), need, &n);
    }
  }
  const double cpu = cpu_seconds() - c0;
  ZSTD_freeDCtx(z);
  libdeflate_free_decompressor(d);
  return cpu;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"terrain-read-bench: the cooker's GeoTIFF block reader against GDAL and against inflating alone"};
  std::vector<std::string> dems;
  int runs = 5;
  app.add_option("dems", dems, "GeoTIFF DEMs")->required();
  app.add_option("--runs", runs, "runs per measurement (median)")->check(CLI::Range(1, 100));
  CLI11_PARSE(app, argc, argv);
  cook::init_gdal();
  cook::set_gdal_decode_threads(1);
  fmt::print("{:<28} {:>9} {:>8} {:>10} {:>10} {:>10} {:>8} {}\n", "DEM / pattern", "MB", "inflate", "GDAL s",
             "direct s", "direct/G", "MB/s", "samples");
  int failures = 0;
  for (const std::string& dem : dems) {
    std::string error;
    std::vector<float> a, b;
    for (int pattern : {0, 1}) {
      std::vector<double> gdal, direct, inflate;
      bool same = true;
      for (int r = 0; r < runs; ++r) {
        // GDAL's cache as the cook sizes it for a source it does not hold (128 MB); ours likewise.
        cook::set_gdal_cache_bytes(uint64_t(128) << 20);
        gdal.push_back(read_source(dem, false, pattern, a, error));
        cook::set_tiff_block_cache_bytes(uint64_t(32) << 20);
        direct.push_back(read_source(dem, true, pattern, b, error));
        same = same && a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * 4) == 0;
      }
      if (!error.empty()) {
        fmt::print("{}: {}\n", dem, error);
        ++failures;
        break;
      }
      std::unique_ptr<cook::SourceRaster> src;
      cook::ReadOptions ro;
      (void)cook::open_gdal_source(dem, ro, src);
      const int w = src->info().width, h = src->info().height;
      const int bps = src->info().sample_type.find("16") != std::string::npos ? 2
                      : src->info().sample_type.find("8") != std::string::npos ? 1 : 4;
      std::string why;
      for (int r = 0; r < runs; ++r) inflate.push_back(inflate_only(dem, w, h, bps, why));
      const double mb = double(w) * double(h) * bps / 1e6;
      const std::string name = fmt::format("{} {}", dem.substr(dem.find_last_of('/') + 1), pattern == 0 ? "rows" : "2048^2");
      fmt::print("{:<28} {:>9.1f} {:>8} {:>10.3f} {:>10.3f} {:>10.2f} {:>8.0f} {}\n", name, mb,
                 inflate[0] < 0 ? std::string("-") : fmt::format("{:.3f}", median(inflate)), median(gdal),
                 median(direct), median(direct) / median(gdal), mb / median(direct), same ? "same" : "DIFFER");
      if (inflate[0] < 0) fmt::print("  (not decoded by the cooker: {})\n", why);
      if (!same) ++failures;
    }
  }
  return failures ? 1 : 0;
}
