// The overlay rasters of a cook (--albedo orthophoto, --holes mask, --landcover classes): opened
// at start-up, read block by block (a window around each block, never the whole raster), mapped
// from their own CRS to the frame and sampled at the node window vertices.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "surface/surface_layers.h"
#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::cook {

// What the overlays take of the cook's options: the CookOptions fields of the same names, and the
// memory limit in force (memory_limit_of; a window must fit it).
struct OverlayOptions {
  std::string albedo_path, holes_path, landcover_path, landcover_table_path;  // empty: none
  bool heights_only = false;
  uint64_t memory_limit_bytes = 0;
};

// Opens the overlays `o` names (none: `out` stays null: their headers only, no samples) and maps
// each to `frame` over the frame rectangle [x0, x1] x [y0, y1] (metres: the root grid with its
// window margin). Fails on a raster that does not overlap that rectangle, on a bad
// --landcover-table and with --heights-only.
Status load_overlays(const OverlayOptions& o, const FrameCrs& frame, const std::vector<Material>& palette, double x0,
                     double y0, double x1, double y1, int threads, std::unique_ptr<SurfaceOverlays>& out);

// Reads, in place of the previous block's, the window of each overlay that the frame rectangle
// [x0, x1] x [y0, y1] (a block's, pyramid.h block_frame_rect) maps to, plus the sampling's taps:
// every vertex in the rectangle then samples what a read of the whole raster would give it.
// Call before cooking the block's nodes; `ov` is what load_overlays made. A window (4 B a sample)
// must fit --memory-limit. An orthophoto whose Orientation tag is not top-left is read whole, once.
// Decoding is libtiff's, tile by tile or strip by strip (a compressed image stored as one strip is
// decoded whole for every block).
Status prepare_overlays_block(SurfaceOverlays& ov, double x0, double y0, double x1, double y1);

// Process-wide counts since reset_overlay_window_stats(), for the tests: the largest window read
// (samples of one overlay), windows read, and taps that fell inside a raster but outside its
// window (0 unless a window is too small: such a tap counts as no data).
struct OverlayWindowStats {
  uint64_t largest_window_samples = 0;
  uint64_t windows = 0;
  uint64_t misses = 0;
};
OverlayWindowStats overlay_window_stats();
void reset_overlay_window_stats();

}  // namespace terrain::cook
