// A source elevation raster opened for reading by windows: what it is (size, georeferencing, CRS,
// nodata, the file's own scale/offset) and a window reader. A whole-raster read is one window (or
// many, row band by row band); a block-wise cook reads only the windows it needs. No GDAL here:
// the GDAL-backed sources live in input_gdal.cpp and web_tile_source.cpp.
#pragma once
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "inputs/raster.h"
#include "terrain/status.h"

namespace terrain::cook {

struct ReadOptions;

struct SourceInfo {
  std::string path;
  std::string description;  // format, type, size, compression: for the report
  int width = 0, height = 0;
  SampleGeo geo;            // sample centres, in metres / degrees (file units already converted)
  SourceCrs crs;
  std::optional<double> nodata;  // the file's (or --nodata-value's) nodata value, as stored
  double scale = 1.0, offset = 0.0;  // the file's own value -> height (GDAL GetScale / GetOffset)
  HeightUnit height_unit;  // the unit the file declares for its heights (declared fields only)
  std::string sample_type;  // "Int16", "Float32", ...
  uint64_t bytes_read = 0;  // grows with every window read (decoded bytes asked of the driver)
  // Who decodes the samples, for the report (not the archive): the cooker's block reader, or GDAL
  // and why (a GeoTIFF or VRT the reader leaves to it); empty for other formats.
  std::string decoder;
};

class SourceRaster {
 public:
  virtual ~SourceRaster() = default;
  const SourceInfo& info() const { return info_; }
  // Columns x0 .. x0+w-1 of rows y0 .. y0+h-1 into out[w*h] (row-major): the file's value times its
  // scale plus its offset; nodata (the declared value, NaN, +-Inf) as NaN. Reads nothing outside the
  // window but the driver's blocks that cover it.
  virtual Status read_window(int x0, int y0, int w, int h, float* out) = 0;
  // Bytes a read_window of w x h samples needs beyond `out` (its scratch and, for GDAL, the block
  // cache it may fill), for the memory budget.
  virtual uint64_t scratch_bytes(int w, int h) const = 0;

 protected:
  SourceInfo info_;
};

// Opens `path` through GDAL (any raster format GDAL reads: GeoTIFF, COG, VRT, DTED, netCDF, ...).
// Band 1; georeferencing from the geotransform (AREA_OR_POINT honoured as the libgeotiff reader
// did), the CRS mapped to what the cooker understands. A VRT whose tiles are missing or a file GDAL
// cannot read is a named error.
Status open_gdal_source(const std::string& path, const ReadOptions& options, std::unique_ptr<SourceRaster>& out);

// Opens an SRTM HGT tile (plain, .zip or .gz; position from its name, read_hgt's checks) for reading
// by rows: a plain file in place, a zip or gzip inflated once into an unlinked file in $TMPDIR.
Status open_hgt_source(const std::string& path, const ReadOptions& options, std::unique_ptr<SourceRaster>& out);

// Registers GDAL's drivers and sets its cache once (called by every GDAL-backed source).
void init_gdal();
// GDAL's block cache (process-wide): init_gdal sets 64 MB; the block-wise cook gives it a share of
// --memory-limit. An explicit GDAL_CACHEMAX (environment or config option) wins over both.
void set_gdal_cache_bytes(uint64_t bytes);
// Decoding threads of the GDAL datasets opened after this call (GDAL_NUM_THREADS, read by the
// GeoTIFF driver when it opens a file: a read spanning several compressed blocks then decodes them
// in parallel). An explicit GDAL_NUM_THREADS (environment or config option) wins.
void set_gdal_decode_threads(int threads);
// Bytes GDAL's block cache holds now.
uint64_t gdal_cache_used_bytes();
// A VRT (by name, .vrt) whose listed tiles do not all exist: an io_read error naming the VRT and the
// missing tile ("No such file or directory"), which a read of the windows over it would give later.
// Success for anything else.
Status check_vrt_tiles(const std::string& path);

// EPSG `code` as the GDAL reader maps a file in that CRS (kind none when GDAL does not know it).
SourceCrs gdal_crs_of_epsg(int code);

// A point from one CRS's model coordinates to another's (x = easting / longitude); false where it
// has no image. Not to be shared between threads.
using PointTransform = std::function<bool(double& x, double& y)>;
enum class CrsTransformStatus { ok, no_geodetic_crs, no_transformation };
// Transformations between `a` and `b` through OGR (an EPSG code, else the WKT or the parameters
// the CRS was resolved to). no_geodetic_crs: a local or missing CRS on either side.
CrsTransformStatus gdal_point_transforms(const SourceCrs& a, const SourceCrs& b, PointTransform& a_to_b,
                                         PointTransform& b_to_a);

// For the work units of a cook whose one input is a VRT mosaic (units/plan_file.h): the VRT `path` cut
// to each of `windows` (mosaic samples): every source whose DstRect meets the window grown by one
// sample, in order, with absolute file names; the raster, its georeferencing and the bands'
// properties as they are. A read inside the window gives the whole VRT's samples, and a unit parses
// the few hundred tiles it reads instead of every tile of a national mosaic (GDAL's parse of a
// 4096-tile VRT was a sixth of a one-root unit's CPU). Each written to a staged name and renamed
// into `outputs[i]`. `written` false (and success) when the VRT is not one to cut (not a VRT, or a
// relative file name GDAL resolves in its own way or one outside the bands' sources, such as an
// overview's or a mask band's): the units then open the VRT itself.
Status write_vrt_windows(const std::string& path, const std::vector<std::array<int, 4>>& windows,
                         const std::vector<std::string>& outputs, bool& written);

// Where a raster file lies, as GDAL opens it: its geotransform (of sample corners) and size.
struct FilePlacement {
  std::string path;
  bool opened = false;           // GDAL opened it
  bool has_geotransform = false;
  double gt[6] = {};
  int width = 0, height = 0;
};
// `path` first, then, when GDAL opens it, the files it reads besides itself (a VRT's tiles) but
// not its side-cars (.aux.xml, .ovr): the work units' input files (units/plan_file.h).
std::vector<FilePlacement> gdal_file_placements(const std::string& path);

// Reads the whole source into `out` (values, geo, crs, description, nodata_declared), band of rows
// by band of rows, after checking width x height (plus the scratch) against options' budget.
Status read_whole_source(SourceRaster& src, const ReadOptions& options, Raster& out);

}  // namespace terrain::cook
