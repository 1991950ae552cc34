// Readers of the supported input formats, each producing a Raster (heights in metres, NaN = nodata),
// and the dispatcher that picks one by file name and applies the georeferencing flags.
#pragma once
#include <string>
#include <vector>

#include "raster.h"
#include "terrain/cook.h"
#include "terrain/status.h"

namespace terrain::cook {

// Raw sample values before scale/offset; the readers mark nodata themselves.
struct ReadOptions {
  std::optional<double> nodata_value;  // overrides the file's nodata value
  std::array<int, 2> raw_size{0, 0};
  std::string raw_type;
  bool raw_big_endian = false;
};

// GeoTIFF (libtiff + libgeotiff): Int8..Int32, UInt8..UInt32, Float32/64; strips or tiles;
// GDAL_NODATA; PixelIsArea / PixelIsPoint; CRS from the geokeys.
Status read_geotiff(const std::string& path, const ReadOptions& options, Raster& out);
// SRTM HGT (1" 3601 or 3" 1201 samples per side), plain, .zip or .gz; position from the file name.
Status read_hgt(const std::string& path, const ReadOptions& options, Raster& out);
// PNG (8/16-bit grey) and EXR (first channel) heightmaps through OpenImageIO; no georeferencing.
Status read_image(const std::string& path, const ReadOptions& options, Raster& out);
// Raw R16 / R32 heightmaps: size and sample type from the options.
Status read_raw(const std::string& path, const ReadOptions& options, Raster& out);
// NumPy .npz with an `elevation` array and optional xmin/xmax/ymin/ymax/dx/dy extent scalars.
Status read_npz(const std::string& path, const ReadOptions& options, Raster& out);

// Reads every input with the reader its name calls for, applies --crs, --origin, --spacing,
// --height-scale and --height-offset, and checks that each input is positioned.
Status load_inputs(const CookOptions& options, std::vector<Raster>& out);

// Small helpers shared by the readers.
bool ends_with(const std::string& s, const std::string& suffix);  // case-insensitive
Status read_file_bytes(const std::string& path, std::vector<uint8_t>& out);
Status gunzip_file(const std::string& path, std::vector<uint8_t>& out);
// First entry of a zip whose name ends with `suffix` (case-insensitive); its name in `entry`.
Status read_zip_entry(const std::string& path, const std::string& suffix, std::vector<uint8_t>& out,
                      std::string& entry);

}  // namespace terrain::cook
