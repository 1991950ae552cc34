// Picks a reader by file name and applies the georeferencing and height flags.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fmt/format.h>
#include <system_error>

#include "frame/crs.h"
#include "inputs/inputs.h"
#include "base/memory_budget.h"
#include "inputs/source_raster.h"
#include "terrain/output_paths.h"
#include "inputs/web_tiles.h"

namespace terrain::cook {
namespace {

// GDAL reads everything it can; our own readers stay where GDAL cannot do the job or does it
// differently on purpose: .npz (no GDAL driver), raw game heightmaps (size and type from flags),
// SRTM HGT (zip / gz names checked against the tile, positions exact from the name), and PNG / EXR
// heightmap images (OpenImageIO; vertex grids placed by --origin / --spacing). PNG / WebP tiles
// under a z/x/y path are web elevation tiles.
enum class Format { gdal, hgt, image, raw, npz, web_tile };

Format format_of(const std::string& path) {
  const std::string base = std::filesystem::path(path).filename().string();
  TileAddress tile;
  if (parse_tile_address(path, tile)) return Format::web_tile;
  if (ends_with(base, ".hgt") || ends_with(base, ".hgt.zip") || ends_with(base, ".hgt.gz")) return Format::hgt;
  if (ends_with(base, ".png") || ends_with(base, ".exr")) return Format::image;
  if (ends_with(base, ".r16") || ends_with(base, ".raw") || ends_with(base, ".r32") || ends_with(base, ".f32"))
    return Format::raw;
  if (ends_with(base, ".npz")) return Format::npz;
  // SRTM tiles are often zipped as N22W160.zip / .gz without the inner extension in the name.
  if ((ends_with(base, ".zip") || ends_with(base, ".gz")) && base.size() >= 7 &&
      (base[0] == 'N' || base[0] == 'S' || base[0] == 'n' || base[0] == 's'))
    return Format::hgt;
  return Format::gdal;
}

// Extensions a directory input contributes (others, e.g. .aux.xml or README, are skipped).
bool is_raster_name(const std::string& base) {
  static const char* const kExts[] = {".tif", ".tiff", ".vrt", ".hgt", ".hgt.zip", ".hgt.gz", ".dt0", ".dt1", ".dt2",
                                      ".nc", ".img", ".asc", ".bil", ".flt", ".png", ".webp", ".exr", ".npz",
                                      ".r16", ".r32", ".f32", ".raw", ".jp2", ".bt", ".ter", ".xyz"};
  return std::any_of(std::begin(kExts), std::end(kExts), [&](const char* e) { return ends_with(base, e); });
}

// An undeclared -9999 (the most common nodata value written without a tag) is a void when no
// 8-neighbour other than -9999 or nodata lies within 1000 m of it: a real -9999 m depth has
// neighbours near it, a void's rim is land or sea far above it.
constexpr float kSentinel = -9999.0f;
constexpr double kSentinelNeighbourM = 1000.0;

// The -9999 rule at (col, row) of a w x h buffer: true when no 8-neighbour inside the buffer is a
// height within 1000 m of it. Neighbours already dropped (NaN) were -9999 and never count, so the
// answer does not depend on the order the samples are visited in.
bool is_void_sentinel(const float* values, int w, int h, int col, int row) {
  for (int dr = -1; dr <= 1; ++dr)
    for (int dc = -1; dc <= 1; ++dc) {
      const int c = col + dc, rr = row + dr;
      if ((dc == 0 && dr == 0) || c < 0 || rr < 0 || c >= w || rr >= h) continue;
      const float u = values[size_t(rr) * size_t(w) + size_t(c)];
      if (!std::isnan(u) && u != kSentinel && std::fabs(double(u) - kSentinel) <= kSentinelNeighbourM) return false;
    }
  return true;
}

}  // namespace

void finish_window(float* values, int w, int h, int ix0, int iy0, int iw, int ih, const HeightRules& rules,
                   Raster::Implausible* count) {
  Raster::Implausible unused;
  Raster::Implausible& im = count ? *count : unused;
  // Sentinels on the file's own values (-9999 is written before any scale applies): every one of
  // the window first, so the neighbours they look at are still file values.
  if (!rules.nodata_declared)
    for (int row = iy0; row < iy0 + ih; ++row)
      for (int col = ix0; col < ix0 + iw; ++col) {
        float& v = values[size_t(row) * size_t(w) + size_t(col)];
        if (v == kSentinel && is_void_sentinel(values, w, h, col, row)) {
          v = NAN;
          ++im.sentinel;
        }
      }
  const bool affine = rules.scale != 1.0 || rules.offset != 0.0;
  if (!affine) {
    // Heights already in metres: values change only where one is out of range (rare). A vectorisable
    // scan first (NaN compares false: not out of range); the loop below only when one is.
    float lo = INFINITY, hi = -INFINITY;
    for (int row = iy0; row < iy0 + ih; ++row) {
      const float* p = values + size_t(row) * size_t(w);
      for (int col = ix0; col < ix0 + iw; ++col) {
        const float v = p[col];
        lo = v < lo ? v : lo;  // NaN keeps lo and hi
        hi = v > hi ? v : hi;
      }
    }
    if (!(double(lo) < rules.valid_range_m[0] || double(hi) > rules.valid_range_m[1])) return;
  }
  for (int row = iy0; row < iy0 + ih; ++row) {
    float* p = values + size_t(row) * size_t(w);
    for (int col = ix0; col < ix0 + iw; ++col) {
      float& v = p[col];
      if (std::isnan(v)) continue;
      const double m = affine ? double(v) * rules.scale + rules.offset : double(v);
      if (m >= rules.valid_range_m[0] && m <= rules.valid_range_m[1]) {
        v = float(m);
        continue;
      }
      im.lowest = im.out_of_range ? std::min(im.lowest, m) : m;
      im.highest = im.out_of_range ? std::max(im.highest, m) : m;
      ++im.out_of_range;
      v = NAN;
    }
  }
}

uint64_t finish_heights(Raster& r, double scale, double offset, const std::array<double, 2>& valid_range_m,
                        bool nodata_declared) {
  r.implausible = {};
  finish_window(r.values.data(), r.width, r.height, 0, 0, r.width, r.height,
                HeightRules{scale, offset, valid_range_m, nodata_declared}, &r.implausible);
  return r.implausible.out_of_range + r.implausible.sentinel;
}

std::string implausible_heights_warning(const Raster& r, const std::array<double, 2>& valid_range_m) {
  const Raster::Implausible& im = r.implausible;
  std::string what;
  if (im.out_of_range)
    what = fmt::format("{} sample{} outside {} .. {} m (from {:.6g} to {:.6g} m)", im.out_of_range,
                       im.out_of_range == 1 ? "" : "s", valid_range_m[0], valid_range_m[1], im.lowest, im.highest);
  if (im.sentinel)
    what += fmt::format("{}{} sample{} of -9999 with no neighbour within 1000 m", what.empty() ? "" : " and ",
                        im.sentinel, im.sentinel == 1 ? "" : "s");
  return fmt::format("{}: {} cannot be elevations and are treated as nodata (undeclared voids?); declare the file's "
                     "nodata with --nodata-value, or widen the plausible heights with --valid-range MIN,MAX",
                     r.path, what);
}

Status check_raster_memory(const std::string& path, uint64_t width, uint64_t height, const std::string& what,
                           const ReadOptions& options, uint64_t extra_bytes) {
  const uint64_t samples = width * height;  // both below 2^32 in every caller: no overflow
  const uint64_t need = samples * options.bytes_per_sample + extra_bytes;
  return check_memory(need, options.memory_limit_bytes, path,
                      fmt::format("{} samples of {}x{} {} ({} B each while cooking)", format_count(samples), width,
                                  height, what, options.bytes_per_sample),
                      "raise --memory-limit if the machine has it, or cut the input into pieces (gdal_translate "
                      "-srcwin) and cook them apart");
}

// Inputs with every directory replaced by the rasters under it, in path order (so "first listed
// wins" is the sorted order within a directory).
Status expand_inputs(const std::vector<std::string>& inputs, std::vector<std::string>& out) {
  out.clear();
  for (const std::string& in : inputs) {
    std::error_code ec;
    if (!std::filesystem::is_directory(in, ec)) {
      out.push_back(in);
      continue;
    }
    std::vector<std::string> found;
    for (auto it = std::filesystem::recursive_directory_iterator(in, ec); !ec && it != std::filesystem::end(it);
         it.increment(ec))
      if (it->is_regular_file(ec) && is_raster_name(it->path().filename().string())) found.push_back(it->path().string());
    if (ec) return Status::failure(Error::io_open, fmt::format("{}: cannot list the directory: {}", in, ec.message()));
    if (found.empty())
      return Status::failure(Error::unsupported_input, fmt::format("{}: a directory with no raster files in it", in));
    std::sort(found.begin(), found.end());
    out.insert(out.end(), found.begin(), found.end());
  }
  return Status::success();
}

Status check_tile_encoding_use(const InputOptions& options, const std::vector<std::string>& paths) {
  if (options.tile_encoding.empty() || std::any_of(paths.begin(), paths.end(), is_encoded_image_name))
    return Status::success();
  return Status::failure(Error::invalid_argument,
                         fmt::format("--tile-encoding {}: names what a PNG or WebP input holds (a web tile, or an "
                                     "image of encoded heights); none of the inputs is one", options.tile_encoding));
}

InputLayer::InputLayer() = default;
InputLayer::~InputLayer() = default;
InputLayer::InputLayer(InputLayer&&) noexcept = default;
InputLayer& InputLayer::operator=(InputLayer&&) noexcept = default;

Status input_read_options(const InputOptions& options, ReadOptions& ro) {
  if (options.inputs.empty()) return Status::failure(Error::invalid_argument, "no input files given");
  SourceCrs crs_override;
  if (!options.crs.empty())
    TERRAIN_TRY(parse_crs_spec(options.crs, crs_override));
  if (options.origin && !options.spacing)
    return Status::failure(Error::invalid_argument, "--origin needs --spacing (the distance between samples)");
  if (options.spacing && !((*options.spacing)[0] > 0 && (*options.spacing)[1] > 0))
    return Status::failure(Error::invalid_argument, "--spacing must be positive");
  if (!(std::isfinite(options.height_scale) && options.height_scale != 0 && std::isfinite(options.height_offset)))
    return Status::failure(Error::invalid_argument, "--height-scale must be finite and non-zero, --height-offset finite");
  ro = ReadOptions{};
  ro.nodata_value = options.nodata_value;
  ro.raw_size = options.raw_size;
  ro.raw_type = options.raw_type;
  ro.raw_big_endian = options.raw_big_endian;
  if (!(std::isfinite(options.valid_range_m[0]) && std::isfinite(options.valid_range_m[1]) &&
        options.valid_range_m[0] < options.valid_range_m[1]))
    return Status::failure(Error::invalid_argument,
                           fmt::format("--valid-range {},{}: expected MIN,MAX in metres with MIN < MAX, e.g. -12000,9000",
                                       options.valid_range_m[0], options.valid_range_m[1]));
  return Status::success();
}

Status open_input_layer(const std::string& path, const InputOptions& options, const ReadOptions& ro, InputLayer& out) {
  out = InputLayer{};
  TERRAIN_TRY(check_input_file("", path));  // "no such file", "not a regular file (FIFO)"
  Raster r;
  std::unique_ptr<SourceRaster> src;
  Status st;
  const Format format = format_of(path);
  if (format != Format::web_tile && !options.tile_encoding.empty() && is_encoded_image_name(path)) {
    // --tile-encoding says what a PNG / WebP outside a z/x/y path holds: heights encoded in RGB
    // (never a grey heightmap, whose first channel would be cooked as metres), placed by the file's
    // own georeferencing as GDAL reads it (.aux.xml, world file) or by the flags below.
    TileEncoding enc = TileEncoding::none;
    std::unique_ptr<SourceRaster> placement;
    st = tile_encoding_of(path, options.tile_encoding, enc);
    if (st.ok()) st = open_gdal_source(path, ro, placement);
    if (st.ok()) st = open_encoded_image(path, enc, placement->info().geo, placement->info().crs, src);
  } else switch (format) {
    case Format::gdal: st = open_gdal_source(path, ro, src); break;
    case Format::web_tile: {
      TileAddress t;
      parse_tile_address(path, t);
      TileEncoding enc = TileEncoding::none;
      st = tile_encoding_of(path, options.tile_encoding, enc);
      if (st.ok()) st = open_web_tile(path, t, enc, src);
      break;
    }
    case Format::hgt: st = open_hgt_source(path, ro, src); break;
    case Format::image: st = read_image(path, ro, r); break;
    case Format::raw: st = read_raw(path, ro, r); break;
    case Format::npz: st = read_npz(path, ro, r); break;
  }
  if (!st.ok()) return st;
  if (src) {
    // What read_whole_source states of a source, without its values.
    const SourceInfo& info = src->info();
    r.path = info.path;
    r.width = info.width;
    r.height = info.height;
    r.geo = info.geo;
    r.crs = info.crs;
    r.nodata_declared = info.nodata.has_value();
    r.description = info.description;
    r.height_unit = info.height_unit;
  }
  if (r.width < 2 || r.height < 2)
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: {}x{} samples; at least 2x2 are needed", path, r.width, r.height));

  if (options.spacing) {
    // Heightmap images and raw grids are vertex grids: the terrain ends at the outer samples.
    if (!r.geo.valid) r.geo.point_samples = true;
    const double sx = (*options.spacing)[0], sy = (*options.spacing)[1];
    const std::array<double, 2> o = options.origin.value_or(std::array<double, 2>{0.0, 0.0});
    r.geo.c[0] = o[0];
    r.geo.c[1] = sx;
    r.geo.c[2] = 0;
    r.geo.c[3] = o[1] + double(r.height - 1) * sy;  // row 0 is the northern row
    r.geo.c[4] = 0;
    r.geo.c[5] = -sy;
    r.geo.valid = true;
  }
  if (!r.geo.valid)
    return Status::failure(Error::invalid_argument,
                           fmt::format("{}: carries no georeferencing; give --spacing DX,DY (and --origin X,Y of the "
                                       "south-west sample, --crs)", path));
  if (!options.crs.empty())
    if (Status cst = parse_crs_spec(options.crs, r.crs); !cst.ok()) return cst;
  if (r.crs.kind == CrsKind::none)
    return Status::failure(Error::invalid_argument,
                           fmt::format("{}: has no CRS; say what its coordinates are with --crs (EPSG:4326 for lon/lat, "
                                       "EPSG:326xx for UTM, any Transverse Mercator EPSG code, tm:lon0=..,k0=..,x0=.., "
                                       "or local for a game heightmap)", path));
  if (r.crs.kind == CrsKind::unsupported)
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: its CRS is {}, which terrain-cook cannot use (it reads geographic lon/lat, "
                                       "UTM and other Transverse Mercator CRSs); {}",
                                       path, describe_crs(r.crs), conversion_hint(r.crs, path)));
  // Heights to metres: the factor of the unit the file declares, unless --height-scale replaces it.
  HeightUnit& unit = r.height_unit;
  unit.scale_from_flag = options.height_scale_set || options.height_scale != 1.0;
  if (!unit.scale_from_flag && !std::isfinite(unit.declared_m))
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: its heights are in '{}' (its {}), a unit terrain-cook does not know (it "
                                       "converts metres, feet, US survey feet, centimetres and millimetres); give "
                                       "--height-scale with the metres per unit of its values",
                                       path, unit.declared, unit.declared_by));
  unit.scale = unit.scale_from_flag ? options.height_scale : unit.declared_m;
  out.rules = HeightRules{unit.scale, options.height_offset, options.valid_range_m,
                          r.nodata_declared || options.nodata_value.has_value()};
  // Inputs read whole are finished now (their implausible counts are then known).
  if (!src) finish_heights(r, out.rules.scale, out.rules.offset, out.rules.valid_range_m, out.rules.nodata_declared);
  out.raster = std::move(r);
  out.source = std::move(src);
  return Status::success();
}

Status read_layer_window(InputLayer& layer, int x0, int y0, int w, int h, float* out, std::vector<float>& scratch,
                         Raster::Implausible* count) {
  const Raster& r = layer.raster;
  if (x0 < 0 || y0 < 0 || w <= 0 || h <= 0 || x0 + w > r.width || y0 + h > r.height)
    return Status::failure(Error::invalid_argument, fmt::format("{}: window {}x{} at ({}, {}) outside the {}x{} raster",
                                                                r.path, w, h, x0, y0, r.width, r.height));
  if (!layer.source) {
    for (int row = 0; row < h; ++row)
      std::copy_n(&r.values[size_t(y0 + row) * size_t(r.width) + size_t(x0)], size_t(w), out + size_t(row) * size_t(w));
    return Status::success();
  }
  // The -9999 rule looks at 8 neighbours: read a ring of one sample around the window (inside the input).
  const int ring = layer.rules.nodata_declared ? 0 : 1;
  const int rx0 = std::max(0, x0 - ring), ry0 = std::max(0, y0 - ring);
  const int rx1 = std::min(r.width, x0 + w + ring), ry1 = std::min(r.height, y0 + h + ring);
  const int rw = rx1 - rx0, rh = ry1 - ry0;
  if (rw == w && rh == h) {
    TERRAIN_TRY(layer.source->read_window(x0, y0, w, h, out));
    finish_window(out, w, h, 0, 0, w, h, layer.rules, count);
    return Status::success();
  }
  scratch.resize(size_t(rw) * size_t(rh));
  TERRAIN_TRY(layer.source->read_window(rx0, ry0, rw, rh, scratch.data()));
  finish_window(scratch.data(), rw, rh, x0 - rx0, y0 - ry0, w, h, layer.rules, count);
  for (int row = 0; row < h; ++row)
    std::copy_n(&scratch[size_t(y0 - ry0 + row) * size_t(rw) + size_t(x0 - rx0)], size_t(w), out + size_t(row) * size_t(w));
  return Status::success();
}

Status load_inputs(const InputOptions& options, std::vector<Raster>& out) {
  out.clear();
  ReadOptions ro;
  TERRAIN_TRY(input_read_options(options, ro));
  // The budget: each input's whole-cook estimate, less what the inputs before it took.
  const uint64_t limit = memory_limit_of(options.memory_limit_bytes);
  uint64_t reserved = 0;
  ro.bytes_per_sample = kCookBytesPerSample;

  std::vector<std::string> paths;
  TERRAIN_TRY(expand_inputs(options.inputs, paths));
  TERRAIN_TRY(check_tile_encoding_use(options, paths));
  std::vector<float> scratch;
  for (const std::string& path : paths) {
    ro.memory_limit_bytes = limit > reserved ? limit - reserved : 0;
    InputLayer layer;
    TERRAIN_TRY(open_input_layer(path, options, ro, layer));
    if (layer.source) {
      // One window over the whole input: the windowed mosaic's path.
      const SourceInfo& info = layer.source->info();
      if (Status st = check_raster_memory(info.path, uint64_t(info.width), uint64_t(info.height), info.sample_type, ro,
                                          layer.source->scratch_bytes(info.width, info.height));
          !st.ok())
        return st;
      Raster& r = layer.raster;
      r.values.assign(size_t(r.width) * size_t(r.height), NAN);
      r.implausible = {};
      if (Status st = read_layer_window(layer, 0, 0, r.width, r.height, r.values.data(), scratch, &r.implausible);
          !st.ok())
        return st;
    }
    reserved += uint64_t(layer.raster.values.size()) * kCookBytesPerSample;
    out.push_back(std::move(layer.raster));
  }
  return Status::success();
}

}  // namespace terrain::cook
