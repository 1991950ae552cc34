// Readers of the supported input formats, each producing a Raster (heights in metres, NaN = nodata),
// and the dispatcher that picks one by file name and applies the georeferencing flags.
#pragma once
#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "inputs/raster.h"
#include "terrain/status.h"

namespace terrain::cook {

// What the readers and the mosaic take of the cook's options: the CookOptions fields of the same
// names and meanings (terrain/cook.h), copied by input_options (session/cook_session.h).
struct InputOptions {
  std::vector<std::string> inputs;
  std::string crs;
  std::optional<std::array<double, 2>> origin;
  std::optional<std::array<double, 2>> spacing;
  double height_scale = 1.0;
  double height_offset = 0.0;
  bool height_scale_set = false;
  std::optional<double> nodata_value;
  std::array<double, 2> valid_range_m{-12000.0, 9000.0};
  uint64_t memory_limit_bytes = 0;  // 0: default_memory_limit_bytes() (load_inputs only)
  std::array<int, 2> raw_size{0, 0};
  std::string raw_type;
  bool raw_big_endian = false;
  std::string tile_encoding;
  // Where inputs overlap: true = the finest wins (CookOptions::overlap finer, precedence.h); false =
  // the first listed. The winner's grid and CRS are the mosaic's (open_mosaic_source).
  bool finer_wins = true;
};

// Raw sample values before scale/offset; the readers mark nodata themselves.
struct ReadOptions {
  std::optional<double> nodata_value;  // overrides the file's nodata value
  std::array<int, 2> raw_size{0, 0};
  std::string raw_type;
  bool raw_big_endian = false;
  // Memory budget: a reader checks samples * bytes_per_sample (plus its own buffers) against the
  // limit before allocating. load_inputs passes the cook's budget and kCookBytesPerSample (what
  // the whole cook will need per sample); the defaults check the raster alone against 2 GB.
  uint64_t memory_limit_bytes = uint64_t(2) << 30;
  uint64_t bytes_per_sample = sizeof(float);
  // read_geotiff only: size, georeferencing, CRS, description and nodata_declared, no samples
  // (values stays empty; the overlays read their samples by windows, overlays.cpp).
  bool header_only = false;
  // The caller has stat'ed every file this open may read (a work unit: the plan's files that meet
  // its window, units/plan_file.h): the existence checks of each file a multi-file input names (a VRT's
  // tiles) are skipped. With thousands of tiles they were thousands of stats per unit on a shared
  // filesystem, nearly all of tiles the unit never reads.
  bool files_checked = false;
};

// Success when a width x height raster (plus `extra_bytes` of reader buffers) fits the budget of
// `options`; else "<path>: needs 57.6 GB for 3.6 G samples of <what> (16 B each while cooking),
// over --memory-limit 2.0 GB; ...". Called by every reader before it allocates.
Status check_raster_memory(const std::string& path, uint64_t width, uint64_t height, const std::string& what,
                           const ReadOptions& options, uint64_t extra_bytes = 0);

// GeoTIFF (libtiff + libgeotiff): Int8..Int32, UInt8..UInt32, Float32/64; strips or tiles;
// GDAL_NODATA; PixelIsArea / PixelIsPoint; CRS from the geokeys.
Status read_geotiff(const std::string& path, const ReadOptions& options, Raster& out);
// One decoded TIFF sample as a double (`format`: SampleFormat 1 uint, 2 int, 3 float; `bits` 8..64),
// NaN for a combination read_geotiff refuses; shared with the overlay windows (overlays.cpp).
double sample_value(const uint8_t* p, int bits, int format);
// SRTM HGT (1" 3601 or 3" 1201 samples per side), plain, .zip or .gz; position from the file name.
// Read whole (tools and tests); the cook opens it with open_hgt_source (source_raster.h).
Status read_hgt(const std::string& path, const ReadOptions& options, Raster& out);
// PNG (8/16-bit grey) and EXR (first channel) heightmaps through OpenImageIO; no georeferencing.
Status read_image(const std::string& path, const ReadOptions& options, Raster& out);
// Raw R16 / R32 heightmaps: size and sample type from the options.
Status read_raw(const std::string& path, const ReadOptions& options, Raster& out);
// NumPy .npz with an `elevation` array and optional xmin/xmax/ymin/ymax/dx/dy extent scalars.
Status read_npz(const std::string& path, const ReadOptions& options, Raster& out);

// Reads every input with the reader its name calls for, applies --crs, --origin, --spacing,
// --height-scale and --height-offset, and checks that each input is positioned. Each input is an
// InputLayer (below) read whole through read_layer_window: the same path as the windowed mosaic.
Status load_inputs(const InputOptions& options, std::vector<Raster>& out);

// What turns a file's values into heights (after the reader's own scale/offset and nodata):
// --height-scale / --height-offset, --valid-range, and the undeclared -9999 rule.
struct HeightRules {
  double scale = 1.0, offset = 0.0;
  std::array<double, 2> valid_range_m{-12000.0, 9000.0};
  bool nodata_declared = false;  // the file or --nodata-value declares nodata: no -9999 rule
};

// One input, opened. GDAL-readable inputs (and web tiles) keep their SourceRaster open and are read
// by windows, their heights finished per window; the inputs only our own readers take (.npz, HGT,
// PNG/EXR, raw) are read whole at open and finished then (`raster.values` holds them).
class SourceRaster;
struct InputLayer {
  Raster raster;  // path, description, size, geo and crs after the flags; values only when source is null
  std::unique_ptr<SourceRaster> source;
  HeightRules rules;
  InputLayer();
  ~InputLayer();
  InputLayer(InputLayer&&) noexcept;
  InputLayer& operator=(InputLayer&&) noexcept;
};

// The checks of the flags load_inputs makes before reading anything, and the options every reader
// gets from them (memory limit and bytes per sample left to the caller).
Status input_read_options(const InputOptions& options, ReadOptions& ro);
// The inputs with every directory replaced by the rasters under it, in path order.
Status expand_inputs(const std::vector<std::string>& inputs, std::vector<std::string>& out);
// --tile-encoding given while none of `paths` (expanded inputs) is a PNG / WebP it could apply to:
// an invalid_argument error (a flag that would change nothing). Success otherwise.
Status check_tile_encoding_use(const InputOptions& options, const std::vector<std::string>& paths);
// Opens `path` (file checks, reader by name, --crs/--origin/--spacing, positioned, CRS usable, at
// least 2x2) as load_inputs does, with `ro`'s memory budget for an input read whole.
Status open_input_layer(const std::string& path, const InputOptions& options, const ReadOptions& ro, InputLayer& out);
// Heights of samples [x0, x0+w) x [y0, y0+h) of the layer (inside it) into out: every rule of
// HeightRules applied (a 1-sample ring is read around the window so the -9999 rule sees the same
// neighbours as over the whole input). `scratch` holds the ring window between calls. Counts the
// implausible samples of the window into `count` when given.
Status read_layer_window(InputLayer& layer, int x0, int y0, int w, int h, float* out, std::vector<float>& scratch,
                         Raster::Implausible* count);

// The rules on samples [ix0, ix0+iw) x [iy0, iy0+ih) of a w x h buffer of file heights (the samples
// around them are the neighbours the -9999 rule looks at and stay as they are). finish_heights is
// this over a whole raster. Counts into `count` when given.
void finish_window(float* values, int w, int h, int ix0, int iy0, int iw, int ih, const HeightRules& rules,
                   Raster::Implausible* count);

// Small helpers shared by the readers.
bool ends_with(const std::string& s, const std::string& suffix);  // case-insensitive
Status read_file_bytes(const std::string& path, std::vector<uint8_t>& out);
// Refuses (before filling more) output beyond max_bytes, so a gzip bomb costs nothing.
Status gunzip_file(const std::string& path, std::vector<uint8_t>& out,
                   uint64_t max_bytes = uint64_t(1) << 32);
// First entry of a zip whose name ends with `suffix` (case-insensitive); its name in `entry`. An
// entry larger than max_bytes (its header's size, checked before allocating) is refused; memory grows
// with the bytes that really decompress, never with the header's claim.
Status read_zip_entry(const std::string& path, const std::string& suffix, std::vector<uint8_t>& out,
                      std::string& entry, uint64_t max_bytes = uint64_t(1) << 32);
// The file name stored in a gzip header (FNAME), or "" when there is none.
std::string gzip_stored_name(const std::string& path);

// The one step after every reader: file values to metres (value * scale + offset), and heights
// that cannot be elevations become nodata: outside valid_range_m (metres, after scale/offset,
// +-Inf included) or, unless nodata is declared, an undeclared -9999 with no neighbour within
// 1000 m. Counts them in r.implausible and returns how many.
uint64_t finish_heights(Raster& r, double scale, double offset, const std::array<double, 2>& valid_range_m,
                        bool nodata_declared);
// The warning for them: count, what they were, and the flags that change it.
std::string implausible_heights_warning(const Raster& r, const std::array<double, 2>& valid_range_m);

}  // namespace terrain::cook
