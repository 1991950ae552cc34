#include "mosaic/mosaic_source.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fmt/format.h>

#include "frame/crs.h"
#include "base/memory_budget.h"
#include "mosaic/precedence.h"
#include "mosaic/resample_inputs.h"
#include "inputs/source_raster.h"
#include "inputs/tiff_blocks.h"

namespace terrain::cook {

MosaicSource::MosaicSource() = default;
MosaicSource::~MosaicSource() = default;
MosaicSource::MosaicSource(MosaicSource&&) noexcept = default;
MosaicSource& MosaicSource::operator=(MosaicSource&&) noexcept = default;

Status MosaicSource::assemble(std::vector<Layer> layers, std::vector<InputStat> stats, uint64_t held_bytes,
                              uint64_t memory_limit_bytes, MosaicSource& out) {
  out = MosaicSource{};
  if (layers.empty()) return Status::failure(Error::invalid_argument, "no inputs to mosaic");
  // Grid families (precedence.h), before any layer is placed on the first one's grid.
  std::vector<Family> families;
  std::vector<uint8_t> family_of_layer(layers.size());
  {
    std::vector<size_t> first_of;  // the first layer of each family
    for (size_t i = 0; i < layers.size(); ++i) {
      size_t f = 0;
      while (f < first_of.size() && needs_resampling(layers[first_of[f]].input.raster, layers[i].input.raster)) ++f;
      if (f == first_of.size()) {
        first_of.push_back(i);
        Family fam;
        double sx = 0, sy = 0;
        ground_spacing_axes_m(layers[i].input.raster, sx, sy);
        fam.spacing_m = std::min(sx, sy);
        families.push_back(std::move(fam));
      }
      families[f].inputs.push_back(i);
      family_of_layer[i] = uint8_t(std::min<size_t>(f, kMaxFamilies - 1));
    }
    // Beyond kMaxFamilies, the last number stands for all the rest (at the finest of their spacings).
    for (size_t f = kMaxFamilies; f < families.size(); ++f) {
      Family& last = families[kMaxFamilies - 1];
      last.spacing_m = std::min(last.spacing_m, families[f].spacing_m);
      last.inputs.insert(last.inputs.end(), families[f].inputs.begin(), families[f].inputs.end());
    }
    if (families.size() > kMaxFamilies) families.resize(kMaxFamilies);
  }
  const Raster& ref = layers[0].input.raster;
  const AffineMap ref_map = AffineMap::from(ref.geo);
  int64_t c0 = 0, r0 = 0, c1 = ref.width, r1 = ref.height;
  double ref_lon = 0, ref_lat = 0;
  ref_map.to_model(0.5 * (ref.width - 1), 0.5 * (ref.height - 1), ref_lon, ref_lat);
  for (size_t i = 0; i < layers.size(); ++i) {
    InputLayer& in = layers[i].input;
    Raster& r = in.raster;
    if (i > 0 && needs_resampling(ref, r)) {
      // Another CRS or spacing: seen on the first input's grid, read by windows (resample_inputs.h).
      const Raster header = [&] {
        Raster h;
        h.path = r.path;
        h.description = r.description;
        h.crs = r.crs;
        h.geo = r.geo;
        h.width = r.width;
        h.height = r.height;
        h.nodata_declared = r.nodata_declared;
        return h;
      }();
      const bool windowed = in.source != nullptr;
      held_bytes -= uint64_t(r.values.size()) * sizeof(float);  // counted again below when held whole
      std::unique_ptr<ResampledInput> resampled;
      TERRAIN_TRY(ResampledInput::open(ref, std::move(in), resampled));
      held_bytes += uint64_t(resampled->input().values.size()) * sizeof(float) + resampled->resident_bytes();
      if (Status st = check_memory(held_bytes, memory_limit_bytes, header.path,
                                   "its anchors and the inputs held whole",
                                   "raise --memory-limit, or reproject the inputs to one grid with gdalwarp first");
          !st.ok())
        return st;
      stats[i].implausible = resampled->implausible();
      stats[i].bytes_read = resampled->bytes_read();
      stats[i].windowed = windowed;
      in = InputLayer{};
      Raster& placed = in.raster;
      placed.path = header.path;
      placed.width = resampled->width();
      placed.height = resampled->height();
      placed.crs = ref.crs;
      placed.geo = ref.geo;
      ref_map.to_model(double(resampled->col()), double(resampled->row()), placed.geo.c[0], placed.geo.c[3]);
      placed.nodata_declared = header.nodata_declared;
      placed.implausible = resampled->implausible();
      placed.description = fmt::format("{}, resampled from {} onto the first input's grid as {}x{} (tent filter of "
                                        "radius {:.3g} input samples)",
                                        header.description, describe_crs(header.crs), placed.width, placed.height,
                                        resampled->radius());
      layers[i].resampled = std::move(resampled);
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
    layers[i].col = int64_t(rc);
    layers[i].row = int64_t(rr);
    c0 = std::min(c0, layers[i].col);
    r0 = std::min(r0, layers[i].row);
    c1 = std::max(c1, layers[i].col + r.width);
    r1 = std::max(r1, layers[i].row + r.height);
  }
  const int64_t w = c1 - c0, h = r1 - r0;
  if (w * h > (int64_t(1) << 32))
    return Status::failure(Error::unsupported_input, fmt::format("the mosaic would be {}x{} samples: too large", w, h));
  Raster m;
  if (layers.size() == 1) {
    // A single input is the mosaic as it is.
    m.path = ref.path;
    m.description = ref.description;
    m.width = ref.width;
    m.height = ref.height;
    m.geo = ref.geo;
    m.crs = ref.crs;
    m.nodata_declared = ref.nodata_declared;
  } else {
    m.path = ref.path;
    m.width = int(w);
    m.height = int(h);
    m.crs = ref.crs;
    m.geo = ref.geo;
    ref_map.to_model(double(c0), double(r0), m.geo.c[0], m.geo.c[3]);
    m.description = fmt::format("mosaic {}x{} of {} inputs:", w, h, layers.size());
    for (const Layer& l : layers) m.description += fmt::format(" [{}: {}]", l.input.raster.path, l.input.raster.description);
  }
  for (Layer& l : layers) {
    l.col -= c0;
    l.row -= r0;
  }
  out.header_ = std::move(m);
  out.layers_ = std::move(layers);
  out.stats_ = std::move(stats);
  out.families_ = std::move(families);
  out.family_of_layer_ = std::move(family_of_layer);
  return Status::success();
}

Status MosaicSource::read(int c0, int r0, int w, int h, float* out, uint8_t* family) {
  if (w < 0 || h < 0)
    return Status::failure(Error::invalid_argument, fmt::format("mosaic window {}x{}: negative size", w, h));
  if (seam_radius_ == 0 || w == 0 || h == 0) return compose(c0, r0, w, h, out, family, nullptr, count_implausible_);
  if (!family) {
    own_family_.resize(size_t(w) * size_t(h));
    family = own_family_.data();
  }
  TERRAIN_TRY(compose(c0, r0, w, h, out, family, nullptr, count_implausible_));
  return blend_seams(c0, r0, w, h, family, out);
}

void MosaicSource::enable_seam_blend() {
  seam_band_m_.clear();
  seam_radius_ = 0;
  if (families_.size() < 2 || layers_.empty()) return;
  ground_spacing_axes_m(layers_[0].input.raster, seam_sx_, seam_sy_);
  if (!(seam_sx_ > 0 && seam_sy_ > 0)) return;
  seam_band_m_.assign(families_.size(), 0.0);
  double widest = 0;
  for (size_t f = 0; f + 1 < families_.size(); ++f) {
    double coarser = INFINITY;
    for (size_t g = f + 1; g < families_.size(); ++g) coarser = std::min(coarser, families_[g].spacing_m);
    seam_band_m_[f] = 2.0 * coarser;
    widest = std::max(widest, seam_band_m_[f]);
  }
  seam_radius_ = int(std::ceil(widest / std::min(seam_sx_, seam_sy_))) + 1;
}

namespace {

// Squared distances along a line of n values: d[p] = min over q of g[q] + s2 (p - q)^2, g[q]
// INFINITY where unset (Felzenszwalb and Huttenlocher's lower envelope of parabolas; exact).
void distance_1d(const double* g, int n, double s2, double* d, std::vector<int>& v, std::vector<double>& z) {
  v.resize(size_t(n));
  z.resize(size_t(n) + 1);
  int k = -1;
  for (int q = 0; q < n; ++q) {
    if (!std::isfinite(g[q])) continue;
    double s = -INFINITY;
    while (k >= 0) {
      const int p = v[size_t(k)];
      s = ((g[q] + s2 * q * q) - (g[p] + s2 * p * p)) / (2.0 * s2 * (q - p));
      if (s <= z[size_t(k)]) --k;
      else break;
    }
    ++k;
    v[size_t(k)] = q;
    z[size_t(k)] = k == 0 ? -INFINITY : s;
    z[size_t(k) + 1] = INFINITY;
  }
  if (k < 0) {
    std::fill_n(d, n, INFINITY);
    return;
  }
  int j = 0;
  for (int q = 0; q < n; ++q) {
    while (z[size_t(j) + 1] < q) ++j;
    const int p = v[size_t(j)];
    d[q] = s2 * double(q - p) * double(q - p) + g[p];
  }
}

}  // namespace

Status MosaicSource::blend_seams(int c0, int r0, int w, int h, const uint8_t* family, float* out) {
  constexpr int kTile = 256;
  const int R = seam_radius_;
  const size_t nfam = seam_band_m_.size();
  std::vector<int> v;
  std::vector<double> z, line, col;
  for (int ty = r0; ty < r0 + h; ty += kTile)
    for (int tx = c0; tx < c0 + w; tx += kTile) {
      const int tw = std::min(kTile, c0 + w - tx), th = std::min(kTile, r0 + h - ty);
      // Only where layers of two families meet the tile (their placed boxes, grown by the band).
      const int64_t gx0 = int64_t(tx) - R, gy0 = int64_t(ty) - R, gx1 = int64_t(tx) + tw + R, gy1 = int64_t(ty) + th + R;
      int fmin = kNoFamily, fmax = -1;
      for (size_t i = 0; i < layers_.size(); ++i) {
        const Layer& l = layers_[i];
        if (l.col >= gx1 || l.row >= gy1 || l.col + l.input.raster.width <= gx0 || l.row + l.input.raster.height <= gy0)
          continue;
        fmin = std::min<int>(fmin, family_of_layer_[i]);
        fmax = std::max<int>(fmax, family_of_layer_[i]);
      }
      if (fmax <= fmin) continue;
      bool owned_by_finer = false;  // an inner sample of a family with a band
      for (int j = 0; j < th && !owned_by_finer; ++j)
        for (int i = 0; i < tw; ++i) {
          const uint8_t f = family[size_t(ty - r0 + j) * size_t(w) + size_t(tx - c0 + i)];
          if (f < nfam && seam_band_m_[f] > 0) {
            owned_by_finer = true;
            break;
          }
        }
      if (!owned_by_finer) continue;
      const int gw = tw + 2 * R, gh = th + 2 * R;
      const size_t gn = size_t(gw) * size_t(gh);
      tile_values_.resize(gn);
      tile_family_.resize(gn);
      tile_next_.resize(gn);
      TERRAIN_TRY(compose(int(gx0), int(gy0), gw, gh, tile_values_.data(), tile_family_.data(), tile_next_.data(), false));
      seam_d2_.resize(gn);
      line.resize(size_t(std::max(gw, gh)));
      col.resize(size_t(gh));
      for (size_t f = 0; f + 1 < nfam; ++f) {
        if (!(seam_band_m_[f] > 0) || int(f) < fmin || int(f) >= fmax) continue;
        bool any = false;  // an inner sample of f with a coarser value under it
        for (int j = 0; j < th && !any; ++j)
          for (int i = 0; i < tw && !any; ++i) {
            const size_t k = size_t(j + R) * size_t(gw) + size_t(i + R);
            any = tile_family_[k] == f && !std::isnan(tile_next_[k]);
          }
        if (!any) continue;
        // Squared ground distance to the nearest sample a coarser family holds (where it takes over).
        for (int j = 0; j < gh; ++j) {
          for (int i = 0; i < gw; ++i) {
            const uint8_t g = tile_family_[size_t(j) * size_t(gw) + size_t(i)];
            line[size_t(i)] = g != kNoFamily && g > f ? 0.0 : INFINITY;
          }
          distance_1d(line.data(), gw, seam_sx_ * seam_sx_, &seam_d2_[size_t(j) * size_t(gw)], v, z);
        }
        for (int i = R; i < R + tw; ++i) {
          for (int j = 0; j < gh; ++j) line[size_t(j)] = seam_d2_[size_t(j) * size_t(gw) + size_t(i)];
          distance_1d(line.data(), gh, seam_sy_ * seam_sy_, col.data(), v, z);
          for (int j = R; j < R + th; ++j) {
            const size_t k = size_t(j) * size_t(gw) + size_t(i);
            if (tile_family_[k] != f || std::isnan(tile_next_[k])) continue;
            const double d = std::sqrt(col[size_t(j)]);
            if (!(d < seam_band_m_[f])) continue;
            const double coarser = tile_next_[k], own = tile_values_[k];
            out[size_t(ty - r0 + j - R) * size_t(w) + size_t(tx - c0 + i - R)] =
                float(coarser + d / seam_band_m_[f] * (own - coarser));
          }
        }
      }
    }
  return Status::success();
}

Status MosaicSource::compose(int c0, int r0, int w, int h, float* out, uint8_t* family, float* next, bool count) {
  const int64_t wc0 = c0, wr0 = r0, wc1 = wc0 + w, wr1 = wr0 + h;
  // One input holding the whole window (the common case): read straight into `out`.
  if (layers_.size() == 1 && layers_[0].input.source && !next) {
    Layer& l = layers_[0];
    const Raster& r = l.input.raster;
    if (wc0 >= l.col && wr0 >= l.row && wc1 <= l.col + r.width && wr1 <= l.row + r.height && w > 0 && h > 0) {
      if (Status st = read_layer_window(l.input, int(wc0 - l.col), int(wr0 - l.row), w, h, out, scratch_,
                                        count ? &stats_[0].implausible : nullptr);
          !st.ok())
        return st;
      stats_[0].bytes_read = l.input.source->info().bytes_read;
      if (family)
        for (size_t k = 0, n = size_t(w) * size_t(h); k < n; ++k) family[k] = std::isnan(out[k]) ? kNoFamily : 0;
      if (count) {
        uint64_t valid = 0;
        for (size_t k = 0, n = size_t(w) * size_t(h); k < n; ++k) valid += std::isnan(out[k]) ? 0 : 1;
        stats_[0].samples_read += valid;
        stats_[0].samples_used += valid;
      }
      return Status::success();
    }
  }
  std::fill_n(out, size_t(w) * size_t(h), NAN);
  if (family) std::fill_n(family, size_t(w) * size_t(h), kNoFamily);
  if (next) std::fill_n(next, size_t(w) * size_t(h), NAN);
  for (size_t i = 0; i < layers_.size(); ++i) {
    Layer& l = layers_[i];
    const Raster& r = l.input.raster;
    const int64_t x0 = std::max(wc0, l.col), x1 = std::min(wc1, l.col + r.width);
    const int64_t y0 = std::max(wr0, l.row), y1 = std::min(wr1, l.row + r.height);
    if (x0 >= x1 || y0 >= y1) continue;
    const int iw = int(x1 - x0), ih = int(y1 - y0);
    const float* src = nullptr;
    size_t src_stride = 0;
    if (l.resampled) {
      window_.resize(size_t(iw) * size_t(ih));
      if (Status st = l.resampled->read(int(x0 - l.col), int(y0 - l.row), iw, ih, window_.data()); !st.ok()) return st;
      stats_[i].bytes_read = l.resampled->bytes_read();
      src = window_.data();
      src_stride = size_t(iw);
    } else if (l.input.source) {
      window_.resize(size_t(iw) * size_t(ih));
      if (Status st = read_layer_window(l.input, int(x0 - l.col), int(y0 - l.row), iw, ih, window_.data(), scratch_,
                                        count ? &stats_[i].implausible : nullptr);
          !st.ok())
        return st;
      stats_[i].bytes_read = l.input.source->info().bytes_read;
      src = window_.data();
      src_stride = size_t(iw);
    } else {
      // Held whole (heights finished): straight from its values.
      src = &r.values[size_t(y0 - l.row) * size_t(r.width) + size_t(x0 - l.col)];
      src_stride = size_t(r.width);
    }
    uint64_t read = 0, used = 0;
    for (int row = 0; row < ih; ++row) {
      float* dst = out + size_t(y0 - wr0 + row) * size_t(w) + size_t(x0 - wc0);
      const float* s = src + size_t(row) * src_stride;
      if (count)
        for (int col = 0; col < iw; ++col) {
          const bool has = !std::isnan(s[col]);
          read += has ? 1 : 0;
          used += has && std::isnan(dst[col]) ? 1 : 0;
        }
      if (family) {
        uint8_t* fam = family + (dst - out);
        const uint8_t f = family_of_layer_[i];
        if (next) {
          // The first value of a coarser family under the sample's own (blend_seams' other side).
          float* nx = next + (dst - out);
          for (int col = 0; col < iw; ++col)
            if (!std::isnan(dst[col]) && !std::isnan(s[col]) && std::isnan(nx[col]) && f > fam[col]) nx[col] = s[col];
        }
        for (int col = 0; col < iw; ++col)
          if (std::isnan(dst[col]) && !std::isnan(s[col])) fam[col] = f;
      }
      for (int col = 0; col < iw; ++col)
        if (std::isnan(dst[col])) dst[col] = s[col];  // the input that takes precedence wins
    }
    stats_[i].samples_read += read;
    stats_[i].samples_used += used;
  }
  return Status::success();
}

uint64_t MosaicSource::held_input_bytes() const {
  uint64_t n = 0;
  for (const Layer& l : layers_) {
    n += uint64_t(l.input.raster.values.size()) * sizeof(float);
    if (l.resampled) n += uint64_t(l.resampled->input().values.size()) * sizeof(float);
  }
  return n;
}

uint64_t MosaicSource::resident_bytes() const {
  uint64_t n = 0;
  bool windowed = false;
  for (const Layer& l : layers_) {
    n += uint64_t(l.input.raster.values.capacity()) * sizeof(float);
    if (l.resampled) n += uint64_t(l.resampled->input().values.capacity()) * sizeof(float) + l.resampled->resident_bytes();
    windowed = windowed || l.input.source || (l.resampled && l.resampled->bytes_read() > 0);
  }
  n += uint64_t(window_.capacity() + scratch_.capacity()) * sizeof(float);
  return n + (windowed ? gdal_cache_used_bytes() + tiff_block_cache_used_bytes() : 0);
}

Status open_mosaic_source(const InputOptions& options, uint64_t memory_limit_bytes, MosaicSource& out,
                          bool files_checked) {
  out = MosaicSource{};
  ReadOptions ro;
  if (Status st = input_read_options(options, ro); !st.ok()) return st;
  ro.files_checked = files_checked;
  ro.bytes_per_sample = sizeof(float);  // what this source holds of an input read whole
  std::vector<std::string> paths;
  TERRAIN_TRY(expand_inputs(options.inputs, paths));
  TERRAIN_TRY(check_tile_encoding_use(options, paths));
  std::vector<MosaicSource::Layer> layers;
  std::vector<MosaicSource::InputStat> stats;
  uint64_t held = 0;
  for (const std::string& path : paths) {
    ro.memory_limit_bytes = memory_limit_bytes > held ? memory_limit_bytes - held : 0;
    MosaicSource::Layer l;
    TERRAIN_TRY(open_input_layer(path, options, ro, l.input));
    // A VRT's missing tile would only show when a window first reaches it: name it now.
    if (l.input.source && !files_checked)
      TERRAIN_TRY(check_vrt_tiles(path));
    const Raster& r = l.input.raster;
    MosaicSource::InputStat s;
    s.path = r.path;
    s.description = r.description;
    s.crs = r.crs;
    s.windowed = l.input.source != nullptr;
    s.height_unit = r.height_unit;
    if (s.windowed) s.decoder = l.input.source->info().decoder;
    if (!s.windowed) s.implausible = r.implausible;
    held += uint64_t(r.values.size()) * sizeof(float);
    stats.push_back(std::move(s));
    layers.push_back(std::move(l));
  }
  if (options.finer_wins && layers.size() > 1) {
    // Precedence: finest first (precedence.h); the layers and their stats in that order.
    std::vector<const Raster*> headers;
    for (const MosaicSource::Layer& l : layers) headers.push_back(&l.input.raster);
    const std::vector<size_t> order = finer_first_order(headers);
    std::vector<MosaicSource::Layer> ordered_layers;
    std::vector<MosaicSource::InputStat> ordered_stats;
    for (size_t i : order) {
      ordered_layers.push_back(std::move(layers[i]));
      ordered_stats.push_back(std::move(stats[i]));
    }
    layers = std::move(ordered_layers);
    stats = std::move(ordered_stats);
  }
  TERRAIN_TRY(MosaicSource::assemble(std::move(layers), std::move(stats), held, memory_limit_bytes, out));
  if (options.finer_wins) out.enable_seam_blend();
  return Status::success();
}

}  // namespace terrain::cook
