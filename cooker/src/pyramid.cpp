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

// One node's surface statistics into the cook's totals (every field of SurfaceStats).
void add_surface_stats(SurfaceTotals& t, const SurfaceStats& n) {
  t.cpu_normals += n.seconds_normals;
  t.cpu_albedo += n.seconds_albedo;
  t.cpu_splat += n.seconds_splat;
  t.cpu_cones += n.seconds_cones;
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
}

double rms_of(const ErrorStats& e) { return e.samples ? std::sqrt(e.sum_sq / double(e.samples)) : 0.0; }

}  // namespace

Status build_pyramid(CookContext& ctx, const RangeIndex& index, uint32_t roots_x, uint32_t roots_y, int threads, ArchiveWriter& writer,
                     const ProgressFn& progress, CookReport& report) {
  std::array<ErrorStats, kLevelCount> level_error{};
  ErrorStats leaf;  // each source sample against the finest node covering it
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
    LevelStats& ls = report.levels[size_t(level)];
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
    ErrorStats& le = level_error[size_t(level)];
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
          else leaf.add(r.error.quadrant[size_t(c)]);
        }
        report.cpu_heights += r.cpu_heights;
        report.cpu_error += r.cpu_error;
        report.cpu_surface += r.cpu_surface;
        report.cpu_encode += r.cpu_encode;
        add_surface_stats(report.surface, r.surface);
        r.payload = {};
      }
      if (progress) {
        const double done = double(kRootLevel - level) + double(start + n) / double(keys.size());
        if (!progress(done / level_count, fmt::format("level {}", level)))
          return Status::failure(Error::cancelled, "cancelled");
      }
    }
    report.nodes += ls.nodes;
    ls.error_samples = le.samples;
    ls.error_max_m = le.max_m;
    ls.error_rms_m = rms_of(le);
    ls.uncovered_samples = le.uncovered;
    std::sort(next.begin(), next.end(), key_less);
    keys = std::move(next);
  }
  report.output_vertices = report.nodes * uint64_t(kHeightCount);
  for (int l = 0; l < kLevelCount; ++l) report.levels[size_t(l)].step_log2 = ctx.step_log2[size_t(l)];
  report.leaf_error_samples = leaf.samples;
  report.leaf_error_max_m = leaf.max_m;
  report.leaf_error_rms_m = rms_of(leaf);
  report.leaf_uncovered_samples = leaf.uncovered;
  return Status::success();
}

}  // namespace terrain::cook
