// The mosaic of every input, read by windows (bounded memory). A block-wise cook reads
// only the rectangle of mosaic samples each block needs; GDAL-readable inputs stay open and are read
// window by window, never whole. Any window is bit-identical to the same rectangle of the whole
// mosaic (load_inputs + mosaic, which are themselves this reader over one window covering all).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "inputs/inputs.h"
#include "inputs/raster.h"
#include "mosaic/resample_inputs.h"
#include "terrain/height_unit.h"
#include "terrain/status.h"

namespace terrain::cook {

class MosaicSource {
 public:
  MosaicSource();
  ~MosaicSource();
  MosaicSource(MosaicSource&&) noexcept;
  MosaicSource& operator=(MosaicSource&&) noexcept;

  // width, height, geo, crs, path, description, nodata_declared of the mosaic (as mosaic() states
  // them: a single input's own, else "mosaic WxH of N inputs: ..."); values and implausible EMPTY.
  const Raster& header() const { return header_; }

  // Samples [c0, c0+w) x [r0, r0+h) of the mosaic into out (w*h, row-major); any rectangle, parts
  // outside the mosaic are NaN. Heights after every rule load_inputs applies; where inputs
  // overlap, the first in the order of precedence (open_mosaic_source) wins. `family`, when not
  // null (w*h bytes): the grid family (family_of) of the input that gave each sample, kNoFamily
  // where none did. Called from one thread at a time (it reuses its scratch).
  Status read(int c0, int r0, int w, int h, float* out, uint8_t* family = nullptr);

  // Grid families: inputs on one grid (same CRS and spacing, precedence.h) form one, numbered in
  // the order of precedence from 0 (the mosaic's own grid); at most kMaxFamilies, later ones share
  // the last number. spacing_m: the finer axis of its ground sample spacing (ground_spacing_axes_m)
  // of its first input. One family: every sample is family 0.
  static constexpr uint8_t kNoFamily = 255, kMaxFamilies = 254;
  struct Family {
    double spacing_m = 0;
    std::vector<size_t> inputs;  // indices into inputs()
  };
  const std::vector<Family>& families() const { return families_; }

  // Seam blend (open_mosaic_source with finer_wins): where a family's data end inside a coarser
  // family's, its samples within seam_band_m(f) of that end become
  //   coarser + (d / band) (own - coarser),
  // d the ground distance (metres, on the mosaic's grid) to the nearest sample a coarser family
  // holds (where the coarser data take over; edges with no data beyond are no seam), `coarser` the
  // value of the first coarser input under the sample. The band is twice
  // the spacing of the finest coarser family (60 m for 1 m lidar in a 30 m DEM). So a step between
  // the sources becomes a ramp; a family's samples change by at most (1 - d / band) |own - coarser|
  // inside the band, not at all beyond it, and the coarser family's own samples never. A function
  // of the sample's position and the inputs only (any window gives the same bits). 0: no blend
  // (one family, the coarsest family, or --overlap list).
  void enable_seam_blend();
  double seam_band_m(size_t family) const { return family < seam_band_m_.size() ? seam_band_m_[family] : 0.0; }

  struct InputStat {
    std::string path, description;  // description as load_inputs' Raster::description (before resampling)
    std::string decoder;            // SourceInfo::decoder of a windowed input
    SourceCrs crs;
    uint64_t bytes_read = 0;        // SourceInfo::bytes_read of a windowed input; 0 for inputs read whole
    bool windowed = false;          // read by windows (GDAL); false: held whole (own readers)
    HeightUnit height_unit;         // the unit its heights declare and the factor applied (Raster::height_unit)
    // Implausible heights of the input (Raster::Implausible as load_inputs counts them). Inputs held
    // whole: complete from open. Windowed inputs: counted by read() while count_implausible is on.
    Raster::Implausible implausible;
    // Mosaic samples where the input has a height, and those of them the mosaic keeps (the first
    // listed input wins): counted by read() while count_implausible is on (InputSamples, cook.h).
    uint64_t samples_read = 0, samples_used = 0;
  };
  const std::vector<InputStat>& inputs() const { return stats_; }

  // While on, read() adds the implausible samples of each windowed input inside the window to its
  // InputStat::implausible. They equal load_inputs' counts when the windows read while it is on
  // cover every mosaic sample exactly once (the driver's first pass); overlapping windows would
  // count twice. The 1-sample ring read around a window is never counted. The same windows count
  // each input's samples_read and samples_used.
  void set_count_implausible(bool on) { count_implausible_ = on; }

  // Bytes this source holds in memory now: inputs held whole (own readers), resampled inputs' anchors, its scratch,
  // and GDAL's block cache (process-wide; set by set_gdal_cache_bytes) when an input is windowed.
  uint64_t resident_bytes() const;
  // Bytes of the inputs held whole (their values): mosaic()'s memory check.
  uint64_t held_input_bytes() const;

  // Internals, for open_mosaic_source and mosaic().
  struct Layer {
    InputLayer input;       // resampled inputs: raster is its place on the grid (no values), source is null
    std::unique_ptr<ResampledInput> resampled;  // set for an input in another CRS or spacing
    int64_t col = 0, row = 0;  // its sample (0, 0) in mosaic samples
  };
  static Status assemble(std::vector<Layer> layers, std::vector<InputStat> stats, uint64_t held_bytes,
                         uint64_t memory_limit_bytes, MosaicSource& out);

 private:
  // read() without the seam blend: first-wins composition; `next` (optional, with family): the
  // first coarser family's value under each sample; count: the stats of set_count_implausible.
  Status compose(int c0, int r0, int w, int h, float* out, uint8_t* family, float* next, bool count);
  Status blend_seams(int c0, int r0, int w, int h, const uint8_t* family, float* out);

  Raster header_;
  std::vector<Layer> layers_;
  std::vector<InputStat> stats_;
  std::vector<Family> families_;
  std::vector<uint8_t> family_of_layer_;
  std::vector<double> seam_band_m_;  // per family; empty: no blend
  int seam_radius_ = 0;              // the widest band in samples (rounded up): blend_seams' margin
  double seam_sx_ = 1, seam_sy_ = 1; // the mosaic's sample spacing, ground metres
  std::vector<float> tile_values_, tile_next_;
  std::vector<uint8_t> tile_family_, own_family_;
  std::vector<double> seam_d2_;
  std::vector<float> window_, scratch_;
  bool count_implausible_ = false;
};

// Opens every input of `options` (the errors and messages of load_inputs: missing files, no CRS,
// unsupported CRS, too small, ...; a VRT naming a missing tile is refused here already). GDAL-
// readable inputs (and web tiles) stay OPEN and are read by windows through
// SourceRaster::read_window, as are SRTM HGT tiles (open_hgt_source); .npz, PNG/EXR and raw inputs
// are read whole. The inputs are taken in the order of precedence: with options.finer_wins finest
// first (finer_first_order, precedence.h), else in list order; inputs() lists them so. The first
// sets the mosaic's grid and CRS; an input that needs resampling (another CRS or spacing) is seen
// on that grid through a ResampledInput, read by windows like the others. memory_limit_bytes:
// budget for what this source itself holds (inputs held whole at 4 B per sample, the resampled
// inputs' anchors). files_checked: ReadOptions::files_checked (a work unit, whose plan's files
// were stat'ed).
Status open_mosaic_source(const InputOptions& options, uint64_t memory_limit_bytes, MosaicSource& out,
                          bool files_checked = false);

}  // namespace terrain::cook
