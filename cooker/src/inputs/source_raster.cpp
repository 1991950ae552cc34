// The whole-raster read on top of a window reader (load_inputs reads through read_layer_window instead,
// which adds the height rules; this stays for the readers' own tests).
#include "inputs/source_raster.h"

#include <algorithm>
#include <cmath>

#include "inputs/inputs.h"

namespace terrain::cook {

Status read_whole_source(SourceRaster& src, const ReadOptions& options, Raster& out) {
  const SourceInfo& info = src.info();
  if (Status st = check_raster_memory(info.path, uint64_t(info.width), uint64_t(info.height), info.sample_type, options,
                                      src.scratch_bytes(info.width, info.height));
      !st.ok())
    return st;
  out = Raster{};
  out.path = info.path;
  out.width = info.width;
  out.height = info.height;
  out.values.assign(size_t(info.width) * size_t(info.height), NAN);
  // One window; the source bands it by rows internally so its scratch stays bounded.
  if (Status st = src.read_window(0, 0, info.width, info.height, out.values.data()); !st.ok()) {
    out = Raster{};
    return st;
  }
  out.geo = info.geo;
  out.crs = info.crs;
  out.nodata_declared = info.nodata.has_value();
  out.description = info.description;
  return Status::success();
}

}  // namespace terrain::cook
