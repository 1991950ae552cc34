// terrain-cook-bench: sweeps --tolerance over the real DEMs of the data directory (TERRAIN_DATA_DIR) and prints, per
// setting, nodes, bytes, cook time, max/RMS height error and the height stage's output samples per
// CPU-second, next to what `gdalwarp -r cubic` (the baseline a user would otherwise run, measured
// in the same run) takes to resample the same source to the finest cooked spacing; then the
// default cook of each DEM with every section and its peak memory. Medians of --runs runs.
//
// Each cook runs terrain-cook (next to this program) as a child process, so peak memory is the
// child's own (wait4 ru_maxrss) and the numbers are those a user sees.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
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

}  // namespace

int main(int argc, char** argv) {
  std::string data = TERRAIN_DEFAULT_DATA_DIR;
  std::vector<double> tolerances = {0.25, 0.5, 1.0, 2.0, 4.0};
  std::vector<std::string> only;
  int runs = 3;
  bool skip_default = false;
  CLI::App app{"terrain-cook-bench: tolerance sweep over the shared DEMs against gdalwarp -r cubic"};
  app.add_option("--data", data, "Folder of the shared DEMs")->capture_default_str();
  app.add_option("--tolerances", tolerances, "Tolerances to sweep (metres)")->delimiter(',');
  app.add_option("--dems", only, "Only these DEMs (names as printed)")->delimiter(',');
  app.add_option("--runs", runs, "Runs per measurement (median)")->capture_default_str();
  app.add_flag("--skip-default", skip_default, "Skip the default cooks with every section");
  CLI11_PARSE(app, argc, argv);

  const std::filesystem::path self = std::filesystem::canonical("/proc/self/exe").parent_path();
  const std::string tool = (self / "terrain-cook").string();
  if (!std::filesystem::exists(tool)) {
    fmt::print(stderr, "terrain-cook-bench: {} not found (build the terrain-cook target)\n", tool);
    return 1;
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
