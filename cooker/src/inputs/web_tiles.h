// Web elevation tiles (AWS Terrain Tiles, MapTiler, Mapbox): RGB-encoded heights in 256 or 512
// pixel PNG / WebP tiles addressed z/x/y, georeferenced in EPSG:3857 from that address.
#pragma once
#include <cstdint>
#include <memory>
#include <string>

#include "inputs/raster.h"
#include "inputs/source_raster.h"
#include "terrain/status.h"

namespace terrain::cook {

enum class TileEncoding : uint8_t { none, terrarium, mapbox };

struct TileAddress {
  int z = 0, x = 0, y = 0;
};

// Mapzen terrarium: h = R*256 + G + B/256 - 32768 (metres).
inline double terrarium_height(uint8_t r, uint8_t g, uint8_t b) { return r * 256.0 + g + b / 256.0 - 32768.0; }
// Mapbox terrain-RGB: h = -10000 + (R*65536 + G*256 + B) * 0.1 (metres).
inline double mapbox_height(uint8_t r, uint8_t g, uint8_t b) {
  return -10000.0 + double(uint32_t(r) * 65536u + uint32_t(g) * 256u + b) * 0.1;
}

// "…/12/654/1583.png" (or .webp, .pngraw): true with z/x/y when the last three path parts are a
// valid tile address (0 <= z <= 30, 0 <= x, y < 2^z).
bool parse_tile_address(const std::string& path, TileAddress& out);

// The encoding: `flag` (--tile-encoding: "terrarium" / "mapbox", or "") wins, else a path naming
// it ("terrarium", "mapbox", "terrain-rgb"); a tile with neither is an invalid_argument error.
// A PNG / WebP not under a z/x/y path is an encoded heights image only when the flag says so.
Status tile_encoding_of(const std::string& path, const std::string& flag, TileEncoding& out);

// Sample centres of a size x size tile in EPSG:3857 metres (pixel areas: the tile's edges are the
// outer samples' edges).
SampleGeo web_tile_geo(const TileAddress& t, int size);

// EPSG:3857 as the GDAL reader states it for a GeoTIFF in that CRS.
SourceCrs web_mercator_crs();

// Opens one tile through GDAL (bands 1-3, alpha 0 as nodata when there is a 4th band).
Status open_web_tile(const std::string& path, const TileAddress& t, TileEncoding enc,
                     std::unique_ptr<SourceRaster>& out);

// Opens an RGB(A) 8-bit image of encoded heights that is not addressed z/x/y (--tile-encoding on
// a PNG or WebP of any size), decoded as open_web_tile decodes a tile and placed by `geo` and `crs`
// (the file's own georeferencing as GDAL reads it, or invalid / none: the flags then place it). An
// image with fewer than 3 bands or other than 8-bit samples is an unsupported_input error naming
// --tile-encoding.
Status open_encoded_image(const std::string& path, TileEncoding enc, const SampleGeo& geo, const SourceCrs& crs,
                          std::unique_ptr<SourceRaster>& out);

// True for the names --tile-encoding applies to: .png, .webp, .pngraw.
bool is_encoded_image_name(const std::string& path);

}  // namespace terrain::cook
