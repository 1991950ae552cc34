#include "pyramid/pyramid.h"

#include <bit>

#include <algorithm>
#include <cmath>
#include <fmt/format.h>

#include "base/parallel.h"
#include "pyramid/quantize.h"

namespace terrain::cook {
namespace {

constexpr double kRootSizeM = node_size_m(kRootLevel);

// The source rectangle a node's range bound queries: Catmull-Rom taps reach one sample west/south
// and two east/north of the cell; one more sample absorbs the curvature of a projected node edge.
SampleRect node_query_rect(const CookContext& ctx, const NodeKey& key) {
  double cmin = 0, cmax = 0, rmin = 0, rmax = 0;
  node_sample_bounds(ctx, key, cmin, rmin, cmax, rmax);
  return {int(std::floor(cmin)) - 2, int(std::floor(rmin)) - 2, int(std::floor(cmax)) + 3, int(std::floor(rmax)) + 3};
}

// One node's surface statistics into the cook's totals (every field of SurfaceStats).
void add_surface_stats(SurfaceTotals& t, const SurfaceStats& n) {
  t.cpu_normals += n.seconds_normals;
  t.cpu_albedo += n.seconds_albedo;
  t.cpu_splat += n.seconds_splat;
  t.cpu_cones += n.seconds_cones;
  for (size_t k = 0; k < kCpuParts; ++k) t.cpu_parts[k] += n.seconds_parts[k];
  t.normal_err_max_deg = std::max(t.normal_err_max_deg, n.normal_err_max_deg);
  t.normal_err_sum_deg += n.normal_err_sum_deg;
  t.normal_samples += n.normal_samples;
  t.albedo_sq_err_sum += n.albedo_sq_err_sum;
  t.albedo_samples += n.albedo_samples;
  t.albedo_hole_texels += n.albedo_hole_texels;
  t.albedo_alpha_mismatches += n.albedo_alpha_mismatches;
  t.cone_exact_deg_sum += n.cone_exact_deg_sum;
  t.cone_encoded_deg_sum += n.cone_encoded_deg_sum;
  t.cone_patches += n.cone_patches;
  t.cone_patches_never_cull += n.cone_patches_never_cull;
  t.nodes += n.nodes;
  t.checked_nodes += n.checked_nodes;
}

SampleRect source_rect(const CookContext& ctx) { return {0, 0, ctx.source_width - 1, ctx.source_height - 1}; }

}  // namespace

void block_frame_rect(const CookContext& ctx, const RootBlock& b, double& x0, double& y0, double& x1, double& y1) {
  const double margin = ctx.window_margin() * vertex_spacing_m(kRootLevel);
  x0 = ctx.origin_x + b.x0 * kRootSizeM - margin;
  x1 = ctx.origin_x + b.x1 * kRootSizeM + margin;
  y0 = ctx.origin_y + b.y0 * kRootSizeM - margin;
  y1 = ctx.origin_y + b.y1 * kRootSizeM + margin;
}

SampleRect block_cook_rect(const CookContext& ctx, const RootBlock& b) {
  // The block's square plus the root windows' margin, mapped along its edges (a projected square
  // bends by far less than a sample between 64 points of an edge).
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  block_frame_rect(ctx, b, x0, y0, x1, y1);
  double cmin = INFINITY, cmax = -INFINITY, rmin = INFINITY, rmax = -INFINITY;
  constexpr int kPoints = 64;
  for (int e = 0; e <= kPoints; ++e) {
    const double t = double(e) / kPoints;
    const double pts[4][2] = {{x0 + t * (x1 - x0), y0}, {x0 + t * (x1 - x0), y1}, {x0, y0 + t * (y1 - y0)},
                              {x1, y0 + t * (y1 - y0)}};
    for (const auto& p : pts) {
      double c = 0, r = 0;
      ctx.mapping->frame_to_sample(p[0], p[1], c, r);
      cmin = std::min(cmin, c);
      cmax = std::max(cmax, c);
      rmin = std::min(rmin, r);
      rmax = std::max(rmax, r);
    }
  }
  // Taps: one sample before, two after (Catmull-Rom), the error's ring of one and slack of one.
  const SampleRect r{int(std::floor(cmin)) - 4, int(std::floor(rmin)) - 4, int(std::ceil(cmax)) + 4,
                     int(std::ceil(rmax)) + 4};
  return intersect(r, source_rect(ctx));
}

void level_range_bounds(const CookContext& ctx, const RangeSummary& ranges, uint32_t roots_x, uint32_t roots_y,
                        int threads, std::array<double, kLevelCount>& worst) {
  for (int level = kRootLevel; level >= ctx.finest_level; --level) {
    const uint32_t f = 1u << (kRootLevel - level), nx = roots_x * f, ny = roots_y * f;
    std::vector<double> row_worst(ny, 0.0);  // one row of nodes per task; the max over rows after
    parallel_for(ny, resolve_threads(threads), [&](size_t y) {
      double w = 0;
      for (uint32_t x = 0; x < nx; ++x) {
        const SampleRect q = node_query_rect(ctx, {uint32_t(level), x, uint32_t(y)});
        w = std::max(w, ranges.surface_range_bound(q.c0, q.r0, q.c1, q.r1));
      }
      row_worst[y] = w;
    });
    for (double w : row_worst) worst[size_t(level)] = std::max(worst[size_t(level)], w);
  }
}

double overview_range_bound(const CookContext& ctx, const RangeSummary& ranges, uint32_t roots_x, uint32_t roots_y,
                            int levels) {
  double worst = 0;
  for (int level = kLevelCount; level < kLevelCount + levels; ++level) {
    const uint32_t nx = uint32_t(level_grid_cells(roots_x, level)), ny = uint32_t(level_grid_cells(roots_y, level));
    for (uint32_t y = 0; y < ny; ++y)
      for (uint32_t x = 0; x < nx; ++x) {
        const SampleRect q = node_query_rect(ctx, {uint32_t(level), x, y});
        worst = std::max(worst, ranges.surface_range_bound(q.c0, q.r0, q.c1, q.r1));
      }
  }
  return worst;
}

void choose_steps(const std::array<double, kLevelCount>& worst, int floor_step, int finest_level,
                  std::array<uint8_t, kLevelCount>& steps, int overview_step) {
  for (int level = kRootLevel; level >= finest_level; --level) {
    const double w = worst[size_t(level)];
    const int coarsest = std::max(int(steps[kRootLevel]), overview_step);
    const int step = level == kRootLevel
                         ? std::max(required_step(w, overview_step), floor_step)
                         : std::min(std::max(required_step(w, coarsest), floor_step), int(steps[size_t(level + 1)]));
    steps[size_t(level)] = uint8_t(step);
  }
  for (int level = finest_level - 1; level >= 0; --level) steps[size_t(level)] = steps[size_t(finest_level)];
}

Status cook_block(const CookContext& ctx, const RootBlock& b, int threads, const NodeSink& sink, PyramidTotals& totals) {
  const int nthreads = resolve_threads(threads);
  // Roots that hold terrain.
  std::vector<NodeKey> keys;
  {
    std::vector<NodeKey> all;
    for (uint32_t y = b.y0; y < b.y1; ++y)
      for (uint32_t x = b.x0; x < b.x1; ++x) all.push_back({uint32_t(kRootLevel), x, y});
    std::vector<uint8_t> has(all.size(), 0);
    parallel_for(all.size(), nthreads, [&](size_t i) { has[i] = node_has_terrain(ctx, all[i]) ? 1 : 0; });
    for (size_t i = 0; i < all.size(); ++i)
      if (has[i]) keys.push_back(all[i]);
  }
  const size_t batch = size_t(16) * size_t(nthreads);
  std::vector<NodeResult> results;
  for (int level = kRootLevel; level >= ctx.finest_level && !keys.empty(); --level) {
    LevelStats& ls = totals.levels[size_t(level)];
    ErrorStats& le = totals.level_error[size_t(level)];
    std::vector<NodeKey> next;
    for (size_t start = 0; start < keys.size(); start += batch) {
      const size_t n = std::min(batch, keys.size() - start);
      results.resize(n);
      parallel_for(n, nthreads, [&](size_t i) { cook_node(ctx, keys[start + i], results[i]); });
      for (size_t i = 0; i < n; ++i) {  // key order: deterministic bytes and sums
        NodeResult& r = results[i];
        if (!r.status.ok()) return r.status;
        ++ls.nodes;
        ls.vertices += r.vertices;
        for (uint64_t f = r.families; f; f &= f - 1) totals.reach_family_level(size_t(std::countr_zero(f)), level);
        le.add(r.error.total);
        for (int c = 0; c < 4; ++c) {
          if (r.record.child_mask & (1u << c)) next.push_back(child_of(r.record.key, c));
          else totals.leaf.add(r.error.quadrant[size_t(c)]);
        }
        totals.cpu_heights += r.cpu_heights;
        totals.cpu_error += r.cpu_error;
        totals.cpu_surface += r.cpu_surface;
        totals.cpu_encode += r.cpu_encode;
        ls.cpu_heights += r.cpu_heights;
        ls.cpu_error += r.cpu_error;
        ls.cpu_surface += r.cpu_surface;
        ls.cpu_encode += r.cpu_encode;
        for (size_t k = 0; k < kCpuParts; ++k) ls.cpu_parts[k] += r.surface.seconds_parts[k];
        add_surface_stats(totals.surface, r.surface);
        TERRAIN_TRY(sink(r));
        r.payload = {};
      }
    }
    std::sort(next.begin(), next.end(), key_less);
    keys = std::move(next);
  }
  return Status::success();
}

}  // namespace terrain::cook
