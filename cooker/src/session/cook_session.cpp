#include "session/cook_session.h"

#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "frame/crs.h"
#include "inputs/height_units.h"
#include "inputs/inputs.h"
#include "overlays/overlays.h"
#include "pyramid/overview_levels.h"
#include "base/parallel.h"
#include "pyramid/quantize.h"
#include "session/cook_options_table.h"
#include "inputs/source_raster.h"
#include "terrain/archive_reader.h"
#include "inputs/tiff_blocks.h"

namespace terrain::cook {
namespace {

constexpr double kRootSizeM = node_size_m(kRootLevel);

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

// The vertex lattice's phase along one axis (cooker/README.md, "Lattice phase"): the offset in
// [0, spacing) of the source's samples from the frame's multiples of their spacing. The origin is
// that offset plus a multiple of the root size, so a sample is a vertex of every level whose
// spacing divides the samples' (1 m lidar: every sample is a level-1 vertex, and level 1 reproduces
// the samples up to the height step), and cooks of neighbouring tiles of one product share the
// root grid. 0 where the samples do not lie on lines of the frame's axes (another CRS, rotation).
double lattice_phase(double sample0, double spacing) {
  const double s = std::abs(spacing);
  if (!(s > 0) || !std::isfinite(sample0)) return 0.0;
  double p = std::fmod(sample0, s);  // exact
  if (p < 0) p += s;
  return p < s ? p : 0.0;
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
  const std::string tolerance = r.tolerance_from_source ? fmt::format("the tolerance of {:.3g} m (from the source)", r.tolerance_m)
                                                       : fmt::format("--tolerance {} m", r.tolerance_m);
  return fmt::format("{} is not met everywhere: the full-detail error reaches {:.3f} m because {}", tolerance,
                     r.leaf_error_max_m, why);
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
uint32_t block_roots_for(uint64_t window_bytes, int margin_vertices, double sx, double sy, uint32_t roots_x,
                         uint32_t roots_y) {
  const uint32_t most = std::max(roots_x, roots_y);
  uint32_t side = 1;
  while (side < most) {
    const uint32_t next = side + 1;
    const double margin_m = 2.0 * margin_vertices * vertex_spacing_m(kRootLevel);
    const double cols = (next * kRootSizeM + margin_m) / std::max(sx, 1e-3) + 2 * kVoidPlanTile + 16;
    const double rows = (next * kRootSizeM + margin_m) / std::max(sy, 1e-3) + 2 * kVoidPlanTile + 16;
    if (cols * rows * double(kWindowBytesPerSample) > double(window_bytes)) break;
    side = next;
  }
  return side;
}

uint64_t peak_rss_bytes() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return uint64_t(u.ru_maxrss) * 1024;
}

}  // namespace

double default_tolerance_m(double source_spacing_m) {
  return std::max(0.5, source_spacing_m / 32.0);
}

// `inputs`: (path, description) of every raster read (a directory input stands for several).
std::string cook_info(const CookOptions& o, const CookReport& r,
                      const std::vector<std::pair<std::string, std::string>>& descriptions) {
  nlohmann::ordered_json j;
  j["tool"] = "terrain-cook";
  j["version"] = TERRAIN_VERSION;  // the project version (CMakeLists.txt), defined by cooker/CMakeLists.txt
  nlohmann::ordered_json inputs = nlohmann::ordered_json::array();
  for (size_t i = 0; i < descriptions.size(); ++i) {
    inputs.push_back({{"path", descriptions[i].first}, {"description", descriptions[i].second}});
    // The unit of its heights and the factor applied (terrain-inspect shows them).
    if (i < r.input_height_units.size()) inputs.back()["heights"] = height_unit_json(r.input_height_units[i]);
  }
  j["inputs"] = inputs;
  CookOptions recorded = o;
  recorded.tolerance_m = r.tolerance_m;  // the tolerance in force, also when it came from the source
  j["options"] = cook_info_options_json(recorded);
  j["frame_reason"] = r.frame_reason;
  j["reconstruction"] = "Catmull-Rom bicubic in source sample space; bilinear over valid taps next to nodata";
  j["finest_level"] = r.finest_level;
  j["voids_filled_samples"] = r.voids_filled_samples;
  j["hole_samples"] = r.hole_samples;
  // Lets terrain-inspect give bytes per source sample as the cook report does.
  j["source_valid_samples"] = r.source_valid_samples;
  if (r.overview_levels > 0) j["overview_levels"] = r.overview_levels;  // absent: none (version-1 bytes kept)
  return j.dump();
}

void set_tiff_block_cache(const CookSession& s, uint64_t most) {
  // Blocks the cooker decodes itself (tiff_blocks.h) are cheap to decode again, and a cache larger
  // than the blocks a pass reuses only adds fresh pages: two rows of blocks across the source, at
  // least 16 MB, at most `most`. The 1 m lidar-like 8 km square (512-row tiles: 32 MB), CPU s:
  // `plan` 0.72 with 24 MB, 0.85 with 64, 1.06 with 128; its unit 2.26 / 2.39 / 2.37 and 2.54 with
  // the whole source (300 MB).
  const uint64_t rows = tiff_block_rows_bytes(s.source.header().width);
  set_tiff_block_cache_bytes(std::min(most, std::max<uint64_t>(rows, uint64_t(16) << 20)));
}

InputOptions input_options(const CookOptions& o) {
  InputOptions in;
  in.inputs = o.inputs;
  in.crs = o.crs;
  in.origin = o.origin;
  in.spacing = o.spacing;
  in.height_scale = o.height_scale;
  in.height_offset = o.height_offset;
  in.height_scale_set = o.height_scale_set;
  in.nodata_value = o.nodata_value;
  in.valid_range_m = o.valid_range_m;
  in.memory_limit_bytes = o.memory_limit_bytes;
  in.raw_size = o.raw_size;
  in.raw_type = o.raw_type;
  in.raw_big_endian = o.raw_big_endian;
  in.tile_encoding = o.tile_encoding;
  in.finer_wins = o.overlap == OverlapRule::finer;
  return in;
}

OverlayOptions overlay_options(const CookOptions& o, uint64_t memory_limit_bytes) {
  OverlayOptions ov;
  ov.albedo_path = o.albedo_path;
  ov.holes_path = o.holes_path;
  ov.landcover_path = o.landcover_path;
  ov.landcover_table_path = o.landcover_table_path;
  ov.heights_only = o.heights_only;
  ov.memory_limit_bytes = memory_limit_bytes;
  return ov;
}

Status open_inputs(const CookOptions& options, CookSession& s, bool files_checked) {
  if (!(options.tolerance_m >= 0) || !std::isfinite(options.tolerance_m))
    return Status::failure(Error::invalid_argument, "--tolerance must be a positive number of metres (0: from the source)");
  if (options.finest_level < -1 || options.finest_level > kRootLevel)
    return Status::failure(Error::invalid_argument, "--finest-level must be 0..5");
  if (!(options.height_step_m >= 0 && options.height_step_m <= 16))
    return Status::failure(Error::invalid_argument, "--height-step must be 0 (from the tolerance) .. 16 metres");
  s.options = options;
  s.threads = resolve_threads(options.threads);
  s.decided.memory_limit_bytes = memory_limit_of(options);
  s.shares = memory_shares(s.decided.memory_limit_bytes);
  set_gdal_cache_bytes(s.shares.gdal_cache);
  set_gdal_decode_threads(s.threads);
  TERRAIN_TRY(open_mosaic_source(input_options(options), s.shares.inputs, s.source, files_checked));
  const Raster& header = s.source.header();
  // GDAL's cache: the whole decoded source when it fits the share and the process reads it again
  // (the cook then decodes nothing twice), else enough for a row of GDAL blocks across a wide input
  // (the first pass reads tile rows shorter than a block row) and a block's window: 128 MB. A
  // larger cache buys nothing on a source read once, in order, and costs a fresh page for every
  // decoded tile: `plan` alone on the 1 m lidar-like 8 km square took 2.75-2.79 CPU s with the
  // whole source cached, 1.57-1.70 with 32 MB (GDAL_CACHEMAX; 96 000 against 16 500 page faults).
  {
    const uint64_t decoded = uint64_t(header.width) * uint64_t(header.height) * sizeof(float);
    const uint64_t want = decoded + decoded / 8;
    const uint64_t bounded = std::min<uint64_t>(s.shares.gdal_cache, uint64_t(128) << 20);
    set_gdal_cache_bytes(s.reads_source_again && want <= s.shares.gdal_cache ? want : bounded);
    set_tiff_block_cache(s, bounded);
  }
  s.descriptions.clear();
  for (const MosaicSource::InputStat& in : s.source.inputs()) s.descriptions.emplace_back(in.path, in.description);
  return Status::success();
}

Status first_pass(CookSession& s, const ProgressFn& progress) {
  const Raster& header = s.source.header();
  s.source.set_count_implausible(true);
  // Read ahead on a second thread (2+ threads), in reads wide enough for GDAL to decode several
  // compressed blocks at once on every thread (open_session): on a cluster the plan's pass is the
  // serial part, and decoding is most of it.
  const bool ahead = s.threads > 1;
  const ReadSamples read = [&](int c0, int r0, int w, int h, float* out) { return s.source.read(c0, r0, w, h, out); };
  s.ranges.start(header.width, header.height);
  if (Status st = plan_voids(header.width, header.height, read, s.options.nodata, s.options.fill_max_samples,
                             kVoidPlanTile, s.voids, progress, &s.ranges, ahead);
      !st.ok())
    return st;
  s.ranges.finish();
  s.source.set_count_implausible(false);
  s.voids.source_name = header.path;
  for (const MosaicSource::InputStat& in : s.source.inputs())
    if (const uint64_t n = in.implausible.out_of_range + in.implausible.sentinel; n) {
      s.stats.implausible_samples += n;
      Raster named;
      named.path = in.path;
      named.implausible = in.implausible;
      s.stats.warnings.push_back(implausible_heights_warning(named, s.options.valid_range_m));
    }
  // What each input gave (InputSamples, cook.h): one that the inputs before it cover is named.
  const char* overlap_rule =
      s.options.overlap == OverlapRule::finer
          ? "where inputs overlap, the finer wins, then the one listed first; the finest input's grid is the mosaic's"
          : "--overlap list: where inputs overlap, the one listed first wins; its grid is the mosaic's: list it first "
            "to prefer it";
  s.stats.input_samples.clear();
  for (const MosaicSource::InputStat& in : s.source.inputs()) {
    s.stats.input_samples.push_back(InputSamples{.path = in.path, .read = in.samples_read, .used = in.samples_used});
    if (in.samples_used > 0 && in.samples_used * 100 >= in.samples_read) continue;
    if (in.samples_read == 0)
      s.stats.warnings.push_back(fmt::format("{}: contributes nothing to the archive: it has no height on the mosaic's "
                                             "grid (every sample nodata or implausible)", in.path));
    else if (in.samples_used == 0)
      s.stats.warnings.push_back(fmt::format(
          "{}: contributes nothing to the archive: inputs that take precedence have a height at each of its {} samples "
          "on the mosaic's grid ({})", in.path, in.samples_read, overlap_rule));
    else
      s.stats.warnings.push_back(fmt::format(
          "{}: contributes only {} of its {} samples on the mosaic's grid ({:.2f} %) to the archive: inputs that take "
          "precedence have heights at the others ({})", in.path, in.samples_used, in.samples_read,
          100.0 * double(in.samples_used) / double(in.samples_read), overlap_rule));
  }
  for (size_t f = 0; f < s.source.families().size(); ++f)
    for (size_t i : s.source.families()[f].inputs) {
      s.stats.input_samples[i].family = uint32_t(f);
      s.stats.input_samples[i].spacing_m = s.source.families()[f].spacing_m;
    }
  if (s.voids.valid_samples == 0)
    return Status::failure(Error::no_data, fmt::format("{}: every sample is nodata; nothing to cook", header.path));
  return Status::success();
}

Status check_plan_size(double roots_x, double roots_y, bool force, double span_x_km, double span_y_km) {
  const bool too_wide = roots_x > kStreamerMaxRootsPerSide || roots_y > kStreamerMaxRootsPerSide;
  if (too_wide || (!force && roots_x * roots_y > double(kMaxPlannedRoots)))
    return Status::failure(
        Error::unsupported_input,
        fmt::format("the plan needs {:.0f} x {:.0f} root nodes (the data spans {:.0f} x {:.0f} km): beyond {}; check "
                    "--spacing and the CRS{}", roots_x, roots_y, span_x_km, span_y_km,
                    too_wide ? fmt::format("{} per side (the format's limit, which is the streamer's)",
                                           kStreamerMaxRootsPerSide)
                             : fmt::format("{} roots", kMaxPlannedRoots),
                    too_wide ? "" : ", or give --force"));
  return Status::success();
}

Status frame_and_grid(CookSession& s, const FrameCrs* planned) {
  const Raster& header = s.source.header();
  const CookOptions& options = s.options;
  // Filling every void (--nodata fill) leaves no nodata: the data then reach the raster's edges.
  const SampleRect data = options.nodata == NodataPolicy::fill ? SampleRect{0, 0, header.width - 1, header.height - 1}
                                                               : s.voids.valid_bounds;
  if (planned) {
    s.frame = *planned;
  } else if (Status st = choose_frame(header, options.frame, s.frame, s.decided.frame_reason, &data); !st.ok()) {
    return st;
  }
  TERRAIN_TRY(s.mapping.init(header, s.frame, s.threads));
  double fx0 = 0, fy0 = 0, fx1 = 0, fy1 = 0;
  // The footprint: pixel areas, or for point samples the samples' hull.
  s.mapping.frame_bounds(data.c0, data.r0, data.c1, data.r1, header.geo.point_samples ? 0.0 : 0.5, fx0, fy0, fx1, fy1);
  CookContext& ctx = s.ctx;
  ctx.source_width = header.width;
  ctx.source_height = header.height;
  ctx.mapping = &s.mapping;
  // The root grid covers the footprint; where the samples lie on the frame's axes it starts at
  // their phase and covers their centres (the samples' hull), so a footprint whose pixel edges lie
  // on root boundaries does not spill half a pixel into one more row and column of roots.
  double phase_x = 0, phase_y = 0, gx0 = fx0, gy0 = fy0, gx1 = fx1, gy1 = fy1;
  if (s.mapping.axis_aligned()) {
    double x00 = 0, y00 = 0, step_x = 0, step_y = 0;
    s.mapping.sample_grid(x00, y00, step_x, step_y);
    phase_x = lattice_phase(x00, step_x);
    phase_y = lattice_phase(y00, step_y);
    s.mapping.frame_bounds(data.c0, data.r0, data.c1, data.r1, 0.0, gx0, gy0, gx1, gy1);
  }
  ctx.origin_x = std::floor((gx0 - phase_x) / kRootSizeM) * kRootSizeM + phase_x;
  ctx.origin_y = std::floor((gy0 - phase_y) / kRootSizeM) * kRootSizeM + phase_y;
  const double roots_x = std::ceil((gx1 - ctx.origin_x) / kRootSizeM), roots_y = std::ceil((gy1 - ctx.origin_y) / kRootSizeM);
  if (roots_x * roots_y > 1e7)
    return Status::failure(Error::unsupported_input,
                           fmt::format("the data spans {:.0f} x {:.0f} km in the frame: too large for one archive",
                                       (fx1 - fx0) / 1000, (fy1 - fy0) / 1000));
  TERRAIN_TRY(check_plan_size(roots_x, roots_y, options.force, (fx1 - fx0) / 1000, (fy1 - fy0) / 1000));
  s.world = WorldInfo{.crs = s.frame,
                      .origin_x_m = ctx.origin_x,
                      .origin_y_m = ctx.origin_y,
                      .roots_x = uint32_t(std::max(1.0, roots_x)),
                      .roots_y = uint32_t(std::max(1.0, roots_y)),
                      .extent_min_x_m = fx0,
                      .extent_min_y_m = fy0,
                      .extent_max_x_m = fx1,
                      .extent_max_y_m = fy1};
  const uint32_t rx = s.world.roots_x, ry = s.world.roots_y;
  const double margin = kWindowMargin * vertex_spacing_m(kRootLevel) + kRootSizeM;
  s.mapping.cover_frame_area(ctx.origin_x - margin, ctx.origin_y - margin, ctx.origin_x + rx * kRootSizeM + margin,
                             ctx.origin_y + ry * kRootSizeM + margin, s.threads);
  double sx = 0, sy = 0;
  s.mapping.spacing_m(sx, sy);
  s.decided.source_spacing_m = std::min(sx, sy);
  s.decided.source_sample_area_m2 = sx * sy;
  {
    const RefineRules own = family_refine_rules(options, s.decided.source_spacing_m, 0, 0);
    ctx.finest_level = own.finest_level;
    ctx.tolerance_m = own.tolerance_m;
    ctx.source_spacing_m = own.source_spacing_m;
  }
  // Several grid families: each refines by its own spacing (family 0 is the mosaic's grid: the
  // rules above); an explicit --tolerance or --finest-level holds for all of them.
  ctx.family_rules.clear();
  if (const auto& families = s.source.families(); families.size() > 1)
    for (size_t f = 0; f < families.size(); ++f)
      ctx.family_rules.push_back(family_refine_rules(options, ctx.source_spacing_m, families[f].spacing_m, f));
  ctx.heights_only = options.heights_only;
  ctx.payload.zstd_level = options.zstd_level;
  ctx.payload.surface_zstd_level = options.surface_zstd_level;
  // Where even the finest level's vertices are further apart than half a source sample, widen the
  // covered band beyond the raster's outer samples to one vertex spacing (reconstruct.h), so the
  // triangles holding the outer samples are drawn. A function of position only, as hole flags
  // must be; 0.5 (no change) for sources of 1 m and coarser.
  {
    const double sp = vertex_spacing_m(ctx.finest_level);
    ctx.surface.set_outer_apron(sx > 0 ? sp / sx : 0.5, sy > 0 ? sp / sy : 0.5);
  }
  // Blocks of roots, each reading only its window of the source; work units of whole blocks.
  uint32_t side =
      options.block_roots ? options.block_roots : block_roots_for(s.shares.window, ctx.window_margin(), sx, sy, rx, ry);
  const uint32_t unit_side =
      options.unit_roots ? options.unit_roots : default_unit_roots(side, sx, sy, ctx.finest_level, rx, ry);
  side = std::min(side, unit_side);  // a unit smaller than a block is cooked as one block
  s.grid = BlockGrid{rx, ry, side};
  s.units = BlockGrid{rx, ry, unit_side};
  return Status::success();
}

RefineRules family_refine_rules(const CookOptions& options, double mosaic_spacing_m, double family_spacing_m,
                                size_t family) {
  const double spacing = family == 0 ? mosaic_spacing_m : std::max(mosaic_spacing_m, family_spacing_m);
  return RefineRules{.tolerance_m = options.tolerance_m > 0 ? options.tolerance_m : default_tolerance_m(spacing),
                     .source_spacing_m = spacing,
                     .finest_level = options.finest_level >= 0 ? options.finest_level : finest_level_for(spacing)};
}

uint32_t default_unit_roots(uint32_t block_side, double spacing_x_m, double spacing_y_m, int finest_level,
                            uint32_t roots_x, uint32_t roots_y) {
  const uint32_t most = std::max(roots_x, roots_y);
  if (block_side >= most) return block_side;
  const double samples_per_root =
      (kRootSizeM / std::max(spacing_x_m, 1e-3)) * (kRootSizeM / std::max(spacing_y_m, 1e-3));
  double nodes_per_root = 0;  // a full pyramid from the finest level up
  for (int l = std::clamp(finest_level, 0, kRootLevel); l <= kRootLevel; ++l)
    nodes_per_root += double(1u << (2 * (kRootLevel - l)));
  uint32_t k = 1;
  while (k * block_side < most) {
    const double roots = double((k + 1) * block_side) * double((k + 1) * block_side);
    if (roots * samples_per_root > kUnitSamples || roots * nodes_per_root > kUnitNodes) break;
    ++k;
  }
  return k * block_side;
}

// Whether the nodes cooked from the source code their normals with codec 4 (SPEC 16.7); the archive
// then declares it (WorldInfo::derived_normals), in one process and in the merge alike.
bool derives_normals(const CookOptions& o) { return !o.heights_only && o.normals == NormalsMode::derived; }

Status surface_setup(CookSession& s) {
  const double margin = kWindowMargin * vertex_spacing_m(kRootLevel) + kRootSizeM;
  SurfaceOptions so;
  so.materials_path = s.options.materials_path;
  so.bc_quality = BcQuality(uint8_t(s.options.surface_quality));
  s.ctx.bc_quality = so.bc_quality;
  s.ctx.bc_rdo = s.options.bc_rdo;
  s.ctx.derive_normals = derives_normals(s.options);
  // A grid of at most 4 roots (a few hundred nodes at most) is measured whole: a sample of a few
  // nodes would say little there, and the time is small.
  s.ctx.check_all_errors =
      s.options.error_checks == ErrorChecks::all || uint64_t(s.world.roots_x) * uint64_t(s.world.roots_y) <= 4;
  TERRAIN_TRY(load_material_rules(so, s.rules));
  s.ctx.rules = s.rules.get();
  const CookContext& ctx = s.ctx;
  if (Status st = load_overlays(overlay_options(s.options, s.decided.memory_limit_bytes), s.frame, palette_of(*s.rules),
                                ctx.origin_x - margin, ctx.origin_y - margin,
                                ctx.origin_x + s.world.roots_x * kRootSizeM + margin,
                                ctx.origin_y + s.world.roots_y * kRootSizeM + margin, s.threads, s.overlays);
      !st.ok())
    return st;
  s.ctx.overlays = s.overlays.get();
  return Status::success();
}

namespace {

// A block's window: the samples it needs, grown so that every void reaching into them is filled
// exactly as over the whole raster (void_plan.h), read from the inputs and filled.
Status read_window(CookSession& s, const SampleRect& need, PyramidTotals& totals) {
  // The window read last already holds these samples exactly.
  if (!s.window.values.empty() && s.window_need.contains(need)) return Status::success();
  const SampleRect rect = fill_read_rect(s.voids, need);
  if (!s.read_bounds.empty() && !s.read_bounds.contains(rect))
    return Status::failure(Error::internal,
                           fmt::format("a window read (samples {}..{} x {}..{}) outside the unit's planned window "
                                       "({}..{} x {}..{})",
                                       rect.c0, rect.c1, rect.r0, rect.r1, s.read_bounds.c0, s.read_bounds.c1,
                                       s.read_bounds.r0, s.read_bounds.r1));
  s.window_need = SampleRect{};
  SampleWindow& w = s.window;
  // Room for the largest window of the grid, reserved once: growing block by block reallocated
  // and copied the window (and faulted in each new buffer), ~0.3 s of CPU on 9 blocks of 8 km of
  // 1 m lidar. Reserving touches no page; only the samples read are faulted in.
  if (w.values.capacity() < size_t(rect.samples())) {
    uint64_t most = uint64_t(rect.samples());
    for (uint32_t i = 0; i < s.grid.count(); ++i) {
      const SampleRect r = block_cook_rect(s.ctx, s.grid.block(i));
      if (!r.empty()) most = std::max(most, uint64_t(fill_read_rect(s.voids, r).samples()));
    }
    w.values = LargeVector<float>();
    w.filled = LargeVector<uint8_t>();
    w.family = LargeVector<uint8_t>();
    w.values.reserve(size_t(most));
    w.filled.reserve(size_t(most));
    if (s.source.families().size() > 1) w.family.reserve(size_t(most));
  }
  w.rect = rect;
  w.source_width = s.ctx.source_width;
  w.source_height = s.ctx.source_height;
  w.values.resize(size_t(rect.samples()));
  w.filled.resize(size_t(rect.samples()));
  const bool families = s.source.families().size() > 1;
  w.family.resize(families ? size_t(rect.samples()) : 0);
  if (Status st = s.source.read(rect.c0, rect.r0, rect.width(), rect.height(), w.values.data(),
                                families ? w.family.data() : nullptr);
      !st.ok())
    return st;
  double residual = 0;
  if (Status st = fill_voids_window(s.voids, rect, w.values.data(), w.filled.data(), residual, s.decided.memory_limit_bytes);
      !st.ok())
    return st;
  totals.void_fill_residual_m = std::max(totals.void_fill_residual_m, residual);
  totals.window_samples_max = std::max(totals.window_samples_max, uint64_t(rect.samples()));
  s.window_need = need;
  return Status::success();
}

}  // namespace

void choose_session_steps(CookSession& s) {
  std::array<double, kLevelCount>& worst = s.decided.range_bound_m;
  worst = {};
  level_range_bounds(s.ctx, s.ranges, s.grid.roots_x, s.grid.roots_y, s.threads, worst);
  const int floor_step =
      s.options.height_step_m > 0 ? step_at_most(s.options.height_step_m) : tolerance_step(s.ctx.tolerance_m);
  choose_steps(worst, floor_step, s.ctx.finest_level, s.ctx.step_log2);
  // Overview levels (SPEC 19): one step for all of them, from the bound over their nodes, at least
  // the roots'. Where it is coarser, the roots' even vertices are rounded to it as they are cooked
  // (compute_window), so no node is re-rounded afterwards; every level's range then widens by up to
  // half of it, and the steps are chosen again with that rounding.
  const int k = overview_levels_for(s.options.overview_levels, s.grid.roots_x, s.grid.roots_y);
  s.world.overview_step_log2.clear();
  s.ctx.overview_step_log2 = -1;
  if (k > 0) {
    const double bound = overview_range_bound(s.ctx, s.ranges, s.grid.roots_x, s.grid.roots_y, k);
    int step = std::max(required_step(bound, -1), int(s.ctx.step_log2[kRootLevel]));
    if (step > s.ctx.step_log2[kRootLevel]) {
      choose_steps(worst, floor_step, s.ctx.finest_level, s.ctx.step_log2, step);
      step = std::max(step, int(s.ctx.step_log2[kRootLevel]));
      s.ctx.overview_step_log2 = step;
    }
    s.world.overview_step_log2.assign(size_t(k), uint8_t(step));
    s.decided.overview_range_bound_m = bound;
  }
  s.ranges = RangeSummary{};
}

void restore_overview_steps(const std::vector<uint8_t>& steps, CookSession& s) {
  s.world.overview_step_log2 = steps;
  s.ctx.overview_step_log2 = !steps.empty() && steps[0] > s.ctx.step_log2[kRootLevel] ? int(steps[0]) : -1;
}

OverviewSettings overview_settings(const CookSession& s) {
  OverviewSettings o;
  o.world = s.world;
  o.world.step_log2 = s.ctx.step_log2;
  o.rules = s.rules.get();
  o.bc_quality = BcQuality(uint8_t(s.options.surface_quality));
  o.bc_rdo = s.options.bc_rdo;
  o.check_all_errors = s.ctx.check_all_errors;  // surface_setup()
  o.payload.zstd_level = s.options.zstd_level;
  o.payload.surface_zstd_level = s.options.surface_zstd_level;
  o.heights_only = s.options.heights_only;
  o.threads = s.threads;
  return o;
}

int overview_levels_for(OverviewMode mode, uint32_t roots_x, uint32_t roots_y) {
  if (mode == OverviewMode::off) return 0;
  if (mode == OverviewMode::automatic && uint64_t(roots_x) * roots_y <= kOverviewAutoRoots) return 0;
  return std::max(1, overview_levels_needed(roots_x, roots_y));
}

namespace {

// Reads and fills the window of the roots `b` and cooks their nodes into `sink`.
Status cook_roots(CookSession& s, const RootBlock& b, const NodeSink& sink, PyramidTotals& totals) {
  const SampleRect rect = block_cook_rect(s.ctx, b);
  if (rect.empty()) return Status::success();
  if (Status st = read_window(s, rect, totals); !st.ok()) return st;
  s.ctx.set_window(s.window);
  if (s.overlays) {
    double bx0 = 0, by0 = 0, bx1 = 0, by1 = 0;
    block_frame_rect(s.ctx, b, bx0, by0, bx1, by1);
    TERRAIN_TRY(prepare_overlays_block(*s.overlays, bx0, by0, bx1, by1));
  }
  return cook_block(s.ctx, b, s.threads, sink, totals);
}

}  // namespace

Status cook_block_of_session(CookSession& s, uint32_t index, const NodeSink& sink, PyramidTotals& totals) {
  return cook_roots(s, s.grid.block(index), sink, totals);
}

Status cook_unit_of_session(CookSession& s, uint32_t index, const NodeSink& sink, PyramidTotals& totals) {
  const RootBlock u = s.units.block(index);
  const uint32_t side = std::max(1u, s.grid.side);
  for (uint32_t y = u.y0; y < u.y1; y += side)
    for (uint32_t x = u.x0; x < u.x1; x += side)
      if (Status st = cook_roots(s, RootBlock{x, y, std::min(u.x1, x + side), std::min(u.y1, y + side)}, sink, totals);
          !st.ok())
        return st;
  return Status::success();
}

void finish_levels(CookSession& s, const PyramidTotals& totals) {
  // Levels finer than the finest level cooked hold no node; they record its step (as the steps of
  // a level-by-level cook did).
  int f = 0;
  while (f < kRootLevel && totals.levels[size_t(f)].nodes == 0) ++f;
  for (int l = f - 1; l >= 0; --l) s.ctx.step_log2[size_t(l)] = s.ctx.step_log2[size_t(f)];
}

Status finish_archive(CookSession& s, const PyramidTotals& totals, const CookReport& decided, ArchiveWriter& writer) {
  uint64_t nodes = 0;
  for (const LevelStats& ls : totals.levels) nodes += ls.nodes;
  if (nodes == 0) {
    writer.abort();
    return Status::failure(Error::no_data, "no node holds terrain (is the data smaller than a vertex?)");
  }
  s.world.step_log2 = s.ctx.step_log2;
  if (s.rules) s.world.palette = palette_of(*s.rules);
  s.world.cook_info_json = cook_info(s.options, decided, s.descriptions);
  s.world.derived_normals = derives_normals(s.options);
  if (Status st = writer.finish(s.world); !st.ok()) return st;
  s.stats.archive_bytes = writer.bytes_written();
  // From the payload tables the writer parsed (reading the archive back would keep its directory
  // in memory: the merge must not grow with the archive).
  s.stats.sections = writer.section_bytes();
  s.stats.peak_rss_bytes = peak_rss_bytes();
  return Status::success();
}

void report_decisions(const CookSession& s, CookReport& report) {
  report.threads = s.threads;
  report.memory_limit_bytes = s.decided.memory_limit_bytes;
  report.tolerance_m = s.ctx.tolerance_m;
  report.tolerance_from_source = !(s.options.tolerance_m > 0);
  // The inputs (open_inputs).
  const Raster& header = s.source.header();
  report.source_samples = uint64_t(header.width) * uint64_t(header.height);
  report.input_descriptions.clear();
  report.input_height_units.clear();
  for (const MosaicSource::InputStat& in : s.source.inputs()) {
    report.input_height_units.push_back(in.height_unit);
    report.input_descriptions.push_back(fmt::format("{}: {}; {}{}{}", in.path, in.description, describe_crs(in.crs),
                                                    in.decoder.empty() ? "" : "; ", in.decoder));
  }
  // The first pass.
  report.implausible_samples = s.stats.implausible_samples;
  report.input_samples = s.stats.input_samples;
  report.warnings = s.stats.warnings;
  report.source_valid_samples = s.voids.valid_samples;
  report.voids_filled_samples = s.voids.stats.filled_samples;
  report.voids_filled_regions = s.voids.stats.filled_regions;
  report.hole_samples = s.voids.stats.hole_samples;
  report.hole_regions = s.voids.stats.hole_regions;
  // Frame and grid.
  report.frame = s.frame;
  report.frame_reason = s.decided.frame_reason;
  grid_of(report) = grid_of(s.world);
  report.source_spacing_m = s.decided.source_spacing_m;
  report.source_sample_area_m2 = s.decided.source_sample_area_m2;
  report.finest_level = s.ctx.finest_level;
  report.block_roots = s.grid.side;
  report.blocks = s.grid.count();
  report.surface_layers = !s.options.heights_only;
  // The steps' bounds and the overview levels.
  for (int l = 0; l < kLevelCount; ++l) report.levels[size_t(l)].range_bound_m = s.decided.range_bound_m[size_t(l)];
  report.overview_levels = int(s.world.overview_step_log2.size());
  report.overview_step_log2 = s.world.overview_step_log2.empty() ? 0 : s.world.overview_step_log2[0];
  report.overview_range_bound_m = s.decided.overview_range_bound_m;
}

void report_blocks(const CookSession& s, const PyramidTotals& totals, CookReport& report) {
  report.nodes = 0;
  for (int l = 0; l < kLevelCount; ++l) {
    LevelStats& ls = report.levels[size_t(l)];
    const LevelStats& counted = totals.levels[size_t(l)];
    const ErrorStats& le = totals.level_error[size_t(l)];
    ls.nodes = counted.nodes;
    ls.vertices = counted.vertices;
    ls.cpu_heights = counted.cpu_heights;
    ls.cpu_error = counted.cpu_error;
    ls.cpu_surface = counted.cpu_surface;
    ls.cpu_encode = counted.cpu_encode;
    ls.cpu_parts = counted.cpu_parts;
    report.nodes += ls.nodes;
    ls.error_samples = le.samples;
    ls.error_max_m = le.max_m;
    ls.error_rms_m = le.rms_m();
    ls.uncovered_samples = le.uncovered;
    ls.step_log2 = s.ctx.step_log2[size_t(l)];
  }
  report.output_vertices = report.nodes * uint64_t(kHeightCount);
  report.leaf_error_samples = totals.leaf.samples;
  report.leaf_error_max_m = totals.leaf.max_m;
  report.leaf_error_rms_m = totals.leaf.rms_m();
  report.leaf_uncovered_samples = totals.leaf.uncovered;
  report.cpu_heights = totals.cpu_heights;
  report.cpu_error = totals.cpu_error;
  report.cpu_surface = totals.cpu_surface;
  report.cpu_encode = totals.cpu_encode;
  report.surface = totals.surface;
  report.void_fill_residual_m = totals.void_fill_residual_m;
  report.block_window_samples_max = totals.window_samples_max;
  report.height_samples_per_cpu_second =
      report.cpu_heights > 0 ? double(report.output_vertices) / report.cpu_heights : 0;
  // Per input: the area it owns, its family's tolerance and the finest level it reached (one
  // family: the finest level of any node).
  int finest_any = -1;
  for (int l = 0; l < kLevelCount; ++l)
    if (totals.levels[size_t(l)].nodes) {
      finest_any = l;
      break;
    }
  for (InputSamples& in : report.input_samples) {
    in.area_km2 = double(in.used) * report.source_sample_area_m2 * 1e-6;
    in.tolerance_m = family_refine_rules(s.options, report.source_spacing_m, in.spacing_m, in.family).tolerance_m;
    in.finest_level = in.family < totals.family_finest_level.size() ? totals.family_finest_level[in.family]
                      : totals.family_finest_level.empty()          ? finest_any
                                                                    : -1;
    if (in.finest_level >= kLevelCount) in.finest_level = -1;
  }
}

void report_archive(const CookSession& s, CookReport& report) {
  report.archive_bytes = s.stats.archive_bytes;
  const SectionBytes& sb = s.stats.sections;
  for (int k = 0; k < 5; ++k) {
    report.section_stored_bytes[size_t(k)] = sb.stored[k];
    report.section_raw_bytes[size_t(k)] = sb.raw[k];
    for (int l = 0; l < kMaxLevels; ++l) report.level_section_stored_bytes[size_t(l)][size_t(k)] = sb.stored_by_level[l][k];
  }
  for (int l = 0; l < kMaxLevels; ++l) report.level_nodes[size_t(l)] = sb.nodes_by_level[l];
  report.peak_rss_bytes = s.stats.peak_rss_bytes;
  // Several grid families: a coarser family's leaves are held to its own, wider tolerance.
  double allowed = report.tolerance_m;
  for (const InputSamples& in : report.input_samples)
    if (in.used > 0) allowed = std::max(allowed, in.tolerance_m);
  if (s.stats.archive_bytes > 0 && report.leaf_error_max_m > allowed)
    report.warnings.push_back(unmet_tolerance_warning(report));
}

void fill_report(const CookSession& s, const PyramidTotals& totals, CookReport& report) {
  report_decisions(s, report);
  report_blocks(s, totals, report);
  report_archive(s, report);
  report.input_bytes_read.clear();
  for (const MosaicSource::InputStat& in : s.source.inputs()) report.input_bytes_read.push_back(in.bytes_read);
}

}  // namespace terrain::cook
