// terrain-cook-bench: sweeps --tolerance over the real DEMs of the data directory (TERRAIN_DATA_DIR) and prints, per
// setting, nodes, bytes, cook time, max/RMS height error and the height stage's output samples per
// CPU-second, next to what `gdalwarp -r cubic` (the baseline a user would otherwise run, measured
// in the same run) takes to resample the same source to the finest cooked spacing; then the
// default cook of each DEM with every section and its peak memory. Medians of --runs runs.
//
// Each cook runs terrain-cook (next to this program) as a child process, so peak memory is the
// child's own (wait4 ru_maxrss) and the numbers are those a user sees.
//
// --scale: cooks squares of --sizes km of real lidar (mirror mosaics of one shared lidar tile, made
// by make_mirror_mosaic.py in the build tree: --lidar slovenia (1 m, the default), tahoe_bare or
// tahoe_highest (0.5 m, warped to UTM first), or --source FILE) with default flags (the
// bounded-memory, block-wise cook) and, for --baseline-sizes, in-core (one block) side by side;
// prints peak memory, time and throughput per size and the issue-13 targets. Every row also gives
// nodes per km2 and archive bytes per valid source sample, beside those of the real tile cooked
// alone with the same flags (the reference row), so that a reader can check the squares cook like
// the real data. --lidar lidar_like keeps the old, smoother squares (make_lidar_like.py: Kilauea
// 30 m upsampled plus value noise) for comparison with earlier measurements.
//
// --units: plan + units + merge against the one-process cook of the --units-km square of --scale
// (made when missing) or of --units-dem, with the same two statistics and the reference row.
//
// --steps MM,...: heights-only cooks of each DEM at each --height-step: height bytes per source sample
// and the full-detail error against the step (the height step study of issue 50).
//
// --chart FILE.svg: the sweep's cook time and archive size against tolerance and measured error,
// one series per DEM (bench_chart.h); with --scale, the scale chart.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <sys/statvfs.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "bench_chart.h"
#include "bench_paths.h"

namespace {

struct Dem {
  std::string name, file;
  std::vector<std::string> flags;  // georeferencing for files that lack it
  std::string gdal;                // how GDAL opens it ("" = GDAL cannot: no baseline)
};

struct Run {
  bool ok = false;
  double wall_s = 0, cpu_s = 0;  // cpu_s: the child's user + system time
  uint64_t rss_bytes = 0;
  std::string out;
};

// Runs argv, capturing stdout; wall time and the child's peak RSS.
Run run(const std::vector<std::string>& argv) {
  Run r;
  int pipe_fd[2];
  if (pipe(pipe_fd) != 0) return r;
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(pipe_fd[1], 1);
    close(pipe_fd[0]);
    close(pipe_fd[1]);
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execvp(args[0], args.data());
    _exit(127);
  }
  close(pipe_fd[1]);
  char buf[1 << 16];
  ssize_t n;
  while ((n = read(pipe_fd[0], buf, sizeof buf)) > 0) r.out.append(buf, size_t(n));
  close(pipe_fd[0]);
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.rss_bytes = uint64_t(usage.ru_maxrss) * 1024;
  r.cpu_s = double(usage.ru_utime.tv_sec) + 1e-6 * double(usage.ru_utime.tv_usec) + double(usage.ru_stime.tv_sec) +
            1e-6 * double(usage.ru_stime.tv_usec);
  r.ok = WIFEXITED(status) && WEXITSTATUS(status) == 0;
  return r;
}

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

struct CookStats {
  uint64_t nodes = 0, bytes = 0, output_vertices = 0;
  double wall_s = 0, max_err = 0, rms_err = 0, cpu_heights = 0, rss_mb = 0;
  int finest_present = 5;
  nlohmann::json report;
};

// Median over `runs` cooks (times, memory); sizes and errors are deterministic.
std::optional<CookStats> cook(const std::string& tool, const Dem& dem, const std::vector<std::string>& extra, int runs,
                              const std::string& out) {
  std::vector<double> wall, heights, rss;
  CookStats s;
  for (int k = 0; k < runs; ++k) {
    std::vector<std::string> argv = {tool, dem.file, "-o", out, "--json"};
    argv.insert(argv.end(), dem.flags.begin(), dem.flags.end());
    argv.insert(argv.end(), extra.begin(), extra.end());
    const Run r = run(argv);
    if (!r.ok) {
      fmt::print(stderr, "terrain-cook failed on {}\n", dem.file);
      return std::nullopt;
    }
    s.report = nlohmann::json::parse(r.out);
    wall.push_back(r.wall_s);
    heights.push_back(s.report["time_s"]["cpu_heights"].get<double>());
    rss.push_back(double(r.rss_bytes) / (1 << 20));
  }
  const auto& j = s.report;
  s.nodes = j["output"]["nodes"];
  s.bytes = j["output"]["archive_bytes"];
  s.output_vertices = j["speed"]["output_vertices"];
  s.max_err = j["full_detail_error"]["max_m"];
  s.rms_err = j["full_detail_error"]["rms_m"];
  for (const auto& l : j["levels"])
    if (l["nodes"].get<uint64_t>() > 0) s.finest_present = std::min(s.finest_present, l["level"].get<int>());
  s.wall_s = median(wall);
  s.cpu_heights = median(heights);
  s.rss_mb = median(rss);
  return s;
}

struct Baseline {
  double seconds = NAN, spacing = 0;
  uint64_t samples = 0;
};
constexpr uint64_t kMaxBaselineSamples = 60'000'000;  // coarser baseline grids beyond this (same rate)

// gdalwarp -r cubic of the source onto the archive's frame at `spacing` over the data's footprint
// (gdal_translate -r cubic for images without georeferencing). Median of `runs` of the child's CPU
// time (user + system, whole process: start-up, read, warp, write), comparable with our height
// stage's thread CPU time on a loaded machine. gdalwarp runs with its defaults (one warp thread, no
// -multi): per CPU-second the thread count does not matter.
Baseline gdal_baseline(const Dem& dem, const nlohmann::json& report, double spacing, int runs, const std::string& out) {
  Baseline b;
  if (dem.gdal.empty()) return b;
  const auto& f = report["frame"];
  const auto e = f["extent_m"];
  const double x0 = e[0], y0 = e[1], x1 = e[2], y1 = e[3];
  uint64_t w = 0, h = 0;
  for (;;) {  // the whole footprint at a very fine spacing would be gigabytes: measure the rate coarser
    w = uint64_t(std::ceil((x1 - x0) / spacing));
    h = uint64_t(std::ceil((y1 - y0) / spacing));
    if (w * h <= kMaxBaselineSamples) break;
    spacing *= 2;
  }
  b.samples = w * h;
  b.spacing = spacing;
  std::vector<std::string> argv;
  if (f["local"].get<bool>()) {
    argv = {"gdal_translate", "-q", "-r", "cubic", "-outsize", std::to_string(w), std::to_string(h), dem.gdal, out};
  } else {
    const std::string proj = fmt::format(
        "+proj=tmerc +lat_0={:.12g} +lon_0={:.12g} +k={:.12g} +x_0={:.12g} +y_0={:.12g} +a={:.12g} +rf={:.12g} "
        "+units=m +no_defs",
        f["lat0_deg"].get<double>(), f["lon0_deg"].get<double>(), f["k0"].get<double>(),
        f["false_easting_m"].get<double>(), f["false_northing_m"].get<double>(), f["semi_major_m"].get<double>(),
        f["inverse_flattening"].get<double>());
    argv = {"gdalwarp", "-q", "-overwrite", "-r", "cubic", "-t_srs", proj, "-te", fmt::format("{:.3f}", x0),
            fmt::format("{:.3f}", y0), fmt::format("{:.3f}", x0 + double(w) * spacing),
            fmt::format("{:.3f}", y0 + double(h) * spacing), "-tr", fmt::format("{}", spacing), fmt::format("{}", spacing),
            dem.gdal, out};
  }
  std::vector<double> t;
  for (int k = 0; k < runs; ++k) {
    const Run r = run(argv);
    if (!r.ok) return Baseline{};
    t.push_back(r.cpu_s);  // CPU seconds, like our height stage (the machine may be loaded)
    if (r.wall_s > 20) break;  // one run of a slow baseline is enough
  }
  b.seconds = median(t);
  return b;
}

std::string mb(double bytes) { return fmt::format("{:.2f}", bytes / 1e6); }

// ---- --scale: peak memory and throughput against source size -------------------------------------
//
// Per size: the default cook (block-wise, bounded memory) and, for --baseline-sizes, the in-core cook
// of the same DEM measured in the same run: one block holding every root and a budget large enough to
// hold the whole source (today's behaviour before the block-wise cook). The two archives must be
// byte-identical.

constexpr const char* kInCoreBlockRoots = "4096";  // 4096 roots of 2 km: one block for any input
constexpr const char* kInCoreMemoryLimit = "20G";
// The in-core cook holds the source and per-sample working grids, so its peak grows with the source:
// refuse a size whose estimate exceeds what the machine has instead of swapping. The estimate is the
// larger of this figure and the bytes per sample measured on in-core cooks earlier in this run.
constexpr double kAssumedInCoreBytesPerSample = 17.0;
constexpr double kUsableMemoryFraction = 0.8;     // of MemAvailable: others share the machine
constexpr double kGeneratedBytesPerSample = 4.5;  // disk for one generated DEM (ZSTD float32 + margin)
// Targets of issue 13. Binary units, like terrain-cook's --memory-limit 2G.
constexpr double kPeakTargetBytes = 2.0 * double(1ull << 30);
constexpr double kPeakGrowthTarget = 1.25;       // peak(40 km) / peak(8 km)
constexpr double kThroughputTarget = 1.0;        // blocks / in-core samples per CPU-second, 8 km

uint64_t mem_available_bytes() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  uint64_t kb = 0;
  std::string unit;
  while (in >> key >> kb >> unit)
    if (key == "MemAvailable:") return kb * 1024;
  return 0;
}

uint64_t disk_free_bytes(const std::string& dir) {
  struct statvfs s {};
  if (statvfs(dir.c_str(), &s) != 0) return 0;
  return uint64_t(s.f_bavail) * s.f_frsize;
}

double gb(double bytes) { return bytes / double(1ull << 30); }
double mib(double bytes) { return bytes / double(1ull << 20); }

// True when both files exist and hold the same bytes (what `cmp` says, without a child process).
bool same_bytes(const std::string& a, const std::string& b) {
  std::error_code ec;
  const auto na = std::filesystem::file_size(a, ec);
  if (ec) return false;
  const auto nb = std::filesystem::file_size(b, ec);
  if (ec || na != nb) return false;
  std::ifstream fa(a, std::ios::binary), fb(b, std::ios::binary);
  std::vector<char> ba(1 << 20), bb(1 << 20);
  while (fa && fb) {
    fa.read(ba.data(), std::streamsize(ba.size()));
    fb.read(bb.data(), std::streamsize(bb.size()));
    if (fa.gcount() != fb.gcount() || !std::equal(ba.begin(), ba.begin() + fa.gcount(), bb.begin())) return false;
  }
  return fa.eof() && fb.eof();
}

// What a cook's report says about how the data cooks: nodes and archive bytes against the valid
// source samples and the ground they cover (valid samples x spacing^2). Generated squares must give
// figures close to those of the real tile they are made of before anything measured on them is quoted.
struct DataStats {
  uint64_t nodes = 0, archive_bytes = 0, valid_samples = 0;
  double spacing_m = 0;  // the report's source spacing (frame metres)
  double area_km2() const { return double(valid_samples) * spacing_m * spacing_m / 1e6; }
  double nodes_per_km2() const { return area_km2() > 0 ? double(nodes) / area_km2() : NAN; }
  double bytes_per_sample() const { return valid_samples ? double(archive_bytes) / double(valid_samples) : NAN; }
};

DataStats data_stats(const nlohmann::json& report) {
  DataStats d;
  d.nodes = report["output"]["nodes"];
  d.archive_bytes = report["output"]["archive_bytes"];
  if (report.contains("source")) {
    d.valid_samples = report["source"].value("valid_samples", uint64_t(0));
    d.spacing_m = report["source"].value("spacing_m", 0.0);
  }
  return d;
}

struct ScaleRow {
  std::string mode;  // "blocks" (default flags) or "in-core" (one block, large budget)
  int km = 0;
  uint64_t samples = 0;  // of the square: estimated before the cook, the report's valid samples after
  std::string status = "ok";  // or why the row was skipped / failed
  double gen_s = NAN, wall_s = NAN, cpu_s = NAN, rss_bytes = NAN;
  DataStats data;
  uint64_t report_peak_rss_bytes = 0, memory_limit_bytes = 0;
  int64_t blocks = -1, block_roots = -1;  // -1: the report has no "blocks" (a cooker before issue 13)
  uint64_t window_samples_max = 0, spool_bytes = 0;
  std::string vs_in_core = "-";  // blocks rows: "same bytes" / "DIFFERENT" against the in-core archive
  std::vector<double> wall_runs, cpu_runs, rss_runs;  // per run; the row holds their medians
  bool ok() const { return status == "ok"; }
  double rss_bytes_per_sample() const { return rss_bytes / double(samples); }
  double samples_per_cpu_s() const { return double(samples) / cpu_s; }
};

// One cook of `dem` into `archive` (kept for the byte comparison), added to the row's runs; sizes
// from the report (deterministic). False (and the row's status says why) when it failed.
bool scale_cook_once(ScaleRow& row, const std::string& tool, const std::string& dem, const std::string& archive,
                     const std::vector<std::string>& flags) {
  std::vector<std::string> argv = {tool, dem, "-o", archive, "--json"};
  argv.insert(argv.end(), flags.begin(), flags.end());
  const Run r = run(argv);
  if (!r.ok) {
    row.status = "failed: terrain-cook exited non-zero";
    return false;
  }
  const auto j = nlohmann::json::parse(r.out, nullptr, false);
  if (j.is_discarded() || !j.contains("output")) {
    row.status = "failed: terrain-cook printed no JSON report";
    return false;
  }
  row.data = data_stats(j);
  if (row.data.valid_samples) row.samples = row.data.valid_samples;
  row.report_peak_rss_bytes = j.value("peak_rss_bytes", uint64_t(0));
  row.memory_limit_bytes = j.value("memory_limit_bytes", uint64_t(0));
  if (j.contains("blocks") && j["blocks"].is_object()) {
    const auto& b = j["blocks"];
    row.block_roots = b.value("block_roots", int64_t(-1));
    row.blocks = b.value("count", int64_t(-1));
    row.window_samples_max = b.value("window_samples_max", uint64_t(0));
    row.spool_bytes = b.value("spool_bytes", uint64_t(0));
  }
  row.wall_runs.push_back(r.wall_s);
  row.cpu_runs.push_back(r.cpu_s);
  row.rss_runs.push_back(double(r.rss_bytes));
  row.wall_s = median(row.wall_runs);
  row.cpu_s = median(row.cpu_runs);
  row.rss_bytes = median(row.rss_runs);
  return true;
}

// The real lidar tile the benchmark squares are made of (--lidar), and how they are made.
struct Lidar {
  std::string name;          // tables and file names: "slovenia", "tahoe_bare", ... or --source's stem
  std::string file;          // the shared tile (or --source)
  std::string tr_m;          // "": the tile is metric; else the spacing make_mirror_mosaic.py warps it to
  bool lidar_like = false;   // squares from make_lidar_like.py (Kilauea upsampled), not mirrored from `file`
};

// The --lidar choices; nullopt for an unknown name.
std::optional<Lidar> lidar_choice(const std::string& choice, const std::string& data) {
  const std::string d = data + "/";
  if (choice == "slovenia") return Lidar{"slovenia", d + "slovenia_TM1_564_146.tif", "", false};
  if (choice == "tahoe_bare") return Lidar{"tahoe_bare", d + "tahoe_lidar_bareearth.tif", "0.5", false};
  if (choice == "tahoe_highest") return Lidar{"tahoe_highest", d + "tahoe_lidar_highesthit.tif", "0.5", false};
  // The reference of the lidar-like squares is the real 1 m lidar they stand in for.
  if (choice == "lidar_like") return Lidar{"slovenia", d + "slovenia_TM1_564_146.tif", "", true};
  return std::nullopt;
}

struct ScaleOptions {
  std::vector<int> sizes, baseline_sizes;  // km
  bool heights_only = false;
  int runs = 1;
  double tile_km = 0;  // > 0: each DEM is a VRT of tile_km x tile_km km GeoTIFF tiles
  Lidar lidar;
  std::string data;    // the shared DEMs (lidar_like: its Kilauea source)
  std::string work, python;
  std::string tile;    // the real tile in a metric CRS, in work (made by prepare_tile)
  std::string chart;   // --chart: a copy of the scale chart
};

std::string script_path(const std::string& name) {
  return std::string(terrain::bench_source_dir()) + "/cooker/bench/" + name;
}

// File stem of the generated squares: which data they hold.
std::string square_stem(const ScaleOptions& o) {
  return o.lidar.lidar_like ? std::string("lidar_like") : o.lidar.name + "_mirror";
}

// The generated DEM of one size: one tiled GeoTIFF, or a VRT of GeoTIFF tiles (--tile-km).
std::string dem_path(const ScaleOptions& o, int km) {
  return o.tile_km > 0 ? fmt::format("{}/{}_{}km_tiles{:g}km.vrt", o.work, square_stem(o), km, o.tile_km)
                       : fmt::format("{}/{}_{}km.tif", o.work, square_stem(o), km);
}

// Copies the real tile into the work folder in a metric CRS (make_mirror_mosaic.py --grid 1x1
// --metric: a geographic tile is warped to UTM at lidar.tr_m, or its own spacing, and cropped to its
// data) unless present; "" or why not.
std::string prepare_tile(ScaleOptions& o) {
  o.tile = fmt::format("{}/{}_tile.tif", o.work, o.lidar.name);
  if (std::filesystem::exists(o.tile)) return "";
  std::vector<std::string> argv = {o.python, script_path("make_mirror_mosaic.py"), "--source", o.lidar.file, "--grid",
                                   "1x1", "--metric", "--out", o.tile};
  if (!o.lidar.tr_m.empty()) argv.insert(argv.end(), {"--tr", o.lidar.tr_m});
  return run(argv).ok ? "" : fmt::format("{} make_mirror_mosaic.py could not copy {} to {}", o.python, o.lidar.file, o.tile);
}

// The real tile cooked alone with the benchmark's flags: the figures the squares should come close to.
std::optional<DataStats> cook_reference(const std::string& tool, const ScaleOptions& o) {
  const std::string archive = o.work + "/reference.terrain";
  std::vector<std::string> argv = {tool, o.tile, "-o", archive, "--json"};
  if (o.heights_only) argv.push_back("--heights-only");
  const Run r = run(argv);
  std::error_code ec;
  std::filesystem::remove(archive, ec);
  if (!r.ok) return std::nullopt;
  const auto j = nlohmann::json::parse(r.out, nullptr, false);
  if (j.is_discarded() || !j.contains("output")) return std::nullopt;
  return data_stats(j);
}

std::string describe_reference(const ScaleOptions& o, const DataStats& ref) {
  return fmt::format("{} tile ({}, {:.3g} km2, {} samples at {:.3g} m): {} nodes, {:.1f} nodes/km2, {:.3f} bytes/sample",
                     o.lidar.name, o.tile, ref.area_km2(), ref.valid_samples, ref.spacing_m, ref.nodes,
                     ref.nodes_per_km2(), ref.bytes_per_sample());
}

// Makes the DEM of one size unless present; "" or why not.
std::string ensure_dem(const ScaleOptions& o, const std::string& dem, uint64_t samples, int km, double& gen_s) {
  if (std::filesystem::exists(dem)) {
    gen_s = 0;  // reused
    return "";
  }
  const double disk_need = kGeneratedBytesPerSample * double(samples);
  if (disk_need > double(disk_free_bytes(o.work)))
    return fmt::format("skipped: generating the DEM needs ~{:.1f} GB of disk in {}", gb(disk_need), o.work);
  const std::string script = script_path(o.lidar.lidar_like ? "make_lidar_like.py" : "make_mirror_mosaic.py");
  const std::string source = o.lidar.lidar_like ? o.data + "/kilauea_utm5n.tif" : o.tile;
  std::vector<std::string> argv = {o.python, script, "--source", source, "--size-km", std::to_string(km), "--out", dem};
  if (o.tile_km > 0) argv.insert(argv.end(), {"--tile-km", fmt::format("{:g}", o.tile_km)});
  const Run g = run(argv);
  gen_s = g.wall_s;
  return g.ok ? "" : fmt::format("failed: {} {} could not make {}", o.python, script, dem);
}

std::string count_or_dash(int64_t v) { return v < 0 ? "-" : std::to_string(v); }

void print_scale_header() {
  fmt::print("{:<8} {:>4} {:>13} {:>9} {:>8} {:>8} {:>8} {:>9} {:>7} {:>9} {:>8} {:>12} {:>6} {:>6} {:>6}  {:<10}  {}\n",
             "mode", "km", "samples", "peak_MiB", "rssB/smp", "wall_s", "cpu_s", "MS/cpu_s", "nodes", "nodes/km2",
             "arcB/smp", "archive_B", "blocks", "roots", "gen_s", "vs_in-core", "status");
}

void print_scale_row(const ScaleRow& r) {
  fmt::print("{:<8} {:>4} {:>13} {:>9.1f} {:>8.2f} {:>8.2f} {:>8.2f} {:>9.2f} {:>7} {:>9.1f} {:>8.3f} {:>12} {:>6} {:>6} "
             "{:>6.1f}  {:<10}  {}\n",
             r.mode, r.km, r.samples, mib(r.rss_bytes), r.rss_bytes_per_sample(), r.wall_s, r.cpu_s,
             r.samples_per_cpu_s() / 1e6, r.data.nodes, r.data.nodes_per_km2(), r.data.bytes_per_sample(),
             r.data.archive_bytes, count_or_dash(r.blocks), count_or_dash(r.block_roots), r.gen_s, r.vs_in_core,
             r.status);
  std::fflush(stdout);
}

const ScaleRow* find_row(const std::vector<ScaleRow>& rows, const std::string& mode, int km) {
  for (const ScaleRow& r : rows)
    if (r.mode == mode && r.km == km && r.ok()) return &r;
  return nullptr;
}

struct TargetCheck {
  std::string name, verdict, detail;  // verdict: PASS, FAIL or n/a
};

std::vector<TargetCheck> scale_targets(const std::vector<ScaleRow>& rows) {
  std::vector<TargetCheck> checks;
  {  // Peak RSS of every default (block-wise) cook.
    TargetCheck c{fmt::format("peak RSS <= {:.0f} MiB at every size (blocks)", mib(kPeakTargetBytes)), "PASS", ""};
    int measured = 0;
    for (const ScaleRow& r : rows) {
      if (r.mode != "blocks") continue;
      if (!c.detail.empty()) c.detail += ", ";
      if (!r.ok()) {
        c.verdict = "FAIL";
        c.detail += fmt::format("{} km not measured", r.km);
        continue;
      }
      ++measured;
      c.detail += fmt::format("{} km {:.0f} MiB", r.km, mib(r.rss_bytes));
      if (r.rss_bytes > kPeakTargetBytes) c.verdict = "FAIL";
    }
    if (!measured) c.verdict = "n/a";
    checks.push_back(c);
  }
  {  // Peak growth: 40 km (or the largest size) against 8 km (or the smallest).
    std::vector<const ScaleRow*> ok;
    for (const ScaleRow& r : rows)
      if (r.mode == "blocks" && r.ok()) ok.push_back(&r);
    std::sort(ok.begin(), ok.end(), [](const ScaleRow* a, const ScaleRow* b) { return a->km < b->km; });
    const ScaleRow* ref = find_row(rows, "blocks", 8);
    const ScaleRow* top = find_row(rows, "blocks", 40);
    if (!ref && !ok.empty()) ref = ok.front();
    if (!top && !ok.empty()) top = ok.back();
    TargetCheck c{fmt::format("peak(40 km) / peak(8 km) <= {:.2f} (blocks)", kPeakGrowthTarget), "n/a",
                  "needs two sizes"};
    if (ref && top && ref->km != top->km) {
      const double ratio = top->rss_bytes / ref->rss_bytes;
      c.verdict = ratio <= kPeakGrowthTarget ? "PASS" : "FAIL";
      c.detail = fmt::format("{} km {:.0f} MiB / {} km {:.0f} MiB = {:.3f}", top->km, mib(top->rss_bytes), ref->km,
                             mib(ref->rss_bytes), ratio);
      if (ref->km != 8 || top->km != 40) c.detail += " (sizes measured in this run)";
    }
    checks.push_back(c);
  }
  {  // Throughput: blocks against in-core on the same DEM, 8 km (or the largest size with both).
    const ScaleRow *b = find_row(rows, "blocks", 8), *i = find_row(rows, "in-core", 8);
    if (!b || !i) {
      b = i = nullptr;
      for (const ScaleRow& r : rows) {
        const ScaleRow* other = find_row(rows, "in-core", r.km);
        if (r.mode == "blocks" && r.ok() && other && (!b || r.km > b->km)) b = &r, i = other;
      }
    }
    TargetCheck c{fmt::format("samples per CPU-s, blocks / in-core on 8 km >= {:.2f}", kThroughputTarget), "n/a",
                  "needs an in-core row (--baseline-sizes)"};
    if (b && i) {
      // Run k of each mode ran back to back: the median of the paired ratios (in-core CPU-s /
      // blocks CPU-s) is what decides; the ratio of the medians is printed beside it.
      const double of_medians = b->samples_per_cpu_s() / i->samples_per_cpu_s();
      std::vector<double> paired;
      for (size_t k = 0; k < std::min(b->cpu_runs.size(), i->cpu_runs.size()); ++k)
        paired.push_back(i->cpu_runs[k] / b->cpu_runs[k]);
      const double ratio = paired.empty() ? of_medians : median(paired);
      std::string each;
      for (double p : paired) each += fmt::format("{}{:.3f}", each.empty() ? "" : " ", p);
      c.verdict = ratio >= kThroughputTarget ? "PASS" : "FAIL";
      c.detail = fmt::format("{} km: median of {} paired ratios {:.3f} ({}); medians {:.2f} / {:.2f} M samples per "
                             "CPU-s = {:.3f}",
                             b->km, paired.size(), ratio, each, b->samples_per_cpu_s() / 1e6,
                             i->samples_per_cpu_s() / 1e6, of_medians);
      if (b->km != 8) c.detail += " (8 km not measured)";
    }
    checks.push_back(c);
  }
  return checks;
}

// Two panels, peak RSS (MiB) and M samples per CPU-second against the square's side (km), one series
// per mode (in-core as rings around the blocks dots, so equal values stay visible); the peak panel
// draws the 2 GiB target.
terrain::chart::Chart scale_chart(const std::vector<ScaleRow>& rows, const std::string& title) {
  namespace ch = terrain::chart;
  ch::Chart c;
  c.title = title;
  c.note = ch::machine_note();
  ch::Panel peak, rate;
  peak.title = "peak RSS, MiB";
  rate.title = "M source samples per CPU-second";
  for (ch::Panel* p : {&peak, &rate}) {
    p->x = {"square side, km", ch::Scale::linear, true};
    p->y = {p->title, ch::Scale::linear, true};
  }
  peak.lines.push_back({"2 GiB target", mib(kPeakTargetBytes), true});
  for (const char* mode : {"blocks", "in-core"}) {
    ch::Series s;
    s.name = mode;
    s.hollow = std::string(mode) == "in-core";
    ch::Series r = s;
    for (const ScaleRow& row : rows) {
      if (row.mode != mode || !row.ok()) continue;
      const std::string label = fmt::format("{} km", row.km);
      s.points.push_back({double(row.km), mib(row.rss_bytes), label});
      r.points.push_back({double(row.km), row.samples_per_cpu_s() / 1e6, label});
    }
    if (s.points.empty()) continue;
    peak.series.push_back(s);
    rate.series.push_back(r);
  }
  c.panels = {peak, rate};
  return c;
}

// The work folder, the real tile in it and the tile cooked alone (the reference row of --scale and
// --units); nullopt after printing why not.
std::optional<DataStats> prepare_reference(const std::string& tool, ScaleOptions& o) {
  std::error_code ec;
  if (!std::filesystem::exists(o.lidar.file)) {
    fmt::print(stderr, "terrain-cook-bench: lidar tile {} not found (--lidar, --source or --data)\n", o.lidar.file);
    return std::nullopt;
  }
  std::filesystem::create_directories(o.work, ec);
  if (ec) {
    fmt::print(stderr, "terrain-cook-bench: cannot create --work {}: {}\n", o.work, ec.message());
    return std::nullopt;
  }
  if (const std::string why = prepare_tile(o); !why.empty()) {
    fmt::print(stderr, "terrain-cook-bench: {}\n", why);
    return std::nullopt;
  }
  const auto ref = cook_reference(tool, o);
  if (!ref || !ref->valid_samples) {
    fmt::print(stderr, "terrain-cook-bench: terrain-cook failed on the reference tile {}\n", o.tile);
    return std::nullopt;
  }
  return ref;
}

void print_reference(const ScaleOptions& o, const DataStats& ref) {
  fmt::print("reference, the real tile cooked alone ({}): {}\n", o.heights_only ? "--heights-only" : "default flags",
             describe_reference(o, ref));
}

// How the squares are made, for the table's heading.
std::string describe_squares(const ScaleOptions& o) {
  const std::string form = o.tile_km > 0 ? fmt::format("VRT of {:g} km GeoTIFF tiles", o.tile_km) : "one GeoTIFF";
  if (o.lidar.lidar_like)
    return fmt::format("1 m lidar-like squares (make_lidar_like.py: {}/kilauea_utm5n.tif upsampled plus value noise; "
                       "{})", o.data, form);
  return fmt::format("squares mirrored from the {} lidar tile (make_mirror_mosaic.py of {}; {})", o.lidar.name, o.tile,
                     form);
}

// Beside each size: its nodes per km2 and bytes per sample over the reference tile's.
void print_likeness(const std::vector<ScaleRow>& rows, const DataStats& ref) {
  std::vector<std::string> sizes;
  for (const ScaleRow& r : rows)
    if (r.mode == "blocks" && r.ok())
      sizes.push_back(fmt::format("{} km {:.2f}x, {:.2f}x", r.km, r.data.nodes_per_km2() / ref.nodes_per_km2(),
                                  r.data.bytes_per_sample() / ref.bytes_per_sample()));
  fmt::print("\nLike the real tile? nodes/km2 and archive bytes per source sample over the reference's ({:.1f}, "
             "{:.3f}): {}\n",
             ref.nodes_per_km2(), ref.bytes_per_sample(), fmt::join(sizes, "; "));
}

int scale_main(const std::string& tool, const ScaleOptions& o, const DataStats& ref) {
  const std::string& work = o.work;
  const bool heights_only = o.heights_only;
  const int runs = o.runs;
  std::error_code ec;
  const std::string mode = heights_only ? "heights-only" : "full";
  const std::vector<std::string> common = heights_only ? std::vector<std::string>{"--heights-only"}
                                                       : std::vector<std::string>{};
  std::vector<std::string> in_core = common;
  in_core.insert(in_core.end(), {"--block-roots", kInCoreBlockRoots, "--memory-limit", kInCoreMemoryLimit});
  fmt::print("terrain-cook-bench --scale: {} cooks of {}, work {}, median of {} run{}\n", mode, describe_squares(o),
             work, runs, runs == 1 ? "" : "s");
  fmt::print("blocks: default flags{}; in-core: the same plus --block-roots {} --memory-limit {} (one block: "
             "the whole source in memory), skipped when its estimated peak (max({} B/sample, measured so far) x "
             "samples) exceeds {:.0f}% of MemAvailable. vs_in-core: the blocks archive compared byte for byte "
             "with the in-core one. rssB/smp: peak RSS per source sample; nodes/km2 and arcB/smp (archive bytes "
             "per valid source sample) against the reference row below.\n",
             heights_only ? " + --heights-only" : "", kInCoreBlockRoots, kInCoreMemoryLimit,
             kAssumedInCoreBytesPerSample, 100 * kUsableMemoryFraction);
  print_reference(o, ref);
  fmt::print("\n");
  print_scale_header();
  std::vector<ScaleRow> rows;
  double in_core_bps = 0;  // largest in-core bytes per sample measured so far
  bool different = false;
  for (int km : o.sizes) {
    ScaleRow b;
    b.mode = "blocks";
    b.km = km;
    const double spacing = o.lidar.lidar_like ? 1.0 : ref.spacing_m;
    const uint64_t side = uint64_t(std::llround(km * 1000.0 / spacing));
    b.samples = side * side;  // the report's valid samples once cooked
    const std::string dem = dem_path(o, km);
    const std::string why = ensure_dem(o, dem, b.samples, km, b.gen_s);
    const bool have_dem = why.empty();
    if (!have_dem) b.status = why;
    const std::string blocks_archive = fmt::format("{}/{}_{}km.blocks.terrain", work, square_stem(o), km);
    const std::string in_core_archive = fmt::format("{}/{}_{}km.in-core.terrain", work, square_stem(o), km);
    const bool want_in_core =
        std::find(o.baseline_sizes.begin(), o.baseline_sizes.end(), km) != o.baseline_sizes.end();
    ScaleRow i;
    i.mode = "in-core";
    i.km = km;
    i.samples = b.samples;
    i.gen_s = 0;
    if (want_in_core && !have_dem) i.status = b.status;
    if (want_in_core && have_dem) {
      const double need = std::max(kAssumedInCoreBytesPerSample, in_core_bps) * double(i.samples);
      const double avail = kUsableMemoryFraction * double(mem_available_bytes());
      if (need > avail)
        i.status = fmt::format("skipped: in-core cook needs ~{:.1f} GB, {:.1f} GB usable", gb(need), gb(avail));
    }
    // Runs alternate between the two modes, so a change of machine load between runs falls on both
    // alike; the throughput check uses the median of the paired ratios.
    for (int k = 0; k < runs && b.ok(); ++k) {
      if (!scale_cook_once(b, tool, dem, blocks_archive, common)) break;
      if (want_in_core && i.ok()) scale_cook_once(i, tool, dem, in_core_archive, in_core);
    }
    if (!want_in_core || !b.ok()) print_scale_row(b);  // else printed with the comparison below
    if (want_in_core) {
      if (i.ok()) in_core_bps = std::max(in_core_bps, i.rss_bytes_per_sample());
      if (b.ok() && i.ok()) {
        b.vs_in_core = same_bytes(blocks_archive, in_core_archive) ? "same bytes" : "DIFFERENT";
        different |= b.vs_in_core == "DIFFERENT";
      }
      if (b.ok()) print_scale_row(b);
      print_scale_row(i);
      rows.push_back(b);
      rows.push_back(i);
    } else {
      rows.push_back(b);
    }
    std::filesystem::remove(blocks_archive, ec);  // archives of the large sizes are gigabytes
    std::filesystem::remove(in_core_archive, ec);
  }

  print_likeness(rows, ref);
  const std::vector<TargetCheck> checks = scale_targets(rows);
  fmt::print("\nTargets (issue 13):\n");
  for (const TargetCheck& c : checks) fmt::print("  {:<4}  {}: {}\n", c.verdict, c.name, c.detail);

  // The table next to the DEMs, one set of files per mode (heights-only and full runs do not overwrite each other).
  const std::string stem =
      fmt::format("{}/scale-{}-{}", work, o.lidar.lidar_like ? std::string("lidar_like") : o.lidar.name, mode);
  nlohmann::json js = nlohmann::json::array();
  std::ofstream csv(stem + ".csv");
  csv << "mode,size_km,samples,peak_rss_bytes,bytes_per_sample,wall_s,cpu_s,samples_per_cpu_s,nodes,archive_bytes,"
         "blocks,block_roots,window_samples_max,spool_bytes,gen_s,vs_in_core,status,nodes_per_km2,"
         "archive_bytes_per_source_sample\n";
  auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  auto opt = [](int64_t v) { return v < 0 ? nlohmann::json(nullptr) : nlohmann::json(v); };
  for (const ScaleRow& r : rows) {
    js.push_back({{"mode", r.mode}, {"size_km", r.km}, {"samples", r.samples}, {"peak_rss_bytes", num(r.rss_bytes)},
                  {"report_peak_rss_bytes", r.report_peak_rss_bytes}, {"memory_limit_bytes", r.memory_limit_bytes},
                  {"bytes_per_sample", num(r.rss_bytes_per_sample())}, {"wall_s", num(r.wall_s)},
                  {"cpu_s", num(r.cpu_s)}, {"samples_per_cpu_s", num(r.samples_per_cpu_s())}, {"nodes", r.data.nodes},
                  {"nodes_per_km2", num(r.data.nodes_per_km2())},
                  {"archive_bytes_per_source_sample", num(r.data.bytes_per_sample())},
                  {"archive_bytes", r.data.archive_bytes}, {"blocks", opt(r.blocks)}, {"block_roots", opt(r.block_roots)},
                  {"window_samples_max", r.window_samples_max}, {"spool_bytes", r.spool_bytes},
                  {"gen_s", num(r.gen_s)}, {"vs_in_core", r.vs_in_core}, {"status", r.status}});
    csv << fmt::format("{},{},{},{:.0f},{:.3f},{:.3f},{:.3f},{:.0f},{},{},{},{},{},{},{:.1f},{},\"{}\",{:.2f},{:.4f}\n",
                       r.mode, r.km, r.samples, r.rss_bytes, r.rss_bytes_per_sample(), r.wall_s, r.cpu_s,
                       r.samples_per_cpu_s(), r.data.nodes, r.data.archive_bytes, count_or_dash(r.blocks),
                       count_or_dash(r.block_roots), r.window_samples_max, r.spool_bytes, r.gen_s, r.vs_in_core,
                       r.status, r.data.nodes_per_km2(), r.data.bytes_per_sample());
  }
  nlohmann::json targets = nlohmann::json::array();
  for (const TargetCheck& c : checks) targets.push_back({{"target", c.name}, {"verdict", c.verdict}, {"detail", c.detail}});
  std::ofstream(stem + ".json") << nlohmann::json{{"mode", mode},
                                                  {"squares", describe_squares(o)},
                                                  {"lidar", o.lidar.name},
                                                  {"reference", {{"tile", o.tile},
                                                                 {"nodes", ref.nodes},
                                                                 {"archive_bytes", ref.archive_bytes},
                                                                 {"valid_samples", ref.valid_samples},
                                                                 {"spacing_m", ref.spacing_m},
                                                                 {"nodes_per_km2", num(ref.nodes_per_km2())},
                                                                 {"archive_bytes_per_source_sample",
                                                                  num(ref.bytes_per_sample())}}},
                                                  {"runs", runs},
                                                  {"threads", std::thread::hardware_concurrency()},
                                                  {"in_core_flags", in_core},
                                                  {"rows", js},
                                                  {"targets", targets}}
                                       .dump(2)
                                << "\n";
  const std::string chart_error = terrain::chart::write_svg(
      scale_chart(rows, fmt::format("terrain-cook {} on {} squares: blocks (default flags) vs in-core", mode,
                                    o.lidar.lidar_like ? std::string("1 m lidar-like") : "mirrored " + o.lidar.name)),
      stem + ".svg");
  if (!chart_error.empty()) fmt::print(stderr, "terrain-cook-bench: {}\n", chart_error);
  if (!o.chart.empty()) {
    std::error_code copy_ec;
    std::filesystem::copy_file(stem + ".svg", o.chart, std::filesystem::copy_options::overwrite_existing, copy_ec);
    if (copy_ec) fmt::print(stderr, "terrain-cook-bench: cannot write --chart {}: {}\n", o.chart, copy_ec.message());
    else fmt::print("Wrote {}\n", o.chart);
  }
  fmt::print("\nWrote {}.json, .csv and .svg\n", stem);
  bool failed = different;
  for (const ScaleRow& r : rows) failed |= r.status.rfind("failed", 0) == 0;
  std::fflush(stdout);
  if (different) fmt::print(stderr, "terrain-cook-bench: a block-wise archive differs from the in-core one\n");
  return failed ? 1 : 0;
}


// ---- --units: work units + merge against the one-process cook (issue 14) -------------------------

struct UnitRun {
  double wall_s = 0, cpu_s = 0;
};

// Runs `terrain-cook unit W i` for every unit with `workers` processes in flight; per-unit times.
bool run_units(const std::string& tool, const std::string& work, uint32_t units, int workers, std::vector<UnitRun>& out,
               double& wall_s) {
  out.assign(units, UnitRun{});
  std::map<pid_t, std::pair<uint32_t, std::chrono::steady_clock::time_point>> running;
  uint32_t next = 0;
  bool ok = true;
  const auto t0 = std::chrono::steady_clock::now();
  while (next < units || !running.empty()) {
    while (next < units && int(running.size()) < workers) {
      const pid_t pid = fork();
      if (pid == 0) {
        const std::string idx = std::to_string(next);
        execl(tool.c_str(), tool.c_str(), "unit", work.c_str(), idx.c_str(), "-q", "--threads", "1", nullptr);
        _exit(127);
      }
      running[pid] = {next++, std::chrono::steady_clock::now()};
    }
    int status = 0;
    rusage usage{};
    const pid_t pid = wait4(-1, &status, 0, &usage);
    if (pid <= 0) break;
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    UnitRun& r = out[it->second.first];
    r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - it->second.second).count();
    r.cpu_s = double(usage.ru_utime.tv_sec) + 1e-6 * double(usage.ru_utime.tv_usec) + double(usage.ru_stime.tv_sec) +
              1e-6 * double(usage.ru_stime.tv_usec);
    ok = ok && WIFEXITED(status) && WEXITSTATUS(status) == 0;
    running.erase(it);
  }
  wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return ok;
}

bool same_file(const std::string& a, const std::string& b) {
  std::ifstream fa(a, std::ios::binary), fb(b, std::ios::binary);
  return std::equal(std::istreambuf_iterator<char>(fa), std::istreambuf_iterator<char>(),
                    std::istreambuf_iterator<char>(fb), std::istreambuf_iterator<char>());
}

// Longest-processing-time-first schedule of `times` on `machines`: the busiest machine's load.
double lpt_makespan(std::vector<double> times, int machines) {
  std::sort(times.rbegin(), times.rend());
  std::vector<double> load(size_t(machines), 0.0);
  for (double t : times) *std::min_element(load.begin(), load.end()) += t;
  return *std::max_element(load.begin(), load.end());
}

// One round of --units: the one-process cook, then plan + units + merge with 1 and with 2 workers.
struct UnitsPass {
  Run plan, merge, cp, cp_sync;
  double units_wall = 0, units_cpu = 0, total_cpu = 0;
  std::vector<double> unit_cpu;
  uint32_t units = 0;
  bool same = false;
};
struct UnitsRound {
  Run one;
  double first_pass_cpu = 0, blocks_cpu = 0;  // from the one-process cook's report
  UnitsPass pass[2];                          // 1 and 2 workers
};

int units_main(const std::string& tool, const std::string& dem, uint32_t unit_roots, const ScaleOptions& o,
               const DataStats& ref, int runs, const std::string& work_root) {
  const bool heights_only = o.heights_only;
  std::error_code ec;
  std::filesystem::create_directories(work_root, ec);
  if (!std::filesystem::exists(dem)) {
    fmt::print(stderr, "terrain-cook-bench --units: {} not found\n", dem);
    return 1;
  }
  std::vector<std::string> flags;
  if (heights_only) flags.push_back("--heights-only");
  fmt::print("terrain-cook-bench --units: {} ({}), units of {} roots, {} round{}, work {}\n", dem,
             heights_only ? "heights only" : "full",
             unit_roots ? std::to_string(unit_roots) : std::string("the plan's default"), runs, runs == 1 ? "" : "s",
             work_root);
  print_reference(o, ref);
  const std::string one = work_root + "/one.terrain";
  // A process start of terrain-cook (its shared libraries), which every unit and the merge pay:
  // the median of 3 runs of `terrain-cook merge --help`.
  std::vector<Run> starts;
  for (int i = 0; i < 3; ++i) starts.push_back(run({tool, "merge", "--help"}));
  std::sort(starts.begin(), starts.end(), [](const Run& a, const Run& b) { return a.cpu_s < b.cpu_s; });
  const Run start = starts[1];
  // Rounds: each runs the one-process cook and both unit passes in turn, so that a change in the
  // machine's load hits both sides of a ratio alike; the medians of the per-round ratios decide.
  std::vector<UnitsRound> rounds;
  int failures = 0;
  uint64_t bytes = 0;
  DataStats data;  // of the one-process archive
  fmt::print("\n{:<6} {:>7} {:>9} {:>9} {:>9} {:>9} {:>8} {:>9} {:>9} {:>7} {:>7} {:>7}\n", "round", "workers",
             "one cpu_s", "plan cpu", "units cpu", "merge s", "cp s", "dd sync s", "total cpu", "over %", "x cp",
             "x dd");
  for (int r = 0; r < runs; ++r) {
    UnitsRound round;
    std::vector<std::string> argv = {tool, dem, "-o", one, "-q", "--report", work_root + "/one.json"};
    argv.insert(argv.end(), flags.begin(), flags.end());
    round.one = run(argv);
    if (!round.one.ok) return 1;
    bytes = std::filesystem::file_size(one);
    {
      std::ifstream in(work_root + "/one.json");
      const auto j = nlohmann::json::parse(in, nullptr, false);
      if (!j.is_discarded() && j.contains("output")) data = data_stats(j);
      if (!j.is_discarded() && j.contains("time_s")) {
        round.first_pass_cpu = j["time_s"].value("cpu_first_pass", 0.0);
        round.blocks_cpu = j["time_s"].value("cpu_blocks", 0.0);
      }
    }
    for (int wi = 0; wi < 2; ++wi) {
      const int workers = wi + 1;
      UnitsPass& p = round.pass[wi];
      const std::string w = fmt::format("{}/w{}", work_root, workers);
      std::filesystem::remove_all(w, ec);
      std::vector<std::string> pa = {tool, "plan", dem, "--work-dir", w, "-q"};
      if (unit_roots) pa.insert(pa.end(), {"--unit-roots", std::to_string(unit_roots)});
      pa.insert(pa.end(), flags.begin(), flags.end());
      p.plan = run(pa);
      if (!p.plan.ok) return 1;
      p.units = uint32_t(std::stoul(p.plan.out));
      std::vector<UnitRun> per_unit;
      if (!run_units(tool, w, p.units, workers, per_unit, p.units_wall)) return 1;
      const std::string merged = w + "/merged.terrain";
      p.merge = run({tool, "merge", w, "-o", merged, "-q"});
      if (!p.merge.ok) return 1;
      p.cp = run({"cp", merged, w + "/copy.terrain"});
      // The merge fsyncs its archive before the rename (a crash must not leave a renamed, unwritten
      // file over an earlier archive); cp does not. The same copy made as durable: dd conv=fsync.
      p.cp_sync = run({"dd", "if=" + merged, "of=" + w + "/copy-sync.terrain", "bs=4M", "conv=fsync", "status=none"});
      for (const UnitRun& u : per_unit) {
        p.units_cpu += u.cpu_s;
        p.unit_cpu.push_back(u.cpu_s);
      }
      p.total_cpu = p.plan.cpu_s + p.units_cpu + p.merge.cpu_s;
      p.same = same_file(one, merged);
      failures += p.same ? 0 : 1;
      fmt::print("{:<6} {:>7} {:>9.2f} {:>9.2f} {:>9.2f} {:>9.3f} {:>8.3f} {:>9.3f} {:>9.2f} {:>+7.1f} {:>7.2f} "
                 "{:>7.2f}{}\n",
                 r + 1, workers, round.one.cpu_s, p.plan.cpu_s, p.units_cpu, p.merge.wall_s, p.cp.wall_s,
                 p.cp_sync.wall_s, p.total_cpu, 100.0 * (p.total_cpu / round.one.cpu_s - 1.0),
                 p.cp.wall_s / p.merge.wall_s, p.cp_sync.wall_s / p.merge.wall_s, p.same ? "" : "  DIFFERENT BYTES");
    }
    rounds.push_back(std::move(round));
  }
  const UnitsPass& last = rounds.back().pass[1];
  fmt::print("\nArchive {:.1f} MB, {} units; process start-up (terrain-cook merge --help) {:.3f} s wall, {:.3f} s CPU; "
             "merge peak RSS {:.1f} MB\n",
             double(bytes) / 1e6, last.units, start.wall_s, start.cpu_s, double(last.merge.rss_bytes) / 1e6);
  fmt::print("Like the real tile? The one-process archive: {} nodes, {:.1f} nodes/km2 ({:.2f}x the reference's "
             "{:.1f}), {:.3f} bytes per source sample ({:.2f}x the reference's {:.3f})\n",
             data.nodes, data.nodes_per_km2(), data.nodes_per_km2() / ref.nodes_per_km2(), ref.nodes_per_km2(),
             data.bytes_per_sample(), data.bytes_per_sample() / ref.bytes_per_sample(), ref.bytes_per_sample());
  auto med = [&](auto f) {
    std::vector<double> v;
    for (const UnitsRound& r : rounds) v.push_back(f(r));
    return median(v);
  };
  fmt::print("Where the CPU goes (medians): one-process first pass {:.2f} s + blocks {:.2f} s; plan {:.2f} s; units "
             "{:.2f} s (1 worker), {:.2f} s (2 workers)\n",
             med([](const UnitsRound& r) { return r.first_pass_cpu; }),
             med([](const UnitsRound& r) { return r.blocks_cpu; }),
             med([](const UnitsRound& r) { return r.pass[0].plan.cpu_s; }),
             med([](const UnitsRound& r) { return r.pass[0].units_cpu; }),
             med([](const UnitsRound& r) { return r.pass[1].units_cpu; }));
  for (int wi = 0; wi < 2; ++wi) {
    const double over = med([&](const UnitsRound& r) { return 100.0 * (r.pass[wi].total_cpu / r.one.cpu_s - 1.0); });
    const double xcp = med([&](const UnitsRound& r) { return r.pass[wi].cp.wall_s / r.pass[wi].merge.wall_s; });
    const double xdd = med([&](const UnitsRound& r) { return r.pass[wi].cp_sync.wall_s / r.pass[wi].merge.wall_s; });
    const double merge_mbs = med([&](const UnitsRound& r) { return double(bytes) / 1e6 / r.pass[wi].merge.wall_s; });
    const double cp_mbs = med([&](const UnitsRound& r) { return double(bytes) / 1e6 / r.pass[wi].cp.wall_s; });
    fmt::print("{} worker{}: CPU of plan + units + merge {:+.1f} % over the one-process cook (target <= +5 %: {}); merge "
               "{:.0f} MB/s, cp {:.0f} MB/s: {:.2f} x cp (target >= 0.5: {}), {:.2f} x a copy as durable (dd conv=fsync)\n",
               wi + 1, wi ? "s" : "", over, over <= 5.0 ? "PASS" : "FAIL", merge_mbs, cp_mbs, xcp,
               xcp >= 0.5 ? "PASS" : "FAIL", xdd);
  }
  // 16 machines, on paper: the measured per-unit CPU seconds scheduled longest first.
  std::vector<double> unit_cpu = last.unit_cpu;
  std::sort(unit_cpu.begin(), unit_cpu.end());
  if (!unit_cpu.empty()) {
    fmt::print("Per-unit CPU (last round, 2 workers): min {:.2f} s, median {:.2f} s, max {:.2f} s\n", unit_cpu.front(),
               unit_cpu[unit_cpu.size() / 2], unit_cpu.back());
    const double makespan = last.plan.wall_s + lpt_makespan(unit_cpu, 16) + last.merge.wall_s;
    fmt::print("16 machines (simulated from the per-unit times): makespan {:.2f} s = plan {:.2f} + units {:.2f} + merge "
               "{:.2f} ({:.0f} % in the merge); one process on one core would take {:.2f} s\n",
               makespan, last.plan.wall_s, lpt_makespan(unit_cpu, 16), last.merge.wall_s,
               100.0 * last.merge.wall_s / makespan, last.total_cpu);
  }
  fmt::print("Archive {} the one-process bytes in every round\n", failures ? "DIFFERS FROM" : "equals");
  return failures ? 1 : 0;
}
struct SweepPoint {
  std::string dem;
  double tolerance = 0, wall_s = 0, bytes = 0, max_err = 0, rms_err = 0;
};

// --chart: the heights-only sweep, one series per DEM: cook time and archive size against the
// tolerance asked for and against the largest height error measured (log-log: DEMs differ by
// orders of magnitude).
terrain::chart::Chart sweep_chart(const std::vector<SweepPoint>& points, int runs) {
  namespace ch = terrain::chart;
  ch::Chart c;
  c.title = "terrain-cook-bench: heights-only cooks, tolerance sweep per DEM";
  c.note = fmt::format("Cook time = wall seconds of terrain-cook (median of {} run{}); archive = bytes written; error = "
                       "largest |cooked - source| height over the full-detail surface, from the cook report. {}",
                       runs, runs == 1 ? "" : "s", ch::machine_note());
  const ch::Axis tol{"tolerance, m", ch::Scale::log10}, err{"measured max height error, m", ch::Scale::log10};
  const ch::Axis time{"cook wall time, s", ch::Scale::log10}, size{"archive, MB", ch::Scale::log10};
  ch::Panel p[4] = {{"cook time against tolerance", tol, time, {}, {}, {}},
                    {"archive size against tolerance", tol, size, {}, {}, {}},
                    {"cook time against measured error", err, time, {}, {}, {}},
                    {"archive size against measured error", err, size, {}, {}, {}}};
  std::vector<std::string> dems;
  for (const SweepPoint& q : points)
    if (std::find(dems.begin(), dems.end(), q.dem) == dems.end()) dems.push_back(q.dem);
  for (const std::string& dem : dems) {
    ch::Series s[4];
    for (ch::Series& x : s) x.name = dem;
    for (const SweepPoint& q : points) {
      if (q.dem != dem) continue;
      const std::string label = fmt::format("{} m", q.tolerance);
      s[0].points.push_back({q.tolerance, q.wall_s, label});
      s[1].points.push_back({q.tolerance, q.bytes / 1e6, label});
      s[2].points.push_back({q.max_err, q.wall_s, label});
      s[3].points.push_back({q.max_err, q.bytes / 1e6, label});
    }
    for (int k = 0; k < 4; ++k) p[k].series.push_back(s[k]);
  }
  c.panels.assign(std::begin(p), std::end(p));
  return c;
}

// Writes a mode's chart and says where; false (with the reason on stderr) when it cannot.
bool write_chart(const terrain::chart::Chart& c, const std::string& path) {
  if (const std::string e = terrain::chart::write_svg(c, path); !e.empty()) {
    fmt::print(stderr, "terrain-cook-bench: {}\n", e);
    return false;
  }
  fmt::print("Wrote {}\n", path);
  return true;
}

// --rdo: the rate-distortion pass (--bc-rdo) against the plain encoders, per DEM.
struct RdoRow {
  std::string dem;
  double lambda = 0;
  uint64_t nodes = 0, archive = 0, normals = 0, albedo = 0;
  double normal_err_deg = 0, albedo_psnr_db = 0;
  uint64_t alpha_mismatches = 0;
  // CPU ms per node (medians): the whole node, the surface stage, the two BC parts (encoder plus the
  // pass) and zstd of the two sections.
  double ms_total = 0, ms_surface = 0, ms_bc = 0, ms_zstd = 0;
};

int rdo_main(const std::string& tool, const std::vector<Dem>& dems, const std::vector<std::string>& only,
             const std::vector<double>& lambdas, int runs, const std::string& chart_path) {
  const auto scratch = std::filesystem::temp_directory_path() / fmt::format("terrain-cook-bench-rdo-{}", getpid());
  std::filesystem::create_directories(scratch);
  const std::string archive = (scratch / "rdo.terrain").string();
  std::vector<double> all = {0.0};
  all.insert(all.end(), lambdas.begin(), lambdas.end());
  fmt::print("terrain-cook-bench --rdo: default cooks with --bc-rdo 0 (the encoders as they are) and {}; {} run{} per "
             "row, taken in turn (medians of CPU ms per node from the cook report); sizes and errors are deterministic.\n"
             "n+a = stored normal + albedo bytes; err = mean angle of the decoded normals against the float normals; "
             "PSNR of the decoded albedo against the baked one.\n\n",
             fmt::join(lambdas, ", "), runs, runs == 1 ? "" : "s");
  fmt::print("{:<16} {:>6} {:>6} {:>9} {:>9} {:>6} {:>8} {:>7} {:>8} {:>7} {:>8} {:>8} {:>8} {:>8}\n", "dem", "lambda",
             "nodes", "MB", "n+a MB", "x", "err_deg", "+deg", "PSNR_dB", "dB", "ms/node", "surf_ms", "bc_ms", "zstd_ms");
  std::vector<RdoRow> rows;
  for (const Dem& dem : dems) {
    if (!only.empty() && std::find(only.begin(), only.end(), dem.name) == only.end()) continue;
    if (!std::filesystem::exists(dem.file)) {
      fmt::print("{:<16} (missing: {})\n", dem.name, dem.file);
      continue;
    }
    std::vector<RdoRow> r(all.size());
    std::vector<std::vector<double>> total(all.size()), surface(all.size()), bc(all.size()), zstd(all.size());
    bool ok = true;
    for (int k = 0; k < runs && ok; ++k)
      for (size_t l = 0; l < all.size() && ok; ++l) {
        // Every node decoded and measured: the error columns are the point of this table. Stored
        // normals: the pass shapes their blocks (derived normals have none to shape).
        const auto c = cook(tool, dem, {"--bc-rdo", fmt::format("{}", all[l]), "--error-checks", "all", "--normals", "stored"},
                            1, archive);
        if (!c) {
          ok = false;
          break;
        }
        const auto& j = c->report;
        const auto& ms = j["time_s"]["cpu_ms_per_node"];
        total[l].push_back(ms["total"]);
        surface[l].push_back(ms["surface"]);
        bc[l].push_back(ms["normals_bc3"].get<double>() + ms["albedo_bc1"].get<double>());
        zstd[l].push_back(ms["zstd_normals"].get<double>() + ms["zstd_albedo"].get<double>());
        RdoRow& row = r[l];
        row.dem = dem.name;
        row.lambda = all[l];
        row.nodes = c->nodes;
        row.archive = c->bytes;
        row.normals = j["output"]["sections"]["normals"]["stored_bytes"];
        row.albedo = j["output"]["sections"]["albedo"]["stored_bytes"];
        row.normal_err_deg = j["surface"]["normal_err_mean_deg"];
        row.albedo_psnr_db = j["surface"]["albedo_psnr_db"];
        row.alpha_mismatches = j["surface"]["albedo_alpha_mismatches"];
      }
    if (!ok) continue;
    for (size_t l = 0; l < all.size(); ++l) {
      RdoRow& row = r[l];
      row.ms_total = median(total[l]);
      row.ms_surface = median(surface[l]);
      row.ms_bc = median(bc[l]);
      row.ms_zstd = median(zstd[l]);
      const double na = double(row.normals + row.albedo), na0 = double(r[0].normals + r[0].albedo);
      fmt::print("{:<16} {:>6} {:>6} {:>9} {:>9} {:>6.3f} {:>8.3f} {:>7.3f} {:>8.2f} {:>7.2f} {:>8.3f} {:>8.3f} {:>8.3f} {:>8.3f}{}\n",
                 dem.name, row.lambda, row.nodes, mb(double(row.archive)), mb(na), na / na0, row.normal_err_deg,
                 row.normal_err_deg - r[0].normal_err_deg, row.albedo_psnr_db, row.albedo_psnr_db - r[0].albedo_psnr_db,
                 row.ms_total, row.ms_surface, row.ms_bc, row.ms_zstd,
                 row.alpha_mismatches ? fmt::format("  ALPHA MISMATCHES {}", row.alpha_mismatches) : "");
      rows.push_back(row);
    }
  }
  std::filesystem::remove_all(scratch);
  fmt::print("\nTargets (issue 17): n+a at most 0.7x for at most +0.5 degrees and -0.5 dB; every alpha exact.\n");
  const bool alpha_exact = std::all_of(rows.begin(), rows.end(), [](const RdoRow& r) { return r.alpha_mismatches == 0; });
  if (!alpha_exact) fmt::print(stderr, "terrain-cook-bench: hole alpha mismatches (see the table)\n");
  const int rc = alpha_exact ? 0 : 1;
  if (chart_path.empty()) return rc;
  namespace ch = terrain::chart;
  ch::Chart c;
  c.title = "terrain-cook-bench --rdo: normal + albedo bytes against the loss, per DEM and lambda";
  c.note = fmt::format("Default cooks of each DEM with --bc-rdo 0 and {}; bytes = stored normal + albedo sections over "
                       "those of --bc-rdo 0; loss from the cook report (mean normal angle, albedo PSNR). {}",
                       fmt::join(lambdas, ", "), ch::machine_note());
  const ch::Axis ratio{"normal + albedo bytes, x plain", ch::Scale::linear, true};
  const ch::Axis added{"mean normal error added, degrees"}, lost{"albedo PSNR lost, dB"};
  ch::Panel p[2] = {{"bytes against mean normal error added", added, ratio, {}, {}, {}},
                    {"bytes against albedo PSNR lost", lost, ratio, {}, {}, {}}};
  for (ch::Panel& q : p) q.lines.push_back({"target 0.7x", 0.7, true});
  p[0].lines.push_back({"+0.5 deg", 0.5, false});
  p[1].lines.push_back({"0.5 dB", 0.5, false});
  for (size_t i = 0; i < rows.size();) {
    size_t e = i;
    while (e < rows.size() && rows[e].dem == rows[i].dem) ++e;
    ch::Series s[2];
    for (ch::Series& x : s) x.name = rows[i].dem, x.label_points = true;
    const double na0 = double(rows[i].normals + rows[i].albedo);
    for (size_t k = i; k < e; ++k) {
      const double y = double(rows[k].normals + rows[k].albedo) / na0;
      const std::string label = k == i ? "" : fmt::format("{}", rows[k].lambda);
      s[0].points.push_back({rows[k].normal_err_deg - rows[i].normal_err_deg, y, label});
      s[1].points.push_back({rows[i].albedo_psnr_db - rows[k].albedo_psnr_db, y, label});
    }
    p[0].series.push_back(s[0]);
    p[1].series.push_back(s[1]);
    i = e;
  }
  c.panels.assign(std::begin(p), std::end(p));
  return write_chart(c, chart_path) ? rc : 1;
}

// --steps: the height step against bytes and error. Heights-only cooks of each DEM with
// --height-step at each step (and the default, from the tolerance): the heights section per source
// sample and the full-detail error against every source sample (sizes and errors are deterministic:
// one cook each).
struct StepRow {
  std::string dem;
  double step_m = 0;  // 0: the default
  double finest_step_m = 0, bytes_per_sample = 0, rms_m = 0, max_m = 0;
  uint64_t nodes = 0;
};

int steps_main(const std::string& tool, const std::vector<Dem>& dems, const std::vector<std::string>& only,
               const std::vector<double>& steps_mm, const std::string& chart_path) {
  const auto scratch = std::filesystem::temp_directory_path() / fmt::format("terrain-cook-bench-steps-{}", getpid());
  std::filesystem::create_directories(scratch);
  const std::string archive = (scratch / "steps.terrain").string();
  fmt::print("terrain-cook-bench --steps: --heights-only cooks at the default tolerance with --height-step {} mm and "
             "the default step (tolerance / 32); heights = stored height bytes per source sample; error = the "
             "full-detail error against every source sample (the cook report's).\n\n",
             fmt::join(steps_mm, ", "));
  fmt::print("{:<16} {:>9} {:>9} {:>7} {:>10} {:>7} {:>9} {:>8}\n", "dem", "step_mm", "finest_mm", "nodes", "heights_B",
             "x", "rms_mm", "max_m");
  std::vector<StepRow> rows;
  for (const Dem& dem : dems) {
    if (!only.empty() && std::find(only.begin(), only.end(), dem.name) == only.end()) continue;
    if (!std::filesystem::exists(dem.file)) {
      fmt::print("{:<16} (missing: {})\n", dem.name, dem.file);
      continue;
    }
    std::vector<double> all = {0.0};
    for (double mm : steps_mm) all.push_back(mm / 1000.0);
    std::vector<StepRow> r;
    for (double step : all) {
      std::vector<std::string> flags = {"--heights-only"};
      if (step > 0) flags.insert(flags.end(), {"--height-step", fmt::format("{}", step)});
      const auto c = cook(tool, dem, flags, 1, archive);
      if (!c) break;
      const auto& j = c->report;
      StepRow row;
      row.dem = dem.name;
      row.step_m = step;
      row.nodes = c->nodes;
      const double samples = j["source"]["valid_samples"].get<double>();
      row.bytes_per_sample = j["output"]["sections"]["heights"]["stored_bytes"].get<double>() / samples;
      row.rms_m = j["full_detail_error"]["rms_m"];
      row.max_m = j["full_detail_error"]["max_m"];
      row.finest_step_m = 1e9;
      for (const auto& l : j["levels"])
        if (l["nodes"].get<uint64_t>() > 0) row.finest_step_m = std::min(row.finest_step_m, l["step_m"].get<double>());
      r.push_back(row);
    }
    if (r.empty()) continue;
    for (const StepRow& row : r) {
      fmt::print("{:<16} {:>9} {:>9.3f} {:>7} {:>10.4f} {:>7.3f} {:>9.3f} {:>8.4f}\n", row.dem,
                 row.step_m > 0 ? fmt::format("{:.3f}", row.step_m * 1000) : "default", row.finest_step_m * 1000,
                 row.nodes, row.bytes_per_sample, row.bytes_per_sample / r[0].bytes_per_sample, row.rms_m * 1000,
                 row.max_m);
      rows.push_back(row);
    }
  }
  std::filesystem::remove_all(scratch);
  if (chart_path.empty()) return 0;
  namespace ch = terrain::chart;
  ch::Chart c;
  c.title = "terrain-cook-bench --steps: height bytes and full-detail error against the height step, per DEM";
  c.note = fmt::format("--heights-only cooks at the default tolerance (0.5 m) with --height-step {} mm; the "
                       "default step is tolerance / 32 = 15.6 mm. {}",
                       fmt::join(steps_mm, ", "), ch::machine_note());
  const ch::Axis step_axis{"finest height step, mm", ch::Scale::log10, false};
  const ch::Axis bytes{"height bytes per source sample", ch::Scale::linear, true};
  const ch::Axis rms{"full-detail RMS error, mm", ch::Scale::log10, false};
  ch::Panel p[2] = {{"height bytes against the step", step_axis, bytes, {}, {}, {}},
                    {"full-detail RMS error against the step", step_axis, rms, {}, {}, {}}};
  for (size_t i = 0; i < rows.size();) {
    size_t e = i;
    while (e < rows.size() && rows[e].dem == rows[i].dem) ++e;
    ch::Series s[2];
    for (ch::Series& x : s) x.name = rows[i].dem;
    for (size_t k = i + 1; k < e; ++k) {  // the explicit steps (the default repeats one of them)
      s[0].points.push_back({rows[k].finest_step_m * 1000, rows[k].bytes_per_sample, ""});
      s[1].points.push_back({rows[k].finest_step_m * 1000, rows[k].rms_m * 1000, ""});
    }
    p[0].series.push_back(s[0]);
    p[1].series.push_back(s[1]);
    i = e;
  }
  c.panels.assign(std::begin(p), std::end(p));
  return write_chart(c, chart_path) ? 0 : 1;
}

// --worlds: cooks of worlds made of several sources against the sources cooked apart (issue 51's
// table). (a) the shared 1 m lidar tile inside a 30 m DEM made from it (make_lidar_in_coarse.py: its
// mirrored copies averaged over 30 m blocks, +3 m), in both orders; (c) the shared SRTM tiles at the
// default tolerance and at --tolerance 50. One thread per cook, CPU = the child's user + system time,
// medians of `runs` rounds taken in turn.
struct WorldCook {
  std::string name;
  std::vector<std::string> argv;  // inputs and flags after the tool
  std::vector<double> cpu;
  uint64_t nodes = 0, bytes = 0, valid_samples = 0;
  double rms_m = 0, max_m = 0, tolerance_m = 0;
  std::vector<std::pair<uint64_t, uint64_t>> samples;  // per input (in the order of precedence): read, used
  std::vector<std::string> paths;                      // the same inputs' paths
  std::string archive;
};

bool world_cook_once(const std::string& tool, WorldCook& c) {
  std::vector<std::string> argv = {tool};
  argv.insert(argv.end(), c.argv.begin(), c.argv.end());
  argv.insert(argv.end(), {"-o", c.archive, "--json", "--threads", "1"});
  const Run r = run(argv);
  if (!r.ok) {
    fmt::print(stderr, "terrain-cook-bench --worlds: terrain-cook failed: {}\n", fmt::join(c.argv, " "));
    return false;
  }
  const auto j = nlohmann::json::parse(r.out);
  c.cpu.push_back(r.cpu_s);
  c.nodes = j["output"]["nodes"];
  c.bytes = j["output"]["archive_bytes"];
  c.valid_samples = j["source"]["valid_samples"];
  c.rms_m = j["full_detail_error"]["rms_m"];
  c.max_m = j["full_detail_error"]["max_m"];
  c.tolerance_m = j["tolerance_m"];
  c.samples.clear();
  c.paths.clear();
  for (const auto& in : j["input_samples"]) {
    c.samples.emplace_back(in["samples_read"], in["samples_used"]);
    c.paths.push_back(in["path"]);
  }
  return true;
}

int worlds_main(const std::string& tool, const std::string& data, const std::string& python, const std::string& work,
                int runs) {
  const std::string lidar = data + "/slovenia_TM1_564_146.tif";
  if (!std::filesystem::exists(lidar)) {
    fmt::print("terrain-cook-bench --worlds: skipped: the shared lidar tile {} is not there (--data)\n", lidar);
    return 0;
  }
  std::filesystem::create_directories(work);
  const std::string coarse = work + "/coarse.tif";
  if (!std::filesystem::exists(coarse)) {
    const Run g = run({python, script_path("make_lidar_in_coarse.py"), "--lidar", lidar, "--out-dir", work});
    if (!g.ok) {
      fmt::print(stderr, "terrain-cook-bench --worlds: make_lidar_in_coarse.py failed\n");
      return 1;
    }
    fmt::print("{}", g.out);
  }
  std::vector<WorldCook> cooks = {
      {"lidar 1 m alone", {lidar}},
      {"30 m DEM alone", {coarse}},
      {"lidar, then 30 m", {lidar, coarse}},
      {"30 m, then lidar", {coarse, lidar}},
      // The earlier rule of precedence, the first listed (no seam blend; the grid families' rules stay).
      {"lidar, then 30 m, list", {lidar, coarse, "--overlap", "list"}},
      {"30 m, then lidar, list", {coarse, lidar, "--overlap", "list"}},
  };
  const char* srtm[] = {"N22W160.hgt.zip", "N19W155.hgt.zip", "S46W066.hgt.gz"};
  for (const char* f : srtm) {
    const std::string path = data + "/" + f;
    if (!std::filesystem::exists(path)) continue;
    cooks.push_back({fmt::format("{} default", f), {path}});
    cooks.push_back({fmt::format("{} --tolerance 50", f), {path, "--tolerance", "50"}});
  }
  for (size_t i = 0; i < cooks.size(); ++i) cooks[i].archive = fmt::format("{}/world-{}.terrain", work, i);
  for (int round = 0; round < runs; ++round)
    for (WorldCook& c : cooks)
      if (!world_cook_once(tool, c)) return 1;
  const auto cpu = [](const WorldCook& c) { return median(c.cpu); };
  fmt::print("\nterrain-cook-bench --worlds: one thread per cook, CPU = user + system s of the process (median of {} "
             "rounds taken in turn); samples used = per input, the mosaic samples it gave the archive.\n\n",
             runs);
  fmt::print("{:<30} {:>7} {:>8} {:>9} {:>10} {:>9} {:>9}  {}\n", "cook", "tol_m", "nodes", "MB", "CPU_s",
             "ns/sample", "rms_mm", "samples used per input");
  for (const WorldCook& c : cooks) {
    std::string used;
    for (const auto& [read, u] : c.samples) used += fmt::format("{}{} of {}", used.empty() ? "" : "; ", u, read);
    fmt::print("{:<30} {:>7.3g} {:>8} {:>9.2f} {:>10.2f} {:>9.0f} {:>9.1f}  {}\n", c.name, c.tolerance_m, c.nodes,
               double(c.bytes) / 1e6, cpu(c), 1e9 * cpu(c) / double(std::max<uint64_t>(c.valid_samples, 1)),
               c.rms_m * 1000, used);
  }
  const WorldCook &l = cooks[0], &d = cooks[1];
  const double apart_cpu = cpu(l) + cpu(d), apart_nodes = double(l.nodes + d.nodes);
  fmt::print("\n(a) lidar inside a 30 m DEM, against the two cooked apart ({:.2f} CPU s, {} nodes); target at most "
             "1.3x the CPU and 1.2x the nodes in either order:\n",
             apart_cpu, l.nodes + d.nodes);
  for (size_t i : {size_t(2), size_t(3), size_t(4), size_t(5)}) {
    const WorldCook& c = cooks[i];
    const double xc = cpu(c) / apart_cpu, xn = double(c.nodes) / apart_nodes;
    // The lidar must hold its area: all but 1 % of its samples on the mosaic's grid are used.
    const size_t li = size_t(std::find(c.paths.begin(), c.paths.end(), lidar) - c.paths.begin());
    if (li >= c.samples.size()) continue;
    const auto& lidar_samples = c.samples[li];
    const bool lidar_used = lidar_samples.second >= lidar_samples.first - lidar_samples.first / 100;
    fmt::print("  {:<24} CPU {:.2f}x, nodes {:.2f}x, lidar samples used {} of {}: {}\n", c.name, xc, xn,
               lidar_samples.second, lidar_samples.first, xc <= 1.3 && xn <= 1.2 && lidar_used ? "met" : "NOT met");
  }
  fmt::print("  both orders give the same archive: {} (default); {} (--overlap list)\n",
             same_bytes(cooks[2].archive, cooks[3].archive) ? "yes" : "NO",
             same_bytes(cooks[4].archive, cooks[5].archive) ? "yes" : "NO");
  for (const WorldCook& c : cooks) std::filesystem::remove(c.archive);
  return 0;
}

// --against BIN: the same default cooks with another terrain-cook (the previous commit's build) and
// this one, in turn; per DEM the nodes per level, the CPU per node and per source sample of every
// stage and part from the two cook reports, bytes per source sample per section, the error figures,
// and whether the archives are identical.
struct AgainstCook {
  nlohmann::json report;
  std::string bytes;  // the archive
};

std::optional<AgainstCook> against_cook(const std::string& tool, const Dem& dem, const std::vector<std::string>& flags,
                                        const std::string& out) {
  std::vector<std::string> argv = {tool, dem.file, "-o", out, "--json"};
  argv.insert(argv.end(), dem.flags.begin(), dem.flags.end());
  argv.insert(argv.end(), flags.begin(), flags.end());
  const Run r = run(argv);
  if (!r.ok) return std::nullopt;
  AgainstCook c;
  try {
    c.report = nlohmann::json::parse(r.out);
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;
  }
  std::ifstream f(out, std::ios::binary);
  c.bytes.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  return c;
}

int against_main(const std::string& before, const std::string& tool, const std::vector<Dem>& dems,
                 const std::vector<std::string>& only, const std::vector<std::string>& flags, int runs) {
  const auto scratch = std::filesystem::temp_directory_path() / fmt::format("terrain-cook-bench-against-{}", getpid());
  std::filesystem::create_directories(scratch);
  const std::string archive = (scratch / "against.terrain").string();
  fmt::print("terrain-cook-bench --against: default cooks{} with\n  before: {}\n  after:  {}\ntaken in turn, {} run{} "
             "each; CPU ms per node from the cook reports (medians), bytes and errors from the last run.\n",
             flags.empty() ? "" : fmt::format(" ({})", fmt::join(flags, " ")), before, tool, runs, runs == 1 ? "" : "s");
  struct Summary {
    std::string dem;
    uint64_t nodes = 0;
    double before_ms = 0, after_ms = 0;
    double surface_ratio = 0, archive_ratio = 0;  // after / before: normals + albedo bytes, the file
    bool same = false;
  };
  std::vector<Summary> summary;
  int rc = 0;
  for (const Dem& dem : dems) {
    if (!only.empty() && std::find(only.begin(), only.end(), dem.name) == only.end()) continue;
    if (!std::filesystem::exists(dem.file)) {
      fmt::print("\n{} (missing: {})\n", dem.name, dem.file);
      continue;
    }
    std::map<std::string, std::vector<double>> ms[2];  // stage -> per-run CPU ms per node
    std::optional<AgainstCook> last[2];
    for (int k = 0; k < runs; ++k)
      for (int side = 0; side < 2; ++side) {
        auto c = against_cook(side ? tool : before, dem, flags, archive);
        if (!c) {
          fmt::print(stderr, "terrain-cook-bench: {} failed on {}\n", side ? tool : before, dem.file);
          rc = 1;
          break;
        }
        for (const auto& [stage, v] : c->report["time_s"]["cpu_ms_per_node"].items())
          if (v.is_number()) ms[side][stage].push_back(v.get<double>());
        last[side] = std::move(c);
      }
    if (!last[0] || !last[1]) continue;
    const nlohmann::json& rb = last[0]->report;
    const nlohmann::json& ra = last[1]->report;
    const bool same = last[0]->bytes == last[1]->bytes;
    const uint64_t nodes = ra["output"]["nodes"].get<uint64_t>();
    fmt::print("\n{}: {} nodes, archive {:.2f} MB, {}\n", dem.name, nodes, double(last[1]->bytes.size()) / 1e6,
               same ? "identical bytes" : fmt::format("DIFFERENT bytes (before {:.2f} MB)", double(last[0]->bytes.size()) / 1e6));
    // Nodes per level (finest first) and CPU per valid source sample: a stage's ms per node times
    // each side's own node count, over the samples (dropping nodes lowers it where ms/node cannot).
    auto level_nodes = [](const nlohmann::json& r) {
      std::vector<uint64_t> n;
      for (const auto& l : r["levels"]) n.push_back(l["nodes"].get<uint64_t>());
      return fmt::format("{}", fmt::join(n, " "));
    };
    fmt::print("  nodes per level 0..5: before {}; after {}\n", level_nodes(rb), level_nodes(ra));
    const double ns_b = 1e6 * rb["output"]["nodes"].get<double>() / rb["source"]["valid_samples"].get<double>();
    const double ns_a = 1e6 * double(nodes) / ra["source"]["valid_samples"].get<double>();
    fmt::print("  {:<16} {:>9} {:>9} {:>8} {:>10} {:>10} {:>8}\n", "CPU per stage", "ms/node b", "ms/node a", "after/b",
               "ns/smp b", "ns/smp a", "after/b");
    for (const auto& [stage, values] : ms[1]) {
      const double a = median(values);
      const double b = ms[0].count(stage) ? median(ms[0].at(stage)) : NAN;
      if (!(a > 0.0005) && !(b > 0.0005)) continue;  // stages this cook does not have
      fmt::print("  {:<16} {:>9.3f} {:>9.3f} {:>8.2f} {:>10.1f} {:>10.1f} {:>8.2f}\n", stage, b, a, a / b, b * ns_b,
                 a * ns_a, (a * ns_a) / (b * ns_b));
    }
    // Stored bytes per valid source sample, per section and for normals + albedo together (the
    // sections the rate-distortion pass works on), each side over its own report.
    auto per_sample = [](const nlohmann::json& r, const std::string& section) {
      const nlohmann::json& sections = r["output"]["sections"];
      const double samples = r["source"]["valid_samples"].get<double>();
      if (section == "normals+albedo")
        return sections.contains("normals") && sections.contains("albedo")
                   ? (sections["normals"]["stored_bytes"].get<double>() + sections["albedo"]["stored_bytes"].get<double>()) / samples
                   : NAN;
      return sections.contains(section) ? sections[section]["stored_bytes"].get<double>() / samples : NAN;
    };
    fmt::print("  {:<16} {:>9} {:>9} {:>8}\n", "bytes/sample", "before", "after", "after/b");
    std::vector<std::string> sections;
    for (const auto& [section, v] : ra["output"]["sections"].items()) sections.push_back(section);
    sections.push_back("normals+albedo");
    for (const std::string& section : sections) {
      const double b = per_sample(rb, section), a = per_sample(ra, section);
      fmt::print("  {:<16} {:>9.3f} {:>9.3f} {:>8.2f}\n", section, b, a, a / b);
    }
    auto errors = [](const nlohmann::json& r) {
      std::string e = fmt::format("height max {:.3f} m rms {:.4f} m", r["full_detail_error"]["max_m"].get<double>(),
                                  r["full_detail_error"]["rms_m"].get<double>());
      if (r.contains("surface")) {
        const nlohmann::json& s = r["surface"];
        e += fmt::format("; normals mean {:.4f} deg; albedo {:.3f} dB", s["normal_err_mean_deg"].get<double>(),
                         s["albedo_psnr_db"].get<double>());
        if (s.contains("checked_nodes"))
          e += fmt::format(" ({} of {} nodes measured)", s["checked_nodes"].get<uint64_t>(), s["nodes"].get<uint64_t>());
      }
      return e;
    };
    fmt::print("  errors before: {}\n  errors after:  {}\n", errors(rb), errors(ra));
    summary.push_back({dem.name, nodes, median(ms[0]["total"]), median(ms[1]["total"]),
                       per_sample(ra, "normals+albedo") / per_sample(rb, "normals+albedo"),
                       double(last[1]->bytes.size()) / double(last[0]->bytes.size()), same});
  }
  std::filesystem::remove_all(scratch);
  fmt::print("\n{:<16} {:>7} {:>10} {:>10} {:>8} {:>8} {:>8} {}\n", "dem", "nodes", "before ms", "after ms", "after/b",
             "n+a a/b", "file a/b", "bytes");
  for (const Summary& r : summary)
    fmt::print("{:<16} {:>7} {:>10.3f} {:>10.3f} {:>8.2f} {:>8.3f} {:>8.3f} {}\n", r.dem, r.nodes, r.before_ms, r.after_ms,
               r.after_ms / r.before_ms, r.surface_ratio, r.archive_ratio, r.same ? "identical" : "different");
  return rc;
}

}  // namespace

int main(int argc, char** argv) {
  std::string data = terrain::bench_data_dir();
  std::vector<double> tolerances = {0.25, 0.5, 1.0, 2.0, 4.0};
  std::vector<std::string> only;
  int runs = 3;
  bool skip_default = false;
  bool scale = false;
  ScaleOptions so;
  so.sizes = {4, 8, 16, 40};
  so.baseline_sizes = {8};
  so.python = "/usr/bin/python3";
  CLI::App app{"terrain-cook-bench: tolerance sweep over the shared DEMs against gdalwarp -r cubic"};
  app.add_option("--data", data, "Folder of the shared DEMs")->capture_default_str();
  app.add_option("--tolerances", tolerances, "Tolerances to sweep (metres)")->delimiter(',');
  app.add_option("--dems", only, "Only these DEMs (names as printed)")->delimiter(',');
  app.add_option("--runs", runs, "Runs per measurement (median; default 3, --scale 1)")->check(CLI::Range(1, 100));
  app.add_flag("--skip-default", skip_default, "Skip the default cooks with every section");
  std::string chart;
  app.add_option("--chart", chart,
                 "Also write an SVG chart: the sweep's cook time and archive size against tolerance and measured "
                 "error per DEM (with --scale: the scale chart)");
  app.add_flag("--scale", scale,
               "Instead of the sweep: cook squares of --sizes km mirrored from a real lidar tile (--lidar), peak "
               "memory, throughput, nodes per km2 and archive bytes per source sample per size, beside the tile "
               "cooked alone");
  app.add_option("--sizes", so.sizes, "--scale: square sides in km")->delimiter(',')->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--baseline-sizes", so.baseline_sizes,
                 "--scale: sizes (of --sizes) also cooked in-core, one block with a large --memory-limit (0: none)")
      ->delimiter(',')
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  app.add_flag("--heights-only", so.heights_only, "--scale, --units: cook with --heights-only");
  app.add_option("--tile-km", so.tile_km,
                 "--scale, --units: generate each square as a VRT of K x K km GeoTIFF tiles, as national lidar comes "
                 "(default 0: one tiled GeoTIFF)")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--work", so.work,
                 "--scale, --units, --worlds: folder for the generated DEMs and the table (default: bench-scale, bench-worlds in the build tree)");
  std::string lidar = "slovenia";
  app.add_option("--lidar", lidar,
                 "--scale, --units: the real tile the squares are mirrored from: slovenia (1 m, EPSG:3794), tahoe_bare "
                 "or tahoe_highest (0.47 x 0.61 m EPSG:4326, warped to UTM at 0.5 m first); lidar_like: the old "
                 "squares of make_lidar_like.py (Kilauea 30 m upsampled plus value noise, far smoother than lidar)")
      ->check(CLI::IsMember({"slovenia", "tahoe_bare", "tahoe_highest", "lidar_like"}))
      ->capture_default_str();
  std::string source;
  app.add_option("--source", source,
                 "--scale, --units: mirror this real DEM tile instead of --lidar's (a geographic one is warped to UTM "
                 "first)");
  app.add_option("--python", so.python, "--scale, --units, --worlds: Python with GDAL and numpy")->capture_default_str();
  bool units = false;
  uint32_t unit_roots = 0;
  std::string units_dem;
  app.add_flag("--units", units,
               "Instead of the sweep: plan + units (1 and 2 worker processes) + merge against the one-process cook "
               "of the --units-km square of --scale (made when missing) or --units-dem, merge MB/s next to cp, a "
               "16-machine makespan, nodes per km2 and bytes per source sample beside the real tile's; --runs rounds "
               "(default 3), medians of the per-round ratios");
  int units_km = 8;
  app.add_option("--units-km", units_km, "--units: side of the square to cook, km")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--units-dem", units_dem, "--units: cook this DEM instead of the --units-km square");
  app.add_option("--unit-roots", unit_roots, "--units: units of N x N roots (0: the plan's default size)")->capture_default_str();
  std::vector<double> rdo_lambdas;
  std::vector<std::string> rdo_extra;
  app.add_option("--rdo", rdo_lambdas,
                 "Instead of the sweep: cooks of each DEM with --normals stored and --bc-rdo 0 and each of these lambdas, in turn "
                 "(--runs, default 3): normal + albedo bytes, mean normal error, albedo PSNR, CPU ms per node (--chart: "
                 "bytes against loss)")
      ->delimiter(',')
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--rdo-dems", rdo_extra,
                 "--rdo, --steps and --against: more DEM files to cook (e.g. the squares --scale made in its --work folder)")
      ->delimiter(',');
  std::vector<double> step_mms;
  app.add_option("--steps", step_mms,
                 "Instead of the sweep: --heights-only cooks of each DEM with --height-step at each of these steps "
                 "(mm) and the default: height bytes per source sample and the full-detail error (--chart: both "
                 "against the step)")
      ->delimiter(',')
      ->check(CLI::Range(0.9, 16000.0));
  std::string against;
  std::vector<std::string> against_flags;
  app.add_option("--against", against,
                 "Instead of the sweep: default cooks of each DEM with this other terrain-cook (e.g. the previous "
                 "commit's build) and ours, in turn (--runs, default 3): CPU ms per node of every stage, bytes per "
                 "source sample per section, the errors, identical archives or not");
  app.add_option("--against-flags", against_flags, "--against: cook flags for both sides, e.g. --tolerance,0.05")
      ->delimiter(',');
  bool worlds = false;
  app.add_flag("--worlds", worlds,
               "Instead of the sweep: worlds of several sources against the sources cooked apart: the shared 1 m "
               "lidar tile inside a 30 m DEM made from it (make_lidar_in_coarse.py, in the --work folder), in both "
               "orders, and the shared SRTM tiles at the default tolerance and at --tolerance 50 (--runs rounds, "
               "default 3)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return e.get_exit_code() == 0 ? 0 : 2;  // usage error: exit 2, like terrain-cook
  }

  const std::filesystem::path self = std::filesystem::canonical("/proc/self/exe").parent_path();
  const std::string tool = (self / "terrain-cook").string();
  if (!std::filesystem::exists(tool)) {
    fmt::print(stderr, "terrain-cook-bench: {} not found (build the terrain-cook target)\n", tool);
    return 1;
  }
  if (worlds) {
    const std::string work = so.work.empty() ? (self.parent_path() / "bench-worlds").string() : so.work;
    return worlds_main(tool, std::filesystem::path(data).lexically_normal().string(), so.python, work, runs);
  }
  if (units || scale) {
    so.data = std::filesystem::path(data).lexically_normal().string();
    so.lidar = *lidar_choice(lidar, so.data);
    if (!source.empty()) so.lidar = Lidar{std::filesystem::path(source).stem().string(), source, "", false};
    if (so.work.empty()) so.work = (self.parent_path() / "bench-scale").string();  // the build tree, never the repo
    if (source.empty() && !std::filesystem::exists(so.lidar.file)) {  // the shared data is not there: skip
      fmt::print("terrain-cook-bench: skipped: the shared lidar tile {} is not there (--data)\n", so.lidar.file);
      return 0;
    }
    const auto ref = prepare_reference(tool, so);
    if (!ref) return 1;
    if (scale) {
      so.runs = app.count("--runs") ? runs : 1;
      so.chart = chart;
      return scale_main(tool, so, *ref);
    }
    std::string dem = units_dem;
    if (dem.empty()) {
      dem = dem_path(so, units_km);
      double gen_s = 0;
      const uint64_t side = uint64_t(std::llround(units_km * 1000.0 / (so.lidar.lidar_like ? 1.0 : ref->spacing_m)));
      if (const std::string why = ensure_dem(so, dem, side * side, units_km, gen_s); !why.empty()) {
        fmt::print(stderr, "terrain-cook-bench --units: {}\n", why);
        return 1;
      }
    }
    return units_main(tool, dem, unit_roots, so, *ref, app.count("--runs") ? runs : 3, so.work + "/units");
  }
  const std::string d = data + "/";
  std::vector<Dem> dems = {
      {"tahoe_bare", d + "tahoe_lidar_bareearth.tif", {}, d + "tahoe_lidar_bareearth.tif"},
      {"tahoe_highest", d + "tahoe_lidar_highesthit.tif", {}, d + "tahoe_lidar_highesthit.tif"},
      {"slovenia", d + "slovenia_TM1_564_146.tif", {}, d + "slovenia_TM1_564_146.tif"},
      {"kilauea", d + "kilauea_utm5n.tif", {}, d + "kilauea_utm5n.tif"},
      {"oetztal", d + "srtm_oetztal.tif", {}, d + "srtm_oetztal.tif"},
      {"n22w160", d + "N22W160.hgt.zip", {}, "/vsizip/" + d + "N22W160.hgt.zip/N22W160.hgt"},
      {"n19w155", d + "N19W155.hgt.zip", {}, "/vsizip/" + d + "N19W155.hgt.zip/N19W155.hgt"},
      {"s46w066", d + "S46W066.hgt.gz", {}, "/vsigzip/" + d + "S46W066.hgt.gz"},
      {"puget", d + "ps_height_1k.png", {"--spacing", "160", "--height-scale", "0.1", "--crs", "local"},
       d + "ps_height_1k.png"},
      {"jacksboro", "/usr/share/matplotlib/mpl-data/sample_data/jacksboro_fault_dem.npz", {"--crs", "EPSG:4326"}, ""},
  };
  if (!against.empty() || !rdo_lambdas.empty() || !step_mms.empty()) {
    // The --rdo-dems files join the shared DEMs (and the --dems filter, when one is given).
    std::vector<std::string> names = only;
    for (const std::string& f : rdo_extra) {
      const std::string name = std::filesystem::path(f).stem().string();
      dems.push_back({name, f, {}, ""});
      if (!only.empty()) names.push_back(name);
    }
    if (!step_mms.empty()) return steps_main(tool, dems, names, step_mms, chart);
    return !against.empty() ? against_main(against, tool, dems, names, against_flags, runs)
                            : rdo_main(tool, dems, names, rdo_lambdas, runs, chart);
  }
  const auto scratch = std::filesystem::temp_directory_path() / fmt::format("terrain-cook-bench-{}", getpid());
  std::filesystem::create_directories(scratch);
  const std::string archive = (scratch / "bench.terrain").string(), warped = (scratch / "gdal.tif").string();
  char host[256] = {};
  gethostname(host, sizeof host - 1);
  fmt::print("terrain-cook-bench: {} runs per row (median), {} threads, host {}\n", runs,
             std::max(1u, std::thread::hardware_concurrency()), host);
  fmt::print("Sweep: --heights-only, default finest level (spacing >= 1/32 of the source's); height stage = output "
             "vertices per CPU-second of the height stage (thread CPU time, summed over threads);\n"
             "baseline: gdalwarp -r cubic (defaults: one warp thread; gdal_s = its CPU seconds, user + system) of the same source onto the archive frame over the data "
             "footprint at the finest cooked spacing (doubled until <= 60 M samples; gdal_translate for the image).\n\n");
  fmt::print("{:<14} {:>6} {:>6} {:>9} {:>7} {:>8} {:>8} {:>6} {:>10} | {:>8} {:>11} {:>7} {:>10} {:>7}\n", "dem",
             "tol_m", "nodes", "MB", "cook_s", "max_m", "rms_m", "finest", "hgt_MS/cs", "spacing", "gdal_samp",
             "gdal_s", "gdal_MS/cs", "peakMB");
  std::vector<std::string> tsv;
  std::vector<SweepPoint> sweep;
  std::map<std::pair<std::string, double>, Baseline> baselines;
  for (const Dem& dem : dems) {
    if (!only.empty() && std::find(only.begin(), only.end(), dem.name) == only.end()) continue;
    if (!std::filesystem::exists(dem.file)) {
      fmt::print("{:<14} (missing: {})\n", dem.name, dem.file);
      continue;
    }
    for (double tol : tolerances) {
      const auto s = cook(tool, dem,
                          {"--heights-only", "--tolerance", fmt::format("{}", tol)}, runs, archive);
      if (!s) continue;
      const double spacing = 0.5 * std::ldexp(1.0, s->finest_present);
      auto key = std::make_pair(dem.name, spacing);
      if (!baselines.count(key)) baselines[key] = gdal_baseline(dem, s->report, spacing, runs, warped);
      const Baseline& b = baselines[key];
      const double ours = s->cpu_heights > 0 ? double(s->output_vertices) / s->cpu_heights / 1e6 : NAN;
      const double theirs = b.samples && std::isfinite(b.seconds) ? double(b.samples) / b.seconds / 1e6 : NAN;
      fmt::print("{:<14} {:>6} {:>6} {:>9} {:>7.2f} {:>8.3f} {:>8.4f} {:>6} {:>10.1f} | {:>8} {:>11} {:>7.2f} {:>10.1f} {:>7.0f}\n",
                 dem.name, tol, s->nodes, mb(double(s->bytes)), s->wall_s, s->max_err, s->rms_err, s->finest_present,
                 ours, b.spacing, b.samples, b.seconds, theirs, s->rss_mb);
      tsv.push_back(fmt::format("sweep\t{}\t{}\t{}\t{}\t{:.3f}\t{:.4f}\t{:.5f}\t{}\t{:.2f}\t{}\t{}\t{:.3f}\t{:.2f}\t{:.0f}",
                                dem.name, tol, s->nodes, s->bytes, s->wall_s, s->max_err, s->rms_err,
                                s->finest_present, ours, b.spacing, b.samples, b.seconds, theirs, s->rss_mb));
      sweep.push_back({dem.name, tol, s->wall_s, double(s->bytes), s->max_err, s->rms_err});
    }
  }
  if (!skip_default) {
    fmt::print("\nDefault cooks (every section, default tolerance and finest level):\n");
    fmt::print("{:<14} {:>6} {:>9} {:>7} {:>8} {:>8} {:>6} {:>10} {:>7}\n", "dem", "nodes", "MB", "cook_s", "max_m",
               "rms_m", "finest", "hgt_MS/cs", "peakMB");
    for (const Dem& dem : dems) {
      if (!only.empty() && std::find(only.begin(), only.end(), dem.name) == only.end()) continue;
      if (!std::filesystem::exists(dem.file)) continue;
      const auto s = cook(tool, dem, {}, runs, archive);
      if (!s) continue;
      const double ours = s->cpu_heights > 0 ? double(s->output_vertices) / s->cpu_heights / 1e6 : NAN;
      fmt::print("{:<14} {:>6} {:>9} {:>7.2f} {:>8.3f} {:>8.4f} {:>6} {:>10.1f} {:>7.0f}\n", dem.name, s->nodes,
                 mb(double(s->bytes)), s->wall_s, s->max_err, s->rms_err, s->finest_present, ours, s->rss_mb);
      tsv.push_back(fmt::format("default\t{}\t{}\t{}\t{:.3f}\t{:.4f}\t{:.5f}\t{}\t{:.2f}\t{:.0f}", dem.name, s->nodes,
                                s->bytes, s->wall_s, s->max_err, s->rms_err, s->finest_present, ours, s->rss_mb));
    }
  }
  fmt::print("\n# TSV (sweep: dem tol nodes bytes cook_s max_m rms_m finest hgt_MS_per_cpu_s spacing gdal_samples gdal_s "
             "gdal_MS_per_cpu_s peak_MB; default: dem nodes bytes cook_s max_m rms_m finest hgt_MS_per_cpu_s peak_MB)\n");
  for (const std::string& line : tsv) fmt::print("{}\n", line);
  std::filesystem::remove_all(scratch);
  if (!chart.empty()) {
    if (const std::string e = terrain::chart::write_svg(sweep_chart(sweep, runs), chart); !e.empty()) {
      fmt::print(stderr, "terrain-cook-bench: {}\n", e);
      return 1;
    }
    fmt::print("\nWrote {}\n", chart);
  }
  return 0;
}
