#include "reconstruct.h"


namespace terrain::cook {

bool Surface::sample_general(const Axis& x, const Axis& y, double& h) const {
  const int ic = x.i, ir = y.i;
  const double tx = x.t, ty = y.t;
  const double* wx = x.w;
  const double* wy = y.w;
  if (!nearest_valid(ic, ir, tx, ty)) return false;  // the hole test of covered()
  double sum = 0;
  if (ic >= 1 && ir >= 1 && ic + 2 < w_ && ir + 2 < h_) {
    const float* p = at(ic - 1, ir - 1);
    for (int j = 0; j < 4; ++j, p += stride_)
      sum += wy[j] * (wx[0] * p[0] + wx[1] * p[1] + wx[2] * p[2] + wx[3] * p[3]);
  } else {
    // Next to the raster's edge: taps beyond it continue the two outermost samples linearly along
    // each axis, so planes (and the data's slope) carry on to the edge and across the half-sample
    // apron instead of flattening.
    for (int j = 0; j < 4; ++j) {
      const int r = ir - 1 + j;
      double along = 0;
      for (int i = 0; i < 4; ++i) along += wx[i] * extended(ic - 1 + i, r);
      sum += wy[j] * along;
    }
  }
  if (!std::isnan(sum)) {  // a NaN tap (nodata) poisons the sum: fall back below
    h = sum;
    return true;
  }
  // Bilinear over the valid taps of the 2x2 cell; a nearest tap is valid (covered) and carries
  // weight >= 1/4, so the normaliser is positive.
  sum = 0;
  double wsum = 0;
  for (int j = 0; j < 2; ++j) {
    const int r = ir + j;
    if (r < 0 || r >= h_) continue;
    const double wr = j ? ty : 1.0 - ty;
    for (int i = 0; i < 2; ++i) {
      const int c = ic + i;
      if (c < 0 || c >= w_) continue;
      const float v = *at(c, r);
      if (std::isnan(v)) continue;
      const double wgt = wr * (i ? tx : 1.0 - tx);
      sum += wgt * v;
      wsum += wgt;
    }
  }
  // No valid tap in the cell: a point in the widened outer apron (set_outer_apron) more than a
  // sample beyond the raster; the outermost sample it is covered by carries it.
  h = wsum > 0 ? sum / wsum : clamped_nearest(ic, ir, tx, ty);
  return true;
}

}  // namespace terrain::cook
