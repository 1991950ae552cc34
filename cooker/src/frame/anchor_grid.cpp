#include "frame/anchor_grid.h"

#include <algorithm>
#include <cmath>

#include "base/parallel.h"

namespace terrain::cook {

void AnchorGrid::build(double x0, double y0, double step, int nx, int ny, const Exact& exact, int threads) {
  x0_ = x0;
  y0_ = y0;
  step_ = step;
  nx_ = std::max(nx, 4);
  ny_ = std::max(ny, 4);
  values_.assign(size_t(nx_) * size_t(ny_) * 2, 0.0);
  parallel_for(size_t(ny_), threads, [&](size_t j) {
    for (int i = 0; i < nx_; ++i) {
      double* v = &values_[(j * size_t(nx_) + size_t(i)) * 2];
      exact(x0_ + i * step_, y0_ + double(j) * step_, v[0], v[1]);
    }
  });
}

void AnchorGrid::eval(double x, double y, double& a, double& b) const {
  // Cell (i, j) with taps i-1..i+2 kept inside the grid.
  double fx = (x - x0_) / step_, fy = (y - y0_) / step_;
  fx = std::clamp(fx, 1.0, double(nx_ - 2) - 1e-9);
  fy = std::clamp(fy, 1.0, double(ny_ - 2) - 1e-9);
  const int i = int(fx), j = int(fy);
  double wx[4], wy[4];
  catmull_rom_weights(fx - i, wx);
  catmull_rom_weights(fy - j, wy);
  double sa = 0, sb = 0;
  for (int r = 0; r < 4; ++r) {
    const double* row = &values_[(size_t(j - 1 + r) * size_t(nx_) + size_t(i - 1)) * 2];
    const double ra = wx[0] * row[0] + wx[1] * row[2] + wx[2] * row[4] + wx[3] * row[6];
    const double rb = wx[0] * row[1] + wx[1] * row[3] + wx[2] * row[5] + wx[3] * row[7];
    sa += wy[r] * ra;
    sb += wy[r] * rb;
  }
  a = sa;
  b = sb;
}

void AnchorGrid::eval_row(double y, const double* x, int n, double* a, double* b) const {
  if (n <= 0) return;
  thread_local RowPlan plan;
  plan_row(x, n, plan);
  eval_planned(y, plan, a, b);
}

void AnchorGrid::plan_row(const double* x, int n, RowPlan& plan) const {
  plan.cell.resize(size_t(std::max(n, 0)));
  plan.wx.resize(size_t(std::max(n, 0)) * 4);
  plan.cols = 0;
  if (n <= 0) return;
  const double inv = 1.0 / step_;
  // Anchor columns the points need.
  double xmin = x[0], xmax = x[0];
  for (int k = 1; k < n; ++k) {
    xmin = std::min(xmin, x[k]);
    xmax = std::max(xmax, x[k]);
  }
  const int i0 = int(std::clamp((xmin - x0_) * inv, 1.0, double(nx_ - 2) - 1e-9)) - 1;
  const int i1 = int(std::clamp((xmax - x0_) * inv, 1.0, double(nx_ - 2) - 1e-9)) + 2;
  plan.i0 = i0;
  plan.cols = i1 - i0 + 1;
  for (int k = 0; k < n; ++k) {
    const double fx = std::clamp((x[k] - x0_) * inv, 1.0, double(nx_ - 2) - 1e-9);
    const int i = int(fx);
    catmull_rom_weights(fx - i, &plan.wx[size_t(k) * 4]);
    plan.cell[size_t(k)] = i - 1 - i0;
  }
}

void AnchorGrid::eval_planned(double y, const RowPlan& plan, double* a, double* b) const {
  const int n = int(plan.cell.size());
  if (n <= 0) return;
  const double inv = 1.0 / step_;
  double fy = std::clamp((y - y0_) * inv, 1.0, double(ny_ - 2) - 1e-9);
  const int j = int(fy);
  double wy[4];
  catmull_rom_weights(fy - j, wy);
  const size_t cols = size_t(plan.cols);
  thread_local std::vector<double> column;
  column.resize(cols * 2);
  for (size_t c = 0; c < cols; ++c) {
    double sa = 0, sb = 0;
    for (int r = 0; r < 4; ++r) {
      const double* v = &values_[(size_t(j - 1 + r) * size_t(nx_) + size_t(plan.i0) + c) * 2];
      sa += wy[r] * v[0];
      sb += wy[r] * v[1];
    }
    column[2 * c] = sa;
    column[2 * c + 1] = sb;
  }
  for (int k = 0; k < n; ++k) {
    const double* wx = &plan.wx[size_t(k) * 4];
    const double* c = &column[size_t(plan.cell[size_t(k)]) * 2];
    a[k] = wx[0] * c[0] + wx[1] * c[2] + wx[2] * c[4] + wx[3] * c[6];
    b[k] = wx[0] * c[1] + wx[1] * c[3] + wx[2] * c[5] + wx[3] * c[7];
  }
}

}  // namespace terrain::cook
