// A smooth 2-D -> 2-D map (a projection between frame and source sample coordinates) evaluated
// exactly at the nodes of a regular grid and Catmull-Rom interpolated in between. Projections are
// so smooth at these scales that the interpolation error stays far below a millimetre (tests/cooker
// check it), at a fraction of the exact GeographicLib call's cost per point (cooker/README.md, "Figures behind the code").
#pragma once
#include <cstddef>
#include <functional>
#include <vector>

namespace terrain::cook {

class AnchorGrid {
 public:
  using Exact = std::function<void(double x, double y, double& a, double& b)>;

  // Anchors at (x0 + i * step, y0 + j * step) for i < nx, j < ny (nx, ny >= 4).
  void build(double x0, double y0, double step, int nx, int ny, const Exact& exact, int threads);
  // Interpolated (a, b) at (x, y); points outside the grid are clamped to it.
  void eval(double x, double y, double& a, double& b) const;
  // The same for n points on one row y: interpolates along y once per anchor column, then along
  // x per point. Each result depends on its own (x, y) only (not on the other points), so a point
  // gets the same bits whichever batch it comes in; eval() may differ in the last bit.
  void eval_row(double y, const double* x, int n, double* a, double* b) const;
  // eval_row split in two for many rows sharing the same x (the vertex columns of a node window):
  // the per-point column cell and weights are computed once; eval_row() is plan_row() + eval_planned()
  // so both give the same bits.
  struct RowPlan {
    int i0 = 0, cols = 0;
    std::vector<int> cell;     // per point: first anchor column used, relative to i0
    std::vector<double> wx;    // per point: 4 Catmull-Rom weights
  };
  void plan_row(const double* x, int n, RowPlan& plan) const;
  void eval_planned(double y, const RowPlan& plan, double* a, double* b) const;

  bool empty() const { return values_.empty(); }
  double step() const { return step_; }
  size_t bytes() const { return values_.capacity() * sizeof(double); }

 private:
  double x0_ = 0, y0_ = 0, step_ = 1;
  int nx_ = 0, ny_ = 0;
  std::vector<double> values_;  // (a, b) pairs, row-major
};

// Catmull-Rom weights for fraction t in [0, 1] (taps -1, 0, 1, 2).
inline void catmull_rom_weights(double t, double w[4]) {
  const double t2 = t * t, t3 = t2 * t;
  w[0] = 0.5 * (-t3 + 2.0 * t2 - t);
  w[1] = 0.5 * (3.0 * t3 - 5.0 * t2 + 2.0);
  w[2] = 0.5 * (-3.0 * t3 + 4.0 * t2 + t);
  w[3] = 0.5 * (t3 - t2);
}

}  // namespace terrain::cook
