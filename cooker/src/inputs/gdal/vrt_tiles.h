// A GDAL VRT that mosaics plain GeoTIFF tiles (what `gdalbuildvrt` writes over a national lidar
// grid) read by windows through each tile's own block reader (tiff_blocks.h) and composed by the
// VRT's rules, so that a .vrt input decodes as fast as its tiles given one by one (GDAL's VRT and
// GeoTIFF drivers decode them several times slower (cooker/README.md, "Figures behind the code")).
//
// Only the plain case, whose result GDAL defines without any arithmetic: one band of 16- or 32-bit
// samples; sources SimpleSource or ComplexSource whose only option is <NODATA>; SrcRect and DstRect
// of one size at whole samples (no resampling), inside the tile; every tile band 1 of the band's
// data type. The rules (GDAL's VRTSourcedRasterBand): the window starts as the band's NoDataValue
// (0 without one); sources are drawn in order, later over earlier; a ComplexSource's samples equal
// to its NODATA are not drawn. Anything else: open() says why and GDAL reads the VRT; a tile the
// block reader leaves to GDAL (uncompressed, another layout) makes every window that touches it a
// GDAL read. Samples are bit for bit GDAL's (test TiffBlocks.VrtWindowsAreGdalsBitForBit).
#pragma once
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "terrain/status.h"

namespace terrain::cook {

class TiffBlockReader;

class VrtTileReader {
 public:
  ~VrtTileReader();
  VrtTileReader(const VrtTileReader&) = delete;
  VrtTileReader& operator=(const VrtTileReader&) = delete;

  // The reader of the VRT at `path` into `out` when it is the plain case above with a band of
  // width x height samples. Otherwise Error::unsupported_input whose message says why (a decision,
  // not a failure: the caller reads the VRT through GDAL), and `out` is null.
  static Status open(const std::string& path, int width, int height, std::unique_ptr<VrtTileReader>& out);
  // Tile readers a VrtTileReader keeps open (default 16384, about 8 MB); returns the previous
  // limit (tests: a tiny one closes and opens tiles again within and between reads).
  static size_t set_open_tile_limit(size_t limit);

  // As TiffBlockReader::read_window: the band's native samples at the start of 4-byte slots. False
  // (slots undefined) when a tile of the window is not one the block reader decodes, or a block
  // does not decode: read the window with GDAL. Safe to call from several threads.
  bool read_window(int x0, int y0, int w, int h, uint8_t* slots, int threads) const;
  // Scratch a read_window of w x h samples takes beyond `slots` (sources drawn over others).
  uint64_t scratch_bytes(int w, int h) const;
  size_t sources() const { return sources_.size(); }

 private:
  struct Source {
    std::string path;
    int tile_w = 0, tile_h = 0;            // the tile's size
    int src_x = 0, src_y = 0;              // SrcRect's corner in the tile
    int dst_x = 0, dst_y = 0, w = 0, h = 0;  // DstRect in the VRT
    bool has_nodata = false;               // a ComplexSource's NODATA that can match a sample
    double nodata_value = 0;
    bool composed = false;  // drawn sample by sample (it has a NODATA that matters: an earlier source or
                            // the band's fill may lie under it)
  };
  VrtTileReader() = default;
  // The tile's block reader, opened on first use; null when the block reader refuses the tile. At
  // most open_tile_limit() stay open (a clock keeps the ones in use): a reader holds its tile's
  // layout, and a national mosaic has 10^5 to 10^6 tiles.
  std::shared_ptr<const TiffBlockReader> tile(size_t i) const;
  // The sources whose DstRect meets the window, in the VRT's order (later ones draw over earlier).
  void sources_in(int x0, int y0, int w, int h, std::vector<uint32_t>& out) const;

  int width_ = 0, height_ = 0, type_ = 0;  // type_: the band's sample type (vrt_tiles.cpp's Type)
  uint32_t fill_bits_ = 0;  // the band's NoDataValue (or 0) as native bytes
  std::vector<Source> sources_;
  // The sources by grid cell (cell_ x cell_ samples, cells_x_ per row): those of cell k are
  // cell_sources_[cell_start_[k] .. cell_start_[k + 1]), ascending. A window looks at the cells it
  // meets, not at every source: a national mosaic has 10^5 to 10^6 of them.
  int cell_ = 1, cells_x_ = 0, cells_y_ = 0;
  std::vector<uint32_t> cell_start_, cell_sources_;
  mutable std::mutex m_;
  mutable std::vector<std::shared_ptr<const TiffBlockReader>> tiles_;
  mutable std::vector<uint8_t> state_;     // per source: kUntried, kRefused, kOpen, kOpenUsed
  mutable std::vector<uint32_t> open_;     // the open readers' sources, in the clock's order
  mutable size_t hand_ = 0;
};

}  // namespace terrain::cook
