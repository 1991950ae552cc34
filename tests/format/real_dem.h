// Reads a single-band GeoTIFF (Int16 or Float32, strips or tiles) with libtiff, and builds an
// archive from 129x129 windows of it: level-0 nodes tile the raster (one sample = one vertex), each
// coarser level takes every 2^L-th sample (clamped at the raster edge), so shared vertices are
// canonical by construction. Nodata samples become holes.
#pragma once
#include <tiffio.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "archive_fixture.h"

namespace terrain::test {

struct Dem {
  int width = 0, height = 0;
  std::vector<float> values;  // row 0 = north (file order); NaN = nodata
};

inline bool read_dem(const std::string& path, float nodata, Dem& dem) {
  TIFFSetWarningHandler(nullptr);
  std::unique_ptr<TIFF, void (*)(TIFF*)> tif(TIFFOpen(path.c_str(), "r"), [](TIFF* t) {
    if (t) TIFFClose(t);
  });
  if (!tif) return false;
  uint32_t w = 0, h = 0;
  uint16_t bits = 0, format = SAMPLEFORMAT_UINT, spp = 1;
  TIFFGetField(tif.get(), TIFFTAG_IMAGEWIDTH, &w);
  TIFFGetField(tif.get(), TIFFTAG_IMAGELENGTH, &h);
  TIFFGetField(tif.get(), TIFFTAG_BITSPERSAMPLE, &bits);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_SAMPLEFORMAT, &format);
  TIFFGetFieldDefaulted(tif.get(), TIFFTAG_SAMPLESPERPIXEL, &spp);
  if (spp != 1 || !((bits == 16 && format == SAMPLEFORMAT_INT) || (bits == 32 && format == SAMPLEFORMAT_IEEEFP))) return false;
  dem.width = int(w);
  dem.height = int(h);
  dem.values.assign(size_t(w) * h, 0.0f);
  auto put = [&](const uint8_t* p, uint32_t x, uint32_t y) {
    float v = 0;
    if (bits == 16) {
      int16_t s;
      std::memcpy(&s, p, 2);
      v = float(s);
    } else {
      std::memcpy(&v, p, 4);
    }
    dem.values[size_t(y) * w + x] = (v == nodata) ? NAN : v;
  };
  const uint32_t bytes = bits / 8;
  if (TIFFIsTiled(tif.get())) {
    uint32_t tw = 0, th = 0;
    TIFFGetField(tif.get(), TIFFTAG_TILEWIDTH, &tw);
    TIFFGetField(tif.get(), TIFFTAG_TILELENGTH, &th);
    std::vector<uint8_t> tile(size_t(TIFFTileSize(tif.get())));
    for (uint32_t ty = 0; ty < h; ty += th)
      for (uint32_t tx = 0; tx < w; tx += tw) {
        if (TIFFReadTile(tif.get(), tile.data(), tx, ty, 0, 0) < 0) return false;
        for (uint32_t y = ty; y < std::min(h, ty + th); ++y)
          for (uint32_t x = tx; x < std::min(w, tx + tw); ++x) put(tile.data() + (size_t(y - ty) * tw + (x - tx)) * bytes, x, y);
      }
    return true;
  }
  std::vector<uint8_t> line(size_t(TIFFScanlineSize(tif.get())));
  for (uint32_t y = 0; y < h; ++y) {
    if (TIFFReadScanline(tif.get(), line.data(), y, 0) < 0) return false;
    for (uint32_t x = 0; x < w; ++x) put(line.data() + size_t(x) * bytes, x, y);
  }
  return true;
}

// Canonical units at world sample (sx, sy) (south-up sample coordinates, clamped); NaN -> hole.
inline bool dem_units(const Dem& dem, int64_t sx, int64_t sy, int32_t& units) {
  sx = std::clamp<int64_t>(sx, 0, dem.width - 1);
  sy = std::clamp<int64_t>(sy, 0, dem.height - 1);
  const float v = dem.values[size_t(dem.height - 1 - sy) * size_t(dem.width) + size_t(sx)];
  if (!std::isfinite(v)) return false;
  units = int32_t(std::lround(double(v) * 1024.0 / 32.0)) * 32;
  return true;
}

inline BuiltNode make_dem_node(const Dem& dem, const WorldInfo& w, const NodeKey& key) {
  BuiltNode n = make_synthetic_node(w, key, 5);  // surface layers; heights replaced below
  NodeData& d = *n.data;
  const int64_t stride = int64_t(1) << key.level;
  std::vector<int32_t> units(static_cast<size_t>(kHeightCount));
  std::vector<uint8_t> holes(static_cast<size_t>(kHeightCount));
  int32_t lo = INT32_MAX, hi = INT32_MIN;
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) {
      const size_t k = size_t(j * kHeightSamples + i);
      const int64_t sx = (int64_t(key.x) * 128 + i) * stride, sy = (int64_t(key.y) * 128 + j) * stride;
      holes[k] = dem_units(dem, sx, sy, units[k]) ? 0 : 1;
      if (!holes[k]) {
        lo = std::min(lo, units[k]);
        hi = std::max(hi, units[k]);
      }
    }
  NodeRecord& r = n.record;
  r.height_offset = lo == INT32_MAX ? 0 : lo;
  const int step = w.step_log2[key.level];
  for (size_t k = 0; k < units.size(); ++k)
    d.heights[k] = holes[k] ? 0 : uint16_t(std::min<int64_t>(65535, (units[k] - r.height_offset) >> step));
  r.min_height = lo == INT32_MAX ? r.height_offset : lo;
  r.max_height = hi == INT32_MIN ? r.height_offset : hi;
  const bool any_hole = std::find(holes.begin(), holes.end(), uint8_t(1)) != holes.end();
  r.flags = any_hole ? kNodeFlagHasHoles : 0;
  std::mt19937 rng(key.x * 31 + key.y * 17 + key.level);
  fill_albedo(holes, rng, d);
  for (size_t k = 0; k < d.normals_bc3.size(); ++k) d.normals_bc3[k] = uint8_t((k % 16) * 9 + key.x);  // small archive
  return n;
}

// Keys of the DEM archive: level-0 nodes over the raster's full 128-sample windows and their parents.
inline std::vector<NodeKey> dem_keys(const Dem& dem) {
  std::vector<NodeKey> leaves;
  for (uint32_t y = 0; (y + 1) * 128 < uint32_t(dem.height); ++y)
    for (uint32_t x = 0; (x + 1) * 128 < uint32_t(dem.width); ++x) leaves.push_back({0, x, y});
  return close_tree(leaves);
}

inline Status write_dem_archive(const std::string& path, const Dem& dem, WorldInfo& w, const PayloadOptions& options = {}) {
  w = make_world(1, 1);
  w.step_log2 = {5, 5, 5, 5, 5, 5};
  return write_archive_of(path, w, dem_keys(dem), options, [&](const NodeKey& k) { return make_dem_node(dem, w, k); });
}

}  // namespace terrain::test
