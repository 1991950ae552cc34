#include "mosaic/mosaic.h"

#include <cmath>
#include <fmt/format.h>

#include "base/memory_budget.h"
#include "mosaic/mosaic_source.h"

namespace terrain::cook {

// The inputs held whole as the layers of a MosaicSource, then one window covering all of it: the
// same placement and overlap code the windowed cook reads through.
Status mosaic(std::vector<Raster>& inputs, Raster& out, uint64_t memory_limit_bytes) {
  if (inputs.empty()) return Status::failure(Error::invalid_argument, "no inputs to mosaic");
  if (inputs.size() == 1) {
    out = std::move(inputs[0]);
    inputs.clear();
    return Status::success();
  }
  std::vector<MosaicSource::Layer> layers(inputs.size());
  std::vector<MosaicSource::InputStat> stats(inputs.size());
  uint64_t held_bytes = 0;
  for (size_t i = 0; i < inputs.size(); ++i) {
    held_bytes += uint64_t(inputs[i].values.size()) * sizeof(float);
    stats[i].path = inputs[i].path;
    stats[i].description = inputs[i].description;
    stats[i].crs = inputs[i].crs;
    stats[i].implausible = inputs[i].implausible;
    layers[i].input.raster = std::move(inputs[i]);
  }
  inputs.clear();
  MosaicSource src;
  if (Status st = MosaicSource::assemble(std::move(layers), std::move(stats), held_bytes, memory_limit_bytes, src);
      !st.ok())
    return st;
  const Raster& head = src.header();
  const uint64_t w = uint64_t(head.width), h = uint64_t(head.height);
  // The cook will hold the mosaic (kCookBytesPerSample each); while it is built, the inputs too.
  if (Status st = check_memory(w * h * kCookBytesPerSample + src.held_input_bytes(), memory_limit_bytes,
                               fmt::format("the mosaic of {} and {} other inputs", head.path, src.inputs().size() - 1),
                               fmt::format("{} samples of {}x{} ({} B each while cooking) and its {} inputs",
                                           format_count(w * h), w, h, kCookBytesPerSample, src.inputs().size()),
                               "raise --memory-limit, or cook inputs far apart in separate archives");
      !st.ok())
    return st;
  Raster m = head;
  m.values.resize(size_t(w * h));
  if (Status st = src.read(0, 0, int(w), int(h), m.values.data()); !st.ok()) return st;
  out = std::move(m);
  return Status::success();
}

}  // namespace terrain::cook
