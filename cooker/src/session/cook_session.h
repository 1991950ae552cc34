// The state of a cook while it runs, and its stages, shared by the one-process cook, `plan`,
// `unit` and `merge`: each of them runs the same stages, so a plan + units + merge
// gives the bytes of the one-process cook.
//
//   open_inputs -> first_pass (voids, valid bounds, implausible heights, range summary) ->
//   frame_and_grid -> surface_setup -> choose_session_steps -> per block: cook_block_of_session ->
//   finish_levels -> finish_archive
//
// Each stage returns what it decides into the session (its members, `decided` and `stats`) or into
// the pyramid's totals; none writes the report. fill_report fills it once, at the end, from them.
//
// The source is read twice: by the first pass, and by the blocks' windows. A unit restores what
// the plan decided (open_session_from_plan in units/plan_file.h) instead of running the first pass.
#pragma once
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "frame/frame.h"
#include "base/memory_budget.h"
#include "mosaic/mosaic_source.h"
#include "pyramid/node_cook.h"
#include "pyramid/overview_levels.h"
#include "pyramid/pyramid.h"
#include "voids/range_summary.h"
#include "base/sample_window.h"
#include "overlays/overlays.h"
#include "surface/surface_layers.h"
#include "terrain/archive_reader.h"
#include "terrain/archive_writer.h"
#include "terrain/cook.h"
#include "voids/void_plan.h"

namespace terrain::cook {

// Tile side (samples) of the void plan's first pass; a block's window grows by up to one tile per
// side to whole tiles (void_plan.h).
inline constexpr int kVoidPlanTile = 64;

// What the global stages decide besides the frame, the grids and the steps (the session's members):
// read by the stages after them and by the report (fill_report).
struct SessionDecisions {
  uint64_t memory_limit_bytes = 0;  // open_inputs: the budget in force (memory_limit_of)
  std::string frame_reason;         // frame_and_grid: why this frame (empty for a planned frame)
  double source_spacing_m = 0;      // frame_and_grid: the finest source sample spacing, frame metres
  double source_sample_area_m2 = 0; // frame_and_grid: the mosaic's sample area in the frame at its centre
  std::array<double, kLevelCount> range_bound_m{};  // choose_session_steps: each level's worst range bound
  double overview_range_bound_m = 0;                // choose_session_steps: the overview levels' (0: none)
};

// What the stages count besides the pyramid's totals (PyramidTotals), for the report.
struct SessionStats {
  uint64_t implausible_samples = 0;         // first_pass: heights made nodata (CookReport's)
  std::vector<InputSamples> input_samples;  // first_pass: per input
  std::vector<std::string> warnings;        // first_pass
  // finish_archive: the archive's bytes, its sections' bytes and the process's peak RSS then.
  uint64_t archive_bytes = 0;
  SectionBytes sections;
  uint64_t peak_rss_bytes = 0;
};

struct CookSession {
  CookOptions options;
  int threads = 1;
  SessionDecisions decided;
  SessionStats stats;
  MemoryShares shares;
  MosaicSource source;
  VoidPlan voids;
  std::vector<std::pair<std::string, std::string>> descriptions;  // (path, description) per input
  FrameCrs frame;
  SourceMapping mapping;
  CookContext ctx;
  WorldInfo world;  // frame, grid and footprint (steps, palette and cook info at the end)
  std::shared_ptr<const MaterialRules> rules;
  std::unique_ptr<SurfaceOverlays> overlays;
  BlockGrid grid;   // memory blocks: the window of one fits the budget (the one-process cook's order)
  BlockGrid units;  // work units (plan.json): each cooked as memory blocks of at most grid.side roots
  SampleWindow window;  // the block being read or cooked
  RangeSummary ranges;   // the first pass's, for the steps (freed once they are chosen)
  SampleRect window_need;  // the samples `window` holds exactly (filled as over the whole raster)
  // When not empty, every window read must lie inside it: a unit reading a VRT cut to its planned
  // window (units/plan_file.h), where samples outside would silently differ from the whole VRT's.
  SampleRect read_bounds{0, 0, -1, -1};
  // Whether this process reads the source again after the first pass (the blocks of a one-process
  // cook): GDAL's cache then holds the whole decoded source where it fits. `plan` reads it once.
  bool reads_source_again = true;
};

// What the inputs (inputs.h, mosaic_source.h) and the overlays (overlays.h) take of the options:
// the one place their small structs are built from CookOptions. `memory_limit_bytes`: the limit
// in force (memory_limit_of).
InputOptions input_options(const CookOptions& o);
OverlayOptions overlay_options(const CookOptions& o, uint64_t memory_limit_bytes);

// Sizes the cache of the blocks the cooker decodes itself (tiff_blocks.h) for this session's
// source, at most `most` bytes (open_inputs calls it; a unit again with its own GDAL share).
void set_tiff_block_cache(const CookSession& s, uint64_t most);
// Checks the options, decides the memory limit (s.decided) and its shares, opens every input (GDAL
// inputs stay open, read by windows), sets GDAL's cache.
// files_checked: the inputs' files were stat'ed against a plan (ReadOptions::files_checked).
Status open_inputs(const CookOptions& options, CookSession& s, bool files_checked = false);
// Reads every sample once: the void plan, the valid samples, the implausible heights (s.stats),
// the range summary (range_summary.h) and what each input gave (s.stats).
Status first_pass(CookSession& s, const ProgressFn& progress);
// Refuses a root grid wider than kStreamerMaxRootsPerSide on a side (always: no archive holds more)
// or, unless `force`, of more than kMaxPlannedRoots roots; the spans (km) go into the message.
Status check_plan_size(double roots_x, double roots_y, bool force, double span_x_km, double span_y_km);
// The frame (choose_frame, or `planned` when given), the mapping, the root grid and the footprint,
// the context's constants, the block grid (block_roots, else from the budget) and the unit grid
// (unit_roots, else default_unit_roots); the frame's reason and the source spacing to s.decided.
Status frame_and_grid(CookSession& s, const FrameCrs* planned);
// Material rules and the overlays (opened; read per block).
Status surface_setup(CookSession& s);
// Every level's step from the range bounds of every node that could exist (s.ctx.step_log2), from
// the first pass's summary: reads nothing. Also the overview levels (s.world.overview_step_log2,
// s.ctx.overview_step_log2). The levels' worst bounds go to s.decided.
void choose_session_steps(CookSession& s);
// Reads and fills block `index`'s window and cooks its nodes into `sink` (key order in the block);
// its counts go to `totals`.
Status cook_block_of_session(CookSession& s, uint32_t index, const NodeSink& sink, PyramidTotals& totals);
// Cooks unit `index` of s.units as memory blocks of at most s.grid.side roots, row by row from the
// unit's corner (block bounds never change a byte: only the windows' sizes).
Status cook_unit_of_session(CookSession& s, uint32_t index, const NodeSink& sink, PyramidTotals& totals);
// A unit's side in roots when --unit-roots is not given: the most memory blocks (`block_side`
// roots each) whose samples and possible nodes stay within kUnitSamples and kUnitNodes, so that a
// unit's fixed costs (process start, opening the inputs, fresh memory) are a few per cent of it.
// 1 m lidar: 6 x 6 roots (9 blocks, 151 M samples, at most 49 140 nodes; cooker/README.md times it).
inline constexpr double kUnitSamples = double(uint64_t(1) << 28);
inline constexpr double kUnitNodes = double(1 << 16);
uint32_t default_unit_roots(uint32_t block_side, double spacing_x_m, double spacing_y_m, int finest_level,
                            uint32_t roots_x, uint32_t roots_y);
// Restores the overview steps a plan decided (world and context).
void restore_overview_steps(const std::vector<uint8_t>& steps, CookSession& s);
// The settings of write_overview_levels (overview_levels.h) for this session.
struct OverviewSettings;
OverviewSettings overview_settings(const CookSession& s);
// Overview levels a cook writes (SPEC 19): 0 (off; auto at most kOverviewAutoRoots root cells), else
// overview_levels_needed(roots), at least 1.
int overview_levels_for(OverviewMode mode, uint32_t roots_x, uint32_t roots_y);
// After every block: levels finer than the finest cooked get its step.
void finish_levels(CookSession& s, const PyramidTotals& totals);
// Writes the metadata (steps, palette, cook info) and renames the archive into place; its bytes
// into s.stats. Fails when no node holds terrain. `decided`: the global decisions as the report
// states them (report_decisions, or a plan's), which the cook info records.
Status finish_archive(CookSession& s, const PyramidTotals& totals, const CookReport& decided, ArchiveWriter& writer);

// The report, from what the stages returned (the session and the pyramid's totals); the timings
// and the overview levels' counts are the caller's. fill_report is the three parts and the inputs'
// bytes read: the one-process cook's whole report, filled once at the end.
// report_decisions: inputs, first pass, frame, grid, finest level, steps' bounds, memory limit, threads.
void report_decisions(const CookSession& s, CookReport& report);
// The refinement rules of grid family `family` (MosaicSource::families) of ground spacing
// family_spacing_m in a mosaic of spacing mosaic_spacing_m (family 0's: the mosaic's own): the
// default tolerance and finest level of its spacing (at least the mosaic's), or the options'.
RefineRules family_refine_rules(const CookOptions& options, double mosaic_spacing_m, double family_spacing_m,
                                size_t family);
// report_blocks: per level counts, errors and steps, nodes, CPU seconds, surface and window statistics.
void report_blocks(const CookSession& s, const PyramidTotals& totals, CookReport& report);
// report_archive (after finish_archive and the other two): bytes, peak RSS, the unmet tolerance warning.
void report_archive(const CookSession& s, CookReport& report);
void fill_report(const CookSession& s, const PyramidTotals& totals, CookReport& report);

// The cook's provenance JSON stored in the archive (options, inputs, frame reason, voids).
std::string cook_info(const CookOptions& o, const CookReport& r,
                      const std::vector<std::pair<std::string, std::string>>& descriptions);

}  // namespace terrain::cook
