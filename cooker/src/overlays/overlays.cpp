// --albedo / --holes / --landcover: overlay rasters in any supported CRS, opened once (header
// only) and read by windows, block by block: the window a block's frame rectangle maps to, tile by
// tile (or strip by strip) through libtiff, the same decoders as a whole read, so every vertex
// samples the same bits whatever the block size (sampled at node window vertices through
// SurfaceOverlays, surface_layers.h).
#include "overlays/overlays.h"

#include <tiffio.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <charconv>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <optional>
#include <unordered_map>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "frame/crs.h"
#include "frame/frame.h"
#include "inputs/inputs.h"
#include "base/memory_budget.h"
#include "base/sample_window.h"

namespace terrain::cook {
namespace {

std::atomic<uint64_t> g_largest_window{0}, g_windows{0}, g_misses{0};

constexpr ttag_t kTagGdalNodata = 42113;

int on_tiff_error(TIFF*, void* user, const char* module, const char* fmt_, va_list ap) {
  char buf[512];
  std::vsnprintf(buf, sizeof buf, fmt_, ap);
  *static_cast<std::string*>(user) = fmt::format("{}{}{}", module ? module : "", module ? ": " : "", buf);
  return 1;
}
int on_tiff_warning(TIFF*, void*, const char*, const char*, va_list) { return 1; }


// One overlay raster, its exact mapping from frame metres to its samples (frame.h), so a vertex
// shared by neighbouring nodes samples the same value in each, and the window of it in memory.
struct OverlayRaster {
  std::string what, path;
  Raster raster;  // header only (no values): size, positions and CRS
  SourceMapping mapping;
  bool rgb = false;  // orthophoto (libtiff's RGBA decoder) or band-1 values (mask, classes)
  // libtiff's view of the file: band 1 through `tif`, the orthophoto's RGBA through `tif_rgba` (the
  // RGBA decoder switches a JPEG file's colour mode, which must not reach band 1).
  std::unique_ptr<TIFF, void (*)(TIFF*)> tif{nullptr, [](TIFF* t) { if (t) TIFFClose(t); }};
  std::unique_ptr<TIFF, void (*)(TIFF*)> tif_rgba{nullptr, [](TIFF* t) { if (t) TIFFClose(t); }};
  bool band1_needed = true;  // false for an integer orthophoto without nodata: band 1 is never NaN
  std::string tiff_error;
  bool tiled = false;
  uint32_t block_w = 0, block_h = 0;  // a tile, or the width x rows per strip
  uint16_t bits = 0, format = SAMPLEFORMAT_UINT, spp = 1, planar = PLANARCONFIG_CONTIG;
  std::optional<double> nodata;
  // The orthophoto is not stored top-left first (Orientation tag): libtiff's oriented whole-image
  // read is the only one that turns it, so the window is the whole raster, read once.
  bool whole = false;
  uint64_t memory_limit = 0;  // --memory-limit: a window (and its decode buffers) must fit it
  // The window: whole-raster sample indices; band 1 (NaN = nodata) or RGB and alpha.
  SampleRect window;
  std::vector<float> values;
  std::vector<uint8_t> rgb_bytes;  // 3 per sample
  std::vector<uint8_t> alpha;      // 0 = no data
  size_t index(int c, int r) const { return size_t(r - window.r0) * size_t(window.width()) + size_t(c - window.c0); }
  bool in_window(int c, int r) const { return c >= window.c0 && r >= window.r0 && c <= window.c1 && r <= window.r1; }
};

// Band 1 of the block (tile or strip) at (bx, by) into `out` (block_w x rows, NaN = nodata), as
// read_geotiff reads it.
Status read_block_band1(OverlayRaster& o, uint32_t bx, uint32_t by, uint32_t rows, std::vector<uint8_t>& buf,
                        std::vector<float>& out) {
  const int bytes = o.bits / 8;
  const size_t pixel_stride = o.planar == PLANARCONFIG_CONTIG ? size_t(bytes) * o.spp : size_t(bytes);
  const tmsize_t block_bytes = o.tiled ? TIFFTileSize(o.tif.get()) : TIFFStripSize(o.tif.get());
  if (block_bytes <= 0 || size_t(block_bytes) < size_t(rows - 1) * o.block_w * pixel_stride + size_t(o.block_w) * pixel_stride)
    return Status::failure(Error::unsupported_input, fmt::format("{} {}: inconsistent {} size", o.what, o.path,
                                                                  o.tiled ? "tile" : "strip"));
  buf.resize(size_t(block_bytes));
  if (o.tiled) {
    if (TIFFReadEncodedTile(o.tif.get(), TIFFComputeTile(o.tif.get(), bx, by, 0, 0), buf.data(), block_bytes) < 0)
      return Status::failure(Error::io_read, fmt::format("{} {}: cannot decode tile at ({}, {}): {}", o.what, o.path,
                                                         bx, by, o.tiff_error));
  } else {
    const tmsize_t got = TIFFReadEncodedStrip(o.tif.get(), TIFFComputeStrip(o.tif.get(), by, 0), buf.data(), block_bytes);
    if (got < tmsize_t(size_t(rows - 1) * o.block_w * pixel_stride + size_t(o.block_w) * pixel_stride))
      return Status::failure(Error::io_read, fmt::format("{} {}: cannot decode strip at row {}: {}", o.what, o.path, by,
                                                         o.tiff_error.empty() ? "short strip" : o.tiff_error));
  }
  const bool is_float = o.format == SAMPLEFORMAT_IEEEFP;
  const float nodata_f = o.nodata ? float(*o.nodata) : 0.0f;
  out.resize(size_t(o.block_w) * rows);
  for (size_t i = 0; i < out.size(); ++i) {
    const double v = sample_value(buf.data() + i * pixel_stride, o.bits, o.format);
    bool missing = std::isnan(v);
    if (o.nodata) missing = missing || (is_float ? float(v) == nodata_f : v == *o.nodata);
    out[i] = missing ? NAN : float(v);
  }
  return Status::success();
}

// Reads `rect` (clipped to the raster) of `o` into its window, replacing the previous one: the
// tiles or strips that cover it, band 1 and (orthophoto) libtiff's RGBA of each.
Status read_overlay_window(OverlayRaster& o, SampleRect rect) {
  rect = intersect(rect, SampleRect{0, 0, o.raster.width - 1, o.raster.height - 1});
  if (o.whole) rect = SampleRect{0, 0, o.raster.width - 1, o.raster.height - 1};
  // 4 bytes a sample (RGB and alpha, or a float), plus a block's raw, RGBA and float buffers (or
  // the whole-image RGBA of the oriented read), checked before anything is allocated.
  const uint64_t block = uint64_t(o.block_w) * o.block_h;
  const uint64_t need = rect.samples() * 4 + block * (uint64_t(o.bits / 8) * o.spp + 8) +
                        (o.rgb && o.whole ? uint64_t(o.raster.width) * uint64_t(o.raster.height) * 4 : 0);
  if (Status st = check_memory(need, o.memory_limit, fmt::format("{} {}", o.what, o.path),
                               fmt::format("a window of {} samples ({}x{})", format_count(rect.samples()), rect.width(),
                                           rect.height()),
                               "give a smaller --block-roots (the default block size counts the DEM's samples only) "
                               "or a coarser overlay");
      !st.ok())
    return st;
  o.window = rect;
  const size_t n = size_t(rect.samples());
  o.values.clear();
  o.rgb_bytes.clear();
  o.alpha.clear();
  if (o.rgb) {
    o.values.shrink_to_fit();
    o.rgb_bytes.resize(n * 3);
    o.alpha.resize(n);
  } else {
    o.values.resize(n);
  }
  if (rect.empty()) return Status::success();
  g_windows.fetch_add(1, std::memory_order_relaxed);
  uint64_t prev = g_largest_window.load(std::memory_order_relaxed);
  while (prev < rect.samples() && !g_largest_window.compare_exchange_weak(prev, rect.samples())) {
  }
  const int width = o.raster.width, height = o.raster.height;
  std::vector<uint32_t> whole_px;
  if (o.rgb && o.whole) {
    whole_px.resize(size_t(width) * size_t(height));
    if (!TIFFReadRGBAImageOriented(o.tif_rgba.get(), uint32_t(width), uint32_t(height), whole_px.data(), ORIENTATION_TOPLEFT, 0))
      return Status::failure(Error::io_read, fmt::format("{} {}: cannot decode the RGB samples", o.what, o.path));
  }
  std::vector<uint8_t> buf;
  std::vector<float> band1;
  std::vector<uint32_t> px;
  const uint32_t bw = o.block_w, bh = o.block_h;
  for (uint32_t by = uint32_t(rect.r0) / bh * bh; by <= uint32_t(rect.r1); by += bh) {
    const uint32_t rows = std::min(bh, uint32_t(height) - by);
    const uint32_t bx_first = o.tiled ? uint32_t(rect.c0) / bw * bw : 0;
    for (uint32_t bx = bx_first; bx <= uint32_t(rect.c1); bx += bw) {
      const uint32_t cols = std::min(bw, uint32_t(width) - bx);
      if (o.band1_needed) {
        if (Status st = read_block_band1(o, bx, by, rows, buf, band1); !st.ok()) return st;
      } else {
        band1.assign(size_t(bw) * rows, 0.0f);
      }
      // libtiff's RGBA of a tile or strip is bottom-up: the block's row i is px row (rows_px - 1 - i)
      // (a tile keeps its full height, edge tiles included; a strip has the rows it holds).
      uint32_t px_rows = 0;
      if (o.rgb && !o.whole) {
        px.assign(size_t(bw) * bh, 0);
        const int ok = o.tiled ? TIFFReadRGBATile(o.tif_rgba.get(), bx, by, px.data())
                               : TIFFReadRGBAStrip(o.tif_rgba.get(), by, px.data());
        if (!ok) return Status::failure(Error::io_read, fmt::format("{} {}: cannot decode the RGB samples", o.what, o.path));
        px_rows = o.tiled ? bh : rows;
      }
      const int c_lo = std::max(rect.c0, int(bx)), c_hi = std::min(rect.c1, int(bx + cols) - 1);
      const int r_lo = std::max(rect.r0, int(by)), r_hi = std::min(rect.r1, int(by + rows) - 1);
      for (int r = r_lo; r <= r_hi; ++r) {
        const uint32_t i = uint32_t(r) - by;
        for (int c = c_lo; c <= c_hi; ++c) {
          const uint32_t k = uint32_t(c) - bx;
          const float v = band1[size_t(i) * bw + k];
          const size_t w = o.index(c, r);
          if (!o.rgb) {
            o.values[w] = v;
            continue;
          }
          const uint32_t p = o.whole ? whole_px[size_t(r) * size_t(width) + size_t(c)] : px[size_t(px_rows - 1 - i) * bw + k];
          o.rgb_bytes[w * 3 + 0] = uint8_t(TIFFGetR(p));
          o.rgb_bytes[w * 3 + 1] = uint8_t(TIFFGetG(p));
          o.rgb_bytes[w * 3 + 2] = uint8_t(TIFFGetB(p));
          o.alpha[w] = uint8_t(TIFFGetA(p) != 0 && !std::isnan(v));  // NaN: GDAL_NODATA
        }
      }
    }
  }
  return Status::success();
}

// The window of `o` the frame rectangle maps to: its edges through the same batch mapping the
// vertices take (map_frame_row), points 64 m apart (at most 4097 an edge: 256 m on a 1000 km edge,
// where a frame line bends by millimetres in any source CRS), plus 2 samples for the bilinear taps
// and the nearest-sample rounding.
SampleRect frame_rect_window(const OverlayRaster& o, double x0, double y0, double x1, double y1) {
  const int n = int(std::min(4096.0, std::ceil(std::max(x1 - x0, y1 - y0) / 64.0))) + 1;
  std::vector<double> xs(size_t(n) + 1), cols(xs.size()), rows(xs.size());
  double cmin = INFINITY, cmax = -INFINITY, rmin = INFINITY, rmax = -INFINITY;
  auto take = [&](size_t count) {
    for (size_t k = 0; k < count; ++k) {
      cmin = std::min(cmin, cols[k]);
      cmax = std::max(cmax, cols[k]);
      rmin = std::min(rmin, rows[k]);
      rmax = std::max(rmax, rows[k]);
    }
  };
  for (int e = 0; e <= n; ++e) xs[size_t(e)] = x0 + (x1 - x0) * double(e) / n;
  for (double y : {y0, y1}) {
    o.mapping.map_frame_row(y, xs.data(), n + 1, cols.data(), rows.data());
    take(size_t(n) + 1);
  }
  for (int e = 0; e <= n; ++e) {
    const double y = y0 + (y1 - y0) * double(e) / n;
    const double xe[2] = {x0, x1};
    o.mapping.map_frame_row(y, xe, 2, cols.data(), rows.data());
    take(2);
  }
  if (!(std::isfinite(cmin) && std::isfinite(cmax) && std::isfinite(rmin) && std::isfinite(rmax)))
    return SampleRect{0, 0, o.raster.width - 1, o.raster.height - 1};
  // Clamped before the int conversion: a rectangle far outside the raster maps far beyond int.
  auto lo = [](double v, int limit) { return int(std::clamp(std::floor(v) - 2, -1.0, double(limit))); };
  auto hi = [](double v, int limit) { return int(std::clamp(std::ceil(v) + 2, -1.0, double(limit))); };
  return SampleRect{lo(cmin, o.raster.width), lo(rmin, o.raster.height), hi(cmax, o.raster.width),
                    hi(rmax, o.raster.height)};
}

class CookOverlays final : public SurfaceOverlays {
 public:
  std::unique_ptr<OverlayRaster> albedo, holes, classes;
  std::unordered_map<int64_t, uint8_t> class_material;  // class value -> palette index
  bool has_albedo() const override { return albedo != nullptr; }
  bool has_holes() const override { return holes != nullptr; }
  bool has_classes() const override { return classes != nullptr; }

  void sample(double x0, double y0, double spacing, uint8_t* rgb, uint8_t* rgb_valid, uint8_t* hole,
              uint8_t* class_materials) const override {
    std::array<double, kWindowSize> xs, cols, rows;
    for (int i = 0; i < kWindowSize; ++i) xs[size_t(i)] = x0 + (i - kWindowMargin) * spacing;
    for (int j = 0; j < kWindowSize; ++j) {
      const double y = y0 + (j - kWindowMargin) * spacing;
      const size_t row0 = size_t(j) * kWindowSize;
      if (albedo && rgb) {
        albedo->mapping.map_frame_row(y, xs.data(), kWindowSize, cols.data(), rows.data());
        for (int i = 0; i < kWindowSize; ++i)
          sample_rgb(*albedo, cols[size_t(i)], rows[size_t(i)], rgb + (row0 + size_t(i)) * 3, rgb_valid[row0 + size_t(i)]);
      }
      if (holes && hole) {
        holes->mapping.map_frame_row(y, xs.data(), kWindowSize, cols.data(), rows.data());
        for (int i = 0; i < kWindowSize; ++i) {
          const float v = nearest_value(*holes, cols[size_t(i)], rows[size_t(i)]);
          hole[row0 + size_t(i)] = uint8_t(!std::isnan(v) && v != 0.0f);
        }
      }
      if (classes && class_materials) {
        classes->mapping.map_frame_row(y, xs.data(), kWindowSize, cols.data(), rows.data());
        for (int i = 0; i < kWindowSize; ++i) {
          const float v = nearest_value(*classes, cols[size_t(i)], rows[size_t(i)]);
          uint8_t id = kNoClassMaterial;
          if (!std::isnan(v)) {
            const auto it = class_material.find(int64_t(std::llround(v)));
            if (it != class_material.end()) id = it->second;
          }
          class_materials[row0 + size_t(i)] = id;
        }
      }
    }
  }

 private:
  // Band 1 at the nearest sample; outside the raster 0 (no hole, no class); NaN = nodata.
  static float nearest_value(const OverlayRaster& o, double col, double row) {
    const double c = std::floor(col + 0.5), r = std::floor(row + 0.5);
    if (!(c >= 0 && r >= 0 && c < o.raster.width && r < o.raster.height)) return 0.0f;
    if (!o.in_window(int(c), int(r))) {
      g_misses.fetch_add(1, std::memory_order_relaxed);
      return NAN;
    }
    return o.values[o.index(int(c), int(r))];
  }

  // Bilinear in sRGB bytes over the valid taps (an edge or nodata tap drops out of the weights).
  static void sample_rgb(const OverlayRaster& o, double col, double row, uint8_t* out, uint8_t& valid) {
    const int w = o.raster.width, h = o.raster.height;
    const double fc = std::floor(col), fr = std::floor(row);
    valid = 0;
    if (!(fc >= -1 && fr >= -1 && fc < w && fr < h)) return;
    const int c0 = int(fc), r0 = int(fr);
    const double tx = col - fc, ty = row - fr;
    double sum[3] = {0, 0, 0}, wsum = 0;
    for (int b = 0; b <= 1; ++b)
      for (int a = 0; a <= 1; ++a) {
        const int c = c0 + a, r = r0 + b;
        if (c < 0 || r < 0 || c >= w || r >= h) continue;
        if (!o.in_window(c, r)) {
          g_misses.fetch_add(1, std::memory_order_relaxed);
          continue;
        }
        const size_t k = o.index(c, r);
        if (!o.alpha[k]) continue;
        const double wt = (a ? tx : 1 - tx) * (b ? ty : 1 - ty);
        if (wt <= 0) continue;
        for (int ch = 0; ch < 3; ++ch) sum[ch] += wt * o.rgb_bytes[k * 3 + size_t(ch)];
        wsum += wt;
      }
    if (wsum < 0.25) return;  // mostly outside the photo or on nodata: keep the splat colour
    for (int ch = 0; ch < 3; ++ch) out[ch] = uint8_t(std::clamp(std::lround(sum[ch] / wsum), 0L, 255L));
    valid = 1;
  }
};

// Positions and CRS through the DEM reader's header (read_geotiff, no samples); the layout of the
// samples through libtiff (the orthophoto's pixels through libtiff's RGBA decoder: any photometric,
// 8/16-bit, strips or tiles), read later by windows.
Status open_overlay(const std::string& what, const std::string& path, bool rgb, OverlayRaster& out) {
  if (!(ends_with(path, ".tif") || ends_with(path, ".tiff")))
    return Status::failure(Error::unsupported_input, fmt::format("{} {}: only GeoTIFF (.tif) is supported", what, path));
  out.what = what;
  out.path = path;
  out.rgb = rgb;
  ReadOptions ro;
  ro.header_only = true;
  if (Status st = read_geotiff(path, ro, out.raster); !st.ok())
    return Status::failure(st.code, fmt::format("{}: {}", what, st.message));
  if (!out.raster.geo.valid || out.raster.crs.kind == CrsKind::none)
    return Status::failure(Error::unsupported_input,
                           fmt::format("{} {}: no georeferencing (needs GeoTIFF position and CRS keys; the DEM's "
                                       "--crs/--origin do not apply to it)", what, path));
  std::unique_ptr<TIFFOpenOptions, void (*)(TIFFOpenOptions*)> topts(TIFFOpenOptionsAlloc(), TIFFOpenOptionsFree);
  TIFFOpenOptionsSetErrorHandlerExtR(topts.get(), on_tiff_error, &out.tiff_error);
  TIFFOpenOptionsSetWarningHandlerExtR(topts.get(), on_tiff_warning, nullptr);
  out.tif.reset(TIFFOpenExt(path.c_str(), "r", topts.get()));
  if (rgb && out.tif) out.tif_rgba.reset(TIFFOpenExt(path.c_str(), "r", topts.get()));
  if (!out.tif || (rgb && !out.tif_rgba))
    return Status::failure(Error::io_open, fmt::format("{} {}: cannot open as TIFF ({})", what, path, out.tiff_error));
  TIFF* t = out.tif.get();
  TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLESPERPIXEL, &out.spp);
  TIFFGetFieldDefaulted(t, TIFFTAG_BITSPERSAMPLE, &out.bits);
  TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLEFORMAT, &out.format);
  TIFFGetFieldDefaulted(t, TIFFTAG_PLANARCONFIG, &out.planar);
  if (rgb && out.spp < 3)
    return Status::failure(Error::unsupported_input,
                           fmt::format("{} {}: expected an RGB image (3 or 4 bands), found {} band(s)", what, path, out.spp));
  // GDAL_NODATA: read_geotiff (above) registered the tag with libtiff for the whole process.
  char* text = nullptr;
  if (TIFFGetField(t, kTagGdalNodata, &text) && text) {
    char* end = nullptr;
    const double v = std::strtod(text, &end);
    if (end != text) out.nodata = v;
    else if (std::strstr(text, "nan") || std::strstr(text, "NaN")) out.nodata = NAN;
  }
  out.tiled = TIFFIsTiled(t);
  const uint32_t height = uint32_t(out.raster.height);
  if (out.tiled) {
    TIFFGetField(t, TIFFTAG_TILEWIDTH, &out.block_w);
    TIFFGetField(t, TIFFTAG_TILELENGTH, &out.block_h);
  } else {
    uint32_t rows_per_strip = height;
    TIFFGetFieldDefaulted(t, TIFFTAG_ROWSPERSTRIP, &rows_per_strip);
    out.block_w = uint32_t(out.raster.width);
    out.block_h = std::min(std::max(rows_per_strip, 1u), height);
  }
  if (out.block_w == 0 || out.block_h == 0)
    return Status::failure(Error::unsupported_input, fmt::format("{} {}: inconsistent tile size", what, path));
  if (rgb) {
    char emsg[1024] = "";
    if (!TIFFRGBAImageOK(out.tif_rgba.get(), emsg))
      return Status::failure(Error::io_read, fmt::format("{} {}: cannot decode the RGB samples ({})", what, path, emsg));
    uint16_t orientation = ORIENTATION_TOPLEFT;
    TIFFGetFieldDefaulted(t, TIFFTAG_ORIENTATION, &orientation);
    out.whole = orientation != ORIENTATION_TOPLEFT;
    out.band1_needed = out.nodata.has_value() || out.format == SAMPLEFORMAT_IEEEFP;
  }
  return Status::success();
}

// --landcover-table: {"classes": {"<integer class>": "<palette name>" or <palette index>, ...}}.
Status load_class_table(const std::string& path, const std::vector<Material>& palette,
                        std::unordered_map<int64_t, uint8_t>& out) {
  std::ifstream f(path);
  if (!f) return Status::failure(Error::io_open, fmt::format("--landcover-table {}: cannot open", path));
  nlohmann::json j;
  try {
    f >> j;
  } catch (const std::exception& e) {
    return Status::failure(Error::invalid_argument, fmt::format("--landcover-table {}: not valid JSON ({})", path, e.what()));
  }
  if (!j.is_object() || !j.contains("classes") || !j["classes"].is_object() || j["classes"].empty())
    return Status::failure(Error::invalid_argument,
                           fmt::format("--landcover-table {}: expected {{\"classes\": {{\"<class>\": \"<material>\", ...}}}}", path));
  for (const auto& [key, value] : j["classes"].items()) {
    int64_t cls = 0;
    const auto [p, ec] = std::from_chars(key.data(), key.data() + key.size(), cls);
    if (ec != std::errc() || p != key.data() + key.size())
      return Status::failure(Error::invalid_argument,
                             fmt::format("--landcover-table {}: class '{}' is not an integer", path, key));
    int id = -1;
    if (value.is_number_integer()) {
      id = value.get<int>();
    } else if (value.is_string()) {
      for (size_t m = 0; m < palette.size(); ++m)
        if (palette[m].name == value.get<std::string>()) id = int(m);
    }
    if (id < 0 || id >= int(palette.size()) || id == kNoClassMaterial) {
      std::string names;
      for (const Material& m : palette) names += (names.empty() ? "" : ", ") + m.name;
      return Status::failure(Error::invalid_argument,
                             fmt::format("--landcover-table {}: class {}: {} is not a material of the palette ({})", path,
                                         key, value.dump(), names));
    }
    out[cls] = uint8_t(id);
  }
  return Status::success();
}

}  // namespace

Status load_overlays(const OverlayOptions& o, const FrameCrs& frame, const std::vector<Material>& palette, double x0,
                     double y0, double x1, double y1, int threads, std::unique_ptr<SurfaceOverlays>& out) {
  if (o.landcover_path.empty() != o.landcover_table_path.empty())
    return Status::failure(Error::invalid_argument, "--landcover and --landcover-table go together");
  if (o.albedo_path.empty() && o.holes_path.empty() && o.landcover_path.empty()) return Status::success();
  if (o.heights_only)
    return Status::failure(Error::invalid_argument,
                           "--albedo, --holes and --landcover need the surface layers (drop --heights-only)");
  auto ov = std::make_unique<CookOverlays>();
  auto load = [&](const char* what, const std::string& path, bool rgb, std::unique_ptr<OverlayRaster>& slot) -> Status {
    if (path.empty()) return Status::success();
    slot = std::make_unique<OverlayRaster>();
    slot->memory_limit = o.memory_limit_bytes;
    TERRAIN_TRY(open_overlay(what, path, rgb, *slot));
    if (Status st = slot->mapping.init(slot->raster, frame, threads); !st.ok())
      return Status::failure(st.code, fmt::format("{} {}: {}", what, path, st.message));
    slot->mapping.cover_frame_area(x0, y0, x1, y1, threads);
    // It must overlap the archive: map the frame rectangle's corners and centre into it.
    bool overlap = false;
    for (double fx : {x0, 0.5 * (x0 + x1), x1})
      for (double fy : {y0, 0.5 * (y0 + y1), y1}) {
        double c = 0, r = 0;
        slot->mapping.exact_frame_to_sample(fx, fy, c, r);
        overlap = overlap || (c >= -0.5 && r >= -0.5 && c < slot->raster.width && r < slot->raster.height);
      }
    double fx0 = 0, fy0 = 0, fx1 = 0, fy1 = 0;
    slot->mapping.frame_bounds(0, 0, slot->raster.width - 1, slot->raster.height - 1, 0.5, fx0, fy0, fx1, fy1);
    overlap = overlap || (fx0 < x1 && fx1 > x0 && fy0 < y1 && fy1 > y0);
    if (!overlap)
      return Status::failure(Error::no_data, fmt::format("{} {}: does not overlap the DEM ({})", what, path,
                                                         describe_crs(slot->raster.crs)));
    return Status::success();
  };
  TERRAIN_TRY(load("--albedo", o.albedo_path, true, ov->albedo));
  TERRAIN_TRY(load("--holes", o.holes_path, false, ov->holes));
  if (!o.landcover_path.empty()) {
    TERRAIN_TRY(load_class_table(o.landcover_table_path, palette, ov->class_material));
    TERRAIN_TRY(load("--landcover", o.landcover_path, false, ov->classes));
  }
  out = std::move(ov);
  return Status::success();
}

Status prepare_overlays_block(SurfaceOverlays& ov, double x0, double y0, double x1, double y1) {
  auto& cook_ov = static_cast<CookOverlays&>(ov);
  for (OverlayRaster* o : {cook_ov.albedo.get(), cook_ov.holes.get(), cook_ov.classes.get()}) {
    if (!o) continue;
    // The whole-raster fallback reads once.
    if (o->whole && !o->window.empty()) continue;
    TERRAIN_TRY(read_overlay_window(*o, frame_rect_window(*o, x0, y0, x1, y1)));
  }
  return Status::success();
}

OverlayWindowStats overlay_window_stats() {
  return {g_largest_window.load(), g_windows.load(), g_misses.load()};
}

void reset_overlay_window_stats() {
  g_largest_window = 0;
  g_windows = 0;
  g_misses = 0;
}

}  // namespace terrain::cook
