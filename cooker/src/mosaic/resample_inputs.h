// An input in another CRS or at another sample spacing, seen on the first input's pixel grid so
// that the mosaic can place it like a tile (mixed CRSs and resolutions in one cook). It
// is read by windows like any other input: nothing here is sized by the whole input.
#pragma once
#include <cstdint>
#include <memory>
#include <vector>

#include "inputs/inputs.h"
#include "inputs/raster.h"
#include "terrain/status.h"

namespace terrain::cook {

// True when `r` must be resampled before it can join `ref`'s grid: another CRS or another sample
// spacing / axis orientation. Same CRS and spacing (whatever the origin) is mosaic()'s exact path.
bool needs_resampling(const Raster& ref, const Raster& r);

// `in` on `ref`'s pixel grid (same CRS, spacing and sample phase), over the part of that grid that
// covers in's footprint. A grid sample's input position comes from an exact CRS transform (PROJ,
// through OGR) at anchors every `anchor_step` grid samples, Catmull-Rom interpolated between
// them (anchor_grid.h); in the same CRS with both grids north-up, from the two affine maps (exact;
// a column's position depends on the column only, a row's on the row). Its height is a tent
// filter over the input samples around that position, of radius max(1, input samples per grid
// sample): bilinear when the input is as fine as the grid or coarser, an area filter when it is
// finer (separable where the positions are: a vertical, then a horizontal pass). A grid sample
// gets data only where every input sample with a non-zero weight has it. Each sample depends on
// its own position and the input's heights only, so any window gives the bits of the same
// rectangle of any other window.
class ResampledInput {
 public:
  ResampledInput();
  ~ResampledInput();
  ResampledInput(const ResampledInput&) = delete;
  ResampledInput& operator=(const ResampledInput&) = delete;

  // Places `layer` (opened by open_input_layer: windowed or held whole; moved in) on `ref`'s grid.
  // Counts its implausible heights by reading it once in strips of rows (bounded memory) when it
  // is windowed. Named errors: no geodetic CRS, no transformation, no footprint, too large.
  static Status open(const Raster& ref, InputLayer layer, std::unique_ptr<ResampledInput>& out);

  // Its place on ref's grid: grid sample (col(), row()) is its (0, 0); width() x height() samples.
  int64_t col() const { return col_; }
  int64_t row() const { return row_; }
  int width() const { return width_; }
  int height() const { return height_; }
  double radius() const { return radius_; }  // the tent filter's radius in input samples
  const Raster& input() const;                // the input as opened (values only when held whole)
  Raster::Implausible implausible() const { return implausible_; }
  uint64_t bytes_read() const;                // of the input's windowed reader; 0 when held whole
  // Samples [x0, x0+w) x [y0, y0+h) of its grid (inside it) into out, row-major. One thread at a time.
  Status read(int x0, int y0, int w, int h, float* out);
  // Bytes it holds besides input().values (an input held whole): the anchors and one tile's scratch.
  uint64_t resident_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  int64_t col_ = 0, row_ = 0;
  int width_ = 0, height_ = 0;
  double radius_ = 1;
  Raster::Implausible implausible_;
};

}  // namespace terrain::cook
