// cook(): read -> mosaic -> voids -> frame and grid -> steps -> pyramid -> finish, timed per stage.
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <numeric>
#include <random>
#include <tuple>
#include <utility>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "crs.h"
#include "frame.h"
#include "inputs.h"
#include "memory_budget.h"
#include "mosaic_source.h"
#include "source_raster.h"
#include "void_plan.h"
#include "node_cook.h"
#include "node_spool.h"
#include "overlays.h"
#include "parallel.h"
#include "pyramid.h"
#include "range_index.h"
#include "terrain/archive_reader.h"
#include "terrain/cook.h"
#include "void_fill.h"

namespace terrain::cook {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

constexpr double kRootSizeM = node_size_m(kRootLevel);
// Tile side (samples) of the void plan's first pass; a block's window grows by up to one tile per
// side to whole tiles (void_plan.h).
constexpr int kVoidPlanTile = 256;

const char* policy_name(NodataPolicy p) {
  switch (p) {
    case NodataPolicy::automatic: return "auto";
    case NodataPolicy::hole: return "hole";
    case NodataPolicy::fill: return "fill";
  }
  return "?";
}

// Finest level allowed by default: vertex spacing at least 1/32 of the source sample spacing.
// Refinement is error-driven, so this only bounds it: bilinear vertices must come within the
// tolerance of a Catmull-Rom surface through coarse samples, and on the shared 21-90 m DEMs the
// tolerance of 0.5 m was met at 2-4 m spacing (1/10 to 1/32 of the source) where the relief is
// steep; flat areas stop at the roots.
int finest_level_for(double source_spacing_m) {
  for (int level = 0; level < kRootLevel; ++level)
    if (vertex_spacing_m(level) >= source_spacing_m / 32.0) return level;
  return kRootLevel;
}

// `inputs`: (path, description) of every raster read (a directory input stands for several).
std::string cook_info(const CookOptions& o, const CookReport& r,
                      const std::vector<std::pair<std::string, std::string>>& descriptions) {
  nlohmann::ordered_json j;
  j["tool"] = "terrain-cook";
  j["version"] = "0.1.0";
  nlohmann::ordered_json inputs = nlohmann::ordered_json::array();
  for (const auto& [path, description] : descriptions)
    inputs.push_back({{"path", path}, {"description", description}});
  j["inputs"] = inputs;
  j["options"] = {{"tolerance_m", o.tolerance_m},
                  {"finest_level", o.finest_level},
                  {"crs", o.crs},
                  {"frame", o.frame},
                  {"height_scale", o.height_scale},
                  {"height_offset", o.height_offset},
                  {"nodata", policy_name(o.nodata)},
                  {"fill_max_samples", o.fill_max_samples},
                  {"materials", o.materials_path},
                  {"albedo", o.albedo_path},
                  {"holes", o.holes_path},
                  {"landcover", o.landcover_path},
                  {"landcover_table", o.landcover_table_path},
                  {"heights_only", o.heights_only},
                  {"zstd_level", o.zstd_level},
                  {"surface_zstd_level", o.surface_zstd_level}};
  if (o.origin) j["options"]["origin"] = *o.origin;
  if (o.spacing) j["options"]["spacing"] = *o.spacing;
  if (o.nodata_value) j["options"]["nodata_value"] = *o.nodata_value;
  j["frame_reason"] = r.frame_reason;
  j["reconstruction"] = "Catmull-Rom bicubic in source sample space; bilinear over valid taps next to nodata";
  j["finest_level"] = r.finest_level;
  j["voids_filled_samples"] = r.voids_filled_samples;
  j["hole_samples"] = r.hole_samples;
  return j.dump();
}

// Nodes stop refining at the finest level allowed, even where the error still exceeds the
// tolerance (coarse sources: Catmull-Rom between 30-100 m samples is not met by bilinear vertices).
std::string unmet_tolerance_warning(const CookReport& r) {
  const int l = r.finest_level;
  std::string why = fmt::format("level {} ({} m vertex spacing) is the finest level allowed", l, vertex_spacing_m(l));
  if (l > 0)
    why += fmt::format(" (from the source spacing {:.3g} m: 1/32 of it, or --finest-level); --finest-level {} lets "
                       "nodes refine further (at the cost of more nodes)", r.source_spacing_m, l - 1);
  else
    why += " and the finest the format has";
  return fmt::format("--tolerance {} m is not met everywhere: the full-detail error reaches {:.3f} m because {}",
                     r.tolerance_m, r.leaf_error_max_m, why);
}

// The root grid and the data footprint, which the report states as the archive's metadata holds
// them (WorldInfo and CookReport name these members the same): grid_of(report) = grid_of(world).
template <class T>
auto grid_of(T& t) {
  return std::tie(t.origin_x_m, t.origin_y_m, t.roots_x, t.roots_y, t.extent_min_x_m, t.extent_min_y_m,
                  t.extent_max_x_m, t.extent_max_y_m);
}

// Blocks of side x side roots: the largest side whose cook window (the roots, their windows'
// margin, the void plan's tile rounding) fits the window budget at kWindowBytesPerSample.
uint32_t block_roots_for(uint64_t window_bytes, double sx, double sy, uint32_t roots_x, uint32_t roots_y) {
  const uint32_t most = std::max(roots_x, roots_y);
  uint32_t side = 1;
  while (side < most) {
    const uint32_t next = side + 1;
    const double margin_m = 2.0 * kWindowMargin * vertex_spacing_m(kRootLevel);
    const double cols = (next * kRootSizeM + margin_m) / std::max(sx, 1e-3) + 2 * kVoidPlanTile + 16;
    const double rows = (next * kRootSizeM + margin_m) / std::max(sy, 1e-3) + 2 * kVoidPlanTile + 16;
    if (cols * rows * double(kWindowBytesPerSample) > double(window_bytes)) break;
    side = next;
  }
  return side;
}

// Block indices in cooking order: row by row, or shuffled by `seed` (tests).
std::vector<uint32_t> block_order(uint32_t count, uint64_t seed) {
  std::vector<uint32_t> order(count);
  std::iota(order.begin(), order.end(), 0u);
  if (seed) {
    std::mt19937_64 rng(seed);
    for (uint32_t i = count; i > 1; --i) std::swap(order[i - 1], order[size_t(rng() % i)]);
  }
  return order;
}

uint64_t peak_rss_bytes() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return uint64_t(u.ru_maxrss) * 1024;
}

}  // namespace

Status cook(const CookOptions& options, const ProgressFn& progress, CookReport& report) {
  report = CookReport{};
  const auto t_start = Clock::now();
  if (options.output.empty()) return Status::failure(Error::invalid_argument, "no output archive given");
  if (!(options.tolerance_m > 0) || !std::isfinite(options.tolerance_m))
    return Status::failure(Error::invalid_argument, "--tolerance must be a positive number of metres");
  if (options.finest_level < -1 || options.finest_level > kRootLevel)
    return Status::failure(Error::invalid_argument, "--finest-level must be 0..5");
  const int threads = resolve_threads(options.threads);
  report.threads = threads;
  report.tolerance_m = options.tolerance_m;
  auto stage = [&](double f, const std::string& name) { return !progress || progress(f, name); };
  if (!stage(0.0, "reading")) return Status::failure(Error::cancelled, "cancelled");

  // ---- open the inputs; the first pass reads every sample once ----
  report.memory_limit_bytes = memory_limit_of(options);
  const MemoryShares shares = memory_shares(report.memory_limit_bytes);
  set_gdal_cache_bytes(shares.gdal_cache);
  MosaicSource source;
  if (Status st = open_mosaic_source(options, shares.inputs, source); !st.ok()) return st;
  const Raster& header = source.header();
  report.source_samples = uint64_t(header.width) * uint64_t(header.height);
  report.seconds_read = seconds_since(t_start);

  // ---- prepare: voids, frame, grid, steps ----
  const auto t_prep = Clock::now();
  VoidPlan voids;
  {
    source.set_count_implausible(true);
    const ReadSamples read = [&](int c0, int r0, int w, int h, float* out) { return source.read(c0, r0, w, h, out); };
    const ProgressFn sub = progress ? scaled_progress(progress, 0.0, 0.03) : ProgressFn{};
    if (Status st = plan_voids(header.width, header.height, read, options.nodata, options.fill_max_samples,
                               kVoidPlanTile, voids, sub);
        !st.ok())
      return st;
    source.set_count_implausible(false);
  }
  std::vector<std::pair<std::string, std::string>> descriptions;
  for (const MosaicSource::InputStat& in : source.inputs()) {
    descriptions.emplace_back(in.path, in.description);
    report.input_descriptions.push_back(fmt::format("{}: {}; {}", in.path, in.description, describe_crs(in.crs)));
    if (const uint64_t n = in.implausible.out_of_range + in.implausible.sentinel; n) {
      report.implausible_samples += n;
      Raster named;
      named.path = in.path;
      named.implausible = in.implausible;
      report.warnings.push_back(implausible_heights_warning(named, options.valid_range_m));
    }
  }
  if (voids.valid_samples == 0)
    return Status::failure(Error::no_data, fmt::format("{}: every sample is nodata; nothing to cook", header.path));
  report.source_valid_samples = voids.valid_samples;
  report.voids_filled_samples = voids.stats.filled_samples;
  report.voids_filled_regions = voids.stats.filled_regions;
  report.hole_samples = voids.stats.hole_samples;
  report.hole_regions = voids.stats.hole_regions;
  // Filling every void (--nodata fill) leaves no nodata: the data then reach the raster's edges.
  const SampleRect data_rect = options.nodata == NodataPolicy::fill
                                   ? SampleRect{0, 0, header.width - 1, header.height - 1}
                                   : voids.valid_bounds;
  const int vc0 = data_rect.c0, vr0 = data_rect.r0, vc1 = data_rect.c1, vr1 = data_rect.r1;
  const Raster& source_header = header;

  FrameCrs frame;
  if (Status st = choose_frame(source_header, options.frame, frame, report.frame_reason, &data_rect); !st.ok())
    return st;
  report.frame = frame;
  SourceMapping mapping;
  if (Status st = mapping.init(source_header, frame, threads); !st.ok()) return st;
  double fx0 = 0, fy0 = 0, fx1 = 0, fy1 = 0;
  // The footprint: pixel areas, or for point samples the samples' hull.
  mapping.frame_bounds(vc0, vr0, vc1, vr1, source_header.geo.point_samples ? 0.0 : 0.5, fx0, fy0, fx1, fy1);
  CookContext ctx;
  ctx.source_width = source_header.width;
  ctx.source_height = source_header.height;
  ctx.mapping = &mapping;
  ctx.origin_x = std::floor(fx0 / kRootSizeM) * kRootSizeM;
  ctx.origin_y = std::floor(fy0 / kRootSizeM) * kRootSizeM;
  const double roots_x = std::ceil((fx1 - ctx.origin_x) / kRootSizeM), roots_y = std::ceil((fy1 - ctx.origin_y) / kRootSizeM);
  if (roots_x * roots_y > 1e7)
    return Status::failure(Error::unsupported_input,
                           fmt::format("the data spans {:.0f} x {:.0f} km in the frame: too large for one archive",
                                       (fx1 - fx0) / 1000, (fy1 - fy0) / 1000));
  if (!options.force && (roots_x * roots_y > double(kMaxPlannedRoots) || roots_x > kStreamerMaxRootsPerSide ||
                         roots_y > kStreamerMaxRootsPerSide))
    return Status::failure(Error::unsupported_input,
                           fmt::format("the plan needs {:.0f} x {:.0f} root nodes (the data spans {:.0f} x {:.0f} km): "
                                       "beyond {} roots or {} per side (terrain-view's limit); check --spacing and "
                                       "the CRS, or give --force", roots_x, roots_y, (fx1 - fx0) / 1000,
                                       (fy1 - fy0) / 1000, kMaxPlannedRoots, kStreamerMaxRootsPerSide));
  WorldInfo world{.crs = frame,
                  .origin_x_m = ctx.origin_x,
                  .origin_y_m = ctx.origin_y,
                  .roots_x = uint32_t(std::max(1.0, roots_x)),
                  .roots_y = uint32_t(std::max(1.0, roots_y)),
                  .extent_min_x_m = fx0,
                  .extent_min_y_m = fy0,
                  .extent_max_x_m = fx1,
                  .extent_max_y_m = fy1};
  grid_of(report) = grid_of(world);
  const double margin = kWindowMargin * vertex_spacing_m(kRootLevel) + kRootSizeM;
  mapping.cover_frame_area(ctx.origin_x - margin, ctx.origin_y - margin,
                           ctx.origin_x + report.roots_x * kRootSizeM + margin,
                           ctx.origin_y + report.roots_y * kRootSizeM + margin, threads);
  double sx = 0, sy = 0;
  mapping.spacing_m(sx, sy);
  report.source_spacing_m = std::min(sx, sy);
  ctx.finest_level = options.finest_level >= 0 ? options.finest_level : finest_level_for(report.source_spacing_m);
  report.finest_level = ctx.finest_level;
  ctx.tolerance_m = options.tolerance_m;
  ctx.source_spacing_m = report.source_spacing_m;
  ctx.heights_only = options.heights_only;
  ctx.payload.zstd_level = options.zstd_level;
  ctx.payload.surface_zstd_level = options.surface_zstd_level;
  // Where even the finest level's vertices are further apart than half a source sample, widen the
  // covered band beyond the raster's outer samples to one vertex spacing (reconstruct.h), so the
  // triangles holding the outer samples are drawn. A function of position only, as hole flags
  // must be; 0.5 (no change) for sources of 1 m and coarser.
  {
    const double s = vertex_spacing_m(ctx.finest_level);
    ctx.surface.set_outer_apron(sx > 0 ? s / sx : 0.5, sy > 0 ? s / sy : 0.5);
  }

  // Surface layers: material rules and palette.
  std::shared_ptr<const MaterialRules> rules;
  {
    SurfaceOptions so;
    so.materials_path = options.materials_path;
    so.bc_quality = BcQuality(uint8_t(options.surface_quality));
    ctx.bc_quality = so.bc_quality;
    if (Status st = load_material_rules(so, rules); !st.ok()) return st;
    ctx.rules = rules.get();
    report.surface_layers = !options.heights_only;
  }
  std::unique_ptr<SurfaceOverlays> overlays;
  if (Status st = load_overlays(options, frame, palette_of(*rules), ctx.origin_x - margin, ctx.origin_y - margin,
                                ctx.origin_x + report.roots_x * kRootSizeM + margin,
                                ctx.origin_y + report.roots_y * kRootSizeM + margin, threads, overlays);
      !st.ok())
    return st;
  ctx.overlays = overlays.get();

  // Blocks of roots, each reading only its window of the source.
  const BlockGrid grid{report.roots_x, report.roots_y,
                       options.block_roots ? options.block_roots
                                           : block_roots_for(shares.window, sx, sy, report.roots_x, report.roots_y)};
  report.block_roots = grid.side;
  report.blocks = grid.count();
  const std::vector<uint32_t> order = block_order(grid.count(), options.block_order);
  // A block's window: the samples it needs, grown so that every void reaching into them is
  // filled exactly as over the whole raster (void_plan.h), read from the inputs and filled.
  SampleWindow window;
  auto read_window = [&](const SampleRect& need) -> Status {
    const SampleRect rect = fill_read_rect(voids, need);
    window.rect = rect;
    window.source_width = source_header.width;
    window.source_height = source_header.height;
    window.values.resize(size_t(rect.samples()));
    window.filled.resize(size_t(rect.samples()));
    if (Status st = source.read(rect.c0, rect.r0, rect.width(), rect.height(), window.values.data()); !st.ok())
      return st;
    double residual = 0;
    if (Status st = fill_voids_window(voids, rect, window.values.data(), window.filled.data(), residual,
                                      report.memory_limit_bytes);
        !st.ok())
      return st;
    report.void_fill_residual_m = std::max(report.void_fill_residual_m, residual);
    report.block_window_samples_max = std::max(report.block_window_samples_max, rect.samples());
    return Status::success();
  };

  // Pass 1: every level's step, from the range bounds of every node that could exist.
  {
    std::array<double, kLevelCount> worst{};
    for (size_t n = 0; n < order.size(); ++n) {
      const RootBlock b = grid.block(order[n]);
      int top = 0;
      const SampleRect rect = block_range_rect(ctx, b, top);
      if (rect.empty()) continue;
      if (Status st = read_window(rect); !st.ok()) return st;
      RangeIndex index;
      index.build(window, top);
      block_range_bounds(ctx, index, b, threads, worst);
      if (!stage(0.02 + 0.08 * double(n + 1) / double(order.size()), "steps"))
        return Status::failure(Error::cancelled, "cancelled");
    }
    choose_steps(worst, ctx.tolerance_m, ctx.finest_level, ctx.step_log2);
  }
  report.seconds_prepare = seconds_since(t_prep);

  // ---- pyramid ----
  const auto t_pyr = Clock::now();
  ArchiveWriter writer;
  if (Status st = writer.open(options.output); !st.ok()) return st;
  NodeSpool spool;
  const bool spooled = grid.count() > 1;
  if (spooled)
    if (Status st = spool.open(fmt::format("{}.spool-{}", options.output, ::getpid())); !st.ok()) return st;
  const NodeSink sink = [&](NodeResult& r) {
    return spooled ? spool.add(r.record, r.payload) : writer.add_node(r.record, r.payload);
  };
  PyramidTotals totals;
  for (size_t n = 0; n < order.size(); ++n) {
    const RootBlock b = grid.block(order[n]);
    const SampleRect rect = block_cook_rect(ctx, b);
    if (rect.empty()) continue;
    if (Status st = read_window(rect); !st.ok()) return st;
    ctx.set_window(window);
    if (overlays) {
      double bx0 = 0, by0 = 0, bx1 = 0, by1 = 0;
      block_frame_rect(ctx, b, bx0, by0, bx1, by1);
      if (Status st = prepare_overlays_block(*overlays, bx0, by0, bx1, by1); !st.ok()) return st;
    }
    if (Status st = cook_block(ctx, b, threads, sink, totals, report); !st.ok()) {
      writer.abort();
      return st;
    }
    if (!stage(0.1 + 0.85 * double(n + 1) / double(order.size()), fmt::format("block {}/{}", n + 1, order.size())))
      return Status::failure(Error::cancelled, "cancelled");
  }
  window = SampleWindow{};
  if (spooled) {
    report.spool_bytes = spool.bytes();
    if (Status st = spool.drain(writer); !st.ok()) return st;
  }
  finish_pyramid_report(ctx, totals, report);
  report.seconds_pyramid = seconds_since(t_pyr);
  if (report.nodes == 0) {
    writer.abort();
    return Status::failure(Error::no_data, "no node holds terrain (is the data smaller than a vertex?)");
  }
  // Levels finer than the finest level cooked hold no node; they record its step (as the steps of
  // a level-by-level cook did).
  {
    int f = 0;
    while (f < kRootLevel && report.levels[size_t(f)].nodes == 0) ++f;
    for (int l = f - 1; l >= 0; --l) {
      ctx.step_log2[size_t(l)] = ctx.step_log2[size_t(f)];
      report.levels[size_t(l)].step_log2 = ctx.step_log2[size_t(f)];
    }
  }

  // ---- finish ----
  const auto t_fin = Clock::now();
  world.step_log2 = ctx.step_log2;
  if (rules) world.palette = palette_of(*rules);
  world.cook_info_json = cook_info(options, report, descriptions);
  if (Status st = writer.finish(world); !st.ok()) return st;
  report.archive_bytes = writer.bytes_written();
  {
    ArchiveReader reader;
    SectionBytes sb;
    if (reader.open(options.output).ok() && reader.section_bytes(sb).ok())
      for (int s = 0; s < 5; ++s) {
        report.section_stored_bytes[size_t(s)] = sb.stored[s];
        report.section_raw_bytes[size_t(s)] = sb.raw[s];
      }
  }
  report.seconds_finish = seconds_since(t_fin);
  for (const MosaicSource::InputStat& in : source.inputs()) report.input_bytes_read.push_back(in.bytes_read);

  report.seconds_total = seconds_since(t_start);
  report.source_samples_per_second = double(report.source_samples) / report.seconds_total;
  report.height_samples_per_cpu_second =
      report.cpu_heights > 0 ? double(report.output_vertices) / report.cpu_heights : 0;
  report.peak_rss_bytes = peak_rss_bytes();
  if (report.leaf_error_max_m > options.tolerance_m) report.warnings.push_back(unmet_tolerance_warning(report));
  if (progress) progress(1.0, "done");
  return Status::success();
}

}  // namespace terrain::cook
