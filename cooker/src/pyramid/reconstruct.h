// The one continuous surface every level samples.
//
// Inside the data: Catmull-Rom bicubic (Keys a = -0.5, the kernel of gdalwarp -r cubic) over the
// 4x4 source samples around the point, in source sample space; it passes through every source
// sample and reproduces planes exactly. Taps beyond the raster's edge continue its two outermost
// samples linearly, the slope limited where the outermost step is a cliff beside the one inside it
// (continued_difference()). Where any tap is nodata, it falls back to bilinear over the valid taps
// of the surrounding 2x2 cell (weights renormalised). A point is a hole when its NEAREST source sample is nodata or outside the raster,
// so the covered area is the union of the valid samples' pixels (half a sample beyond the outer
// samples, also for point-sampled rasters: the data's own edge samples stay fully drawn; the
// archive's footprint and grid origin still follow their hull, frame.h). Beyond the raster's
// outer samples the covered band may be widened (set_outer_apron) to one finest-lattice vertex
// spacing when that exceeds half a sample (sources finer than 1 m): otherwise a triangle holding
// an outer sample can have a vertex outside the band and drop it.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "frame/anchor_grid.h"
#include "inputs/raster.h"
#include "base/sample_window.h"

namespace terrain::cook {

// std::floor for finite |x| < 2^52 without a libm call (x86-64 without SSE4.1 has no inline floor).
inline double fast_floor(double x) {
  const double t = double(int64_t(x));
  return t > x ? t - 1.0 : t;
}

// The per-sample difference the linear continuation beyond the raster's edge uses: `outer`, the
// difference of the two outermost samples of a row or column, limited to kContinuationRatio times
// `inner` (the next difference inwards, the same way round) plus kContinuationSlackM metres, so that
// a cliff between the two outermost samples (a fill value beside terrain, say) is not continued as
// a slope of the cliff's height per sample: each continued sample lies within
// (kContinuationRatio |inner| + kContinuationSlackM) per sample of the outermost one. Where the
// limit does not bind (planes, and edges whose outermost step is within it: terrain, trees, coastal
// bluffs) the result is `outer` itself, bit for bit; a NaN `inner` (nodata) leaves `outer` as it is.
constexpr double kContinuationRatio = 16.0;
constexpr double kContinuationSlackM = 256.0;
inline double continued_difference(double outer, double inner) {
  const double limit = kContinuationRatio * std::fabs(inner) + kContinuationSlackM;
  return outer > limit ? limit : outer < -limit ? -limit : outer;  // NaN limit: both false
}

class SourceSurface {
 public:
  SourceSurface() = default;
  // The whole raster in memory.
  explicit SourceSurface(const Raster& r)
      : z_(r.values.data()), stride_(r.width), rows_(r.height), w_(r.width), h_(r.height) {}
  // A window of the source (block-wise cook): sample coordinates stay the whole source's, and every
  // evaluation that reads only samples inside the window gives the bits the whole raster gives.
  explicit SourceSurface(const SampleWindow& win)
      : z_(win.values.data()), c0_(win.rect.c0), r0_(win.rect.r0), stride_(win.rect.width()), rows_(win.rect.height()),
        w_(win.source_width), h_(win.source_height) {}
  // Keeps the outer apron, replaces the samples.
  void set_samples(const SampleWindow& win) {
    const double ac = apron_c_, ar = apron_r_;
    *this = SourceSurface(win);
    apron_c_ = ac;
    apron_r_ = ar;
  }

  // How far (in samples, per axis) beyond the outer samples the surface is covered: 0.5 (the
  // pixel edge) by default, at most 1.5 (the linear continuation reaches two samples out).
  void set_outer_apron(double columns, double rows) {
    apron_c_ = std::clamp(columns, 0.5, 1.5);
    apron_r_ = std::clamp(rows, 0.5, 1.5);
  }

  // One axis of a sample position: the cell, the fraction and its Catmull-Rom weights.
  struct Axis {
    int i = 0;
    double t = 0, w[4] = {0, 0, 0, 0};
    bool in = false;  // a coordinate sample() can evaluate (finite, near the raster)
  };
  static Axis axis(double coord, int size) {
    Axis a;
    a.in = coord > -2.0 && coord < size + 1.0;  // NaN-safe
    if (!a.in) return a;
    const double f = fast_floor(coord);
    a.i = int(f);
    a.t = coord - f;
    catmull_rom_weights(a.t, a.w);
    return a;
  }
  Axis column(double col) const { return axis(col, w_); }
  Axis row(double r) const { return axis(r, h_); }

  // Whether the 4 taps i - 1 .. i + 2 of a raster axis of `size` samples all lie inside it: the
  // interior rule of every 16-tap sum below (and of sample_points' vector form).
  static constexpr bool taps_inside(int i, int size) { return i >= 1 && i + 2 < size; }

  // Height (metres) at sample coordinates (col, row) (sample centres at integers); false = hole.
  bool sample(double col, double row, double& h) const { return sample(column(col), this->row(row), h); }
  // The same from precomputed axes (a row or column of vertices shares one): identical bits.
  // Inline for the common case (all 16 taps inside the raster and valid).
  bool sample(const Axis& x, const Axis& y, double& h) const {
    if (!x.in || !y.in) return false;
    if (taps_inside(x.i, w_) && taps_inside(y.i, h_)) {
      // The nearest sample is one of the 16 taps and any NaN tap (nodata) poisons the sum (0 * NaN
      // is NaN), so a finite sum means the point is covered; otherwise the general path decides.
      const float* p = at(x.i - 1, y.i - 1);
      double sum = 0;
      for (int j = 0; j < 4; ++j, p += stride_)
        sum += y.w[j] * (x.w[0] * p[0] + x.w[1] * p[1] + x.w[2] * p[2] + x.w[3] * p[3]);
      if (!std::isnan(sum)) {
        h = sum;
        return true;
      }
    }
    return sample_general(x, y, h);
  }
  // Rows of vertices denser than the source's rows share source rows: the horizontal Catmull-Rom
  // sum of source row r at column axis x (x inside the raster with its 4 taps), cached by the
  // caller and combined by sample_rows() with the same operations as sample(): identical bits.
  bool x_interior(const Axis& x) const { return x.in && taps_inside(x.i, w_); }
  bool y_interior(const Axis& y) const { return y.in && taps_inside(y.i, h_); }
  double horizontal(const Axis& x, int r) const {
    const float* p = at(x.i - 1, r);
    return x.w[0] * p[0] + x.w[1] * p[1] + x.w[2] * p[2] + x.w[3] * p[3];
  }
  // `rows[j]` = horizontal(x, y.i - 1 + j); requires x_interior(x) and y_interior(y).
  bool sample_rows(const Axis& x, const Axis& y, const double* const rows[4], double& h) const {
    double sum = 0;  // NaN when any of the 16 taps is (see sample())
    for (int j = 0; j < 4; ++j) sum += y.w[j] * *rows[j];
    if (!std::isnan(sum)) {
      h = sum;
      return true;
    }
    return sample_general(x, y, h);
  }
  // Heights of n points (cols[k], rows[k]) at once, each with the bits sample() gives it; ok[k] = 0
  // where sample() returns false. Points whose rows and columns follow no grid (sources mapped
  // through the anchors): the axes of a whole run in loops that vectorise, then the 16-tap sums
  // with the four rows in vector lanes, a source cell's taps reused by the points that share it.
  void sample_points(const double* cols, const double* rows, int n, double* h, uint8_t* ok) const;

  // Whether every sample of columns c0..c1, rows r0..r1 is inside the raster and the window and is
  // zero (either sign; the sea of SRTM tiles). A point whose 16 taps all lie there has height +0
  // from sample() and sample_points(): every tap's product is a signed zero and each sum starts at
  // +0, so callers may write +0 without evaluating it (node_cook.cpp).
  bool zeros_in(int c0, int r0, int c1, int r1) const;
  // Points (col, row) with c_lo <= col < c_hi and r_lo <= row < r_hi read all 16 taps from samples
  // that zeros_in() holds, so sample() gives them +0.
  struct ZeroBounds {
    double c_lo = 1, c_hi = 0, r_lo = 1, r_hi = 0;  // empty: no such points
    bool holds(double c, double r) const { return c >= c_lo && c < c_hi && r >= r_lo && r < r_hi; }  // NaN: false
  };
  // Bounds around the extent [cmin, cmax] x [rmin, rmax] of some points, `spare` samples wider on
  // every side, when every sample their taps could read is zero; empty otherwise.
  ZeroBounds zero_bounds(double cmin, double cmax, double rmin, double rmax, int spare) const;

  // Whether (col, row) is covered (nearest sample valid): the hole test of sample() alone.
  bool covered(double col, double row) const {
    if (!(col > -2.0 && row > -2.0 && col < w_ + 1.0 && row < h_ + 1.0)) return false;
    const double fc = fast_floor(col), fr = fast_floor(row);
    return nearest_valid(int(fc), int(fr), col - fc, row - fr);
  }

  // Edges of the raster, nodata taps and ties: the hole test, then Catmull-Rom with taps beyond
  // the raster continued linearly, else bilinear over the valid taps. sample() falls back to it;
  // public for callers that evaluate the interior sums themselves (node_cook.cpp).
  bool sample_general(const Axis& x, const Axis& y, double& h) const;

 private:
  // Sample (c, r) of the source (inside the window).
  const float* at(int c, int r) const { return z_ + ptrdiff_t(r - r0_) * stride_ + ptrdiff_t(c - c0_); }

  // Sample (c, r), with samples up to two beyond the raster extrapolated linearly from the two
  // outermost ones (NaN when those are nodata), the difference limited by continued_difference().
  // Needs a raster of at least 2x2 samples.
  double extended(int c, int r) const {
    if (r < 0) {
      const double d = row_extended(c, 1) - row_extended(c, 0);
      return row_extended(c, 0) + r * (h_ > 2 ? continued_difference(d, row_extended(c, 2) - row_extended(c, 1)) : d);
    }
    if (r >= h_) {
      const double d = row_extended(c, h_ - 1) - row_extended(c, h_ - 2);
      return row_extended(c, h_ - 1) +
             (r - h_ + 1) * (h_ > 2 ? continued_difference(d, row_extended(c, h_ - 2) - row_extended(c, h_ - 3)) : d);
    }
    return row_extended(c, r);
  }
  double row_extended(int c, int r) const {
    if (c < 0) {
      const double d = double(*at(1, r)) - *at(0, r);
      return *at(0, r) + c * (w_ > 2 ? continued_difference(d, double(*at(2, r)) - *at(1, r)) : d);
    }
    if (c >= w_) {
      const double d = double(*at(w_ - 1, r)) - *at(w_ - 2, r);
      return *at(w_ - 1, r) + (c - w_ + 1) * (w_ > 2 ? continued_difference(d, double(*at(w_ - 2, r)) - *at(w_ - 3, r)) : d);
    }
    return *at(c, r);
  }
  bool valid(int c, int r) const {
    return c >= 0 && r >= 0 && c < w_ && r < h_ && !std::isnan(*at(c, r));
  }
  // The nearest sample of (ic + tx, ir + ty) is valid; exactly halfway between two samples either
  // may carry the point, so pixel edges belong to the covered side in every direction.
  // Beyond the outer samples (up to the apron) the outermost sample of the row/column carries it.
  bool nearest_valid(int ic, int ir, double tx, double ty) const {
    const int c = ic + (tx > 0.5 ? 1 : 0), r = ir + (ty > 0.5 ? 1 : 0);
    if (valid(c, r)) return true;
    if (tx == 0.5 || ty == 0.5) {
      const int c2 = tx == 0.5 ? ic + 1 : c, r2 = ty == 0.5 ? ir + 1 : r;
      if (valid(c2, r) || valid(c, r2) || valid(c2, r2)) return true;
    }
    const double pc = ic + tx, pr = ir + ty;
    const int cc = pc < 0 && pc >= -apron_c_ ? 0 : pc > w_ - 1 && pc <= w_ - 1 + apron_c_ ? w_ - 1 : c;
    const int rr = pr < 0 && pr >= -apron_r_ ? 0 : pr > h_ - 1 && pr <= h_ - 1 + apron_r_ ? h_ - 1 : r;
    return (cc != c || rr != r) && valid(cc, rr);
  }
  // The outermost valid sample nearest (ic + tx, ir + ty), for points in the widened apron.
  double clamped_nearest(int ic, int ir, double tx, double ty) const {
    const int c = std::clamp(ic + (tx > 0.5 ? 1 : 0), 0, w_ - 1), r = std::clamp(ir + (ty > 0.5 ? 1 : 0), 0, h_ - 1);
    return *at(c, r);
  }

  const float* z_ = nullptr;
  int c0_ = 0, r0_ = 0;  // the window's first sample
  ptrdiff_t stride_ = 0;  // samples per window row
  int rows_ = 0;          // rows of the window
  int w_ = 0, h_ = 0;     // the whole source

  double apron_c_ = 0.5, apron_r_ = 0.5;
};

}  // namespace terrain::cook
