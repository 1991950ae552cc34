// terrain-cook as a library: real DEMs (GeoTIFF, SRTM HGT, PNG16/EXR/raw heightmaps, .npz) to an
// archive's sparse, crack-free height pyramid (plus the surface layers of cooker/src/surface).
// The tool `terrain-cook` is a thin shell over cook(). Light header: no third-party includes.
#pragma once
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "terrain/cook_stats.h"
#include "terrain/format.h"
#include "terrain/height_unit.h"
#include "terrain/nodata_policy.h"
#include "terrain/output_paths.h"
#include "terrain/progress.h"
#include "terrain/status.h"

namespace terrain::cook {

enum class SurfaceQuality : uint8_t { fast, balanced, best };
// Which nodes the report's surface error statistics (normal degrees, albedo PSNR) decode and
// measure: one node in 8, chosen by its key (the same nodes at any thread count or unit split;
// every node when the root grid has at most 4 cells), or every node. Hole alpha is checked on
// every node either way.
enum class ErrorChecks : uint8_t { sample, all };
enum class OverviewMode : uint8_t { automatic, on, off };
// Normals of the nodes cooked from the source (SPEC 16.7): derived = the payload stores only the
// apron and AO and every reader rebuilds the texels from the heights (normals codec 4); stored =
// the cooker's BC3 blocks (with --bc-rdo). Overview nodes above the roots keep stored normals.
enum class NormalsMode : uint8_t { derived, stored };
// Which input wins where inputs overlap, and whose grid and CRS the mosaic is read on (mosaic.h):
// finer = the input with the finest ground sample spacing (precedence.h), list order breaking
// ties, so the archive does not depend on the order of the inputs; list = the first listed.
enum class OverlapRule : uint8_t { finer, list };

// The tolerance a cook uses when none is given: the larger of 0.5 m and 1/32 of the source's
// sample spacing (frame metres, the finer axis). 1 m lidar: 0.5 m; 30 m DEMs: 0.94 m; SRTM3 at
// 86-93 m: 2.7-2.9 m, within SRTM's own 5-10 m relative LE90 (cooker/README.md, "Levels").
double default_tolerance_m(double source_spacing_m);

struct CookOptions {
  std::vector<std::string> inputs;  // one or more DEMs; several are mosaicked (mosaic.h: others resampled onto the finest one's grid)
  std::string output;               // archive path (written atomically)
  OverlapRule overlap = OverlapRule::finer;  // --overlap

  // A node is refined while its geometric error exceeds this (metres); 0: from the source,
  // default_tolerance_m(source spacing).
  double tolerance_m = 0;
  int finest_level = -1;            // -1: from the source resolution; else 0..5
  // --height-step: the finest height step, the largest power of two of 1/1024 m at most this
  // (metres); 0: from the tolerance (tolerance / 32). Levels whose range needs more still coarsen.
  double height_step_m = 0;
  int threads = 0;                  // 0: all cores

  // Georeferencing for inputs that lack it, or overrides (see crs.h for the accepted forms).
  std::string crs;                  // "EPSG:4326", "EPSG:32633", "EPSG:3794", "tm:lon0=..,..", "local"
  std::string frame;                // overrides the automatic frame choice (same forms, TM or local)
  std::optional<std::array<double, 2>> origin;   // images/raw: frame coords of the SOUTH-WEST sample
  std::optional<std::array<double, 2>> spacing;  // images/raw: sample spacing x, y (CRS units)
  double height_scale = 1.0;        // metres = value * scale + offset (after nodata detection)
  double height_offset = 0.0;
  // height_scale was given (--height-scale): it replaces the factor of the unit an input declares
  // for its heights (HeightUnit), never multiplies it. A height_scale other than 1 counts as given.
  bool height_scale_set = false;
  std::optional<double> nodata_value;  // overrides the file's nodata value
  // Heights (metres, after scale/offset) outside this range cannot be elevations (Challenger Deep
  // is -10.9 km, Everest +8.8 km): they are undeclared voids (-3.4e38, 1e30) and become nodata,
  // counted in a warning. An undeclared -9999 far from every neighbour is treated alike.
  std::array<double, 2> valid_range_m{-12000.0, 9000.0};
  // Memory budget in bytes (0: default_memory_limit_bytes()). Every allocation sized by the input
  // is checked against it first. The block-wise cook splits it (memory_budget.h): GDAL's cache, the
  // inputs held whole, and one block's source window, whose size follows from it.
  uint64_t memory_limit_bytes = 0;
  // The block-wise cook: blocks of block_roots x block_roots root nodes (0: the largest
  // whose source window fits the budget). block_order 0 cooks blocks row by row; any other value
  // is the seed of a shuffled order (tests: neither changes a byte of the archive).
  uint32_t block_roots = 0;
  uint64_t block_order = 0;
  // Work units (cooker/src/units/plan_file.h): with work_dir set, cook() writes the plan and
  // one file per unit into it and merges them; run again after a kill it cooks only the units that
  // are missing or stale. unit_roots: units of N x N roots (0: default_unit_roots, whole blocks).
  std::string work_dir;
  uint32_t unit_roots = 0;

  // Raw heightmaps (.r16/.raw: uint16 little-endian by default, .r32/.f32: float32).
  std::array<int, 2> raw_size{0, 0};  // width, height (required for raw input)
  std::string raw_type;               // "u16", "i16", "f32" (empty: from the extension)
  bool raw_big_endian = false;
  std::string tile_encoding;          // z/x/y web tiles: "terrarium" or "mapbox" (empty: from the path)

  NodataPolicy nodata = NodataPolicy::automatic;
  int64_t fill_max_samples = 4096;  // automatic policy: largest enclosed void (in samples) to fill

  // Surface layers (cooker/src/surface).
  std::string materials_path;
  SurfaceQuality surface_quality = SurfaceQuality::balanced;
  ErrorChecks error_checks = ErrorChecks::sample;  // --error-checks
  NormalsMode normals = NormalsMode::derived;      // --normals
  // Rate-distortion pass over the normal and albedo blocks (--bc-rdo, cooker/src/surface/bc_rdo.h):
  // squared error accepted per byte of literals saved; 0 = off (the blocks of the encoder as they are).
  // The default, 28, keeps every shared DEM and the 1 m lidar-like square (down to level 0) within
  // +0.5 degrees mean normal error and -0.5 dB albedo PSNR (cooker/README.md).
  float bc_rdo = 28;
  // Orthophoto for the albedo: GeoTIFF RGB(A) (8 or 16 bits) in any supported CRS, resampled to
  // the frame (bilinear); where it has no data (alpha 0, GDAL_NODATA, outside) the splat bake stays.
  std::string albedo_path;
  // Hole mask: single-band GeoTIFF in any supported CRS; a vertex whose nearest mask sample is
  // nonzero is a hole (drops its triangles, transparent albedo). Outside the mask: no hole.
  std::string holes_path;
  // Class raster (e.g. land cover: single-band integer GeoTIFF, any supported CRS) and its table
  // (JSON: {"classes": {"10": "forest_floor", "30": 2, ...}}, values palette names or indices):
  // a splat sample whose nearest class is in the table takes that material instead of the rules.
  std::string landcover_path;
  std::string landcover_table_path;
  bool heights_only = false;        // skip the surface layers (benchmarks; sections stay zero)
  bool force = false;               // cook plans beyond kMaxPlannedRoots (never wider than kStreamerMaxRootsPerSide)
  // Overview levels above the roots (format/SPEC.md section 19, format version 2): automatic writes
  // them when the root grid has more than kOverviewAutoRoots cells, on always (at least one level),
  // off never. K = overview_levels_needed(roots_x, roots_y) (at least 1 with `on`).
  OverviewMode overview_levels = OverviewMode::automatic;

  // zstd levels: heights at 9 (a quick parse of the predictor residuals, and a lazy one as well
  // where they compress below a quarter, see format/src/payload.cpp; 10-18 parse optimally, a few
  // per cent fewer bytes for a multiple of the encode time); the surface sections at 6. What the
  // levels cost and save is in cooker/README.md ("Figures behind the code").
  int zstd_level = 9;
  int surface_zstd_level = 6;
};

// Work bound: every root of the plan is cooked (at least 129 x 129 vertices each, flat ones too),
// so a coarse raster spread over a huge area (64 x 64 samples at 100 km: 9.8 M
// roots) is refused with a named error unless CookOptions::force.
inline constexpr uint64_t kMaxPlannedRoots = 1000000;

// `--overview-levels auto` writes overview levels when the root grid (roots_x * roots_y, known
// before any node is cooked) has more cells than this: half the streamer's default budget of 512
// nodes. Keeping every root resident would then leave less than half of the budget for the
// refinement near the camera (and above 512 the world cannot be opened at all). Smaller worlds keep
// their version-1 bytes; every test world of the viewer stays below it (the benchmark DEMs on
// either side: cooker/README.md, "Figures behind the code").
inline constexpr uint64_t kOverviewAutoRoots = 256;

// What one input gave the cook, counted on the mosaic's grid (that of the input which takes
// precedence, CookOptions::overlap; an input in another CRS or at another spacing counts its samples
// resampled onto that grid): `read`, the grid samples where it has a height; `used`, those of them
// the mosaic keeps (where inputs overlap, the one that takes precedence wins) and the archive is
// cooked from. The used counts of all inputs add up to source_valid_samples. Listed in the order
// of precedence (the order of the command line under `--overlap list`).
struct InputSamples {
  std::string path;
  uint64_t read = 0, used = 0;
  // Its grid family (MosaicSource::families: inputs on one grid, 0 = the mosaic's own) and that
  // family's ground sample spacing (metres, the finer axis).
  uint32_t family = 0;
  double spacing_m = 0;
  // The report's: the area it owns (used samples times the mosaic's sample area at its centre), the
  // tolerance of its family (RefineRules) and the finest level of a node where its family takes
  // precedence (the first family with a sample in the node; -1: none).
  double area_km2 = 0;
  double tolerance_m = 0;
  int finest_level = -1;
};

struct CookReport {
  // Inputs
  std::vector<std::string> input_descriptions;
  // Per input (same order): decoded bytes asked of GDAL over the whole cook (0 for inputs our own
  // readers hold whole).
  std::vector<uint64_t> input_bytes_read;
  uint64_t source_samples = 0;       // samples read (mosaic)
  uint64_t source_valid_samples = 0;
  uint64_t voids_filled_samples = 0, voids_filled_regions = 0;
  uint64_t hole_samples = 0, hole_regions = 0;
  double void_fill_residual_m = 0;   // largest change of the last relaxation sweep of a filled void
  uint64_t implausible_samples = 0;  // outside valid_range_m or undeclared -9999 voids: made nodata
  double source_spacing_m = 0;       // finest source sample spacing, frame metres
  double source_sample_area_m2 = 0;  // the mosaic's sample area in the frame at its centre
  // Per input (same order as input_descriptions): the unit its heights declare and the factor applied.
  std::vector<HeightUnit> input_height_units;
  // Per input (same order as input_descriptions): its samples read and used (InputSamples). An
  // input that uses none, or under 1 % of what it read, also gets a warning.
  std::vector<InputSamples> input_samples;
  // Frame and grid
  FrameCrs frame;
  std::string frame_reason;          // why this frame was chosen
  double origin_x_m = 0, origin_y_m = 0;
  uint32_t roots_x = 0, roots_y = 0;
  double extent_min_x_m = 0, extent_min_y_m = 0, extent_max_x_m = 0, extent_max_y_m = 0;  // data footprint
  int finest_level = kRootLevel;     // finest level allowed
  double tolerance_m = 0;            // in force: CookOptions::tolerance_m, or the source's default
  bool tolerance_from_source = false;  // default_tolerance_m(source_spacing_m): no tolerance was given
  std::array<LevelStats, kLevelCount> levels{};
  // Height error where the renderer shows full detail (each source sample against the finest
  // node covering it).
  double leaf_error_max_m = 0, leaf_error_rms_m = 0;
  uint64_t leaf_error_samples = 0;
  uint64_t leaf_uncovered_samples = 0;  // valid source samples under a dropped (hole) triangle of a finest node
  // Output
  uint64_t nodes = 0;
  uint64_t archive_bytes = 0;
  std::array<uint64_t, 5> section_stored_bytes{};  // heights, normals, albedo, splat, cones
  std::array<uint64_t, 5> section_raw_bytes{};
  // Stored bytes per level (overview levels included) and section: the report's bytes per km2 and
  // per source sample by level.
  std::array<std::array<uint64_t, 5>, kMaxLevels> level_section_stored_bytes{};
  std::array<uint64_t, kMaxLevels> level_nodes{};
  bool surface_layers = false;       // false when heights_only or the surface library is absent
  // Time (wall seconds per stage; CPU seconds for the per-node work summed over threads)
  double seconds_read = 0, seconds_prepare = 0, seconds_pyramid = 0, seconds_finish = 0, seconds_total = 0;
  double cpu_heights = 0, cpu_error = 0, cpu_surface = 0, cpu_encode = 0;
  // Process CPU seconds (user + system, all threads) of the stages of a one-process cook: the
  // first pass over the source, the steps from its summary (no read), the blocks (read, fill, cook,
  // spool), and the whole.
  double cpu_first_pass = 0, cpu_steps = 0, cpu_blocks = 0, cpu_total = 0;
  int threads = 0;
  uint64_t output_vertices = 0;      // vertices computed for nodes (129x129 each)
  double source_samples_per_second = 0;       // source samples / total seconds
  double height_samples_per_cpu_second = 0;   // output vertices / cpu_heights
  uint64_t peak_rss_bytes = 0;
  uint64_t memory_limit_bytes = 0;   // the budget in force
  // Block-wise cook: blocks of block_roots x block_roots roots; the largest source window a block
  // read (samples); bytes of node payloads spooled (0 when one block took the whole cook).
  uint32_t block_roots = 0, blocks = 0;
  uint64_t block_window_samples_max = 0;
  uint64_t spool_bytes = 0;
  // Spool space given back to the file system while the payloads were copied into the archive
  // (whole 1 MiB chunks; 0 where the file system cannot punch holes).
  uint64_t spool_bytes_returned = 0;
  // What the cook could not do as asked or had to guess (e.g. implausible heights, an unmet
  // tolerance): printed on stderr by terrain-cook and listed in the JSON report.
  std::vector<std::string> warnings;
  // Surface layers (when present)
  SurfaceTotals surface;
  // Overview levels (SPEC 19): how many, their step, their nodes, the range bound of the step rule
  // and the process CPU seconds of building them from the cooked roots (0 when none).
  int overview_levels = 0;
  uint8_t overview_step_log2 = 0;
  double overview_range_bound_m = 0;
  uint64_t overview_nodes = 0;
  double cpu_overview = 0;
  double overview_error_max_m = 0;  // the largest geometric_error_m of an overview node
};

// Progress: fraction 0..1 and a short stage name; return false to cancel (cook returns `cancelled`).
using ProgressFn = terrain::ProgressFn;

// Cooks options.inputs into options.output. On failure the previous file at output is untouched.
// With options.work_dir: plan_cook + every unit not already valid + merge_units (a resume).
Status cook(const CookOptions& options, const ProgressFn& progress, CookReport& report);

// ---- Work units: the commands a scheduler calls ----
struct PlanSummary {
  std::string plan_path;
  uint32_t unit_count = 0;
  uint32_t units_valid = 0;          // unit files already in the work dir that this plan keeps
  std::vector<std::string> changes;  // why units must be cooked again (changed inputs, global decisions)
};
// `terrain-cook plan`: decides everything global (frame, grid, steps, voids, options, input
// fingerprints) and writes options.work_dir/plan.json listing the units; units of an earlier plan
// in the work dir whose inputs and decisions are unchanged stay valid, the others are removed.
Status plan_cook(const CookOptions& options, const ProgressFn& progress, PlanSummary& summary, CookReport& report);
// `terrain-cook unit`: cooks unit `index` of the plan in `work_dir` into its unit file (atomically).
// `skipped`: the unit file was already complete and valid (nothing redone). The unit is cooked as
// memory blocks of block_roots x block_roots roots (0: the largest the plan's memory limit allows);
// they change no byte of the unit.
Status cook_unit(const std::string& work_dir, uint32_t index, int threads, uint32_t block_roots, bool& skipped,
                 CookReport& report);
// True when `path` names a file that `plan`, `unit` or `merge` write or remove in `work_dir`:
// plan.json, an inputs-*.json list or anything in units/ (compared after resolving both, so
// another spelling of the same place counts).
bool work_dir_owns(const std::string& work_dir, const std::string& path);
// `terrain-cook merge`: checks every unit (present, complete, checksum, plan and input fingerprints,
// heights along the edges units share) and writes the archive atomically, payloads in canonical
// order. First, before anything is written, `outputs` (default: {"-o", output}; the caller adds
// the report it will write) are checked against the plan: none may name an input file of the plan
// (a VRT's tiles too), a file of the work dir, a device, a FIFO or a directory (invalid_argument).
Status merge_units(const std::string& work_dir, const std::string& output, const ProgressFn& progress,
                   CookReport& report, const std::vector<NamedPath>& outputs = {});

// --memory-limit: "256M", "2G", "1.5G", "512K" (K/M/G/T are powers of 1024; a trailing B or iB is
// accepted); false unless it is a finite size of at least 1 MB.
bool parse_byte_size(const std::string& text, uint64_t& out);
// The default budget: 2 GB, or half the memory this process may use (physical RAM, the cgroup's
// memory.max or ulimit -v, whichever is least) when that is less.
uint64_t default_memory_limit_bytes();

// The report as JSON (the --report file) and as the closing summary lines.
std::string report_json(const CookReport& report);
// True when `path` holds a report report_json wrote (a JSON object with its sections): what
// --report may replace without --force.
bool is_cook_report(const std::string& path);
std::string report_summary(const CookReport& report);

}  // namespace terrain::cook
