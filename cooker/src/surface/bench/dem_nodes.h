// Real-DEM nodes for terrain-bc-bench and the surface tests: reads a shared DEM (GeoTIFF Int16 /
// Float32 via libtiff, SRTM .hgt inside a zip via libzip), resamples it onto a node's vertex
// lattice and quantizes it the way the height pyramid does (one global lattice of height units,
// so every node sees the same canonical value for a shared vertex).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "materials.h"
#include "surface_layers.h"
#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::cook::bench {

struct DemRaster {
  std::string name;
  int width = 0, height = 0;
  double dx_m = 1, dy_m = 1;  // sample spacing (geographic grids: local metres at the centre)
  std::vector<float> h;       // row 0 = south; NaN = no data
  float at(int x, int y) const { return h[size_t(y) * size_t(width) + size_t(x)]; }
};

// Known shared files get their spacing from a small table (the bench is not a CRS engine).
Status load_dem(const std::string& path, DemRaster& out);

struct DemNode {
  NodeKey key;
  double x0_m = 0, y0_m = 0, spacing_m = 0;
  int step_log2 = 0;
  int32_t height_offset = 0;
  std::vector<float> window;     // kWindowCount
  std::vector<uint8_t> holes;    // kWindowCount
  NodeData node;                 // heights filled
  int hole_vertices = 0;         // inside the node's 129x129
  int data_vertices = 0;
  SurfaceInput input(const MaterialRules* rules, BcQuality q) const;
};

// Node (level, nx, ny) of a frame whose origin is the raster's south-west sample; the raster is
// sampled bilinearly at `metres_per_raster_sample` scale (0 = its own spacing). Vertices outside
// the raster or next to a no-data sample are NaN / holes.
void make_dem_node(const DemRaster& dem, uint32_t level, uint32_t nx, uint32_t ny, int step_log2, DemNode& out);

// Nodes per side of `level` that overlap the raster.
uint32_t nodes_across(const DemRaster& dem, uint32_t level, bool y_axis);

}  // namespace terrain::cook::bench
