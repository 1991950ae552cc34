// Picks a reader by file name and applies the georeferencing and height flags.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fmt/format.h>
#include <system_error>

#include "crs.h"
#include "inputs.h"
#include "memory_budget.h"
#include "source_raster.h"
#include "terrain/output_paths.h"
#include "web_tiles.h"

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

Status read_gdal(const std::string& path, const ReadOptions& ro, Raster& r) {
  std::unique_ptr<SourceRaster> src;
  if (Status st = open_gdal_source(path, ro, src); !st.ok()) return st;
  return read_whole_source(*src, ro, r);
}

Status read_web_tile(const std::string& path, const std::string& encoding_flag, const ReadOptions& ro, Raster& r) {
  TileAddress t;
  parse_tile_address(path, t);
  TileEncoding enc = TileEncoding::none;
  if (Status st = tile_encoding_of(path, encoding_flag, enc); !st.ok()) return st;
  std::unique_ptr<SourceRaster> src;
  if (Status st = open_web_tile(path, t, enc, src); !st.ok()) return st;
  return read_whole_source(*src, ro, r);
}

// An undeclared -9999 (the most common nodata value written without a tag) is a void when no
// 8-neighbour other than -9999 or nodata lies within 1000 m of it: a real -9999 m depth has
// neighbours near it, a void's rim is land or sea far above it.
constexpr float kSentinel = -9999.0f;
constexpr double kSentinelNeighbourM = 1000.0;

uint64_t drop_sentinels(Raster& r) {
  uint64_t n = 0;
  const int w = r.width, h = r.height;
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) {
      float& v = r.values[size_t(row) * size_t(w) + size_t(col)];
      if (v != kSentinel) continue;
      bool near = false;
      for (int dr = -1; dr <= 1 && !near; ++dr)
        for (int dc = -1; dc <= 1 && !near; ++dc) {
          const int c = col + dc, rr = row + dr;
          if ((dc == 0 && dr == 0) || c < 0 || rr < 0 || c >= w || rr >= h) continue;
          const float u = r.at(c, rr);
          near = !std::isnan(u) && u != kSentinel && std::fabs(double(u) - kSentinel) <= kSentinelNeighbourM;
        }
      if (!near) {
        v = NAN;
        ++n;
      }
    }
  return n;
}

}  // namespace

uint64_t finish_heights(Raster& r, double scale, double offset, const std::array<double, 2>& valid_range_m,
                        bool nodata_declared) {
  r.implausible = {};
  // Sentinels on the file's own values (-9999 is written before any scale applies).
  if (!nodata_declared) r.implausible.sentinel = drop_sentinels(r);
  const bool affine = scale != 1.0 || offset != 0.0;
  for (float& v : r.values) {
    if (std::isnan(v)) continue;
    const double m = affine ? double(v) * scale + offset : double(v);
    if (m >= valid_range_m[0] && m <= valid_range_m[1]) {
      v = float(m);
      continue;
    }
    Raster::Implausible& im = r.implausible;
    im.lowest = im.out_of_range ? std::min(im.lowest, m) : m;
    im.highest = im.out_of_range ? std::max(im.highest, m) : m;
    ++im.out_of_range;
    v = NAN;
  }
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

Status load_inputs(const CookOptions& options, std::vector<Raster>& out) {
  out.clear();
  if (options.inputs.empty()) return Status::failure(Error::invalid_argument, "no input files given");
  SourceCrs crs_override;
  if (!options.crs.empty())
    if (Status st = parse_crs_spec(options.crs, crs_override); !st.ok()) return st;
  if (options.origin && !options.spacing)
    return Status::failure(Error::invalid_argument, "--origin needs --spacing (the distance between samples)");
  if (options.spacing && !((*options.spacing)[0] > 0 && (*options.spacing)[1] > 0))
    return Status::failure(Error::invalid_argument, "--spacing must be positive");
  if (!(std::isfinite(options.height_scale) && options.height_scale != 0 && std::isfinite(options.height_offset)))
    return Status::failure(Error::invalid_argument, "--height-scale must be finite and non-zero, --height-offset finite");

  ReadOptions ro;
  ro.nodata_value = options.nodata_value;
  ro.raw_size = options.raw_size;
  ro.raw_type = options.raw_type;
  ro.raw_big_endian = options.raw_big_endian;
  if (!(std::isfinite(options.valid_range_m[0]) && std::isfinite(options.valid_range_m[1]) &&
        options.valid_range_m[0] < options.valid_range_m[1]))
    return Status::failure(Error::invalid_argument,
                           fmt::format("--valid-range {},{}: expected MIN,MAX in metres with MIN < MAX, e.g. -12000,9000",
                                       options.valid_range_m[0], options.valid_range_m[1]));
  // The budget: each input's whole-cook estimate, less what the inputs before it took.
  const uint64_t limit = memory_limit_of(options);
  uint64_t reserved = 0;
  ro.bytes_per_sample = kCookBytesPerSample;

  std::vector<std::string> paths;
  if (Status st = expand_inputs(options.inputs, paths); !st.ok()) return st;
  for (const std::string& path : paths) {
    if (Status st = check_input_file("", path); !st.ok()) return st;  // "no such file", "not a regular file (FIFO)"
    Raster r;
    Status st;
    ro.memory_limit_bytes = limit > reserved ? limit - reserved : 0;
    switch (format_of(path)) {
      case Format::gdal: st = read_gdal(path, ro, r); break;
      case Format::web_tile: st = read_web_tile(path, options.tile_encoding, ro, r); break;
      case Format::hgt: st = read_hgt(path, ro, r); break;
      case Format::image: st = read_image(path, ro, r); break;
      case Format::raw: st = read_raw(path, ro, r); break;
      case Format::npz: st = read_npz(path, ro, r); break;
    }
    if (!st.ok()) return st;
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
    if (!options.crs.empty()) r.crs = crs_override;
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
    finish_heights(r, options.height_scale, options.height_offset, options.valid_range_m,
                   r.nodata_declared || options.nodata_value.has_value());
    reserved += uint64_t(r.values.size()) * kCookBytesPerSample;
    out.push_back(std::move(r));
  }
  return Status::success();
}

}  // namespace terrain::cook
