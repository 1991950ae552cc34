// terrain-cook: a thin shell over terrain::cook::cook(). Exit codes: 0 ok, 1 failure, 2 usage error.
// Built twice (cooker/CMakeLists.txt): the full cooker (terrain-cook-full) and, with
// TERRAIN_COOK_MERGE_ONLY, terrain-cook-merge (linked without GDAL and PROJ); terrain-cook's dispatcher
// (terrain_cook_dispatch.cpp) execs one or the other.
// Safety of the files it names (output_paths.h): outputs that are inputs, devices, FIFOs or
// directories are refused before any work; the archive and the report are staged beside their
// targets and committed together at the end; SIGINT/SIGTERM remove the staged files.
#include <filesystem>
#include <CLI/CLI.hpp>
#include <fcntl.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <climits>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <optional>

#include "cli_checks.h"
#include "terminal_progress.h"
#include "terrain/cook.h"
#include "terrain/output_paths.h"
#include "terrain/progress.h"
#include "session/cook_options_table.h"

namespace {

// "A,B" or a single "A" (then both) into two numbers.
bool parse_pair(const std::string& text, std::array<double, 2>& out, bool allow_single) {
  const size_t comma = text.find(',');
  if (comma == std::string::npos) {
    if (!allow_single || !terrain::cli::parse_number(text, out[0])) return false;
    out[1] = out[0];
    return true;
  }
  return terrain::cli::parse_number(text.substr(0, comma), out[0]) &&
         terrain::cli::parse_number(text.substr(comma + 1), out[1]);
}

// ---- staged files, removed on SIGINT/SIGTERM ----
// Fixed buffers and unlink() only: the handler must be async-signal-safe. A path is fully written
// before the count that publishes it.
constexpr int kMaxStaged = 4;
char g_staged[kMaxStaged][PATH_MAX];
std::atomic<int> g_staged_count{0};

void stage_for_cleanup(const std::string& path) {
  const int i = g_staged_count.load();
  if (i >= kMaxStaged || path.size() >= PATH_MAX) return;
  std::memcpy(g_staged[i], path.c_str(), path.size() + 1);
  g_staged_count.store(i + 1);
}

extern "C" void remove_staged_and_die(int sig) {
  const int n = g_staged_count.load();
  for (int i = 0; i < n; ++i) ::unlink(g_staged[i]);
  // SA_RESETHAND restored the default action: the re-raised signal ends the process once this
  // handler returns, with the usual "killed by signal" status.
  ::raise(sig);
}

void install_signal_cleanup() {
  struct sigaction sa {};
  sa.sa_handler = remove_staged_and_die;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESETHAND;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

// Writes `text` to `path` (created or truncated) and fsyncs it.
bool write_file_durably(const std::string& path, const std::string& text) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return false;
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    done += size_t(n);
  }
  const bool ok = done == text.size() && ::fsync(fd) == 0;
  return ::close(fd) == 0 && ok;
}

// Empty when --report may write `path`: nothing there, an empty file, a previous cook report, or
// `force`; else why not (another archive, a DEM, any other file would be lost).
std::string refuse_report(const std::string& path, bool force) {
  struct stat st {};
  if (force || ::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode) || st.st_size == 0) return {};
  if (terrain::cook::is_cook_report(path)) return {};
  return "--report " + path + ": exists and is not a cook report; refusing to replace it (give --force to replace it)";
}

int run_unit(int argc, char** argv);
int run_merge(int argc, char** argv);

int run(int argc, char** argv) {
  // Work-unit commands (issue 14): `unit` and `merge` have their own flags; `plan` takes the cook's.
  if (argc > 1 && std::strcmp(argv[1], "merge") == 0) return run_merge(argc - 1, argv + 1);
#ifdef TERRAIN_COOK_MERGE_ONLY
  std::fprintf(stderr, "terrain-cook-merge: serves `terrain-cook merge` only; run terrain-cook\n");
  return 2;
#endif
  if (argc > 1 && std::strcmp(argv[1], "unit") == 0) return run_unit(argc - 1, argv + 1);
  const bool planning = argc > 1 && std::strcmp(argv[1], "plan") == 0;
  if (planning) {
    --argc;
    ++argv;
  }
  using terrain::cook::CookOptions;
  namespace cli = terrain::cli;
  CookOptions o;
  using terrain::cook::enum_name;
  std::string origin, spacing, raw_size, valid_range, memory_limit, report_path;
  std::string nodata = enum_name(o.nodata), quality = enum_name(o.surface_quality), error_checks = enum_name(o.error_checks);
  std::string normals = enum_name(o.normals), overlap = enum_name(o.overlap);
  std::optional<double> nodata_value;
  bool quiet = false, json = false;

  CLI::App app{"terrain-cook: real DEMs (GeoTIFF, SRTM HGT, PNG16/EXR/raw heightmaps, .npz) to a sparse, crack-free "
               "terrain archive"};
  app.footer(std::string(cli::kExitCodes) +
             "\nOutputs (-o, --report) must not name an input, each other, a device, a FIFO or a directory; both are "
             "written beside their targets and replace them together at the end (or not at all).");
  app.add_option("inputs", o.inputs, "Input DEM(s); several are mosaicked on one grid (any CRS and spacing: the others are resampled onto the grid of the one that wins overlaps, see --overlap)")
      ->required();
  auto* output_opt = app.add_option("-o,--output", o.output, "Archive to write (atomically)");
  if (!planning) output_opt->required();
  auto* work_dir_opt = app.add_option(
      "--work-dir", o.work_dir,
      planning ? "Work dir of the plan and its units (shared by every machine that runs a unit)"
               : "Keep the plan and one file per work unit here: run the same command again after a kill and it "
                 "cooks only the units that are missing (see `terrain-cook plan`, `unit`, `merge`)");
  if (planning) work_dir_opt->required();
  app.add_option("--unit-roots", o.unit_roots,
                 "Work units of N x N root nodes (2 km each; default: whole memory blocks up to 2^28 source samples "
                 "and 2^16 possible nodes per unit, so that a unit's fixed costs stay a few per cent)")
      ->check(cli::int_range(1, 1 << 16));
  app.add_option("--tolerance", o.tolerance_m,
                 "Refine nodes while their geometric error exceeds this (metres); default: 1/32 of the source's sample "
                 "spacing, at least 0.5 m (1 m lidar 0.5, 30 m DEMs 0.94, SRTM3 about 2.7)")
      ->check(cli::number_check("> 0 and <= 10000", [](double v) { return v > 0 && v <= 1e4; }));
  app.add_option("--finest-level", o.finest_level,
                 "Finest level to cook, 0 (0.5 m) .. 5 (16 m); default: the finest level with spacing >= 1/32 of the source spacing (refinement stops earlier where the tolerance is met)")
      ->check(cli::int_range(0, 5));
  app.add_option("--height-step", o.height_step_m,
                 "Finest height step in metres, rounded down to a power of two of 1/1024 m (default: from the "
                 "tolerance, tolerance / 32: 15.6 mm at 0.5 m); levels whose height range needs more take more")
      ->check(cli::number_check("> 0 and <= 16", [](double v) { return v > 0 && v <= 16; }));
  app.add_option("--threads", o.threads, "Worker threads (default 0: all cores)")->check(cli::int_range(0, 1024));
  app.add_option("--crs", o.crs,
                 "CRS of inputs that lack one (or override): EPSG:<code> (geographic or projected), a PROJ string or WKT, "
                 "tm:lon0=..,lat0=..,k0=..,x0=..,y0=..,ellps=WGS84|GRS80, or local");
  app.add_option("--frame", o.frame, "Archive frame instead of the automatic choice (same forms: any projected CRS PROJ knows, or local)");
  app.add_option("--origin", origin,
                 "Images/raw: frame coordinates X,Y of the south-west sample (default 0,0; each within +-1e8 CRS units)");
  app.add_option("--spacing", spacing, "Images/raw: sample spacing D or DX,DY in CRS units (> 0, <= 1e7)");
  CLI::Option* height_scale =
      app.add_option("--height-scale", o.height_scale,
                     "metres = value * scale + offset (finite, non-zero); replaces the conversion of the unit an input "
                     "declares for its heights (vertical CRS or band unit type: feet, US survey feet, ...)")
      ->capture_default_str()
      ->check(cli::number_check("finite and non-zero", [](double v) { return std::isfinite(v) && v != 0; }));
  app.add_option("--height-offset", o.height_offset, "metres = value * scale + offset")
      ->capture_default_str()
      ->check(cli::in_range(-1e6, 1e6));
  app.add_option("--nodata", nodata, "auto: fill small enclosed voids, holes elsewhere; hole; fill")
      ->check(CLI::IsMember(terrain::cook::enum_spellings<terrain::cook::NodataPolicy>()))
      ->capture_default_str();
  // NaN samples are nodata anyway, so NaN is refused as a value; +-inf is allowed (voids stored as infinity).
  app.add_option("--nodata-value", nodata_value, "Nodata value (overrides the file's); any number or +-inf, not nan")
      ->check(cli::number_check("a number (NaN samples are always nodata)", [](double v) { return !std::isnan(v); }));
  app.add_option("--valid-range", valid_range,
                 "Plausible heights MIN,MAX in metres after scale/offset; others become nodata with a warning "
                 "(default -12000,9000)");
  app.add_option("--memory-limit", memory_limit,
                 "Memory budget, e.g. 256M, 2G: sets the block size (the source is read by windows, one block at a "
                 "time) and GDAL's cache; inputs held whole (npz, images, raw) and voids too large "
                 "to fill within it are refused before reading; default: 2G, or half the RAM, cgroup limit or "
                 "ulimit -v when less (" +
                     fmt::format("{:.1f}G here)", double(terrain::cook::default_memory_limit_bytes()) / (1 << 30)));
  app.add_option("--block-roots", o.block_roots,
                 "Cook blocks of N x N root nodes (2 km each), reading only each block's window of the source "
                 "(default 0: the largest block whose window fits a third of --memory-limit); the archive is the "
                 "same for every N")
      ->check(cli::int_range(0, 1 << 16));
  app.add_option("--block-order", o.block_order,
                 "Cook the blocks in an order shuffled by this seed (0: row by row); tests that the archive does "
                 "not change")
      ->group("");
  app.add_option("--fill-max", o.fill_max_samples, "auto: largest enclosed void to fill, in samples")
      ->capture_default_str()
      ->check(cli::int_range(0, 1000000000000LL));
  app.add_option("--raw-size", raw_size, "Raw heightmaps: WIDTHxHEIGHT");
  app.add_option("--raw-type", o.raw_type, "Raw heightmaps: u16 (default for .r16/.raw), i16, f32 (.r32/.f32)")
      ->check(CLI::IsMember({"u16", "i16", "f32"}));
  app.add_option("--tile-encoding", o.tile_encoding,
                 "RGB-encoded heights: terrarium (Mapzen / AWS Terrain Tiles) or mapbox (Mapbox / MapTiler "
                 "terrain-RGB). Web tiles under z/x/y paths (.png, .webp) whose path does not say; any other "
                 "PNG / WebP input is then decoded so too, placed by its own georeferencing or --spacing/--crs")
      ->check(CLI::IsMember({"terrarium", "mapbox"}));
  app.add_flag("--raw-big-endian", o.raw_big_endian, "Raw heightmaps are big-endian");
  app.add_option("--materials", o.materials_path, "Material rules JSON for the splat map (default: built-in)");
  app.add_option("--albedo", o.albedo_path,
                 "Orthophoto for the albedo: GeoTIFF RGB(A) in any supported CRS, resampled to the frame "
                 "(default: baked from the splat materials)");
  app.add_option("--holes", o.holes_path,
                 "Hole mask: GeoTIFF in any supported CRS; nonzero = hole (those vertices drop their triangles)");
  app.add_option("--landcover", o.landcover_path,
                 "Class raster (e.g. land cover GeoTIFF, integer classes, any supported CRS) for the splat map; "
                 "needs --landcover-table");
  app.add_option("--landcover-table", o.landcover_table_path,
                 "JSON class -> material table: {\"classes\": {\"10\": \"forest_floor\", \"80\": \"water\"}} "
                 "(palette names or indices; classes not listed keep the rules' choice)");
  app.add_option("--bc-quality", quality, "Block compression quality of normals and albedo")
      ->check(CLI::IsMember(terrain::cook::enum_spellings<terrain::cook::SurfaceQuality>()))
      ->capture_default_str();
  app.add_option("--bc-rdo", o.bc_rdo,
                 "Rate-distortion pass over the normal and albedo blocks: where it costs at most LAMBDA squared error "
                 "(8-bit units over a 4x4 block) per byte saved, a block (half) reuses bytes of a nearby earlier block so "
                 "zstd stores a match; a node's albedo loses at most 0.41 dB (0 = off; the default 28 on Kilauea: 0.51x normal "
                 "+ albedo bytes at +0.29 degrees mean normal error and -0.17 dB albedo PSNR, 0.4 ms more CPU per node)")
      ->check(CLI::Range(0.0, 1000.0))
      ->capture_default_str();
  app.add_option("--error-checks", error_checks,
                 "Nodes whose normal and albedo errors the report measures (decoding their blocks): sample = one node in "
                 "8, chosen by its key (every node when the grid has at most 4 roots); all = every node (0.2 ms more CPU per node). "
                 "Hole alpha is checked on every node")
      ->check(CLI::IsMember(terrain::cook::enum_spellings<terrain::cook::ErrorChecks>()))
      ->capture_default_str();
  app.add_option("--normals", normals,
                 "Normals of the nodes cooked from the source: derived = stored as the 2-texel apron and block AO only, "
                 "every reader rebuilds the texels from the heights (format v2, SPEC 16.7; the Slovenian 1 m tile: 0.53x the archive bytes); "
                 "stored = the cooker's BC3 blocks, shaped by --bc-rdo")
      ->check(CLI::IsMember(terrain::cook::enum_spellings<terrain::cook::NormalsMode>()))
      ->capture_default_str();
  app.add_option("--overlap", overlap,
                 "Which input wins where inputs overlap: finer = the finest ground sample spacing (its grid and CRS are "
                 "the mosaic's; list order breaks ties), so the archive does not depend on the order of the inputs; "
                 "list = the first listed (its grid and CRS are the mosaic's)")
      ->check(CLI::IsMember(terrain::cook::enum_spellings<terrain::cook::OverlapRule>()))
      ->capture_default_str();
  std::string overview = enum_name(o.overview_levels);
  app.add_option("--overview-levels", overview,
                 fmt::format("Overview levels above the 2048 m roots (format v2, SPEC section 19) so a streamer can "
                             "open worlds of more roots than its budget: auto = when the root grid has more than {} "
                             "cells (half the streamer's default 512-node budget), on, off",
                             terrain::cook::kOverviewAutoRoots))
      ->check(CLI::IsMember(terrain::cook::enum_spellings<terrain::cook::OverviewMode>()))
      ->capture_default_str();
  app.add_flag("--heights-only", o.heights_only, "Skip normals, albedo, splat and cones (they stay zero)");
  app.add_flag("--force", o.force,
               fmt::format("Cook even when the plan needs more than {} root nodes (never more than {} roots per "
                           "side, the format's limit); let --report replace a file that is not a cook report",
                           terrain::cook::kMaxPlannedRoots, terrain::kStreamerMaxRootsPerSide));
  app.add_option("--report", report_path, "Write the cook report (JSON) to this file");
  app.add_flag("--json", json, "Print the report as JSON on stdout instead of the summary");
  app.add_flag("-q,--quiet", quiet, "No progress bar and no summary");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }

  auto usage = [&](const std::string& msg) {
    std::fprintf(stderr, "terrain-cook: %s\n", msg.c_str());
    return 2;
  };
  o.height_scale_set = height_scale->count() > 0;
  if (!origin.empty()) {
    std::array<double, 2> v{};
    if (!parse_pair(origin, v, false)) return usage("--origin expects X,Y (two numbers), got '" + origin + "'");
    for (double c : v)
      if (!(std::fabs(c) <= 1e8)) return usage("--origin: each coordinate must be finite and within +-1e8, got '" + origin + "'");
    o.origin = v;
  }
  if (!spacing.empty()) {
    std::array<double, 2> v{};
    if (!parse_pair(spacing, v, true)) return usage("--spacing expects D or DX,DY (numbers), got '" + spacing + "'");
    for (double c : v)
      if (!(c > 0 && c <= 1e7)) return usage("--spacing: must be > 0 and <= 1e7, got '" + spacing + "'");
    o.spacing = v;
  }
  if (!raw_size.empty()) {
    int w = 0, h = 0;
    char tail = 0;
    if (std::sscanf(raw_size.c_str(), "%dx%d%c", &w, &h, &tail) != 2 || w <= 0 || h <= 0)
      return usage("--raw-size expects WIDTHxHEIGHT, e.g. 1025x1025");
    o.raw_size = {w, h};
  }
  if (!valid_range.empty()) {
    std::array<double, 2> v{};
    if (!parse_pair(valid_range, v, false)) return usage("--valid-range expects MIN,MAX in metres, e.g. -500,5000");
    o.valid_range_m = v;
  }
  if (!memory_limit.empty() && !terrain::cook::parse_byte_size(memory_limit, o.memory_limit_bytes))
    return usage("--memory-limit " + memory_limit + ": expects a size of at least 1M, e.g. 512M, 2G, 1.5G");
  o.nodata_value = nodata_value;
  // The names the checks above accepted (cook_options_table.h spells them).
  using terrain::cook::enum_of;
  o.nodata = enum_of<terrain::cook::NodataPolicy>(nodata).value_or(o.nodata);
  o.overview_levels = enum_of<terrain::cook::OverviewMode>(overview).value_or(o.overview_levels);
  o.error_checks = enum_of<terrain::cook::ErrorChecks>(error_checks).value_or(o.error_checks);
  o.normals = enum_of<terrain::cook::NormalsMode>(normals).value_or(o.normals);
  o.overlap = enum_of<terrain::cook::OverlapRule>(overlap).value_or(o.overlap);
  o.surface_quality = enum_of<terrain::cook::SurfaceQuality>(quality).value_or(o.surface_quality);

  // ---- the files: refuse before any work ----
  auto fail = [](const terrain::Status& st) {
    std::fprintf(stderr, "terrain-cook: %s\n", st.to_string().c_str());
    return st.code == terrain::Error::invalid_argument ? 2 : 1;
  };
  if (planning && !o.output.empty())
    return usage("plan: -o " + o.output + ": plan writes no archive, only the plan in --work-dir; give -o to "
                 "`terrain-cook merge " + (o.work_dir.empty() ? std::string("WORK_DIR") : o.work_dir) + " -o ARCHIVE`");
  if (planning && !report_path.empty())
    return usage("plan: --report " + report_path + ": plan writes no cook report (it cooks nothing); give --report to "
                 "`terrain-cook merge`");
  std::vector<terrain::NamedPath> inputs, outputs;
  if (!planning) outputs.push_back({"-o", o.output});
  for (const std::string& p : o.inputs) inputs.push_back({"input", p});
  for (const auto& [flag, p] : {std::pair<const char*, const std::string&>{"--albedo", o.albedo_path},
                                {"--holes", o.holes_path},
                                {"--landcover", o.landcover_path},
                                {"--landcover-table", o.landcover_table_path},
                                {"--materials", o.materials_path}})
    if (!p.empty()) inputs.push_back({flag, p});
  if (!report_path.empty()) outputs.push_back({"--report", report_path});
  for (const terrain::NamedPath& in : inputs) {
    // A directory input stands for the rasters under it: load_inputs lists and checks each of them.
    if (std::error_code ec; in.flag == "input" && std::filesystem::is_directory(in.path, ec)) continue;
    if (terrain::Status st = terrain::check_input_file(in.flag == "input" ? "" : in.flag, in.path); !st.ok()) return fail(st);
  }
  if (terrain::Status st = terrain::check_output_paths(inputs, outputs); !st.ok()) return fail(st);
  if (!o.work_dir.empty())
    for (const terrain::NamedPath& out : outputs)
      if (terrain::cook::work_dir_owns(o.work_dir, out.path))
        return usage(out.flag + " " + out.path + ": is a file of the work dir " + o.work_dir +
                     " (its plan, input lists and units); refusing to overwrite it");
  if (!report_path.empty())
    if (const std::string why = refuse_report(report_path, o.force); !why.empty()) return usage(why);

  if (planning) {
    terrain::TerminalProgress bar(!quiet && !json);
    terrain::cook::PlanSummary summary;
    terrain::cook::CookReport report;
    const terrain::Status st =
        terrain::cook::plan_cook(o, bar.active() ? bar.callback() : terrain::ProgressFn{}, summary, report);
    bar.done();
    if (!st.ok()) return fail(st);
    if (json) {
      std::printf("{\"plan\": \"%s\", \"units\": %u, \"units_valid\": %u, \"changes\": %zu}\n",
                  summary.plan_path.c_str(), summary.unit_count, summary.units_valid, summary.changes.size());
    } else if (!quiet) {
      std::printf("%s: %u units (%u of them already cooked and still valid, %u to cook)\n", summary.plan_path.c_str(),
                  summary.unit_count, summary.units_valid, summary.unit_count - summary.units_valid);
      for (const std::string& c : summary.changes) std::printf("  %s\n", c.c_str());
    } else {
      std::printf("%u\n", summary.unit_count);
    }
    return 0;
  }

  // ---- cook into staged files beside the targets ----
  const std::string final_archive = o.output;
  // What a SIGKILLed earlier cook of these targets left goes first (output_paths.h).
  terrain::remove_stale_staging(final_archive);
  if (!report_path.empty()) terrain::remove_stale_staging(report_path);
  const std::string staged_archive = terrain::staging_path(final_archive);
  const std::string staged_report = report_path.empty() ? "" : terrain::staging_path(report_path);
  stage_for_cleanup(terrain::staging_path(staged_archive));           // the writer's own temp file
  stage_for_cleanup(terrain::staging_path(staged_archive, "spool"));  // the cook's node spool
  stage_for_cleanup(staged_archive);
  if (!staged_report.empty()) stage_for_cleanup(staged_report);
  install_signal_cleanup();
  o.output = staged_archive;

  terrain::TerminalProgress bar(!quiet && !json);
  terrain::cook::CookReport report;
  terrain::Status st;
  try {
    st = terrain::cook::cook(o, bar.active() ? bar.callback() : terrain::ProgressFn{}, report);
  } catch (const std::bad_alloc&) {  // past the budget's checks: the system refused (ulimit, overcommit)
    st = terrain::Status::failure(terrain::Error::internal,
                                  "out of memory: the system refused an allocation; give a lower --memory-limit "
                                  "than the memory this process may use, or a smaller input");
  } catch (const std::exception& e) {
    st = terrain::Status::failure(terrain::Error::internal, std::string("unexpected error: ") + e.what());
  }
  bar.done();
  if (!quiet)
    for (const std::string& w : report.warnings) std::fprintf(stderr, "terrain-cook: warning: %s\n", w.c_str());
  if (!st.ok()) {
    ::unlink(staged_archive.c_str());
    return fail(st);
  }
  const std::string report_text = terrain::cook::report_json(report);
  // ---- commit: the report's temp file first, so a report that cannot be written leaves the old archive ----
  if (!staged_report.empty()) {
    if (!write_file_durably(staged_report, report_text + "\n")) {
      const int e = errno;
      ::unlink(staged_report.c_str());
      ::unlink(staged_archive.c_str());
      std::fprintf(stderr, "terrain-cook: cannot write the report %s: %s; %s was not replaced\n", report_path.c_str(),
                   std::strerror(e), final_archive.c_str());
      return 1;
    }
    if (::rename(staged_report.c_str(), report_path.c_str()) != 0) {
      const int e = errno;
      ::unlink(staged_report.c_str());
      ::unlink(staged_archive.c_str());
      std::fprintf(stderr, "terrain-cook: cannot rename %s to %s: %s; %s was not replaced\n", staged_report.c_str(),
                   report_path.c_str(), std::strerror(e), final_archive.c_str());
      return 1;
    }
  }
  if (::rename(staged_archive.c_str(), final_archive.c_str()) != 0) {
    const int e = errno;
    ::unlink(staged_archive.c_str());
    std::fprintf(stderr, "terrain-cook: cannot rename %s to %s: %s%s\n", staged_archive.c_str(), final_archive.c_str(),
                 std::strerror(e), report_path.empty() ? "" : " (the report was written)");
    return 1;
  }
  if (json) std::printf("%s\n", report_text.c_str());
  else if (!quiet) std::printf("%s", terrain::cook::report_summary(report).c_str());
  return 0;
}

// `terrain-cook unit W [INDEX]`: one work unit; INDEX from the argument, SLURM_ARRAY_TASK_ID or
// JOB_COMPLETION_INDEX (a Kubernetes Indexed Job).
int run_unit(int argc, char** argv) {
  std::string work_dir;
  std::optional<uint32_t> index;
  int threads = 0;
  uint32_t block_roots = 0;
  bool quiet = false;
  CLI::App app{"terrain-cook unit: cooks one work unit of a plan into its file in the work dir (idempotent: a unit "
               "already complete and valid is not redone)",
               "terrain-cook unit"};
  app.footer(terrain::cli::kExitCodes);
  app.add_option("work_dir", work_dir, "Work dir written by `terrain-cook plan`")->required();
  app.add_option("index", index, "Unit index (default: $SLURM_ARRAY_TASK_ID, else $JOB_COMPLETION_INDEX)");
  app.add_option("--threads", threads, "Worker threads (default 0: all cores)")->check(terrain::cli::int_range(0, 1024));
  app.add_option("--block-roots", block_roots,
                 "Cook the unit as memory blocks of N x N roots (default: the largest the plan's --memory-limit "
                 "allows); changes no byte")
      ->check(terrain::cli::int_range(1, 1 << 16));
  app.add_flag("-q,--quiet", quiet, "Print nothing on success");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (!index) {
    for (const char* var : {"SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"})
      if (const char* v = std::getenv(var); v && *v) {
        char* end = nullptr;
        const unsigned long n = std::strtoul(v, &end, 10);
        if (*end != 0 || n > UINT32_MAX) {
          std::fprintf(stderr, "terrain-cook unit: %s=%s is not a unit index\n", var, v);
          return 2;
        }
        index = uint32_t(n);
        break;
      }
    if (!index) {
      std::fprintf(stderr, "terrain-cook unit: no unit index (give INDEX, or run as a Slurm array task or Kubernetes Indexed Job)\n");
      return 2;
    }
  }
  bool skipped = false;
  terrain::cook::CookReport report;
  const terrain::Status st = terrain::cook::cook_unit(work_dir, *index, threads, block_roots, skipped, report);
  if (!st.ok()) {
    std::fprintf(stderr, "terrain-cook unit %u: %s\n", *index, st.to_string().c_str());
    return st.code == terrain::Error::invalid_argument ? 2 : 1;
  }
  if (!quiet) std::printf("unit %u: %s\n", *index, skipped ? "already complete" : "cooked");
  return 0;
}

// `terrain-cook merge W -o ARCHIVE`: every unit checked, the archive written atomically.
int run_merge(int argc, char** argv) {
  std::string work_dir, output, report_path;
  bool quiet = false, json = false, force = false;
  CLI::App app{"terrain-cook merge: checks every unit of the plan (present, complete, checksums, fingerprints) and "
               "writes the archive atomically; a missing or bad unit is named and nothing is written",
               "terrain-cook merge"};
  app.add_option("work_dir", work_dir, "Work dir of the plan and its units")->required();
  app.add_option("-o,--output", output, "Archive to write (atomically)")->required();
  app.add_option("--report", report_path, "Write the cook report (JSON) to this file");
  app.add_flag("--json", json, "Print the report as JSON on stdout instead of the summary");
  app.add_flag("--force", force, "Let --report replace a file that is not a cook report");
  app.add_flag("-q,--quiet", quiet, "No progress bar and no summary");
  app.footer(std::string(terrain::cli::kExitCodes) +
             "\nOutputs (-o, --report) must not name an input of the plan (a VRT's tiles too), a file of the work "
             "dir, each other, a device, a FIFO or a directory.");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  std::vector<terrain::NamedPath> outputs{{"-o", output}};
  if (!report_path.empty()) outputs.push_back({"--report", report_path});
  // Devices, FIFOs, directories and the outputs against each other now; against the plan's inputs
  // and the work dir's files in merge_units, once it has read the plan, before it writes anything.
  if (terrain::Status st = terrain::check_output_paths({}, outputs); !st.ok()) {
    std::fprintf(stderr, "terrain-cook merge: %s\n", st.to_string().c_str());
    return st.code == terrain::Error::invalid_argument ? 2 : 1;
  }
  if (!report_path.empty())
    if (const std::string why = refuse_report(report_path, force); !why.empty()) {
      std::fprintf(stderr, "terrain-cook merge: %s\n", why.c_str());
      return 2;
    }
  terrain::TerminalProgress bar(!quiet && !json);
  terrain::cook::CookReport report;
  const terrain::Status st = terrain::cook::merge_units(
      work_dir, output, bar.active() ? bar.callback() : terrain::ProgressFn{}, report, outputs);
  bar.done();
  if (!st.ok()) {
    std::fprintf(stderr, "terrain-cook merge: %s\n", st.to_string().c_str());
    return st.code == terrain::Error::invalid_argument ? 2 : 1;
  }
  const std::string text = terrain::cook::report_json(report);
  if (!report_path.empty() && !write_file_durably(report_path, text + "\n")) {
    std::fprintf(stderr, "terrain-cook merge: cannot write the report %s: %s\n", report_path.c_str(), std::strerror(errno));
    return 1;
  }
  if (json) std::printf("%s\n", text.c_str());
  else if (!quiet) std::printf("%s", terrain::cook::report_summary(report).c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return terrain::cli::guarded_main("terrain-cook", [&] { return run(argc, argv); }); }
