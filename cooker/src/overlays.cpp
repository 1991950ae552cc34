// --albedo / --holes / --landcover: overlay rasters in any supported CRS, read once and placed in
// the node grid (sampled at node window vertices through SurfaceOverlays, surface_layers.h).
#include "overlays.h"

#include <tiffio.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <unordered_map>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "crs.h"
#include "frame.h"
#include "inputs.h"

namespace terrain::cook {
namespace {
// One overlay raster and its exact mapping from frame metres to its samples (frame.h), so a vertex
// shared by neighbouring nodes samples the same value in each.
struct OverlayRaster {
  Raster raster;               // band 1 (NaN = nodata); positions and CRS
  std::vector<uint8_t> rgb;    // orthophoto: 3 bytes per sample (empty for the mask)
  std::vector<uint8_t> alpha;  // orthophoto: 0 = no data
  SourceMapping mapping;
};

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
        const Raster& m = holes->raster;
        for (int i = 0; i < kWindowSize; ++i) {
          const double c = std::floor(cols[size_t(i)] + 0.5), r = std::floor(rows[size_t(i)] + 0.5);
          const bool inside = c >= 0 && r >= 0 && c < m.width && r < m.height;
          const float v = inside ? m.at(int(c), int(r)) : 0.0f;
          hole[row0 + size_t(i)] = uint8_t(!std::isnan(v) && v != 0.0f);
        }
      }
      if (classes && class_materials) {
        classes->mapping.map_frame_row(y, xs.data(), kWindowSize, cols.data(), rows.data());
        const Raster& m = classes->raster;
        for (int i = 0; i < kWindowSize; ++i) {
          const double c = std::floor(cols[size_t(i)] + 0.5), r = std::floor(rows[size_t(i)] + 0.5);
          uint8_t id = kNoClassMaterial;
          if (c >= 0 && r >= 0 && c < m.width && r < m.height) {
            const float v = m.at(int(c), int(r));
            if (!std::isnan(v)) {
              const auto it = class_material.find(int64_t(std::llround(v)));
              if (it != class_material.end()) id = it->second;
            }
          }
          class_materials[row0 + size_t(i)] = id;
        }
      }
    }
  }

 private:
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
        const size_t k = size_t(r) * size_t(w) + size_t(c);
        if (!o.alpha[k]) continue;
        const double wt = (a ? tx : 1 - tx) * (b ? ty : 1 - ty);
        if (wt <= 0) continue;
        for (int ch = 0; ch < 3; ++ch) sum[ch] += wt * o.rgb[k * 3 + size_t(ch)];
        wsum += wt;
      }
    if (wsum < 0.25) return;  // mostly outside the photo or on nodata: keep the splat colour
    for (int ch = 0; ch < 3; ++ch) out[ch] = uint8_t(std::clamp(std::lround(sum[ch] / wsum), 0L, 255L));
    valid = 1;
  }
};

// Positions and CRS through the DEM reader (read_geotiff), pixels through libtiff's RGBA reader
// (any photometric, 8/16-bit, strips or tiles).
Status read_overlay(const std::string& what, const std::string& path, bool rgb, OverlayRaster& out) {
  if (!(ends_with(path, ".tif") || ends_with(path, ".tiff")))
    return Status::failure(Error::unsupported_input, fmt::format("{} {}: only GeoTIFF (.tif) is supported", what, path));
  ReadOptions ro;
  if (Status st = read_geotiff(path, ro, out.raster); !st.ok())
    return Status::failure(st.code, fmt::format("{}: {}", what, st.message));
  if (!out.raster.geo.valid || out.raster.crs.kind == CrsKind::none)
    return Status::failure(Error::unsupported_input,
                           fmt::format("{} {}: no georeferencing (needs GeoTIFF position and CRS keys; the DEM's "
                                       "--crs/--origin do not apply to it)", what, path));
  if (!rgb) return Status::success();
  std::unique_ptr<TIFF, void (*)(TIFF*)> tif(TIFFOpen(path.c_str(), "r"), [](TIFF* t) { if (t) TIFFClose(t); });
  uint16_t spp = 1;
  if (tif) TIFFGetFieldDefaulted(tif.get(), TIFFTAG_SAMPLESPERPIXEL, &spp);
  if (!tif || spp < 3)
    return Status::failure(Error::unsupported_input,
                           fmt::format("{} {}: expected an RGB image (3 or 4 bands), found {} band(s)", what, path, spp));
  const size_t w = size_t(out.raster.width), h = size_t(out.raster.height);
  std::vector<uint32_t> px(w * h);
  if (!TIFFReadRGBAImageOriented(tif.get(), uint32_t(w), uint32_t(h), px.data(), ORIENTATION_TOPLEFT, 0))
    return Status::failure(Error::io_read, fmt::format("{} {}: cannot decode the RGB samples", what, path));
  out.rgb.resize(w * h * 3);
  out.alpha.resize(w * h);
  for (size_t k = 0; k < w * h; ++k) {
    out.rgb[k * 3 + 0] = uint8_t(TIFFGetR(px[k]));
    out.rgb[k * 3 + 1] = uint8_t(TIFFGetG(px[k]));
    out.rgb[k * 3 + 2] = uint8_t(TIFFGetB(px[k]));
    out.alpha[k] = uint8_t(TIFFGetA(px[k]) != 0 && !std::isnan(out.raster.values[k]));  // NaN: GDAL_NODATA
  }
  out.raster.values.clear();
  out.raster.values.shrink_to_fit();
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

Status load_overlays(const CookOptions& o, const FrameCrs& frame, const std::vector<Material>& palette, double x0,
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
    if (Status st = read_overlay(what, path, rgb, *slot); !st.ok()) return st;
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
  if (Status st = load("--albedo", o.albedo_path, true, ov->albedo); !st.ok()) return st;
  if (Status st = load("--holes", o.holes_path, false, ov->holes); !st.ok()) return st;
  if (!o.landcover_path.empty()) {
    if (Status st = load_class_table(o.landcover_table_path, palette, ov->class_material); !st.ok()) return st;
    if (Status st = load("--landcover", o.landcover_path, false, ov->classes); !st.ok()) return st;
  }
  out = std::move(ov);
  return Status::success();
}

}  // namespace terrain::cook
