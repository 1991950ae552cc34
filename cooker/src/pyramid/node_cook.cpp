#include "pyramid/node_cook.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <fmt/format.h>

#include "avx2_clones.h"
#include "pyramid/quantize.h"
#include "terrain/cpu_clock.h"
#include "terrain/derived_normals.h"

namespace terrain::cook {
namespace {

// Level-0 lattice index of vertex i (may be negative in the window margin) of a node column.
int64_t lattice_index(uint32_t node, int i, uint32_t level) {
  return (int64_t(node) * kQuadsPerSide + i) * (int64_t(1) << level);
}

}  // namespace

// Without surface layers the albedo still carries the hole mask (format/SPEC.md: vertex (i, j) is a
// hole when albedo texel (i + kApron, j + kApron) has alpha 0), in flat grey BC1 blocks: both
// endpoints equal selects the 3-colour mode, where index 3 is transparent.
void encode_hole_albedo(const uint8_t* hole_window, std::array<uint8_t, kAlbedoBytes>& out) {
  constexpr uint16_t kGrey565 = 0x8410;
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      uint32_t indices = 0;
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) {
          const int i = bx * 4 + c - kApron + kWindowMargin, j = by * 4 + r - kApron + kWindowMargin;
          if (hole_window[size_t(j) * kWindowSize + size_t(i)]) indices |= 3u << (2 * (4 * r + c));
        }
      uint8_t* b = &out[size_t(by * kTexelBlocks + bx) * 8];
      b[0] = b[2] = uint8_t(kGrey565 & 0xFF);
      b[1] = b[3] = uint8_t(kGrey565 >> 8);
      for (int k = 0; k < 4; ++k) b[4 + k] = uint8_t(indices >> (8 * k));
    }
}

Status compute_window(const CookContext& ctx, const NodeKey& key, NodeWindow& w) {
  // Window elements [lo, hi) per axis are evaluated (the block's window holds their taps, and
  // nothing reads the rest); the rest are holes. Each vertex's bits do not depend on the range.
  const int lo = kWindowMargin - ctx.window_margin(), hi = kWindowSize - lo;
  if (lo > 0) {
    w.hole.fill(1);
    w.units.fill(0);
  }
  std::array<double, kWindowSize> xs, cols, rows;
  std::array<int64_t, kWindowSize> gxs;
  // Entry kLevelCount: the vertices of the overview levels' lattice (level 6 and up), rounded to
  // their step when it is coarser than the roots' (SPEC 19 rule 7); else they are the roots'.
  const bool overview = ctx.overview_step_log2 > int(ctx.step_log2[kRootLevel]);
  const int top = overview ? kLevelCount : kRootLevel;
  std::array<int, kLevelCount + 1> steps;
  std::array<double, kLevelCount + 1> scale;
  for (int l = 0; l < kLevelCount; ++l) steps[size_t(l)] = ctx.step_log2[size_t(l)];
  steps[kLevelCount] = overview ? ctx.overview_step_log2 : ctx.step_log2[kRootLevel];
  for (int l = 0; l <= kLevelCount; ++l) scale[size_t(l)] = std::ldexp(1024.0, -steps[size_t(l)]);
  auto level_of = [top](int64_t g) {
    if (g == 0) return top;
    return std::min(__builtin_ctzll(uint64_t(g)), top);
  };
  // vertex_level(gx, gy) is the smaller of vertex_level(gx, 0) and vertex_level(0, gy) (trailing
  // zeros of gx | gy): the column part once per window.
  std::array<uint8_t, kWindowSize> column_level;
  for (int i = 0; i < kWindowSize; ++i) {
    gxs[size_t(i)] = lattice_index(key.x, i - kWindowMargin, key.level);
    xs[size_t(i)] = ctx.lattice_x(gxs[size_t(i)]);
    column_level[size_t(i)] = uint8_t(level_of(gxs[size_t(i)]));
  }
  // Axis-aligned sources: every row of vertices shares the columns' Catmull-Rom weights (the
  // mapping gives the same column for any row, so the bits are those of the per-vertex path).
  const bool shared_columns = ctx.mapping->axis_aligned();
  std::array<SourceSurface::Axis, kWindowSize> column_axes;
  std::array<bool, kWindowSize> x_in{};
  // Other sources map every row through the anchors at the same x: plan the columns once
  // (identical bits to map_frame_row).
  const AnchorGrid* anchors = shared_columns ? nullptr : ctx.mapping->frame_to_sample_anchors();
  thread_local AnchorGrid::RowPlan plan;
  if (anchors) anchors->plan_row(xs.data(), kWindowSize, plan);
  if (shared_columns) {
    ctx.mapping->map_frame_row(ctx.lattice_y(lattice_index(key.y, 0, key.level)), xs.data(), kWindowSize, cols.data(),
                               rows.data());
    for (int i = 0; i < kWindowSize; ++i) {
      column_axes[size_t(i)] = ctx.surface.column(cols[size_t(i)]);
      x_in[size_t(i)] = ctx.surface.x_interior(column_axes[size_t(i)]);
    }
  }
  // Vertex rows closer than source rows: cache each source row's horizontal sums (per column).
  std::array<SourceSurface::Axis, kWindowSize> row_axes;
  int cache_r0 = 0, cache_rows = 0;
  thread_local std::vector<double> cache;
  thread_local std::vector<uint8_t> cached;
  if (shared_columns) {
    for (int j = lo; j < hi; ++j) {
      double c = 0, r = 0;
      const double y = ctx.lattice_y(lattice_index(key.y, j - kWindowMargin, key.level));
      ctx.mapping->map_frame_row(y, xs.data(), 1, &c, &r);
      row_axes[size_t(j)] = ctx.surface.row(r);
    }
    const SourceSurface::Axis& south = row_axes[size_t(lo)];
    const SourceSurface::Axis& north = row_axes[size_t(hi - 1)];
    if (south.in && north.in && std::abs(south.i - north.i) < kWindowSize) {
      cache_r0 = std::min(south.i, north.i) - 1;
      cache_rows = std::abs(south.i - north.i) + 4;
      cache.resize(size_t(cache_rows) * kWindowSize);
      cached.assign(size_t(cache_rows), 0);
    }
  }
  // Rows mapped point by point (through the anchors or the mapping).
  const auto map_row = [&](double y) {
    if (anchors)
      anchors->eval_planned(y, plan, cols.data(), rows.data());
    else
      ctx.mapping->map_frame_row(y, xs.data(), kWindowSize, cols.data(), rows.data());
  };
  // Zero ground (the sea of SRTM tiles, 91-99 % of the shared ones): when the source around the
  // window holds only zeros, a mapped row whose every point reads its 16 taps there is +0
  // throughout (SourceSurface::zero_bounds) and skips the sums. The bounds come from the first and last
  // rows' extent with two samples to spare; each row checks its own points against them, so the
  // bits are those of sample_points() whatever the mapping does in between.
  SourceSurface::ZeroBounds zero;
  // The first row is mapped last here, and the row loop takes its points as they are.
  bool first_row_mapped = false;
  if (!shared_columns && hi > lo) {
    double cmin = INFINITY, cmax = -INFINITY, rmin = INFINITY, rmax = -INFINITY;
    for (const int j : {hi - 1, lo}) {
      map_row(ctx.lattice_y(lattice_index(key.y, j - kWindowMargin, key.level)));
      for (int i = lo; i < hi; ++i) {
        cmin = std::min(cmin, cols[size_t(i)]);
        cmax = std::max(cmax, cols[size_t(i)]);
        rmin = std::min(rmin, rows[size_t(i)]);
        rmax = std::max(rmax, rows[size_t(i)]);
      }
    }
    zero = ctx.surface.zero_bounds(cmin, cmax, rmin, rmax, 2);
    first_row_mapped = true;
  }
  // Each column's scale and step for every row level (a vertex's level is the smaller of its
  // column's and its row's), for quantize_row.
  std::array<std::array<double, kWindowSize>, kLevelCount + 1> level_scale, level_step;
  for (int rl = 0; rl <= top; ++rl)
    for (int i = 0; i < kWindowSize; ++i) {
      const size_t vl = size_t(std::min(int(column_level[size_t(i)]), rl));
      level_scale[size_t(rl)][size_t(i)] = scale[vl];
      level_step[size_t(rl)][size_t(i)] = std::ldexp(1.0, steps[vl]);
    }
  // A row's heights and data flags (mapped rows: from sample_points); zeroed once so that no
  // element is ever indeterminate (holes leave their height unwritten).
  std::array<double, kWindowSize> row_h{};
  std::array<uint8_t, kWindowSize> row_ok{};
  for (int j = lo; j < hi; ++j) {
    const int64_t gy = lattice_index(key.y, j - kWindowMargin, key.level);
    const double y = ctx.lattice_y(gy);
    // Mapped rows: their heights in one call.
    if (!shared_columns) {
      if (!(j == lo && first_row_mapped)) map_row(y);
      bool zero_row = true;
      for (int i = lo; i < hi && zero_row; ++i) zero_row = zero.holds(cols[size_t(i)], rows[size_t(i)]);
      if (zero_row) {
        std::fill(row_h.begin() + lo, row_h.begin() + hi, 0.0);
        std::fill(row_ok.begin() + lo, row_ok.begin() + hi, uint8_t(1));
      } else {
        ctx.surface.sample_points(cols.data() + lo, rows.data() + lo, hi - lo, row_h.data() + lo,
                                  row_ok.data() + lo);
      }
    }
    const SourceSurface::Axis& row_axis = row_axes[size_t(j)];
    const double* source_rows[4] = {};
    const bool use_cache = cache_rows > 0 && ctx.surface.y_interior(row_axis);
    if (use_cache)
      for (int t = 0; t < 4; ++t) {
        const int slot = row_axis.i - 1 + t - cache_r0;
        if (!cached[size_t(slot)]) {
          double* line = &cache[size_t(slot) * kWindowSize];
          for (int i = lo; i < hi; ++i)
            if (x_in[size_t(i)])
              line[i] = ctx.surface.horizontal(column_axes[size_t(i)], row_axis.i - 1 + t);
          cached[size_t(slot)] = 1;
        }
        source_rows[t] = &cache[size_t(slot) * kWindowSize];
      }
    // Cached rows: the vertical sums of sample_rows() for the whole row in one branch-free pass
    // (same operations in the same order); a NaN sum (a nodata tap) goes to the general path below.
    std::array<double, kWindowSize> row_sum;
    if (use_cache) {
      const double* r0 = source_rows[0];
      const double* r1 = source_rows[1];
      const double* r2 = source_rows[2];
      const double* r3 = source_rows[3];
      const double w0 = row_axis.w[0], w1 = row_axis.w[1], w2 = row_axis.w[2], w3 = row_axis.w[3];
      for (int i = lo; i < hi; ++i) {
        double sum = 0;
        sum += w0 * r0[i];
        sum += w1 * r1[i];
        sum += w2 * r2[i];
        sum += w3 * r3[i];
        row_sum[size_t(i)] = sum;
      }
    }
    const int row_level = level_of(gy);
    if (shared_columns)
      for (int i = lo; i < hi; ++i) {
        double h = 0;
        bool ok = false;
        if (use_cache && x_in[size_t(i)]) {
          h = row_sum[size_t(i)];
          ok = !std::isnan(h) || ctx.surface.sample_general(column_axes[size_t(i)], row_axis, h);
        } else {
          ok = ctx.surface.sample(column_axes[size_t(i)], row_axis, h);
        }
        row_h[size_t(i)] = h;
        row_ok[size_t(i)] = uint8_t(ok);
      }
    const size_t k0 = size_t(j) * kWindowSize;
    if (quantize_row(row_h.data() + lo, row_ok.data() + lo, level_scale[size_t(row_level)].data() + lo,
                     level_step[size_t(row_level)].data() + lo, hi - lo, w.units.data() + k0 + lo,
                     w.hole.data() + k0 + lo))
      continue;
    // A height beyond the archive's: the per-vertex rule, which names the first.
    for (int i = lo; i < hi; ++i) {
      const size_t k = k0 + size_t(i);
      const double h = row_h[size_t(i)];
      if (!row_ok[size_t(i)]) {
        w.hole[k] = 1;
        w.units[k] = 0;
        continue;
      }
      const size_t vl = size_t(std::min(int(column_level[size_t(i)]), row_level));
      // Range first: a height far outside the archive's (a spike of 1e30 kept by --valid-range) would
      // overflow the integer conversion and wrap into range.
      const bool in_range = std::fabs(h) <= double(kMaxHeightUnits) * kHeightUnitM;
      const int64_t u = in_range ? quantize_units(h, scale[vl], steps[vl]) : int64_t(kMaxHeightUnits) + 1;
      if (u > kMaxHeightUnits || u < -kMaxHeightUnits)  // bad data (exit 1), not a bad flag
        return Status::failure(Error::unsupported_input,
                               fmt::format("height {:.3f} m at frame ({:.3f}, {:.3f}) is outside the archive's +-16384 m "
                                           "(a nodata value not declared? see --nodata-value, --height-scale)",
                                           h, xs[size_t(i)], y));
      w.hole[k] = 0;
      w.units[k] = int32_t(u);
    }
  }
  return Status::success();
}

void node_sample_bounds(const CookContext& ctx, const NodeKey& key, double& cmin, double& rmin, double& cmax,
                        double& rmax) {
  const double size = node_size_m(int(key.level));
  const double x0 = ctx.lattice_x(lattice_index(key.x, 0, key.level));
  const double y0 = ctx.lattice_y(lattice_index(key.y, 0, key.level));
  cmin = rmin = INFINITY;
  cmax = rmax = -INFINITY;
  for (int a = 0; a <= 2; ++a)
    for (int b = 0; b <= 2; ++b) {
      double c = 0, r = 0;
      ctx.mapping->frame_to_sample(x0 + 0.5 * a * size, y0 + 0.5 * b * size, c, r);
      cmin = std::min(cmin, c);
      cmax = std::max(cmax, c);
      rmin = std::min(rmin, r);
      rmax = std::max(rmax, r);
    }
}

RefineRules node_refine_rules(const CookContext& ctx, const NodeKey& key, uint64_t* families) {
  const RefineRules own{ctx.tolerance_m, ctx.source_spacing_m, ctx.finest_level};
  if (families) *families = 0;
  const SampleWindow& src = *ctx.window;
  if (ctx.family_rules.empty() || src.family.empty()) return own;
  double cmin = 0, cmax = 0, rmin = 0, rmax = 0;
  node_sample_bounds(ctx, key, cmin, rmin, cmax, rmax);
  const int c0 = std::max(src.rect.c0, int(std::floor(cmin)) - 1), c1 = std::min(src.rect.c1, int(std::ceil(cmax)) + 1);
  const int r0 = std::max(src.rect.r0, int(std::floor(rmin)) - 1), r1 = std::min(src.rect.r1, int(std::ceil(rmax)) + 1);
  std::array<bool, 256> present{};
  for (int r = r0; r <= r1 && c0 <= c1; ++r) {
    const uint8_t* f = &src.family[src.index(c0, r)];
    for (int c = 0; c <= c1 - c0; ++c) present[f[c]] = true;
  }
  RefineRules rules{INFINITY, INFINITY, kLevelCount};
  bool any = false;
  for (size_t f = 0; f < ctx.family_rules.size() && f < SampleWindow::kNoFamily; ++f)
    if (present[f]) {
      const RefineRules& fr = ctx.family_rules[f];
      rules.tolerance_m = std::min(rules.tolerance_m, fr.tolerance_m);
      rules.source_spacing_m = std::min(rules.source_spacing_m, fr.source_spacing_m);
      rules.finest_level = std::min(rules.finest_level, fr.finest_level);
      if (families && !any && f < 64) *families = uint64_t(1) << f;
      any = true;
    }
  return any ? rules : own;
}

bool node_has_terrain(const CookContext& ctx, const NodeKey& key) {
  std::array<double, kHeightSamples> xs, cols, rows;
  for (int i = 0; i < kHeightSamples; ++i) xs[size_t(i)] = ctx.lattice_x(lattice_index(key.x, i, key.level));
  for (int j = 0; j < kHeightSamples; ++j) {
    const double y = ctx.lattice_y(lattice_index(key.y, j, key.level));
    ctx.mapping->map_frame_row(y, xs.data(), kHeightSamples, cols.data(), rows.data());
    for (int i = 0; i < kHeightSamples; ++i)
      if (ctx.surface.covered(cols[size_t(i)], rows[size_t(i)])) return true;
  }
  return false;
}

namespace {

typedef double V4d __attribute__((vector_size(32)));
typedef int64_t V4l __attribute__((vector_size(32)));
typedef float V4f __attribute__((vector_size(16)));

std::atomic<bool> dense_rows_enabled{true};
std::atomic<uint64_t> dense_rows_measured{0};

// A sample that lies exactly on a vertex (fu and fv each 0 or 1) whose own triangle is a hole is
// still on the drawn surface when any of the six triangles around that vertex is drawn (quads are
// split along the south-west to north-east diagonal); the surface there is the vertex's height.
// This is what lets data whose samples are vertices (1 m lidar at level 1) stop refining at its
// edges. (i, j): the vertex, node coordinates; its neighbours lie in the window's margin.
struct VertexCover {
  const NodeWindow* w;
  bool hole(int i, int j) const {
    return w->hole[size_t(j + kWindowMargin) * kWindowSize + size_t(i + kWindowMargin)] != 0;
  }
  // NaN when no triangle around vertex (i, j) is drawn.
  double height_if_drawn(int i, int j) const {
    if (hole(i, j)) return NAN;
    const bool e = !hole(i + 1, j), n = !hole(i, j + 1), ne = !hole(i + 1, j + 1);
    const bool w_ = !hole(i - 1, j), s = !hole(i, j - 1), sw = !hole(i - 1, j - 1);
    const bool drawn = (e && ne) || (n && ne) || (w_ && n) || (s && e) || (sw && s) || (sw && w_);
    return drawn ? double(w->units[size_t(j + kWindowMargin) * kWindowSize + size_t(i + kWindowMargin)]) * kHeightUnitM
                 : double(NAN);
  }
  // The sample at fraction (fu, fv) of quad (i, j): its vertex's height when it is on a vertex
  // around which a triangle is drawn, else NaN.
  double on_vertex(int i, int j, double fu, double fv) const {
    if (!((fu == 0.0 || fu == 1.0) && (fv == 0.0 || fv == 1.0))) return NAN;
    return height_if_drawn(i + (fu == 1.0), j + (fv == 1.0));
  }
};

// measure_error's rows where the source is denser than the node's vertices and the frame's axes
// are the source's: every sample of a row has the row's frame y, and per column the quad and its
// fraction are column_quad and column_fu (count + 4 elements: 4 past the last column are read and
// dropped). Each error is the per-sample loop's, with the same operations in the same order (no
// FMA in either clone), 4 columns at a time along each run of columns in one quad, the quad's terms
// computed once per run. Maxima and counts are the per-sample loop's; the squared errors are summed
// in 4 lanes per quadrant (lane k: every 4th sample of each run), then lane 0 + 1 + 2 + 3, so the
// rms may differ from a sample-by-sample sum in its last bits.
TERRAIN_AVX2_CLONES void measure_dense_level_rows(const CookContext& ctx, const SampleWindow& src, int r0, int r1, int c0,
                                                  int c1, double y0, double inv_s, const double* hv,
                                                  const int* column_quad, const double* column_fu,
                                                  const VertexCover& cover, NodeError& out) {
  const int count = c1 - c0 + 1;
  const bool any_filled = !src.filled.empty();
  const V4d zero = {0, 0, 0, 0};
  const V4l none = {0, 0, 0, 0}, lane = {0, 1, 2, 3};
  const V4l magnitude = {INT64_MAX, INT64_MAX, INT64_MAX, INT64_MAX};
  struct Lanes {
    V4d max_m = {0, 0, 0, 0}, sum_sq = {0, 0, 0, 0};
    V4l samples = {0, 0, 0, 0}, uncovered = {0, 0, 0, 0};
  };
  Lanes quadrant[4];
  uint64_t rows_measured = 0;
  const auto at = [&](int i, int j) { return hv[size_t(j) * kHeightSamples + size_t(i)]; };
  // The runs of columns in one quad (the same for every row).
  struct Run {
    int a, b, cq;
  };
  thread_local std::vector<Run> runs;
  runs.clear();
  for (int a = 0; a < count;) {
    int b = a + 1;
    while (b < count && column_quad[b] == column_quad[a]) ++b;
    if (column_quad[a] >= 0) runs.push_back({a, b, column_quad[a]});  // else outside the node
    a = b;
  }
  for (int row = r0; row <= r1; ++row) {
    double fx = 0, fy = 0;
    ctx.mapping->map_sample_row(row, c0, 1, &fx, &fy);
    const double v = (fy - y0) * inv_s;
    if (!(v >= 0 && v <= kQuadsPerSide)) continue;
    const int j = std::min(int(v), kQuadsPerSide - 1);
    const double fv = v - j;
    const int qv = v >= 0.5 * kQuadsPerSide ? 2 : 0;
    const V4d fv4 = {fv, fv, fv, fv};
    ++rows_measured;
    const size_t row_idx = src.index(c0, row);
    const float* zs = &src.values[row_idx];
    const uint8_t* filled = any_filled ? &src.filled[row_idx] : nullptr;
    for (const Run& run : runs) {
      const int a = run.a, b = run.b, cq = run.cq;
      const int i = cq & 0xFFFF;
      const double h00 = at(i, j), h10 = at(i + 1, j), h01 = at(i, j + 1), h11 = at(i + 1, j + 1);
      const int64_t se_ok = -int64_t(!(std::isnan(h00) || std::isnan(h11) || std::isnan(h10)));
      const int64_t nw_ok = -int64_t(!(std::isnan(h00) || std::isnan(h11) || std::isnan(h01)));
      const double d_se = h10 - h00, t_se = fv * (h11 - h10), t_nw = h00 + fv * (h01 - h00), d_nw = h11 - h01;
      const V4d h00v = {h00, h00, h00, h00}, d_sev = {d_se, d_se, d_se, d_se}, t_sev = {t_se, t_se, t_se, t_se};
      const V4d t_nwv = {t_nw, t_nw, t_nw, t_nw}, d_nwv = {d_nw, d_nw, d_nw, d_nw};
      const V4l se_okv = {se_ok, se_ok, se_ok, se_ok}, nw_okv = {nw_ok, nw_ok, nw_ok, nw_ok};
      Lanes& q = quadrant[(cq >> 16) | qv];
      if (!(se_ok && nw_ok)) {
        // A quad with a hole vertex (data edges): sample by sample, the same operations, each
        // sample in the lane the vector loop gives it, with the on-vertex rule for missed samples.
        for (int m = a; m < b; ++m) {
          const int k = (m - a) & 3;
          const float zf = zs[m];
          if (std::isnan(zf) || (filled && filled[m])) continue;
          const double fu = column_fu[m];
          const bool se = fu >= fv;
          double h = NAN;
          if (se ? se_ok : nw_ok)
            h = se ? (h00 + fu * d_se) + t_se : t_nw + fu * d_nw;
          else
            h = cover.on_vertex(i, j, fu, fv);
          if (std::isnan(h)) {
            ++q.uncovered[k];
            continue;
          }
          const double e = std::fabs(h - double(zf));
          if (e > q.max_m[k]) q.max_m[k] = e;
          q.sum_sq[k] += e * e;
          ++q.samples[k];
        }
        continue;
      }
      for (int n = a; n < b; n += 4) {
        const int left = b - n;
        V4d fu, z;
        V4l no_data = none;
        std::memcpy(&fu, column_fu + n, sizeof fu);
        if (left >= 4) {
          V4f zf;
          std::memcpy(&zf, zs + n, sizeof zf);
          z = __builtin_convertvector(zf, V4d);
          uint32_t any = 0;
          if (filled) std::memcpy(&any, filled + n, sizeof any);
          if (any)
            for (int k = 0; k < 4; ++k) no_data[k] = -int64_t(filled[n + k] != 0);
        } else {
          z = zero;
          for (int k = 0; k < left; ++k) {
            z[k] = double(zs[n + k]);
            if (filled) no_data[k] = -int64_t(filled[n + k] != 0);
          }
        }
        const V4l valid = (lane < int64_t(left)) & ~no_data & (z == z);
        const V4l se = fu >= fv4;
        const V4d h = se ? h00v + fu * d_sev + t_sev : t_nwv + fu * d_nwv;
        const V4l ok = se ? se_okv : nw_okv;
        const V4d e = (V4d)((V4l)(h - z) & magnitude);  // fabs
        const V4l measured = valid & ok;
        q.max_m = (measured & (e > q.max_m)) ? e : q.max_m;
        q.sum_sq += measured ? e * e : zero;
        q.samples -= measured;
        q.uncovered -= valid & ~ok;
      }
    }
  }
  dense_rows_measured.fetch_add(rows_measured, std::memory_order_relaxed);
  for (int k = 0; k < 4; ++k) {
    const Lanes& q = quadrant[k];
    ErrorStats& s = out.quadrant[size_t(k)];
    s.max_m = std::max(std::max(q.max_m[0], q.max_m[1]), std::max(q.max_m[2], q.max_m[3]));
    s.sum_sq = ((q.sum_sq[0] + q.sum_sq[1]) + q.sum_sq[2]) + q.sum_sq[3];
    s.samples = uint64_t(q.samples[0] + q.samples[1] + q.samples[2] + q.samples[3]);
    s.uncovered = uint64_t(q.uncovered[0] + q.uncovered[1] + q.uncovered[2] + q.uncovered[3]);
  }
}

}  // namespace

bool measure_error_dense_rows(bool enabled) { return dense_rows_enabled.exchange(enabled); }
uint64_t dense_error_rows_measured() { return dense_rows_measured.load(); }

void measure_error(const CookContext& ctx, const NodeKey& key, const NodeWindow& w, NodeError& out) {
  out = NodeError{};
  const SampleWindow& src = *ctx.window;
  const double s = vertex_spacing_m(int(key.level));
  const double x0 = ctx.lattice_x(lattice_index(key.x, 0, key.level));
  const double y0 = ctx.lattice_y(lattice_index(key.y, 0, key.level));
  // Samples of the node square, plus one sample around.
  double cmin = 0, cmax = 0, rmin = 0, rmax = 0;
  node_sample_bounds(ctx, key, cmin, rmin, cmax, rmax);
  const int c0 = std::max(0, int(std::floor(cmin)) - 1), c1 = std::min(src.source_width - 1, int(std::ceil(cmax)) + 1);
  const int r0 = std::max(0, int(std::floor(rmin)) - 1), r1 = std::min(src.source_height - 1, int(std::ceil(rmax)) + 1);
  const double inv_s = 1.0 / s;
  if (c1 < c0) return;
  // Height in metres of node vertex (i, j), NaN at a hole (a hole vertex drops its triangles).
  const auto vertex_m = [&](int i, int j) {
    const size_t k = size_t(j + kWindowMargin) * kWindowSize + size_t(i + kWindowMargin);
    return w.hole[k] ? double(NAN) : double(w.units[k]) * kHeightUnitM;
  };
  // Where the source is denser than the node's vertices (coarse nodes over lidar: up to 4 M samples
  // per root), the vertex heights are converted once, so a sample reads three doubles; sparser
  // sources convert per sample (16 641 conversions would cost more than their samples). Same values
  // either way: the bits of every error are unchanged.
  const bool dense = uint64_t(c1 - c0 + 1) * uint64_t(r1 - r0 + 1) > uint64_t(kHeightSamples) * kHeightSamples;
  thread_local std::vector<double> hv;
  if (dense) {
    hv.resize(size_t(kHeightSamples) * kHeightSamples);
    for (int j = 0; j < kHeightSamples; ++j)
      for (int i = 0; i < kHeightSamples; ++i) hv[size_t(j) * kHeightSamples + size_t(i)] = vertex_m(i, j);
  }
  thread_local std::vector<double> fxs, fys;
  fxs.resize(size_t(c1 - c0 + 1));
  fys.resize(size_t(c1 - c0 + 1));
  const bool any_filled = !src.filled.empty();
  const bool level_rows = ctx.mapping->axis_aligned();
  const VertexCover cover{&w};
  // Axis-aligned: every row has the same frame x per column too (bitwise), so each column's u, quad
  // column and fraction are computed once per node (column_quad < 0: outside the node).
  thread_local std::vector<double> column_fu;
  thread_local std::vector<int> column_quad;
  if (level_rows) {
    ctx.mapping->map_sample_row(r0, c0, c1 - c0 + 1, fxs.data(), fys.data());
    column_fu.resize(fxs.size() + 4);  // measure_dense_level_rows reads 4 at a time past the end
    column_quad.resize(fxs.size());
    for (size_t n = 0; n < fxs.size(); ++n) {
      const double u = (fxs[n] - x0) * inv_s;
      column_quad[n] = -1;
      column_fu[n] = 0.0;
      if (!(u >= 0 && u <= kQuadsPerSide)) continue;
      const int i = std::min(int(u), kQuadsPerSide - 1);
      column_quad[n] = i | (u >= 0.5 * kQuadsPerSide ? 1 << 16 : 0);  // bit 16: the east half
      column_fu[n] = u - i;
    }
  }
  const auto measure_rows = [&](auto&& at) {
    for (int row = r0; row <= r1; ++row) {
      if (level_rows) {
        ctx.mapping->map_sample_row(row, c0, 1, fxs.data(), fys.data());
      } else {
        ctx.mapping->map_sample_row(row, c0, c1 - c0 + 1, fxs.data(), fys.data());
      }
      const size_t row_idx = src.index(c0, row);
      const float* zs = &src.values[row_idx];
      const uint8_t* filled = any_filled ? &src.filled[row_idx] : nullptr;
      // The current quadrant's sums live in registers (a quadrant changes at most a few times per
      // row); they are loaded and stored back, so each sum sees the same additions in the same order.
      int cur = -1;
      ErrorStats acc;
      const auto enter = [&](int q) {
        if (q == cur) return;
        if (cur >= 0) out.quadrant[size_t(cur)] = acc;
        cur = q;
        acc = out.quadrant[size_t(q)];
      };
      const auto record = [&](double e) {
        acc.max_m = std::max(acc.max_m, e);
        acc.sum_sq += e * e;
        ++acc.samples;
      };
      if (level_rows) {
        // Every sample of the row has the same frame y (bitwise: the cross term is zero), so the
        // same v, quad row and fraction: the row is measured by the loop below with v fixed.
        const double v = (fys[0] - y0) * inv_s;
        if (!(v >= 0 && v <= kQuadsPerSide)) continue;
        const int j = std::min(int(v), kQuadsPerSide - 1);
        const double fv = v - j;
        const int qv = v >= 0.5 * kQuadsPerSide ? 2 : 0;
        // Per quad of the row, the parts of the two triangles' interpolation that do not depend on
        // the sample: south-east (fu >= fv) (h00 + fu d_se) + t_se, north-west t_nw + fu d_nw,
        // the general formula below with its products and sums grouped as it groups them.
        int quad = -1;
        double h00 = 0, d_se = 0, t_se = 0, d_nw = 0, t_nw = 0;
        bool se_ok = false, nw_ok = false;
        for (int col = c0; col <= c1; ++col) {
          const size_t n = size_t(col - c0);
          const float z = zs[n];
          if (std::isnan(z) || (filled && filled[n])) continue;
          const int cq = column_quad[n];
          if (cq < 0) continue;
          const int i = cq & 0xFFFF;
          const double fu = column_fu[n];
          const int q = (cq >> 16) | qv;
          enter(q);
          if (i != quad) {
            quad = i;
            h00 = at(i, j);
            const double h10 = at(i + 1, j), h01 = at(i, j + 1), h11 = at(i + 1, j + 1);
            se_ok = !(std::isnan(h00) || std::isnan(h11) || std::isnan(h10));
            nw_ok = !(std::isnan(h00) || std::isnan(h11) || std::isnan(h01));
            d_se = h10 - h00;
            t_se = fv * (h11 - h10);
            t_nw = h00 + fv * (h01 - h00);
            d_nw = h11 - h01;
          }
          const bool se = fu >= fv;
          if (!(se ? se_ok : nw_ok)) {
            const double hv_k = cover.on_vertex(i, j, fu, fv);
            if (std::isnan(hv_k))
              ++acc.uncovered;
            else
              record(std::fabs(hv_k - double(z)));
            continue;
          }
          const double h = se ? h00 + fu * d_se + t_se : t_nw + fu * d_nw;
          record(std::fabs(h - double(z)));
        }
        if (cur >= 0) out.quadrant[size_t(cur)] = acc;
        continue;
      }
      for (int col = c0; col <= c1; ++col) {
        const size_t n = size_t(col - c0);
        const float z = zs[n];
        if (std::isnan(z) || (filled && filled[n])) continue;
        const double u = (fxs[n] - x0) * inv_s, v = (fys[n] - y0) * inv_s;
        if (!(u >= 0 && v >= 0 && u <= kQuadsPerSide && v <= kQuadsPerSide)) continue;
        const int i = std::min(int(u), kQuadsPerSide - 1), j = std::min(int(v), kQuadsPerSide - 1);
        const double fu = u - i, fv = v - j;
        const int q = (u >= 0.5 * kQuadsPerSide ? 1 : 0) | (v >= 0.5 * kQuadsPerSide ? 2 : 0);
        enter(q);
        // Quads split along the south-west to north-east diagonal (format/SPEC.md "Surface").
        const double h00 = at(i, j), h11 = at(i + 1, j + 1), hc = fu >= fv ? at(i + 1, j) : at(i, j + 1);
        if (std::isnan(h00) || std::isnan(h11) || std::isnan(hc)) {
          const double hv_k = cover.on_vertex(i, j, fu, fv);
          if (std::isnan(hv_k))
            ++acc.uncovered;
          else
            record(std::fabs(hv_k - double(z)));
          continue;
        }
        const double h = fu >= fv ? h00 + fu * (hc - h00) + fv * (h11 - hc) : h00 + fv * (hc - h00) + fu * (h11 - hc);
        record(std::fabs(h - double(z)));
      }
      if (cur >= 0) out.quadrant[size_t(cur)] = acc;
    }
  };
  if (dense && level_rows && dense_rows_enabled.load(std::memory_order_relaxed))
    measure_dense_level_rows(ctx, src, r0, r1, c0, c1, y0, inv_s, hv.data(), column_quad.data(), column_fu.data(), cover,
                             out);
  else if (dense)
    measure_rows([&](int i, int j) { return hv[size_t(j) * kHeightSamples + size_t(i)]; });
  else
    measure_rows(vertex_m);
  for (const ErrorStats& q : out.quadrant) out.total.add(q);
}

void cook_node(const CookContext& ctx, const NodeKey& key, NodeResult& out) {
  out = NodeResult{};
  out.record.key = key;
  const double t0 = thread_cpu_seconds();
  // Per-thread buffers (136 KB window, 63 KB node, 109 KB float heights): fresh allocations of this
  // size are mmapped and page-faulted in again for every node.
  static thread_local std::unique_ptr<NodeWindow> window_buffer;
  static thread_local std::unique_ptr<NodeData> data_buffer;
  static thread_local std::vector<float> heights_m;
  if (!window_buffer) window_buffer = std::make_unique<NodeWindow>();
  if (!data_buffer) data_buffer = std::make_unique<NodeData>();
  NodeWindow* window = window_buffer.get();  // compute_window writes every element
  out.status = compute_window(ctx, key, *window);
  if (!out.status.ok()) return;
  NodeData* data = data_buffer.get();
  // Sections a cook leaves alone stay zero (heights-only archives), as in a fresh NodeData.
  data->heights.fill(0);
  data->normals_bc3.fill(0);
  data->albedo_bc1.fill(0);
  data->splat.fill(0);
  data->cones_bc3.fill(0);
  const int step = ctx.step_log2[key.level];
  const size_t inner = size_t(kWindowMargin) * kWindowSize + kWindowMargin;
  out.status = pack_heights(&window->units[inner], &window->hole[inner], kWindowSize, step, out.record, data->heights);
  if (!out.status.ok()) {
    out.status.message = fmt::format("node {}/{}/{}: {}", key.level, key.x, key.y, out.status.message);
    return;
  }
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i)
      out.vertices += window->hole[inner + size_t(j) * kWindowSize + size_t(i)] == 0;
  const double t1 = thread_cpu_seconds();

  measure_error(ctx, key, *window, out.error);
  // Stored as float: round up so the recorded error never understates the measured one.
  float err = float(out.error.total.max_m);
  if (double(err) < out.error.total.max_m) err = std::nextafter(err, INFINITY);
  out.record.geometric_error_m = err;
  // Refine where the error exceeds the tolerance, or where hole triangles drop valid source
  // samples along a data edge while the vertices are coarser than half the source spacing: from
  // there on every vertex of a triangle holding an edge sample lies within that sample's pixel,
  // whose nearest sample is valid, so the triangle is drawn.
  // A mosaic of several grid families: each part by its own source's rules (node_refine_rules).
  const RefineRules rules = node_refine_rules(ctx, key, &out.families);
  const bool refine =
      int(key.level) > rules.finest_level &&
      (out.error.total.max_m > rules.tolerance_m ||
       (out.error.total.uncovered > 0 && vertex_spacing_m(int(key.level)) > 0.5 * rules.source_spacing_m));
  if (refine) {
    for (int c = 0; c < 4; ++c) {
      // Parent vertices inside the quadrant are child vertices too: any with terrain decides it.
      const int i0 = (c & 1) * (kQuadsPerSide / 2), j0 = (c >> 1) * (kQuadsPerSide / 2);
      bool any = false;
      for (int j = j0; j <= j0 + kQuadsPerSide / 2 && !any; ++j)
        for (int i = i0; i <= i0 + kQuadsPerSide / 2 && !any; ++i)
          any = window->hole[inner + size_t(j) * kWindowSize + size_t(i)] == 0;
      if (!any) any = node_has_terrain(ctx, child_of(key, c));
      if (any) out.record.child_mask = uint8_t(out.record.child_mask | (1u << c));
    }
  }
  const double t2 = thread_cpu_seconds();

  bool surface_done = false;
  static thread_local NormalsDerivation derivation;
  if (!ctx.heights_only) {
    surface_done = true;
    heights_m.resize(kWindowCount);
    for (size_t k = 0; k < size_t(kWindowCount); ++k)
      heights_m[k] = window->hole[k] ? NAN : units_to_metres_f32(window->units[k]);
    SurfaceInput in;
    in.key = key;
    in.x0_m = ctx.lattice_x(lattice_index(key.x, 0, key.level));
    in.y0_m = ctx.lattice_y(lattice_index(key.y, 0, key.level));
    in.spacing_m = vertex_spacing_m(int(key.level));
    in.heights_m = heights_m.data();
    in.holes = window->hole.data();
    in.rules = ctx.rules;
    in.bc_quality = ctx.bc_quality;
    in.bc_rdo = ctx.bc_rdo;
    in.measure_errors = ctx.check_all_errors || error_check_sampled(key);
    in.overlays = ctx.overlays;
    out.status = cook_surface_layers(in, *data, out.record.height_offset, step, *data, &out.surface,
                                     ctx.derive_normals ? &derivation : nullptr);
    if (!out.status.ok()) return;
  }
  if (!surface_done) encode_hole_albedo(window->hole.data(), data->albedo_bc1);
  const double t3 = thread_cpu_seconds();
  PayloadTiming timing;
  out.status = encode_node_payload(*data, ctx.payload, out.payload, &timing,
                                   surface_done && ctx.derive_normals ? &derivation : nullptr);
  if (!out.status.ok()) return;
  const double t4 = timing.section_end_s[4];
  for (size_t s = 0; s < 5; ++s)
    out.surface.seconds_parts[size_t(CpuPart::zstd_heights) + s] = timing.section_end_s[s] - (s ? timing.section_end_s[s - 1] : t3);
  out.cpu_heights = t1 - t0;
  out.cpu_error = t2 - t1;
  out.cpu_surface = t3 - t2;
  out.cpu_encode = t4 - t3;
}

}  // namespace terrain::cook
