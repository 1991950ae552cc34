// cook(): read -> mosaic -> voids -> frame and grid -> steps -> pyramid -> finish, timed per stage.
#include <sys/resource.h>
#include <tiffio.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <fstream>
#include <memory>
#include <unordered_map>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "crs.h"
#include "frame.h"
#include "inputs.h"
#include "memory_budget.h"
#include "mosaic.h"
#include "node_cook.h"
#include "parallel.h"
#include "pyramid.h"
#include "range_index.h"
#include "terrain/archive_reader.h"
#include "terrain/cook.h"
#include "void_fill.h"

namespace terrain::cook {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

constexpr double kRootSizeM = node_size_m(kRootLevel);

const char* policy_name(NodataPolicy p) {
  switch (p) {
    case NodataPolicy::automatic: return "auto";
    case NodataPolicy::hole: return "hole";
    case NodataPolicy::fill: return "fill";
  }
  return "?";
}

// Finest level allowed by default: vertex spacing at least 1/32 of the source sample spacing.
// Refinement is error-driven, so this only bounds it: bilinear vertices must come within the
// tolerance of a Catmull-Rom surface through coarse samples, and on the shared 21-90 m DEMs the
// tolerance of 0.5 m was met at 2-4 m spacing (1/10 to 1/32 of the source) where the relief is
// steep; flat areas stop at the roots.
int finest_level_for(double source_spacing_m) {
  for (int level = 0; level < kRootLevel; ++level)
    if (vertex_spacing_m(level) >= source_spacing_m / 32.0) return level;
  return kRootLevel;
}

std::string cook_info(const CookOptions& o, const CookReport& r, const std::vector<std::string>& descriptions) {
  nlohmann::ordered_json j;
  j["tool"] = "terrain-cook";
  j["version"] = "0.1.0";
  nlohmann::ordered_json inputs = nlohmann::ordered_json::array();
  for (size_t i = 0; i < o.inputs.size(); ++i)
    inputs.push_back({{"path", o.inputs[i]}, {"description", i < descriptions.size() ? descriptions[i] : ""}});
  j["inputs"] = inputs;
  j["options"] = {{"tolerance_m", o.tolerance_m},
                  {"finest_level", o.finest_level},
                  {"crs", o.crs},
                  {"frame", o.frame},
                  {"height_scale", o.height_scale},
                  {"height_offset", o.height_offset},
                  {"nodata", policy_name(o.nodata)},
                  {"fill_max_samples", o.fill_max_samples},
                  {"materials", o.materials_path},
                  {"albedo", o.albedo_path},
                  {"holes", o.holes_path},
                  {"landcover", o.landcover_path},
                  {"landcover_table", o.landcover_table_path},
                  {"heights_only", o.heights_only},
                  {"zstd_level", o.zstd_level},
                  {"surface_zstd_level", o.surface_zstd_level}};
  if (o.origin) j["options"]["origin"] = *o.origin;
  if (o.spacing) j["options"]["spacing"] = *o.spacing;
  if (o.nodata_value) j["options"]["nodata_value"] = *o.nodata_value;
  j["frame_reason"] = r.frame_reason;
  j["reconstruction"] = "Catmull-Rom bicubic in source sample space; bilinear over valid taps next to nodata";
  j["finest_level"] = r.finest_level;
  j["voids_filled_samples"] = r.voids_filled_samples;
  j["hole_samples"] = r.hole_samples;
  return j.dump();
}

// ---- --albedo / --holes / --landcover: rasters in any supported CRS, sampled at node window vertices ----

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

Status load_overlays(const CookOptions& o, const FrameCrs& frame, const std::vector<Material>& palette, double x0,
                     double y0, double x1, double y1, int threads, std::unique_ptr<CookOverlays>& out) {
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

// Nodes stop refining at the finest level allowed, even where the error still exceeds the
// tolerance (coarse sources: Catmull-Rom between 30-100 m samples is not met by bilinear vertices).
std::string unmet_tolerance_warning(const CookReport& r) {
  const int l = r.finest_level;
  std::string why = fmt::format("level {} ({} m vertex spacing) is the finest level allowed", l, vertex_spacing_m(l));
  if (l > 0)
    why += fmt::format(" (from the source spacing {:.3g} m: 1/32 of it, or --finest-level); --finest-level {} lets "
                       "nodes refine further (at the cost of more nodes)", r.source_spacing_m, l - 1);
  else
    why += " and the finest the format has";
  return fmt::format("--tolerance {} m is not met everywhere: the full-detail error reaches {:.3f} m because {}",
                     r.tolerance_m, r.leaf_error_max_m, why);
}

uint64_t peak_rss_bytes() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return uint64_t(u.ru_maxrss) * 1024;
}

}  // namespace

Status cook(const CookOptions& options, const ProgressFn& progress, CookReport& report) {
  report = CookReport{};
  const auto t_start = Clock::now();
  if (options.output.empty()) return Status::failure(Error::invalid_argument, "no output archive given");
  if (!(options.tolerance_m > 0) || !std::isfinite(options.tolerance_m))
    return Status::failure(Error::invalid_argument, "--tolerance must be a positive number of metres");
  if (options.finest_level < -1 || options.finest_level > kRootLevel)
    return Status::failure(Error::invalid_argument, "--finest-level must be 0..5");
  const int threads = resolve_threads(options.threads);
  report.threads = threads;
  report.tolerance_m = options.tolerance_m;
  auto stage = [&](double f, const char* name) { return !progress || progress(f, name); };
  if (!stage(0.0, "reading")) return Status::failure(Error::cancelled, "cancelled");

  // ---- read ----
  std::vector<Raster> rasters;
  if (Status st = load_inputs(options, rasters); !st.ok()) return st;
  std::vector<std::string> descriptions;
  for (const Raster& r : rasters) {
    descriptions.push_back(r.description);
    report.input_descriptions.push_back(fmt::format("{}: {}; {}", r.path, r.description, describe_crs(r.crs)));
    if (const uint64_t n = r.implausible.out_of_range + r.implausible.sentinel; n) {
      report.implausible_samples += n;
      report.warnings.push_back(implausible_heights_warning(r, options.valid_range_m));
    }
  }
  report.memory_limit_bytes = memory_limit_of(options);
  Raster source;
  if (Status st = mosaic(rasters, source, report.memory_limit_bytes); !st.ok()) return st;
  report.source_samples = source.values.size();
  report.seconds_read = seconds_since(t_start);

  // ---- prepare: voids, frame, grid, steps ----
  const auto t_prep = Clock::now();
  int vc0 = 0, vr0 = 0, vc1 = 0, vr1 = 0;
  uint64_t valid = 0;
  if (!valid_bounds(source, vc0, vr0, vc1, vr1, valid))
    return Status::failure(Error::no_data, fmt::format("{}: every sample is nodata; nothing to cook", source.path));
  report.source_valid_samples = valid;
  std::vector<uint8_t> filled;
  VoidStats voids;
  if (Status st = fill_voids(source, options.nodata, options.fill_max_samples, filled, voids, report.memory_limit_bytes);
      !st.ok())
    return st;
  report.voids_filled_samples = voids.filled_samples;
  report.voids_filled_regions = voids.filled_regions;
  report.hole_samples = voids.hole_samples;
  report.hole_regions = voids.hole_regions;
  if (options.nodata == NodataPolicy::fill) valid_bounds(source, vc0, vr0, vc1, vr1, valid);

  FrameCrs frame;
  if (Status st = choose_frame(source, options.frame, frame, report.frame_reason); !st.ok()) return st;
  report.frame = frame;
  SourceMapping mapping;
  if (Status st = mapping.init(source, frame, threads); !st.ok()) return st;
  double fx0 = 0, fy0 = 0, fx1 = 0, fy1 = 0;
  // The footprint: pixel areas, or for point samples the samples' hull.
  mapping.frame_bounds(vc0, vr0, vc1, vr1, source.geo.point_samples ? 0.0 : 0.5, fx0, fy0, fx1, fy1);
  CookContext ctx(source);
  ctx.filled = &filled;
  ctx.mapping = &mapping;
  ctx.origin_x = std::floor(fx0 / kRootSizeM) * kRootSizeM;
  ctx.origin_y = std::floor(fy0 / kRootSizeM) * kRootSizeM;
  const double roots_x = std::ceil((fx1 - ctx.origin_x) / kRootSizeM), roots_y = std::ceil((fy1 - ctx.origin_y) / kRootSizeM);
  if (roots_x * roots_y > 1e7)
    return Status::failure(Error::unsupported_input,
                           fmt::format("the data spans {:.0f} x {:.0f} km in the frame: too large for one archive",
                                       (fx1 - fx0) / 1000, (fy1 - fy0) / 1000));
  if (!options.force && (roots_x * roots_y > double(kMaxPlannedRoots) || roots_x > kStreamerMaxRootsPerSide ||
                         roots_y > kStreamerMaxRootsPerSide))
    return Status::failure(Error::unsupported_input,
                           fmt::format("the plan needs {:.0f} x {:.0f} root nodes (the data spans {:.0f} x {:.0f} km): "
                                       "beyond {} roots or {} per side (terrain-view's limit); check --spacing and "
                                       "the CRS, or give --force", roots_x, roots_y, (fx1 - fx0) / 1000,
                                       (fy1 - fy0) / 1000, kMaxPlannedRoots, kStreamerMaxRootsPerSide));
  report.roots_x = uint32_t(std::max(1.0, roots_x));
  report.roots_y = uint32_t(std::max(1.0, roots_y));
  report.origin_x_m = ctx.origin_x;
  report.origin_y_m = ctx.origin_y;
  report.extent_min_x_m = fx0;
  report.extent_min_y_m = fy0;
  report.extent_max_x_m = fx1;
  report.extent_max_y_m = fy1;
  const double margin = kWindowMargin * vertex_spacing_m(kRootLevel) + kRootSizeM;
  mapping.cover_frame_area(ctx.origin_x - margin, ctx.origin_y - margin,
                           ctx.origin_x + report.roots_x * kRootSizeM + margin,
                           ctx.origin_y + report.roots_y * kRootSizeM + margin, threads);
  double sx = 0, sy = 0;
  mapping.spacing_m(sx, sy);
  report.source_spacing_m = std::min(sx, sy);
  ctx.finest_level = options.finest_level >= 0 ? options.finest_level : finest_level_for(report.source_spacing_m);
  report.finest_level = ctx.finest_level;
  ctx.tolerance_m = options.tolerance_m;
  ctx.source_spacing_m = report.source_spacing_m;
  ctx.heights_only = options.heights_only;
  ctx.payload.zstd_level = options.zstd_level;
  ctx.payload.surface_zstd_level = options.surface_zstd_level;

  RangeIndex index;
  index.build(source);

  // Surface layers: material rules and palette.
  std::shared_ptr<const MaterialRules> rules;
  {
    SurfaceOptions so;
    so.materials_path = options.materials_path;
    so.bc_quality = BcQuality(uint8_t(options.surface_quality));
    ctx.bc_quality = so.bc_quality;
    if (Status st = load_material_rules(so, rules); !st.ok()) return st;
    ctx.rules = rules.get();
    report.surface_layers = !options.heights_only;
  }
  std::unique_ptr<CookOverlays> overlays;
  if (Status st = load_overlays(options, frame, palette_of(*rules), ctx.origin_x - margin, ctx.origin_y - margin,
                                ctx.origin_x + report.roots_x * kRootSizeM + margin,
                                ctx.origin_y + report.roots_y * kRootSizeM + margin, threads, overlays);
      !st.ok())
    return st;
  ctx.overlays = overlays.get();
  report.seconds_prepare = seconds_since(t_prep);

  // ---- pyramid ----
  const auto t_pyr = Clock::now();
  ArchiveWriter writer;
  if (Status st = writer.open(options.output); !st.ok()) return st;
  PyramidStats pyr;
  const ProgressFn sub = progress ? scaled_progress(progress, 0.05, 0.98) : ProgressFn{};
  if (Status st = build_pyramid(ctx, index, report.roots_x, report.roots_y, threads, writer, sub, pyr); !st.ok()) {
    writer.abort();
    return st;
  }
  report.seconds_pyramid = seconds_since(t_pyr);
  if (pyr.nodes == 0) {
    writer.abort();
    return Status::failure(Error::no_data, "no node holds terrain (is the data smaller than a vertex?)");
  }

  // ---- finish ----
  const auto t_fin = Clock::now();
  WorldInfo world;
  world.crs = frame;
  world.origin_x_m = ctx.origin_x;
  world.origin_y_m = ctx.origin_y;
  world.roots_x = report.roots_x;
  world.roots_y = report.roots_y;
  world.extent_min_x_m = fx0;
  world.extent_min_y_m = fy0;
  world.extent_max_x_m = fx1;
  world.extent_max_y_m = fy1;
  world.step_log2 = ctx.step_log2;
  if (rules) world.palette = palette_of(*rules);
  world.cook_info_json = cook_info(options, report, descriptions);
  if (Status st = writer.finish(world); !st.ok()) return st;
  report.archive_bytes = writer.bytes_written();
  {
    ArchiveReader reader;
    SectionBytes sb;
    if (reader.open(options.output).ok() && reader.section_bytes(sb).ok())
      for (int s = 0; s < 5; ++s) {
        report.section_stored_bytes[size_t(s)] = sb.stored[s];
        report.section_raw_bytes[size_t(s)] = sb.raw[s];
      }
  }
  report.seconds_finish = seconds_since(t_fin);

  report.levels = pyr.levels;
  report.nodes = pyr.nodes;
  report.leaf_error_max_m = pyr.leaf.max_m;
  report.leaf_error_samples = pyr.leaf.samples;
  report.leaf_error_rms_m = pyr.leaf.samples ? std::sqrt(pyr.leaf.sum_sq / double(pyr.leaf.samples)) : 0.0;
  report.cpu_heights = pyr.cpu_heights;
  report.cpu_error = pyr.cpu_error;
  report.cpu_surface = pyr.cpu_surface;
  report.cpu_encode = pyr.cpu_encode;
  report.output_vertices = pyr.output_vertices;
  report.seconds_total = seconds_since(t_start);
  report.source_samples_per_second = double(report.source_samples) / report.seconds_total;
  report.height_samples_per_cpu_second = pyr.cpu_heights > 0 ? double(pyr.output_vertices) / pyr.cpu_heights : 0;
  report.peak_rss_bytes = peak_rss_bytes();
  if (pyr.surface.normal_samples) {
    report.normal_err_max_deg = pyr.surface.normal_err_max_deg;
    report.normal_err_mean_deg = pyr.surface.normal_err_sum_deg / double(pyr.surface.normal_samples);
  }
  if (pyr.surface.albedo_samples && pyr.surface.albedo_sq_err_sum > 0)
    report.albedo_psnr_db =
        10.0 * std::log10(255.0 * 255.0 / (pyr.surface.albedo_sq_err_sum / double(pyr.surface.albedo_samples)));
  if (report.leaf_error_max_m > options.tolerance_m) report.warnings.push_back(unmet_tolerance_warning(report));
  if (progress) progress(1.0, "done");
  return Status::success();
}

}  // namespace terrain::cook
