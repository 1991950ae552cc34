// terrain-cook-bench: sweeps --tolerance over the real DEMs of the data directory (TERRAIN_DATA_DIR) and prints, per
// setting, nodes, bytes, cook time, max/RMS height error and the height stage's output samples per
// CPU-second, next to what `gdalwarp -r cubic` (the baseline a user would otherwise run, measured
// in the same run) takes to resample the same source to the finest cooked spacing; then the
// default cook of each DEM with every section and its peak memory. Medians of --runs runs.
//
// Each cook runs terrain-cook (next to this program) as a child process, so peak memory is the
// child's own (wait4 ru_maxrss) and the numbers are those a user sees.
//
// --scale: cooks 1 m lidar-like squares of --sizes km (made by make_lidar_like.py from a real DEM)
// and prints peak memory, time and throughput per size: the issue-13 baseline (bounded-memory cook).
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

// Today's cooker holds the whole source raster (and per-sample working grids) in memory, so its
// peak grows with the source. Refuse a size whose estimate exceeds what the machine has, instead of
// swapping it: the estimate is the larger of this figure and the bytes per sample measured on the
// sizes already cooked in this run.
constexpr double kAssumedBytesPerSourceSample = 17.0;
constexpr double kUsableMemoryFraction = 0.8;  // of MemAvailable: others share the machine
constexpr double kGeneratedBytesPerSample = 4.5;  // disk for one generated DEM (ZSTD float32 + margin)

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

struct ScaleRow {
  int km = 0;
  uint64_t samples = 0;
  std::string status = "ok";  // or why the size was skipped / failed
  double gen_s = NAN, wall_s = NAN, cpu_s = NAN, rss_bytes = NAN;
  uint64_t nodes = 0, archive_bytes = 0;
  double bytes_per_sample() const { return rss_bytes / double(samples); }
  double samples_per_cpu_s() const { return double(samples) / cpu_s; }
};

double gb(double bytes) { return bytes / double(1ull << 30); }

int scale_main(const std::string& tool, const std::filesystem::path& self, std::vector<int> sizes, bool heights_only,
               std::string work, const std::string& source, const std::string& python, std::string script) {
  if (work.empty()) work = (self.parent_path() / "bench-scale").string();  // the build tree, never the repo
  if (script.empty()) script = std::string(TERRAIN_BENCH_DIR) + "/make_lidar_like.py";
  std::error_code ec;
  std::filesystem::create_directories(work, ec);
  if (ec) {
    fmt::print(stderr, "terrain-cook-bench: cannot create --work {}: {}\n", work, ec.message());
    return 1;
  }
  if (!std::filesystem::exists(source)) {
    fmt::print(stderr, "terrain-cook-bench: source DEM {} not found (--source, or --data)\n", source);
    return 1;
  }
  const std::string mode = heights_only ? "heights-only" : "full";
  fmt::print("terrain-cook-bench --scale: {} cooks (default flags{}) of 1 m lidar-like squares from {}, work {}\n",
             mode, heights_only ? " + --heights-only" : "", source, work);
  fmt::print("Limit today: the cooker holds the source in memory; a size is skipped when its estimated peak "
             "(max({} B/sample, measured so far) x samples) exceeds {:.0f}% of MemAvailable.\n\n",
             kAssumedBytesPerSourceSample, 100 * kUsableMemoryFraction);
  fmt::print("{:>5} {:>13} {:>9} {:>8} {:>8} {:>8} {:>10} {:>7} {:>12} {:>7}  {}\n", "km", "samples", "peak_MB",
             "B/samp", "wall_s", "cpu_s", "MS/cpu_s", "nodes", "archive_B", "gen_s", "status");
  std::vector<ScaleRow> rows;
  double measured_bps = 0;
  for (int km : sizes) {
    ScaleRow row;
    row.km = km;
    row.samples = uint64_t(km) * 1000 * uint64_t(km) * 1000;
    const std::string dem = fmt::format("{}/lidar_like_{}km.tif", work, km);
    const double need = std::max(kAssumedBytesPerSourceSample, measured_bps) * double(row.samples);
    const double avail = kUsableMemoryFraction * double(mem_available_bytes());
    if (need > avail) {
      row.status = fmt::format("skipped: in-core cook needs ~{:.1f} GB, {:.1f} GB usable (source held in memory)",
                               gb(need), gb(avail));
    } else if (!std::filesystem::exists(dem)) {
      const double disk_need = kGeneratedBytesPerSample * double(row.samples);
      if (disk_need > double(disk_free_bytes(work))) {
        row.status = fmt::format("skipped: generating the DEM needs ~{:.1f} GB of disk in {}", gb(disk_need), work);
      } else {
        const Run g = run({python, script, "--source", source, "--size-km", std::to_string(km), "--out", dem});
        row.gen_s = g.wall_s;
        if (!g.ok) row.status = fmt::format("failed: {} {} could not make {}", python, script, dem);
      }
    } else {
      row.gen_s = 0;  // reused
    }
    if (row.status == "ok") {
      const std::string archive = fmt::format("{}/lidar_like_{}km.terrain", work, km);
      std::vector<std::string> argv = {tool, dem, "-o", archive, "--json"};
      if (heights_only) argv.push_back("--heights-only");
      const Run r = run(argv);
      if (!r.ok) {
        row.status = "failed: terrain-cook exited non-zero";
      } else {
        const auto j = nlohmann::json::parse(r.out, nullptr, false);
        if (j.is_discarded() || !j.contains("output")) {
          row.status = "failed: terrain-cook printed no JSON report";
        } else {
          row.nodes = j["output"]["nodes"];
          row.archive_bytes = j["output"]["archive_bytes"];
        }
        row.wall_s = r.wall_s;
        row.cpu_s = r.cpu_s;
        row.rss_bytes = double(r.rss_bytes);
        measured_bps = std::max(measured_bps, row.bytes_per_sample());
      }
      std::filesystem::remove(archive, ec);  // archives of the large sizes are gigabytes
    }
    fmt::print("{:>5} {:>13} {:>9.0f} {:>8.2f} {:>8.2f} {:>8.2f} {:>10.2f} {:>7} {:>12} {:>7.1f}  {}\n", row.km,
               row.samples, row.rss_bytes / 1e6, row.bytes_per_sample(), row.wall_s, row.cpu_s,
               row.samples_per_cpu_s() / 1e6, row.nodes, row.archive_bytes, row.gen_s, row.status);
    std::fflush(stdout);
    rows.push_back(row);
  }
  // The table next to the DEMs, one file per mode (heights-only and full runs do not overwrite each other).
  nlohmann::json js = nlohmann::json::array();
  std::ofstream csv(fmt::format("{}/scale-{}.csv", work, mode));
  csv << "size_km,samples,peak_rss_bytes,bytes_per_sample,wall_s,cpu_s,samples_per_cpu_s,nodes,archive_bytes,gen_s,"
         "status\n";
  auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  for (const ScaleRow& r : rows) {
    js.push_back({{"size_km", r.km}, {"samples", r.samples}, {"peak_rss_bytes", num(r.rss_bytes)},
                  {"bytes_per_sample", num(r.bytes_per_sample())}, {"wall_s", num(r.wall_s)}, {"cpu_s", num(r.cpu_s)},
                  {"samples_per_cpu_s", num(r.samples_per_cpu_s())}, {"nodes", r.nodes},
                  {"archive_bytes", r.archive_bytes}, {"gen_s", num(r.gen_s)}, {"status", r.status}});
    csv << fmt::format("{},{},{:.0f},{:.3f},{:.3f},{:.3f},{:.0f},{},{},{:.1f},\"{}\"\n", r.km, r.samples, r.rss_bytes,
                       r.bytes_per_sample(), r.wall_s, r.cpu_s, r.samples_per_cpu_s(), r.nodes, r.archive_bytes,
                       r.gen_s, r.status);
  }
  std::ofstream(fmt::format("{}/scale-{}.json", work, mode))
      << nlohmann::json{{"mode", mode}, {"source", source}, {"threads", std::thread::hardware_concurrency()},
                        {"rows", js}}
             .dump(2)
      << "\n";
  fmt::print("\nWrote {}/scale-{}.json and .csv\n", work, mode);
  bool failed = false;
  for (const ScaleRow& r : rows) failed |= r.status.rfind("failed", 0) == 0;
  return failed ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  std::string data = TERRAIN_DEFAULT_DATA_DIR;
  std::vector<double> tolerances = {0.25, 0.5, 1.0, 2.0, 4.0};
  std::vector<std::string> only;
  int runs = 3;
  bool skip_default = false;
  bool scale = false, heights_only = false;
  std::vector<int> sizes = {4, 8, 16, 40};
  std::string work, source, script, python = "/usr/bin/python3";
  CLI::App app{"terrain-cook-bench: tolerance sweep over the shared DEMs against gdalwarp -r cubic"};
  app.add_option("--data", data, "Folder of the shared DEMs")->capture_default_str();
  app.add_option("--tolerances", tolerances, "Tolerances to sweep (metres)")->delimiter(',');
  app.add_option("--dems", only, "Only these DEMs (names as printed)")->delimiter(',');
  app.add_option("--runs", runs, "Runs per measurement (median)")->capture_default_str();
  app.add_flag("--skip-default", skip_default, "Skip the default cooks with every section");
  app.add_flag("--scale", scale, "Instead of the sweep: cook 1 m lidar-like squares of --sizes km, peak memory per size");
  app.add_option("--sizes", sizes, "--scale: square sides in km")->delimiter(',')->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_flag("--heights-only", heights_only, "--scale: cook with --heights-only");
  app.add_option("--work", work, "--scale: folder for the generated DEMs and the table (default: bench-scale in the build tree)");
  app.add_option("--source", source, "--scale: real DEM in a metric CRS to upsample (default: <data>/kilauea_utm5n.tif)");
  app.add_option("--python", python, "--scale: Python with GDAL and numpy")->capture_default_str();
  app.add_option("--script", script, "--scale: the DEM generator (default: make_lidar_like.py of the source tree)");
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
  if (scale)
    return scale_main(tool, self, sizes, heights_only, work,
                      source.empty() ? std::filesystem::path(data + "/kilauea_utm5n.tif").lexically_normal().string()
                                     : source,
                      python, script);
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
  return 0;
}
