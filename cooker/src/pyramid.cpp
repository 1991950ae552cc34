#include "pyramid.h"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>

#include "parallel.h"
#include "quantize.h"

namespace terrain::cook {
namespace {

// Upper bound on the surface range (metres) over a node's vertices.
double node_range_bound(const CookContext& ctx, const RangeIndex& index, const NodeKey& key) {
  double cmin = 0, cmax = 0, rmin = 0, rmax = 0;
  node_sample_bounds(ctx, key, cmin, rmin, cmax, rmax);
  // Catmull-Rom taps reach one sample west/south and two east/north of the cell; one more sample
  // absorbs the curvature of a projected node edge.
  return index.surface_range_bound(int(std::floor(cmin)) - 2, int(std::floor(rmin)) - 2, int(std::floor(cmax)) + 3,
                                   int(std::floor(rmax)) + 3);
}

}  // namespace

Status build_pyramid(CookContext& ctx, const RangeIndex& index, uint32_t roots_x, uint32_t roots_y, int threads, ArchiveWriter& writer,
                     const ProgressFn& progress, PyramidStats& out) {
  out = PyramidStats{};
  const int nthreads = resolve_threads(threads);
  const int level_count = kRootLevel - ctx.finest_level + 1;
  // Where even the finest level's vertices are further apart than half a source sample, widen the
  // covered band beyond the raster's outer samples to one vertex spacing (reconstruct.h), so the
  // triangles holding the outer samples are drawn. A function of position only, as hole flags
  // must be; 0.5 (no change) for sources of 1 m and coarser.
  {
    double sx = 0, sy = 0;
    ctx.mapping->spacing_m(sx, sy);
    const double s = vertex_spacing_m(ctx.finest_level);
    ctx.surface.set_outer_apron(sx > 0 ? s / sx : 0.5, sy > 0 ? s / sy : 0.5);
  }

  // Roots that hold terrain.
  std::vector<NodeKey> keys;
  {
    std::vector<NodeKey> all;
    for (uint32_t y = 0; y < roots_y; ++y)
      for (uint32_t x = 0; x < roots_x; ++x) all.push_back({uint32_t(kRootLevel), x, y});
    std::vector<uint8_t> has(all.size(), 0);
    parallel_for(all.size(), nthreads, [&](size_t i) { has[i] = node_has_terrain(ctx, all[i]) ? 1 : 0; });
    for (size_t i = 0; i < all.size(); ++i)
      if (has[i]) keys.push_back(all[i]);
  }

  const size_t batch = size_t(16) * size_t(nthreads);
  std::vector<NodeResult> results;
  for (int level = kRootLevel; level >= ctx.finest_level && !keys.empty(); --level) {
    LevelStats& ls = out.levels[size_t(level)];
    {
      std::vector<double> bound(keys.size(), 0.0);
      parallel_for(keys.size(), nthreads, [&](size_t i) { bound[i] = node_range_bound(ctx, index, keys[i]); });
      const double worst = *std::max_element(bound.begin(), bound.end());
      // The range's step or the tolerance's, whichever is coarser; capped by the parent level's
      // (itself >= the tolerance's), so steps never decrease towards the roots.
      const int floor_step = tolerance_step(ctx.tolerance_m);
      const int step = level == kRootLevel
                           ? std::max(required_step(worst, -1), floor_step)
                           : std::min(std::max(required_step(worst, ctx.step_log2[kRootLevel]), floor_step),
                                      int(ctx.step_log2[size_t(level + 1)]));
      for (int l = level; l >= 0; --l) ctx.step_log2[size_t(l)] = uint8_t(step);  // finer levels: until cooked
    }
    ErrorStats& le = out.level_error[size_t(level)];
    std::vector<NodeKey> next;
    for (size_t start = 0; start < keys.size(); start += batch) {
      const size_t n = std::min(batch, keys.size() - start);
      results.resize(n);
      parallel_for(n, nthreads, [&](size_t i) { cook_node(ctx, keys[start + i], results[i]); });
      for (size_t i = 0; i < n; ++i) {  // key order: deterministic bytes and sums
        NodeResult& r = results[i];
        if (!r.status.ok()) return r.status;
        if (Status st = writer.add_node(r.record, r.payload); !st.ok()) return st;
        ++ls.nodes;
        ls.vertices += r.vertices;
        le.add(r.error.total);
        for (int c = 0; c < 4; ++c) {
          if (r.record.child_mask & (1u << c)) next.push_back(child_of(r.record.key, c));
          else out.leaf.add(r.error.quadrant[size_t(c)]);
        }
        out.vertices += r.vertices;
        out.cpu_heights += r.cpu_heights;
        out.cpu_error += r.cpu_error;
        out.cpu_surface += r.cpu_surface;
        out.cpu_encode += r.cpu_encode;
        SurfaceStats& s = out.surface;
        s.seconds_normals += r.surface.seconds_normals;
        s.seconds_albedo += r.surface.seconds_albedo;
        s.seconds_splat += r.surface.seconds_splat;
        s.seconds_cones += r.surface.seconds_cones;
        s.normal_err_max_deg = std::max(s.normal_err_max_deg, r.surface.normal_err_max_deg);
        s.normal_err_sum_deg += r.surface.normal_err_sum_deg;
        s.normal_samples += r.surface.normal_samples;
        s.albedo_sq_err_sum += r.surface.albedo_sq_err_sum;
        s.albedo_samples += r.surface.albedo_samples;
        r.payload = {};
      }
      if (progress) {
        const double done = double(kRootLevel - level) + double(start + n) / double(keys.size());
        if (!progress(done / level_count, fmt::format("level {}", level)))
          return Status::failure(Error::cancelled, "cancelled");
      }
    }
    out.nodes += ls.nodes;
    ls.error_samples = le.samples;
    ls.error_max_m = le.max_m;
    ls.error_rms_m = le.samples ? std::sqrt(le.sum_sq / double(le.samples)) : 0.0;
    ls.uncovered_samples = le.uncovered;
    std::sort(next.begin(), next.end(), key_less);
    keys = std::move(next);
  }
  out.output_vertices = out.nodes * uint64_t(kHeightCount);
  for (int l = 0; l < kLevelCount; ++l) out.levels[size_t(l)].step_log2 = ctx.step_log2[size_t(l)];
  return Status::success();
}

}  // namespace terrain::cook
