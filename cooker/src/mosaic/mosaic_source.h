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
  // outside the mosaic are NaN. Heights after every rule load_inputs applies, first listed input
  // wins. Called from one thread at a time (it reuses its scratch).
  Status read(int c0, int r0, int w, int h, float* out);

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
  Raster header_;
  std::vector<Layer> layers_;
  std::vector<InputStat> stats_;
  std::vector<float> window_, scratch_;
  bool count_implausible_ = false;
};

// Opens every input of `options` (the errors and messages of load_inputs: missing files, no CRS,
// unsupported CRS, too small, ...; a VRT naming a missing tile is refused here already). GDAL-
// readable inputs (and web tiles) stay OPEN and are read by windows through
// SourceRaster::read_window, as are SRTM HGT tiles (open_hgt_source); .npz, PNG/EXR and raw inputs are read whole. An input that needs
// resampling (another CRS or spacing than the first) is seen on the first input's grid through a
// ResampledInput, read by windows like the others. memory_limit_bytes: budget for what this source
// itself holds (inputs held whole at 4 B per sample, the resampled inputs' anchors).
// files_checked: ReadOptions::files_checked (a work unit, whose plan's files were stat'ed).
Status open_mosaic_source(const InputOptions& options, uint64_t memory_limit_bytes, MosaicSource& out,
                          bool files_checked = false);

}  // namespace terrain::cook
