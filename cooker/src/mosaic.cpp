#include "mosaic.h"

#include <cmath>
#include <fmt/format.h>

#include "crs.h"
#include "memory_budget.h"
#include "resample_inputs.h"

namespace terrain::cook {

Status mosaic(std::vector<Raster>& inputs, Raster& out, uint64_t memory_limit_bytes) {
  if (inputs.empty()) return Status::failure(Error::invalid_argument, "no inputs to mosaic");
  if (inputs.size() == 1) {
    out = std::move(inputs[0]);
    inputs.clear();
    return Status::success();
  }
  const Raster& ref = inputs[0];
  const AffineMap ref_map = AffineMap::from(ref.geo);
  struct Placement { int64_t col, row; };
  std::vector<Placement> at(inputs.size());
  int64_t c0 = 0, r0 = 0, c1 = ref.width, r1 = ref.height;
  double ref_lon = 0, ref_lat = 0;
  ref_map.to_model(0.5 * (ref.width - 1), 0.5 * (ref.height - 1), ref_lon, ref_lat);
  uint64_t held_bytes = 0;
  for (const Raster& r : inputs) held_bytes += uint64_t(r.values.size()) * sizeof(float);
  for (size_t i = 0; i < inputs.size(); ++i) {
    Raster& r = inputs[i];
    if (i > 0 && needs_resampling(ref, r)) {
      // Another CRS or spacing: onto the first input's grid (resample_inputs.h), then a tile as any.
      Raster resampled;
      if (Status st = resample_onto_grid(ref, r, held_bytes, memory_limit_bytes, resampled); !st.ok()) return st;
      held_bytes += uint64_t(resampled.values.size()) * sizeof(float);
      held_bytes -= uint64_t(r.values.size()) * sizeof(float);
      r = std::move(resampled);
    }
    if (r.crs.kind == CrsKind::geographic) {
      // Tiles either side of the antimeridian (N19E179 and N19W180) are neighbours: move each
      // input by whole turns to within half a turn of the first one, so they share one grid.
      double lon = 0, lat = 0;
      AffineMap::from(r.geo).to_model(0.5 * (r.width - 1), 0.5 * (r.height - 1), lon, lat);
      r.geo.c[0] += std::remainder(lon - ref_lon, 360.0) - (lon - ref_lon);
    }
    if (!same_crs(r.crs, ref.crs))
      return Status::failure(Error::unsupported_input,
                             fmt::format("{} and {} are in different CRSs ({} vs {}); mosaicked inputs must share one "
                                         "(reproject with gdalwarp first)", ref.path, r.path, describe_crs(ref.crs),
                                         describe_crs(r.crs)));
    for (int k : {1, 2, 4, 5})
      if (std::fabs(r.geo.c[k] - ref.geo.c[k]) > 1e-9 * (std::fabs(ref.geo.c[1]) + std::fabs(ref.geo.c[5])))
        return Status::failure(Error::unsupported_input,
                               fmt::format("{} and {} have different sample spacings; mosaicked inputs must share one "
                                           "pixel grid (resample with gdalwarp -tr first)", ref.path, r.path));
    double col = 0, row = 0;
    ref_map.to_sample(r.geo.c[0], r.geo.c[3], col, row);
    const double rc = std::round(col), rr = std::round(row);
    if (std::fabs(col - rc) > 1e-3 || std::fabs(row - rr) > 1e-3)
      return Status::failure(Error::unsupported_input,
                             fmt::format("{} is offset by a fraction of a sample ({:.4f}, {:.4f}) from {}; mosaicked "
                                         "inputs must share one pixel grid", r.path, col - rc, row - rr, ref.path));
    at[i] = {int64_t(rc), int64_t(rr)};
    c0 = std::min(c0, at[i].col);
    r0 = std::min(r0, at[i].row);
    c1 = std::max(c1, at[i].col + r.width);
    r1 = std::max(r1, at[i].row + r.height);
  }
  const int64_t w = c1 - c0, h = r1 - r0;
  if (w * h > (int64_t(1) << 32))
    return Status::failure(Error::unsupported_input, fmt::format("the mosaic would be {}x{} samples: too large", w, h));
  // The cook will hold the mosaic (kCookBytesPerSample each); while it is built, the inputs too.
  uint64_t inputs_bytes = 0;
  for (const Raster& r : inputs) inputs_bytes += uint64_t(r.values.size()) * sizeof(float);
  if (Status st = check_memory(uint64_t(w * h) * kCookBytesPerSample + inputs_bytes, memory_limit_bytes,
                               fmt::format("the mosaic of {} and {} other inputs", ref.path, inputs.size() - 1),
                               fmt::format("{} samples of {}x{} ({} B each while cooking) and its {} inputs",
                                           format_count(uint64_t(w * h)), w, h, kCookBytesPerSample, inputs.size()),
                               "raise --memory-limit, or cook inputs far apart in separate archives");
      !st.ok())
    return st;
  Raster m;
  m.path = ref.path;
  m.width = int(w);
  m.height = int(h);
  m.crs = ref.crs;
  m.values.assign(size_t(w * h), NAN);
  m.geo = ref.geo;
  ref_map.to_model(double(c0), double(r0), m.geo.c[0], m.geo.c[3]);
  std::string desc = fmt::format("mosaic {}x{} of {} inputs:", w, h, inputs.size());
  for (size_t i = 0; i < inputs.size(); ++i) {
    const Raster& r = inputs[i];
    for (int row = 0; row < r.height; ++row) {
      float* dst = &m.values[size_t(at[i].row - r0 + row) * size_t(w) + size_t(at[i].col - c0)];
      const float* src = &r.values[size_t(row) * size_t(r.width)];
      for (int col = 0; col < r.width; ++col)
        if (std::isnan(dst[col])) dst[col] = src[col];  // first listed input wins
    }
    desc += fmt::format(" [{}: {}]", r.path, r.description);
  }
  m.description = desc;
  inputs.clear();
  out = std::move(m);
  return Status::success();
}

}  // namespace terrain::cook
