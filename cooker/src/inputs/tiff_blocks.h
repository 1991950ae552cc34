// A plain GeoTIFF's compressed blocks (tiles or strips) decoded by the cooker instead of GDAL, for
// the layouts lidar DEMs ship in: one band of 8-, 16- or 32-bit samples, LZW, deflate or zstd,
// predictor 1, 2 or 3, the host's byte order. libtiff reads the layout (offsets and sizes of the
// blocks), libdeflate and libzstd inflate, LZW is decoded here (as copies of earlier output), and
// the predictors are undone with SSE2: libtiff's floating-point predictor undoes one byte at a time
// and was a third of the CPU of the first pass over a 1 m Float32 DEM (PREDICTOR=3, the GDAL
// default for such files), its block cache's fresh pages another fifth. The samples are bit for
// bit GDAL's (lossless decoding; tests TiffBlocks.*, and fuzz_tiff_blocks against libtiff), so
// archives do not change. Anything else (JPEG, LERC, no compression, another byte order, several
// samples per pixel; sparse or damaged blocks) is left to GDAL: open() says why, read_window()
// returns false and the caller reads through GDAL, which names any damage.
//
// Decoded blocks are kept in one process-wide cache (least recently used out first) so the first
// pass's 64-row reads decode each block once; set_tiff_block_cache_bytes sizes it, and a window
// holds at most one more row of blocks while it is read. They live in slots of huge-page slabs
// (slab_pool.h), which dropped blocks go back to. TERRAIN_TIFF_DIRECT=0 in the environment
// turns the reader off (GDAL then reads everything, as before).
#pragma once
#include <cstdint>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "terrain/status.h"

namespace terrain::cook {

struct TiffBlockLayout {
  int width = 0, height = 0;        // the image
  int block_w = 0, block_h = 0;     // a tile, or the width x rows per strip
  bool tiled = false;
  int bytes_per_sample = 0;         // 1, 2 or 4
  int sample_format = 1;            // TIFF's SampleFormat: 1 unsigned, 2 signed integer, 3 IEEE float
  int compression = 0;              // 5 LZW, 8 / 32946 deflate, 50000 zstd
  int predictor = 1;                // 1 none, 2 horizontal, 3 floating point
  std::vector<uint64_t> offsets, byte_counts;  // per block, row-major
};

// One decoded block's samples (not zeroed when made: the decode writes every byte it is read for).
struct TiffBlockBytes {
  uint8_t* bytes = nullptr;  // a slot of the cache's slab pool (tiff_blocks.cpp), returned by the destructor
  size_t size = 0;
  TiffBlockBytes() = default;
  ~TiffBlockBytes();
  TiffBlockBytes(const TiffBlockBytes&) = delete;
  TiffBlockBytes& operator=(const TiffBlockBytes&) = delete;
};

class TiffBlockReader {
 public:
  ~TiffBlockReader();
  TiffBlockReader(const TiffBlockReader&) = delete;
  TiffBlockReader& operator=(const TiffBlockReader&) = delete;

  // The reader of `path` into `out` when its first image is the layout above with width x height
  // samples of `bytes_per_sample` bytes. Otherwise Error::unsupported_input whose message says what
  // the file is instead (a decision, not a failure: the caller reads the file through GDAL), and
  // `out` is null.
  static Status open(const std::string& path, int width, int height, int bytes_per_sample,
                     std::unique_ptr<TiffBlockReader>& out);

  // Columns x0 .. x0+w-1 of rows y0 .. y0+h-1 into `slots` (row-major, 4 bytes per sample, each
  // sample's native bytes at the start of its slot: what GDAL's RasterIO writes with a pixel
  // spacing of 4). Blocks missing from the cache are decoded on up to `threads` threads. False
  // (slots undefined) when a block of the window is sparse or does not decode: read it with GDAL.
  // `stride`: slots from one row to the next (0: w), to read into part of a larger window.
  bool read_window(int x0, int y0, int w, int h, uint8_t* slots, int threads, size_t stride = 0) const;

  const TiffBlockLayout& layout() const { return layout_; }

 private:
  TiffBlockReader() = default;
  bool decode(int fd, uint32_t index, TiffBlockBytes& block) const;

  TiffBlockLayout layout_;
  // The file is opened by each read that decodes (GDAL already holds a descriptor per input, and a
  // mosaic may have thousands) and must still be the one whose layout was read.
  std::string path_;
  uint64_t file_bytes_ = 0, file_dev_ = 0, file_ino_ = 0;
  int64_t file_mtime_ns_ = 0;
  uint64_t id_ = 0;  // this reader's blocks in the shared cache
};

// Bytes of decoded blocks the process keeps (default 64 MB).
void set_tiff_block_cache_bytes(uint64_t bytes);
// Bytes the decoded blocks occupy now: the slots of their pool touched so far (cached blocks, blocks
// a read holds, free slots).
uint64_t tiff_block_cache_used_bytes();
// Two rows of blocks across `width` samples, for the tallest blocks of any reader opened so far
// (0 before any): what a pass over rows of tiles, or windows beside each other, reuses. More cache
// than that costs a fresh page per decoded block and saves no decoding.
uint64_t tiff_block_rows_bytes(int width);
// Counts blocks of `column_bytes` (block height x bytes per sample) in tiff_block_rows_bytes before
// any reader of them is open (a VRT's tiles open on first read).
void note_tiff_block_column(uint64_t column_bytes);
// Whether TERRAIN_TIFF_DIRECT allows the reader (anything but "0").
bool tiff_direct_enabled();

// TIFF LZW (compression 5) of n bytes into out[0, need); `out` must have 16 writable bytes past
// `need`. False on a stream libtiff would not decode (exposed for the benchmark's floor).
bool lzw_decode(const uint8_t* in, size_t n, uint8_t* out, size_t need);

// The predictors' undo, one row of `samples` samples in place (exposed for the tests; the SSE2
// forms are used where the CPU has them, `scalar` forces the byte-by-byte definitions).
void undo_horizontal_predictor(uint8_t* row, int samples, int bytes_per_sample, bool scalar = false);
// Floating point (32-bit): `row` holds the 4 byte planes (most significant first) differenced along
// the row; `out` receives the samples in the host's (little-endian) order. `row` is overwritten.
void undo_float_predictor(uint8_t* row, int samples, uint8_t* out, bool scalar = false);

}  // namespace terrain::cook
