#include "dem_nodes.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>

#include <tiffio.h>
#include <zip.h>

namespace terrain::cook::bench {
namespace {

Status fail(const std::string& path, const std::string& what) {
  return Status::failure(Error::io_read, path + ": " + what);
}

struct KnownSpacing {
  const char* file;
  double dx_m, dy_m;
};
// Metres per sample of the shared DEMs (README of /work/shared/data; geographic grids converted at
// the tile centre).
constexpr KnownSpacing kKnown[] = {
    {"kilauea_utm5n.tif", 30.0, 30.0},
    {"tahoe_lidar_bareearth.tif", 0.47, 0.61},
    {"tahoe_lidar_highesthit.tif", 0.47, 0.61},
    {"slovenia_TM1_564_146.tif", 1.0, 1.0},
    {"srtm_oetztal.tif", 63.2, 92.6},
    {"N22W160.hgt.zip", 85.6, 92.6},
    {"N19W155.hgt.zip", 87.4, 92.6},
};

Status load_tiff(const std::string& path, DemRaster& out) {
  TIFFSetWarningHandler(nullptr);
  TIFF* tif = TIFFOpen(path.c_str(), "r");
  if (!tif) return fail(path, "cannot open as TIFF");
  uint32_t w = 0, h = 0;
  uint16_t bps = 0, fmt = SAMPLEFORMAT_INT, spp = 1;
  TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &w);
  TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &h);
  TIFFGetField(tif, TIFFTAG_BITSPERSAMPLE, &bps);
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLEFORMAT, &fmt);
  TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &spp);
  if (spp != 1 || !((bps == 16 && fmt == SAMPLEFORMAT_INT) || (bps == 32 && fmt == SAMPLEFORMAT_IEEEFP))) {
    TIFFClose(tif);
    return fail(path, "expected a 1-band Int16 or Float32 GeoTIFF");
  }
  std::vector<uint8_t> raw(size_t(w) * h * (bps / 8));
  if (TIFFIsTiled(tif)) {
    uint32_t tw = 0, th = 0;
    TIFFGetField(tif, TIFFTAG_TILEWIDTH, &tw);
    TIFFGetField(tif, TIFFTAG_TILELENGTH, &th);
    std::vector<uint8_t> tile(size_t(TIFFTileSize(tif)));
    for (uint32_t ty = 0; ty < h; ty += th)
      for (uint32_t tx = 0; tx < w; tx += tw) {
        if (TIFFReadTile(tif, tile.data(), tx, ty, 0, 0) < 0) {
          TIFFClose(tif);
          return fail(path, "tile read failed");
        }
        for (uint32_t y = 0; y < th && ty + y < h; ++y)
          for (uint32_t x = 0; x < tw && tx + x < w; ++x)
            std::memcpy(&raw[(size_t(ty + y) * w + tx + x) * (bps / 8)], &tile[(size_t(y) * tw + x) * (bps / 8)], bps / 8);
      }
  } else {
    const size_t line = size_t(TIFFScanlineSize(tif));
    for (uint32_t y = 0; y < h; ++y)
      if (TIFFReadScanline(tif, &raw[size_t(y) * line], y, 0) < 0) {
        TIFFClose(tif);
        return fail(path, "scanline read failed");
      }
  }
  TIFFClose(tif);
  out.width = int(w);
  out.height = int(h);
  out.h.assign(size_t(w) * h, 0.0f);
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const size_t src = size_t(y) * w + x, dst = size_t(h - 1 - y) * w + x;  // flip: row 0 south
      float v;
      if (bps == 16) {
        int16_t s;
        std::memcpy(&s, &raw[src * 2], 2);
        v = s == -32768 ? NAN : float(s);
      } else {
        std::memcpy(&v, &raw[src * 4], 4);
        if (!(v > -1e30f && v < 1e30f)) v = NAN;
      }
      out.h[dst] = v;
    }
  return Status::success();
}

Status load_hgt_zip(const std::string& path, DemRaster& out) {
  int err = 0;
  zip_t* z = zip_open(path.c_str(), ZIP_RDONLY, &err);
  if (!z) return fail(path, "cannot open as zip");
  zip_stat_t st;
  if (zip_stat_index(z, 0, 0, &st) != 0 || !(st.valid & ZIP_STAT_SIZE)) {
    zip_close(z);
    return fail(path, "empty zip");
  }
  const int n = int(std::lround(std::sqrt(double(st.size) / 2)));
  if (size_t(n) * n * 2 != st.size || (n != 1201 && n != 3601)) {
    zip_close(z);
    return fail(path, "entry is not a 1201^2 or 3601^2 HGT grid");
  }
  std::vector<uint8_t> raw(st.size);
  zip_file_t* f = zip_fopen_index(z, 0, 0);
  const zip_int64_t got = f ? zip_fread(f, raw.data(), st.size) : -1;
  if (f) zip_fclose(f);
  zip_close(z);
  if (got != zip_int64_t(st.size)) return fail(path, "short read");
  out.width = out.height = n;
  out.h.assign(size_t(n) * n, 0.0f);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const size_t src = (size_t(y) * n + x) * 2;
      const int16_t s = int16_t((raw[src] << 8) | raw[src + 1]);
      out.h[size_t(n - 1 - y) * n + x] = s == -32768 ? NAN : float(s);
    }
  return Status::success();
}

}  // namespace

Status load_dem(const std::string& path, DemRaster& out) {
  const std::string file = std::filesystem::path(path).filename().string();
  out = DemRaster{};
  out.name = file;
  bool known = false;
  for (const KnownSpacing& k : kKnown)
    if (file == k.file) {
      out.dx_m = k.dx_m;
      out.dy_m = k.dy_m;
      known = true;
    }
  if (!known) return Status::failure(Error::unsupported_input, path + ": not one of the shared DEMs this bench knows");
  if (file.size() > 8 && file.substr(file.size() - 8) == ".hgt.zip") return load_hgt_zip(path, out);
  return load_tiff(path, out);
}

uint32_t nodes_across(const DemRaster& dem, uint32_t level, bool y_axis) {
  const double extent = y_axis ? (dem.height - 1) * dem.dy_m : (dem.width - 1) * dem.dx_m;
  return uint32_t(std::ceil(extent / node_size_m(int(level))));
}

void make_dem_node(const DemRaster& dem, uint32_t level, uint32_t nx, uint32_t ny, int step_log2, DemNode& out) {
  out.key = {level, nx, ny};
  out.spacing_m = vertex_spacing_m(int(level));
  out.x0_m = nx * node_size_m(int(level));
  out.y0_m = ny * node_size_m(int(level));
  out.step_log2 = step_log2;
  out.window.assign(size_t(kWindowCount), NAN);
  out.holes.assign(size_t(kWindowCount), 1);
  std::vector<int32_t> units(size_t(kWindowCount), 0);
  const double step = double(1 << step_log2);
  for (int b = 0; b < kWindowSize; ++b)
    for (int a = 0; a < kWindowSize; ++a) {
      const double x = out.x0_m + (a - kWindowMargin) * out.spacing_m, y = out.y0_m + (b - kWindowMargin) * out.spacing_m;
      const double rx = x / dem.dx_m, ry = y / dem.dy_m;
      if (rx < 0 || ry < 0 || rx > dem.width - 1 || ry > dem.height - 1) continue;
      const int ix = std::min(int(rx), dem.width - 2), iy = std::min(int(ry), dem.height - 2);
      const double fx = rx - ix, fy = ry - iy;
      // Samples with zero weight (the vertex on a raster row or column) do not count, so a void
      // only removes the vertices whose interpolation really uses it.
      const bool use_x1 = fx > 0, use_y1 = fy > 0;
      const float v00 = dem.at(ix, iy);
      const float v10 = use_x1 ? dem.at(ix + 1, iy) : 0.0f;
      const float v01 = use_y1 ? dem.at(ix, iy + 1) : 0.0f;
      const float v11 = use_x1 && use_y1 ? dem.at(ix + 1, iy + 1) : 0.0f;
      if (std::isnan(v00) || std::isnan(v10) || std::isnan(v01) || std::isnan(v11)) continue;
      const double v = (1 - fy) * ((1 - fx) * v00 + fx * v10) + fy * ((1 - fx) * v01 + fx * v11);
      // Global quantization lattice: units are multiples of 2^step_log2 (canonical across nodes).
      const int32_t u = int32_t(std::llround(v * 1024.0 / step) * int64_t(1 << step_log2));
      units[size_t(b * kWindowSize + a)] = u;
      out.window[size_t(b * kWindowSize + a)] = units_to_metres_f32(u);
      out.holes[size_t(b * kWindowSize + a)] = 0;
    }
  int32_t lo = INT32_MAX;
  out.hole_vertices = out.data_vertices = 0;
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) {
      const size_t w = size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin);
      if (out.holes[w]) {
        ++out.hole_vertices;
      } else {
        ++out.data_vertices;
        lo = std::min(lo, units[w]);
      }
    }
  if (lo == INT32_MAX) lo = 0;
  out.height_offset = lo;
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) {
      const size_t w = size_t((j + kWindowMargin) * kWindowSize + i + kWindowMargin);
      const int32_t r = out.holes[w] ? 0 : (units[w] - lo) >> step_log2;
      out.node.heights[size_t(j * kHeightSamples + i)] = uint16_t(std::clamp(r, 0, 65535));
    }
}

SurfaceInput DemNode::input(const MaterialRules* rules, BcQuality q) const {
  SurfaceInput in;
  in.key = key;
  in.x0_m = x0_m;
  in.y0_m = y0_m;
  in.spacing_m = spacing_m;
  in.heights_m = window.data();
  in.holes = holes.data();
  in.rules = rules;
  in.bc_quality = q;
  return in;
}

}  // namespace terrain::cook::bench
