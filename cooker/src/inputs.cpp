// Picks a reader by file name and applies the georeferencing and height flags.
#include <cmath>
#include <filesystem>
#include <fmt/format.h>

#include "crs.h"
#include "inputs.h"
#include "terrain/output_paths.h"

namespace terrain::cook {
namespace {

enum class Format { geotiff, hgt, image, raw, npz, unknown };

Format format_of(const std::string& path) {
  const std::string base = std::filesystem::path(path).filename().string();
  if (ends_with(base, ".tif") || ends_with(base, ".tiff")) return Format::geotiff;
  if (ends_with(base, ".hgt") || ends_with(base, ".hgt.zip") || ends_with(base, ".hgt.gz")) return Format::hgt;
  if (ends_with(base, ".png") || ends_with(base, ".exr")) return Format::image;
  if (ends_with(base, ".r16") || ends_with(base, ".raw") || ends_with(base, ".r32") || ends_with(base, ".f32"))
    return Format::raw;
  if (ends_with(base, ".npz")) return Format::npz;
  // SRTM tiles are often zipped as N22W160.zip / .gz without the inner extension in the name.
  if ((ends_with(base, ".zip") || ends_with(base, ".gz")) && base.size() >= 7 &&
      (base[0] == 'N' || base[0] == 'S' || base[0] == 'n' || base[0] == 's'))
    return Format::hgt;
  return Format::unknown;
}

}  // namespace

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

  for (const std::string& path : options.inputs) {
    if (Status st = check_input_file("", path); !st.ok()) return st;  // "no such file", "not a regular file (FIFO)"
    Raster r;
    Status st;
    switch (format_of(path)) {
      case Format::geotiff: st = read_geotiff(path, ro, r); break;
      case Format::hgt: st = read_hgt(path, ro, r); break;
      case Format::image: st = read_image(path, ro, r); break;
      case Format::raw: st = read_raw(path, ro, r); break;
      case Format::npz: st = read_npz(path, ro, r); break;
      case Format::unknown:
        return Status::failure(Error::unsupported_input,
                               fmt::format("{}: unknown input format; supported: GeoTIFF (.tif, .tiff), SRTM HGT (.hgt, "
                                           ".hgt.zip, .hgt.gz), PNG16 / EXR heightmaps (.png, .exr), raw (.r16, .raw, "
                                           ".r32, .f32), NumPy (.npz)", path));
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
    if (options.height_scale != 1.0 || options.height_offset != 0.0)
      for (float& v : r.values)
        if (!std::isnan(v)) v = float(double(v) * options.height_scale + options.height_offset);
    out.push_back(std::move(r));
  }
  return Status::success();
}

}  // namespace terrain::cook
