#include "mosaic/resample_inputs.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <memory>

#include "frame/anchor_grid.h"
#include "frame/crs.h"
#include "base/memory_budget.h"
#include "inputs/source_raster.h"

namespace terrain::cook {

bool needs_resampling(const Raster& ref, const Raster& r) {
  if (!same_crs(r.crs, ref.crs)) return true;
  for (int k : {1, 2, 4, 5})
    if (std::fabs(r.geo.c[k] - ref.geo.c[k]) > 1e-9 * (std::fabs(ref.geo.c[1]) + std::fabs(ref.geo.c[5]))) return true;
  return false;
}

struct ResampledInput::Impl {
  InputLayer layer;
  AnchorGrid to_input;  // grid sample (x, y) of this layer -> input sample (col, row)
  int tile = 256;       // grid samples per side of the tiles read() works in
  std::vector<double> xs, a, b;
  std::vector<float> window, scratch;
  AnchorGrid::RowPlan plan;
  // Same CRS, both grids north-up (no rotation terms): the input column of a grid sample depends on
  // its column only, and its row on its row, each an exact affine function (separable_read).
  bool separable = false;
  // Input column of grid column x: col_scale * (col_offset + col_step * x); rows likewise.
  double col_offset = 0, col_scale = 0, col_step = 0, row_offset = 0, row_scale = 0, row_step = 0;
  std::vector<int> tap0;           // separable_read: per grid column of a tile, then per grid row, its first tap,
  std::vector<uint8_t> taps;       // its number of taps (0: no value: a tap falls outside the input),
  std::vector<double> weights;     // their weights (2 span + 2 per column or row)
  std::vector<double> weight_sum;  // and their sum
  std::vector<double> column;   // one grid row's vertical sums at the window's input columns
  Status separable_read(double rad, int x0, int y0, int w, int h, float* out);
};

ResampledInput::ResampledInput() = default;
ResampledInput::~ResampledInput() = default;

const Raster& ResampledInput::input() const { return impl_->layer.raster; }

uint64_t ResampledInput::bytes_read() const {
  return impl_->layer.source ? impl_->layer.source->info().bytes_read : 0;
}

uint64_t ResampledInput::resident_bytes() const {
  const Impl& m = *impl_;
  return uint64_t(m.window.capacity() + m.scratch.capacity()) * sizeof(float) +
         uint64_t(m.xs.capacity() + m.a.capacity() + m.b.capacity() + m.weights.capacity() +
                  m.weight_sum.capacity() + m.column.capacity()) * sizeof(double) +
         uint64_t(m.tap0.capacity()) * sizeof(int) + m.taps.capacity() +
         uint64_t(m.to_input.bytes());
}

Status ResampledInput::open(const Raster& ref, InputLayer layer, std::unique_ptr<ResampledInput>& out) {
  const Raster& in = layer.raster;
  PointTransform to_ref, to_in;
  switch (gdal_point_transforms(in.crs, ref.crs, to_ref, to_in)) {
    case CrsTransformStatus::ok: break;
    case CrsTransformStatus::no_geodetic_crs:
      return Status::failure(Error::unsupported_input,
                             fmt::format("{} ({}) and {} ({}) differ in CRS or sample spacing and one of them has no "
                                         "geodetic CRS to resample through; give inputs one pixel grid",
                                         ref.path, describe_crs(ref.crs), in.path, describe_crs(in.crs)));
    case CrsTransformStatus::no_transformation:
      return Status::failure(Error::unsupported_input,
                             fmt::format("no transformation from {} to {}", describe_crs(in.crs), describe_crs(ref.crs)));
  }
  // Where `in` lands on ref's grid: its border (half a sample beyond the outer centres, where pixel
  // areas reach; densified) through the CRS change.
  const AffineMap in_map = AffineMap::from(in.geo), ref_map = AffineMap::from(ref.geo);
  double cmin = INFINITY, rmin = INFINITY, cmax = -INFINITY, rmax = -INFINITY;
  constexpr int kEdgePoints = 256;
  for (int e = 0; e < 4; ++e)
    for (int k = 0; k <= kEdgePoints; ++k) {
      const double t = double(k) / kEdgePoints;
      const double lo_c = -0.5, hi_c = in.width - 0.5, lo_r = -0.5, hi_r = in.height - 0.5;
      const double col = e == 0 ? lo_c + t * (hi_c - lo_c) : e == 1 ? hi_c : e == 2 ? hi_c - t * (hi_c - lo_c) : lo_c;
      const double row = e == 0 ? lo_r : e == 1 ? lo_r + t * (hi_r - lo_r) : e == 2 ? hi_r : hi_r - t * (hi_r - lo_r);
      double x = 0, y = 0;
      in_map.to_model(col, row, x, y);
      if (!to_ref(x, y)) continue;
      double c = 0, r = 0;
      ref_map.to_sample(x, y, c, r);
      cmin = std::min(cmin, c);
      cmax = std::max(cmax, c);
      rmin = std::min(rmin, r);
      rmax = std::max(rmax, r);
    }
  if (!(cmin <= cmax && rmin <= rmax))
    return Status::failure(Error::unsupported_input,
                           fmt::format("{} cannot be placed in {}'s CRS ({})", in.path, ref.path, describe_crs(ref.crs)));
  const double c0 = std::floor(cmin), r0 = std::floor(rmin), c1 = std::ceil(cmax), r1 = std::ceil(rmax);
  const double wd = c1 - c0 + 1, hd = r1 - r0 + 1;
  if (wd * hd > double(int64_t(1) << 40) || wd > 1e9 || hd > 1e9)
    return Status::failure(Error::unsupported_input,
                           fmt::format("{} resampled onto {}'s grid would be {:.0f}x{:.0f} samples: too large", in.path,
                                       ref.path, wd, hd));
  auto r = std::unique_ptr<ResampledInput>(new ResampledInput());
  r->col_ = int64_t(c0);
  r->row_ = int64_t(r0);
  r->width_ = int(wd);
  r->height_ = int(hd);
  r->impl_ = std::make_unique<Impl>();
  Impl& m = *r->impl_;
  // Same CRS and north-up grids: positions from the two affine maps, no anchors (separable_read).
  m.separable =
      same_crs(in.crs, ref.crs) && in.geo.c[2] == 0 && in.geo.c[4] == 0 && ref.geo.c[2] == 0 && ref.geo.c[4] == 0;
  if (m.separable) {
    // input col = inv1 * ((ref.c0 - in.c0) + ref.c1 c0 + ref.c1 x): the difference of the origins
    // first (no cancellation at projected coordinates of 10^6 m).
    m.col_scale = in_map.inv[1];
    m.col_offset = (ref.geo.c[0] - in.geo.c[0]) + ref.geo.c[1] * c0;
    m.row_scale = in_map.inv[5];
    m.row_offset = (ref.geo.c[3] - in.geo.c[3]) + ref.geo.c[5] * r0;
    m.col_step = ref.geo.c[1];
    m.row_step = ref.geo.c[5];
    // The filter's radius from the exact scale (the anchors give the same to rounding).
    const double scale = std::max(std::fabs(m.col_scale * ref.geo.c[1]), std::fabs(m.row_scale * ref.geo.c[5]));
    r->radius_ = std::max(1.0, scale);
  } else {
    // Anchors at most ~2^20 (16 MB) whatever the footprint, at least every 16 grid samples; one
    // cell beyond each edge for the Catmull-Rom taps.
    const double step = std::max(16.0, std::ceil(std::sqrt(wd * hd / double(1 << 20))));
    const int nx = int(std::floor((wd - 1) / step)) + 4, ny = int(std::floor((hd - 1) / step)) + 4;
    // One thread: a transformation is not to be shared between threads.
    m.to_input.build(-step, -step, step, nx, ny,
                     [&](double x, double y, double& a, double& b) {
                       double gx = 0, gy = 0;
                       ref_map.to_model(c0 + x, r0 + y, gx, gy);
                       if (!to_in(gx, gy)) {
                         a = b = NAN;
                         return;
                       }
                       in_map.to_sample(gx, gy, a, b);
                     },
                     1);
    // Input samples per grid sample at the footprint's centre: the filter's radius.
    {
      const double cx = 0.5 * (wd - 1), cy = 0.5 * (hd - 1);
      double a0 = 0, b0 = 0, ax = 0, bx = 0, ay = 0, by = 0;
      m.to_input.eval(cx, cy, a0, b0);
      m.to_input.eval(cx + 1, cy, ax, bx);
      m.to_input.eval(cx, cy + 1, ay, by);
      const double scale = std::max(std::hypot(ax - a0, bx - b0), std::hypot(ay - a0, by - b0));
      if (!std::isfinite(scale))
        return Status::failure(Error::unsupported_input, fmt::format("{} cannot be placed in {}'s CRS ({}): no position "
                                                                     "at its centre", in.path, ref.path,
                                                                     describe_crs(ref.crs)));
      r->radius_ = std::max(1.0, scale);
    }
  }
  // Tiles whose input window stays near 1024 x 1024 samples.
  m.tile = std::clamp(int(1024.0 / r->radius_), 8, 256);
  m.layer = std::move(layer);
  r->implausible_ = m.layer.raster.implausible;
  if (m.layer.source) {
    // Count the implausible heights once, in strips of rows (read() reads overlapping windows).
    Raster::Implausible count;
    const int width = m.layer.raster.width, height = m.layer.raster.height;
    const int rows = std::max(1, int((uint64_t(1) << 22) / uint64_t(std::max(width, 1))));
    for (int y = 0; y < height; y += rows) {
      const int h = std::min(rows, height - y);
      m.window.resize(size_t(width) * size_t(h));
      TERRAIN_TRY(read_layer_window(m.layer, 0, y, width, h, m.window.data(), m.scratch, &count));
    }
    r->implausible_ = count;
    m.window = std::vector<float>();
    m.scratch = std::vector<float>();
  }
  out = std::move(r);
  return Status::success();
}

namespace {

// The taps of a tent of radius `rad` at input position p (|p - k| < rad, positive weights only)
// inside [k_lo, k_hi]: their first index, their number (0 when a tap falls outside), their weights.
inline uint8_t tent_taps(double p, double rad, int k_lo, int k_hi, int& first, double* w) {
  const int k0 = int(std::floor(p - rad)) + 1, k1 = int(std::ceil(p + rad)) - 1;
  if (!std::isfinite(p) || k0 < k_lo || k1 > k_hi) return 0;
  uint8_t n = 0;
  first = k0;
  for (int k = k0; k <= k1; ++k) {
    const double wk = 1.0 - std::fabs(p - k) / rad;
    if (wk <= 0) {
      if (n == 0) first = k + 1;  // a leading zero weight (p on a sample): start after it
      continue;
    }
    w[n++] = wk;
  }
  return n;
}

}  // namespace

// The tent filter of read() as a vertical then a horizontal pass: per grid row, the weighted sums of
// its taps' input rows at every input column of the window; per grid sample, the weighted sum of
// those at its taps' columns, over the product of the two weight sums. A tap with a positive weight
// that is a hole makes the sample a hole (NaN propagates). Each value depends on the sample's
// column, row and the input only.
Status ResampledInput::Impl::separable_read(double rad, int x0, int y0, int w, int h, float* out) {
  const int span = int(std::ceil(rad));  // taps reach floor(p) - span + 1 .. floor(p) + span
  const size_t stride = size_t(2 * span + 2);
  const Raster& in = layer.raster;
  const auto col_pos = [&](int x) { return col_scale * (col_offset + col_step * double(x)); };
  const auto row_pos = [&](int y) { return row_scale * (row_offset + row_step * double(y)); };
  for (int ty = y0; ty < y0 + h; ty += tile)
    for (int tx = x0; tx < x0 + w; tx += tile) {
      const int tw = std::min(tile, x0 + w - tx), th = std::min(tile, y0 + h - ty);
      // The input rectangle the tile's taps need (positions are monotonic along each axis).
      const double a0 = col_pos(tx), a1 = col_pos(tx + tw - 1), b0 = row_pos(ty), b1 = row_pos(ty + th - 1);
      const double ia0 = std::max(0.0, std::floor(std::min(a0, a1)) - span);
      const double ia1 = std::min(double(in.width - 1), std::floor(std::max(a0, a1)) + span);
      const double ib0 = std::max(0.0, std::floor(std::min(b0, b1)) - span);
      const double ib1 = std::min(double(in.height - 1), std::floor(std::max(b0, b1)) + span);
      if (!(ia0 <= ia1 && ib0 <= ib1)) {
        for (int j = 0; j < th; ++j) std::fill_n(out + size_t(ty - y0 + j) * size_t(w) + size_t(tx - x0), tw, NAN);
        continue;
      }
      const int wx0 = int(ia0), wy0 = int(ib0), ww = int(ia1) - wx0 + 1, wh = int(ib1) - wy0 + 1;
      window.resize(size_t(ww) * size_t(wh));
      TERRAIN_TRY(read_layer_window(layer, wx0, wy0, ww, wh, window.data(), scratch, nullptr));
      // Taps and weight sums of the tile's columns, then of its rows.
      const size_t n = size_t(tw) + size_t(th);
      tap0.resize(n);
      taps.resize(n);
      weights.resize(n * stride);
      weight_sum.resize(n);
      for (size_t k = 0; k < n; ++k) {
        const bool is_col = k < size_t(tw);
        const double p = is_col ? col_pos(tx + int(k)) : row_pos(ty + int(k - size_t(tw)));
        double* wk = &weights[k * stride];
        taps[k] = is_col ? tent_taps(p, rad, wx0, wx0 + ww - 1, tap0[k], wk) : tent_taps(p, rad, wy0, wy0 + wh - 1, tap0[k], wk);
        double sum = 0;
        for (uint8_t t = 0; t < taps[k]; ++t) sum += wk[t];
        weight_sum[k] = sum;
      }
      column.resize(size_t(ww));
      for (int j = 0; j < th; ++j) {
        float* o = out + size_t(ty - y0 + j) * size_t(w) + size_t(tx - x0);
        const size_t rk = size_t(tw) + size_t(j);
        if (taps[rk] == 0) {
          std::fill_n(o, tw, NAN);
          continue;
        }
        // Vertical: the row's taps at every input column of the window.
        const double* wy = &weights[rk * stride];
        std::fill(column.begin(), column.end(), 0.0);
        for (uint8_t t = 0; t < taps[rk]; ++t) {
          const float* z = &window[size_t(tap0[rk] - wy0 + t) * size_t(ww)];
          const double wt = wy[t];
          for (size_t c = 0; c < size_t(ww); ++c) column[c] += wt * double(z[c]);
        }
        // Horizontal: each sample's taps along that row.
        for (int i = 0; i < tw; ++i) {
          const uint8_t nt = taps[size_t(i)];
          if (nt == 0) {
            o[i] = NAN;
            continue;
          }
          const double* wx = &weights[size_t(i) * stride];
          const double* c = &column[size_t(tap0[size_t(i)] - wx0)];
          double sum = 0;
          for (uint8_t t = 0; t < nt; ++t) sum += wx[t] * c[t];
          o[i] = float(sum / (weight_sum[size_t(i)] * weight_sum[rk]));
        }
      }
    }
  return Status::success();
}

Status ResampledInput::read(int x0, int y0, int w, int h, float* out) {
  if (x0 < 0 || y0 < 0 || w <= 0 || h <= 0 || int64_t(x0) + w > width_ || int64_t(y0) + h > height_)
    return Status::failure(Error::invalid_argument, fmt::format("resampled window {}x{} at ({}, {}) outside {}x{}", w, h,
                                                                x0, y0, width_, height_));
  Impl& m = *impl_;
  if (m.separable) return m.separable_read(radius_, x0, y0, w, h, out);
  const Raster& in = m.layer.raster;
  const double rad = radius_;
  const int span = int(std::ceil(rad));  // taps reach floor(p) - span + 1 .. floor(p) + span
  for (int ty = y0; ty < y0 + h; ty += m.tile)
    for (int tx = x0; tx < x0 + w; tx += m.tile) {
      const int tw = std::min(m.tile, x0 + w - tx), th = std::min(m.tile, y0 + h - ty);
      // Input positions of the tile's samples, and the input rectangle their taps need.
      m.xs.resize(size_t(tw));
      for (int i = 0; i < tw; ++i) m.xs[size_t(i)] = double(tx + i);
      m.to_input.plan_row(m.xs.data(), tw, m.plan);
      m.a.resize(size_t(tw) * size_t(th));
      m.b.resize(size_t(tw) * size_t(th));
      double amin = INFINITY, amax = -INFINITY, bmin = INFINITY, bmax = -INFINITY;
      for (int j = 0; j < th; ++j) {
        double* a = &m.a[size_t(j) * size_t(tw)];
        double* b = &m.b[size_t(j) * size_t(tw)];
        m.to_input.eval_planned(double(ty + j), m.plan, a, b);
        for (int i = 0; i < tw; ++i)
          if (std::isfinite(a[i]) && std::isfinite(b[i])) {
            amin = std::min(amin, a[i]);
            amax = std::max(amax, a[i]);
            bmin = std::min(bmin, b[i]);
            bmax = std::max(bmax, b[i]);
          }
      }
      const double ia0 = std::max(0.0, std::floor(amin) - span), ia1 = std::min(double(in.width - 1), std::floor(amax) + span);
      const double ib0 = std::max(0.0, std::floor(bmin) - span), ib1 = std::min(double(in.height - 1), std::floor(bmax) + span);
      const bool any = amin <= amax && ia0 <= ia1 && ib0 <= ib1;
      int wx0 = 0, wy0 = 0, ww = 0, wh = 0;
      if (any) {
        wx0 = int(ia0);
        wy0 = int(ib0);
        ww = int(ia1) - wx0 + 1;
        wh = int(ib1) - wy0 + 1;
        m.window.resize(size_t(ww) * size_t(wh));
        TERRAIN_TRY(read_layer_window(m.layer, wx0, wy0, ww, wh, m.window.data(), m.scratch, nullptr));
      }
      for (int j = 0; j < th; ++j)
        for (int i = 0; i < tw; ++i) {
          float& o = out[size_t(ty - y0 + j) * size_t(w) + size_t(tx - x0 + i)];
          o = NAN;
          const double pa = m.a[size_t(j) * size_t(tw) + size_t(i)], pb = m.b[size_t(j) * size_t(tw) + size_t(i)];
          if (!any || !std::isfinite(pa) || !std::isfinite(pb)) continue;
          // Taps with a non-zero tent weight: |p - k| < rad.
          const int ka0 = int(std::floor(pa - rad)) + 1, ka1 = int(std::ceil(pa + rad)) - 1;
          const int kb0 = int(std::floor(pb - rad)) + 1, kb1 = int(std::ceil(pb + rad)) - 1;
          if (ka0 < wx0 || kb0 < wy0 || ka1 >= wx0 + ww || kb1 >= wy0 + wh) continue;  // beyond the input
          double sum = 0, wsum = 0;
          bool hole = false;
          for (int kb = kb0; kb <= kb1 && !hole; ++kb) {
            const double wy = 1.0 - std::fabs(pb - kb) / rad;
            if (wy <= 0) continue;
            const float* row = &m.window[size_t(kb - wy0) * size_t(ww)];
            for (int ka = ka0; ka <= ka1; ++ka) {
              const double wxk = 1.0 - std::fabs(pa - ka) / rad;
              if (wxk <= 0) continue;
              const float z = row[ka - wx0];
              if (std::isnan(z)) {
                hole = true;
                break;
              }
              sum += wxk * wy * double(z);
              wsum += wxk * wy;
            }
          }
          if (!hole && wsum > 0) o = float(sum / wsum);
        }
    }
  return Status::success();
}

}  // namespace terrain::cook
