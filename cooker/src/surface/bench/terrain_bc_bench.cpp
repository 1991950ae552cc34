// terrain-bc-bench: block-compression encoders on the payloads of real nodes.
//
// For each shared DEM it cuts real nodes, builds their surface payloads exactly as the cooker
// does (splat-baked albedo with holes, a colour-relief albedo like `gdaldem color-relief`, and the
// packed world-space normals), then encodes them with every encoder and prints, in one table:
// microseconds per block (median of repeated runs, one thread), albedo PSNR over non-hole texels,
// punch-through mismatches (must be 0), and normal angular error (mean / max degrees). A second
// table gives the whole per-node surface cook time per quality setting. --frontier --chart FILE.svg
// also draws the frontier (bench_chart.h).
#include <algorithm>
#include <cstdarg>
#include <chrono>
#include <ctime>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <unistd.h>

#include "bc_blocks.h"
#include "bench_chart.h"
#include "bench_paths.h"
#include "dem_nodes.h"
#include "materials.h"
#include "normals.h"
#include "splat.h"
#include "surface_encoders.h"
#include "surface_layers.h"

using namespace terrain;
using namespace terrain::cook;
namespace {


// printf into a std::string (chart titles).
std::string fmt_string(const char* format, ...) __attribute__((format(printf, 1, 2)));
std::string fmt_string(const char* format, ...) {
  char buf[2048];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buf, sizeof buf, format, args);
  va_end(args);
  return buf;
}

struct Dataset {
  const char* file;
  uint32_t level;
  int max_nodes;
};
// Levels chosen so the vertex spacing is close to (or finer than) the data spacing.
constexpr Dataset kDatasets[] = {
    {"kilauea_utm5n.tif", 4, 12},          // 30 m data, 8 m vertices: caldera, cliffs, sea (holes)
    {"N22W160.hgt.zip", 5, 12},            // 90 m data, 16 m vertices: Na Pali cliffs, voids (holes)
    {"srtm_oetztal.tif", 5, 12},           // alpine relief
    {"tahoe_lidar_highesthit.tif", 0, 12}, // 0.5 m lidar with trees: spiky normals
};

// Per-node cook times: every shared DEM the bench can read, at its finest useful level.
constexpr Dataset kCookDatasets[] = {
    {"kilauea_utm5n.tif", 4, 48},        {"N22W160.hgt.zip", 5, 48},           {"N19W155.hgt.zip", 5, 48},
    {"srtm_oetztal.tif", 5, 48},         {"slovenia_TM1_564_146.tif", 1, 48},  {"tahoe_lidar_bareearth.tif", 0, 48},
    {"tahoe_lidar_highesthit.tif", 0, 48},
};

int step_for_level(uint32_t level) {
  static const int kSteps[kLevelCount] = {2, 3, 4, 5, 6, 6};
  return kSteps[level];
}

struct NodePayload {
  std::vector<uint8_t> albedo_splat, albedo_relief;  // 132x132 RGBA
  NormalTexels normals;
  std::array<uint8_t, kTexelCount * 4> normal_rgba{}, normal_rgba_const{};
  int hole_texels = 0;
};

// Hypsometric tint with hillshade-free colours, like `gdaldem color-relief` with a typical ramp.
// Up to `max_nodes` nodes of a level with data on at least a quarter of their vertices, spread
// evenly over the raster (deterministic choice).
std::vector<bench::DemNode> pick_nodes(const bench::DemRaster& dem, uint32_t level, int max_nodes) {
  std::vector<bench::DemNode> nodes;
  const uint32_t nx = bench::nodes_across(dem, level, false), ny = bench::nodes_across(dem, level, true);
  std::vector<std::pair<uint32_t, uint32_t>> cand;
  for (uint32_t y = 0; y < ny; ++y)
    for (uint32_t x = 0; x < nx; ++x) cand.push_back({x, y});
  const size_t stride = std::max<size_t>(1, cand.size() / size_t(max_nodes * 2));
  for (size_t c = 0; c < cand.size() && int(nodes.size()) < max_nodes; c += stride) {
    bench::DemNode n;
    bench::make_dem_node(dem, level, cand[c].first, cand[c].second, step_for_level(level), n);
    if (n.data_vertices > kHeightCount / 4) nodes.push_back(std::move(n));
  }
  return nodes;
}

// Loads a dataset's DEM and picks its nodes; false (with a message) when the file cannot be read.
bool load_dataset(const std::string& data_dir, const Dataset& ds, bench::DemRaster& dem,
                  std::vector<bench::DemNode>& nodes) {
  const std::string path = (std::filesystem::path(data_dir) / ds.file).string();
  if (Status s = bench::load_dem(path, dem); !s.ok()) {
    std::fprintf(stderr, "terrain-bc-bench: skipping %s: %s\n", ds.file, s.to_string().c_str());
    return false;
  }
  nodes = pick_nodes(dem, ds.level, ds.max_nodes);
  return true;
}

void relief_colour(double h, uint8_t rgb[3]) {
  static const double stops[][4] = {{0, 40, 110, 60},     {100, 90, 150, 70},   {400, 170, 180, 100},
                                    {800, 190, 160, 110}, {1200, 150, 120, 90}, {2000, 130, 110, 100},
                                    {3000, 240, 240, 245}, {5000, 255, 255, 255}};
  const int n = int(sizeof stops / sizeof stops[0]);
  if (h <= stops[0][0]) h = stops[0][0];
  for (int i = 0; i + 1 < n; ++i)
    if (h <= stops[i + 1][0] || i + 2 == n) {
      const double t = std::clamp((h - stops[i][0]) / (stops[i + 1][0] - stops[i][0]), 0.0, 1.0);
      for (int c = 0; c < 3; ++c) rgb[c] = uint8_t(std::lround(stops[i][c + 1] + t * (stops[i + 1][c + 1] - stops[i][c + 1])));
      return;
    }
}

void build_payload(const bench::DemNode& node, const MaterialRules& rules, NodePayload& p) {
  const SurfaceInput in = node.input(&rules, BcQuality::balanced);
  SplatLattice lattice;
  compute_splat_lattice(in, rules, lattice);
  p.albedo_splat.assign(size_t(kTexelCount) * 4, 0);
  bake_albedo(in, rules, lattice, p.albedo_splat.data());
  p.albedo_relief = p.albedo_splat;
  p.hole_texels = 0;
  for (int u = 0; u < kTexels; ++u)
    for (int t = 0; t < kTexels; ++t) {
      double sum = 0;
      int n = 0;
      for (int b = 0; b <= 1; ++b)
        for (int a = 0; a <= 1; ++a) {
          const float v = node.window[size_t((u - kApron + kWindowMargin + b) * kWindowSize + t - kApron + kWindowMargin + a)];
          if (!std::isnan(v)) { sum += v; ++n; }
        }
      const size_t k = size_t(u * kTexels + t);
      relief_colour(n ? sum / n : 0.0, &p.albedo_relief[k * 4]);
      p.hole_texels += p.albedo_splat[k * 4 + 3] == 0;
    }
  compute_normal_texels(in, p.normals);
  pack_normal_texels(p.normals, p.normal_rgba, true);
  pack_normal_texels(p.normals, p.normal_rgba_const, false);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

struct Row {
  std::string dataset, payload, encoder;
  double us_per_block = 0;
  double psnr = 0, mean_deg = 0, max_deg = 0;
  uint64_t mismatches = 0;
};

// --block-stats: where the albedo error of the default encoder sits, block by block, against
// libsquish cluster fit (hole-free blocks of the splat albedo only): the share of the squared
// error held by the worst blocks, and how many distinct colours those blocks have.
void print_block_stats(const char* name, const std::vector<NodePayload>& payloads) {
  struct BlockErr {
    int own, squish, colours, cluster;
  };
  std::vector<BlockErr> v;
  for (const NodePayload& p : payloads)
    for (int by = 0; by < kTexelBlocks; ++by)
      for (int bx = 0; bx < kTexelBlocks; ++bx) {
        uint8_t block[64];
        for (int r = 0; r < 4; ++r)
          std::memcpy(block + 16 * r, &p.albedo_splat[size_t((by * 4 + r) * kTexels + bx * 4) * 4], 16);
        bool hole = false;
        uint32_t cols[16];
        int ncol = 0;
        for (int i = 0; i < 16; ++i) {
          hole |= block[4 * i + 3] < 128;
          uint32_t c;
          std::memcpy(&c, block + 4 * i, 4);
          c &= 0xFFFFFFu;
          if (std::find(cols, cols + ncol, c) == cols + ncol) cols[ncol++] = c;
        }
        if (hole) continue;
        auto err = [&](Bc1Method m) {
          uint8_t out[8], dec[64];
          encode_bc1_block(block, m, out);
          decode_bc1_block(out, dec);
          int e = 0;
          for (int i = 0; i < 16; ++i)
            for (int c = 0; c < 3; ++c) e += (block[4 * i + c] - dec[4 * i + c]) * (block[4 * i + c] - dec[4 * i + c]);
          return e;
        };
        v.push_back({err(Bc1Method::axis_fit_hard), err(Bc1Method::squish_cluster), ncol, err(Bc1Method::ordering_search)});
      }
  if (v.empty()) return;
  double own_total = 0, sq_total = 0, cl_total = 0;
  for (const BlockErr& b : v) { own_total += b.own; sq_total += b.squish; cl_total += b.cluster; }
  const double samples = double(v.size()) * 48;
  std::printf("\n# block stats %s splat albedo: %zu hole-free blocks; own %.2f dB, squish-cluster %.2f dB, ordering-search %.2f dB\n",
              name, v.size(), psnr_db(own_total, uint64_t(samples)), psnr_db(sq_total, uint64_t(samples)),
              psnr_db(cl_total, uint64_t(samples)));
  std::sort(v.begin(), v.end(), [](const BlockErr& a, const BlockErr& b) { return a.own > b.own; });
  std::printf("# share of own squared error in the worst blocks (by own error) and squish's error on the same blocks\n");
  std::printf("%8s %10s %12s %12s %10s\n", "worst %", "blocks", "own share", "own/squish", "mean cols");
  for (double f : {0.01, 0.02, 0.05, 0.10, 0.20, 0.50}) {
    const size_t n = std::max<size_t>(1, size_t(f * double(v.size())));
    double o = 0, q = 0, cols = 0;
    for (size_t i = 0; i < n; ++i) { o += v[i].own; q += v[i].squish; cols += v[i].colours; }
    std::printf("%8.0f %10zu %11.1f%% %12.3f %10.2f\n", f * 100, n, 100 * o / own_total, q > 0 ? o / q : 0, cols / double(n));
  }
  // Where own loses to squish: sum of (own - squish) over blocks where own is worse.
  double lose = 0, win = 0;
  std::vector<int> lose_by_cols(17, 0);
  std::vector<double> lose_err_by_cols(17, 0);
  for (const BlockErr& b : v) {
    if (b.own > b.squish) {
      lose += b.own - b.squish;
      lose_by_cols[std::min(b.colours, 16)]++;
      lose_err_by_cols[std::min(b.colours, 16)] += b.own - b.squish;
    } else {
      win += b.squish - b.own;
    }
  }
  std::printf("# own - squish squared error: +%.0f on blocks where own is worse, -%.0f where better (net %.1f%% of own)\n",
              lose, win, 100 * (lose - win) / own_total);
  std::printf("# blocks where own is worse, by distinct colours: ");
  for (int c = 1; c <= 16; ++c)
    if (lose_by_cols[size_t(c)]) std::printf("%d:%d(%.0f%%) ", c, lose_by_cols[size_t(c)], 100 * lose_err_by_cols[size_t(c)] / lose);
  std::printf("\n# all blocks by distinct colours (count, own error share): ");
  std::vector<int> all_cols(17, 0);
  std::vector<double> all_err(17, 0);
  for (const BlockErr& b : v) { all_cols[size_t(b.colours)]++; all_err[size_t(b.colours)] += b.own; }
  for (int c = 1; c <= 16; ++c)
    if (all_cols[size_t(c)]) std::printf("%d:%d(%.0f%%) ", c, all_cols[size_t(c)], 100 * all_err[size_t(c)] / own_total);
  std::printf("\n");
}

// --frontier: speed against PSNR of our opaque BC1 encoder as its effort knobs are swept (hole-free
// blocks of each albedo set; hole blocks take the same 3-colour path in every setting), next to
// stb_dxt and libsquish cluster fit on the same blocks. All rows go through the calls the cooker
// makes (encode_bc1_block for the libraries and the default, encode_bc1_opaque for the
// variants, which is what the default's hot path calls; "scalar" rows force the scalar definition
// that the SSE2 path restates byte for byte); a row "meets" the albedo target when its
// PSNR >= max(stb, squish cluster) and its time <= stb's.
// With `panels`, adds one chart panel per albedo set: PSNR against us/block, the effort sweep as a
// series, the libraries as named points, the target as lines.
void print_frontier(const char* name, const std::vector<NodePayload>& payloads, int reps,
                    std::vector<terrain::chart::Panel>* panels) {
  for (int set = 0; set < 2; ++set) {
    std::vector<uint8_t> blocks;
    for (const NodePayload& p : payloads) {
      const std::vector<uint8_t>& img = set == 0 ? p.albedo_splat : p.albedo_relief;
      for (int by = 0; by < kTexelBlocks; ++by)
        for (int bx = 0; bx < kTexelBlocks; ++bx) {
          uint8_t block[64];
          for (int r = 0; r < 4; ++r) std::memcpy(block + 16 * r, &img[size_t((by * 4 + r) * kTexels + bx * 4) * 4], 16);
          bool hole = false;
          for (int i = 0; i < 16; ++i) hole |= block[4 * i + 3] < 128;
          if (!hole) blocks.insert(blocks.end(), block, block + 64);
        }
    }
    const size_t n = blocks.size() / 64;
    if (n == 0) continue;
    std::vector<uint8_t> out(n * 8);
    struct Result { std::string label; double us, psnr; };
    auto measure = [&](const std::string& label, auto&& encode) {
      std::vector<double> t;
      for (int r = 0; r < reps; ++r) {
        const double t0 = thread_cpu_seconds();
        for (size_t i = 0; i < n; ++i) encode(&blocks[i * 64], &out[i * 8]);
        t.push_back(thread_cpu_seconds() - t0);
      }
      std::sort(t.begin(), t.end());
      double se = 0;
      for (size_t i = 0; i < n; ++i) {
        uint8_t dec[64];
        decode_bc1_block(&out[i * 8], dec);
        for (int k = 0; k < 16; ++k)
          for (int c = 0; c < 3; ++c) {
            const double d = double(blocks[i * 64 + 4 * k + c]) - double(dec[4 * k + c]);
            se += d * d;
          }
      }
      return Result{label, 1e6 * t[t.size() / 2] / double(n), psnr_db(se, uint64_t(n) * 48)};
    };
    auto library = [&](Bc1Method m) {
      return measure(bc1_method_name(m), [m](const uint8_t* in, uint8_t* o) { encode_bc1_block(in, m, o); });
    };
    const Result stb = library(Bc1Method::stb), squish = library(Bc1Method::squish_cluster);
    std::vector<Result> rows = {library(Bc1Method::axis_fit_hard)};
    struct Variant { const char* label; Bc1OpaqueEffort e; };
    const auto effort = hard_block_effort;
    const Variant variants[] = {
        {"search1 >800", effort(1, 800, -1)},           {"search2 >400", effort(2, 400, -1)},
        {"search2 >200", effort(2, 200, -1)},           {"search2 >100", effort(2, 100, -1)},
        {"search2 >16 (ordering-search)", effort(2, 16, -1)}, {"3-colour >1600", effort(0, 16, 1600)},
        {"3-colour >800", effort(0, 16, 800)},          {"search1 >800 + 3-col >1600", effort(1, 800, 1600)},
        {"search2 >400 + 3-col >800", effort(2, 400, 800)}, {"search2 >100 + 3-col >400", effort(2, 100, 400)},
        {"search2 >16 + 3-col >192", effort(2, 16, 192)},
    };
    for (const Variant& v : variants)
      rows.push_back(measure(std::string("own ") + v.label,
                             [&e = v.e](const uint8_t* in, uint8_t* o) { encode_bc1_opaque(in, o, e); }));
    rows.push_back(measure("own, scalar path", [](const uint8_t* in, uint8_t* o) {
      encode_bc1_opaque_scalar(in, o, hard_block_effort(0, 16, -1));
    }));
    rows.push_back(measure("ordering-search, scalar path", [](const uint8_t* in, uint8_t* o) {
      encode_bc1_opaque_scalar(in, o, hard_block_effort(2, 16, -1));
    }));
    const double target_db = std::max(stb.psnr, squish.psnr);
    std::printf("\n# frontier %s %s albedo: %zu hole-free blocks; target >= %.2f dB at <= %.3f us/block\n", name,
                set == 0 ? "splat" : "relief", n, target_db, stb.us);
    std::printf("%-34s %9s %8s %6s\n", "encoder / effort", "us/block", "PSNR", "meets");
    std::printf("%-34s %9.3f %8.2f %6s\n", stb.label.c_str(), stb.us, stb.psnr, "-");
    std::printf("%-34s %9.3f %8.2f %6s\n", squish.label.c_str(), squish.us, squish.psnr, "-");
    for (const Result& r : rows)
      std::printf("%-34s %9.3f %8.2f %6s\n", r.label.c_str(), r.us, r.psnr,
                  r.psnr >= target_db && r.us <= stb.us ? "yes" : "no");
    if (!panels) continue;
    namespace ch = terrain::chart;
    ch::Panel p;
    p.title = fmt_string("%s %s albedo, %zu blocks", name, set == 0 ? "splat" : "relief", n);
    p.x = {"encode time, us per block (thread CPU)", ch::Scale::log10};
    p.y = {"PSNR, dB (hole-free texels)", ch::Scale::linear};
    ch::Series sweep{"own BC1, effort sweep", {}}, scalar{"own BC1, scalar path", {}}, def{"own BC1 default", {}};
    scalar.line = false;
    def.line = false;
    def.hollow = true;
    def.radius = 5;
    def.points.push_back({rows[0].us, rows[0].psnr, rows[0].label});
    for (const Result& r : rows) {
      const bool is_scalar = r.label.find("scalar") != std::string::npos;
      (is_scalar ? scalar : sweep).points.push_back({r.us, r.psnr, r.label});
    }
    std::sort(sweep.points.begin(), sweep.points.end(), [](const ch::Point& a, const ch::Point& b) { return a.x < b.x; });
    p.series = {sweep, def, scalar};
    p.named = {{stb.label, stb.us, stb.psnr}, {squish.label, squish.us, squish.psnr}};
    p.lines = {{"target PSNR", target_db, true}, {"stb time", stb.us, false}};
    panels->push_back(std::move(p));
  }
}

void print_usage(FILE* to) {
  std::fprintf(to,
      "usage: terrain-bc-bench [--data DIR] [--reps N] [--only NAME] [--encoder NAME] [--block-stats] [--frontier [--chart FILE.svg]] [--json] [--quiet] [--help]\n"
      "  Encodes real-node payloads (albedo with holes, normals) with libsquish, stb_dxt and our\n"
      "  encoder; prints us/block (median of N runs), albedo PSNR, punch-through mismatches and\n"
      "  normal angular error, then the per-node surface cook time per quality setting.\n"
      "  --data DIR  folder of the shared DEMs (default: $TERRAIN_DATA_DIR or %s)\n"
      "  --reps N    timing repetitions (default 5)\n"
      "  --only NAME only the shared DEMs whose file name contains NAME\n"
      "  --encoder NAME  only the encoder rows with exactly this name (e.g. own; for\n"
      "              profiling; skips the cook-time table)\n"
      "  --block-stats  only the per-block error distribution of the default encoder against libsquish\n"
      "              cluster fit on the splat albedo (where the dB are lost), no timing\n"
      "  --frontier  only speed against PSNR of our BC1 encoder as its effort knobs are swept, next to\n"
      "              stb_dxt and libsquish cluster fit (hole-free albedo blocks)\n"
      "  --chart FILE.svg  with --frontier: also write the frontier as an SVG chart (a panel per DEM and\n"
      "              albedo set, the libraries as labelled points)\n",
      terrain::bench_data_dir());
}

}  // namespace

int main(int argc, char** argv) {
  std::string data_dir = terrain::bench_data_dir();
  if (const char* env = std::getenv("TERRAIN_DATA_DIR"); env && *env) data_dir = env;
  int reps = 5;
  bool json = false, quiet = false, block_stats = false, frontier = false;
  std::string only, encoder_only, chart_path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") { print_usage(stdout); return 0; }
    if (a == "--json") json = true;
    else if (a == "--quiet") quiet = true;
    else if (a == "--block-stats") block_stats = true;
    else if (a == "--frontier") frontier = true;
    else if (a == "--data" && i + 1 < argc) data_dir = argv[++i];
    else if (a == "--reps" && i + 1 < argc) reps = std::max(1, std::atoi(argv[++i]));
    else if (a == "--only" && i + 1 < argc) only = argv[++i];
    else if (a == "--encoder" && i + 1 < argc) encoder_only = argv[++i];
    else if (a == "--chart" && i + 1 < argc) chart_path = argv[++i];
    else { std::fprintf(stderr, "terrain-bc-bench: unknown argument '%s'\n", a.c_str()); print_usage(stderr); return 2; }
  }
  if (!chart_path.empty() && !frontier) {
    std::fprintf(stderr, "terrain-bc-bench: --chart needs --frontier\n");
    return 2;
  }
  std::vector<terrain::chart::Panel> frontier_panels;
  const bool progress = !quiet && isatty(2);
  const MaterialRules rules = default_material_rules();
  std::vector<Row> rows;
  struct CookRow {
    std::string dataset, quality;
    int nodes;
    double ms_median, ms_p99, ms_max;           // payloads: splat + cones + normals + albedo (with compression)
    double ms_checked_median, ms_checked_max;   // the whole call, incl. the error statistics the cooker reports
    double ms_splat, ms_cones, ms_normals, ms_albedo;  // mean per node
  };
  std::vector<CookRow> cook_rows;

  const Bc1Method bc1_methods[] = {Bc1Method::stb,          Bc1Method::stb_hq,   Bc1Method::squish_range,
                                   Bc1Method::squish_cluster, Bc1Method::squish_iterative, Bc1Method::axis_fit,
                                   Bc1Method::axis_fit_hard,          Bc1Method::ordering_search, Bc1Method::best_of_axis_fit_and_squish};
  const Bc3Method bc3_methods[] = {Bc3Method::stb, Bc3Method::stb_hq, Bc3Method::squish_cluster, Bc3Method::g_axis_fit,
                                   Bc3Method::g_axis_fit_hq};

  for (const Dataset& ds : kDatasets) {
    if (!only.empty() && std::string(ds.file).find(only) == std::string::npos) continue;
    bench::DemRaster dem;
    std::vector<bench::DemNode> nodes;
    if (!load_dataset(data_dir, ds, dem, nodes)) continue;
    if (progress) std::fprintf(stderr, "%s: %zu nodes at level %u\n", ds.file, nodes.size(), ds.level);
    std::vector<NodePayload> payloads(nodes.size());
    int holes = 0;
    for (size_t i = 0; i < nodes.size(); ++i) {
      build_payload(nodes[i], rules, payloads[i]);
      holes += payloads[i].hole_texels;
    }
    if (frontier) {
      print_frontier(dem.name.c_str(), payloads, reps, chart_path.empty() ? nullptr : &frontier_panels);
      continue;
    }
    if (block_stats) {
      print_block_stats(dem.name.c_str(), payloads);
      continue;
    }
    const double blocks = double(nodes.size()) * kTexelBlocks * kTexelBlocks;
    std::vector<uint8_t> out(size_t(kAlbedoBytes) * 2);

    for (int which = 0; which < 2; ++which)
      for (Bc1Method m : bc1_methods) {
        if (!encoder_only.empty() && encoder_only != bc1_method_name(m)) continue;
        Row row{dem.name, which ? "albedo-relief" : "albedo-splat", bc1_method_name(m)};
        std::vector<double> times;
        AlbedoCheck total;
        for (int r = 0; r < reps; ++r) {
          AlbedoCheck acc;
          double secs = 0;
          for (const NodePayload& p : payloads) {
            const uint8_t* img = which ? p.albedo_relief.data() : p.albedo_splat.data();
            const double t0 = thread_cpu_seconds();
            encode_bc1_image(img, m, out.data());
            secs += thread_cpu_seconds() - t0;
            const AlbedoCheck c = check_albedo(img, out.data());
            acc.sq_err += c.sq_err;
            acc.samples += c.samples;
            acc.alpha_mismatches += c.alpha_mismatches;
          }
          times.push_back(secs / blocks * 1e6);
          total = acc;
        }
        row.us_per_block = median(times);
        row.psnr = psnr_db(total.sq_err, total.samples);
        row.mismatches = total.alpha_mismatches;
        rows.push_back(row);
        if (progress) std::fprintf(stderr, "  %s %s done\n", row.payload.c_str(), row.encoder.c_str());
      }
    for (int variant = 0; variant < 2; ++variant)
      for (Bc3Method m : bc3_methods) {
        if (variant == 1 && m != Bc3Method::g_axis_fit && m != Bc3Method::stb) continue;
        if (!encoder_only.empty() && encoder_only != bc3_method_name(m)) continue;
        Row row{dem.name, variant ? "normals(R=const)" : "normals(R=AO)", bc3_method_name(m)};
        std::vector<double> times;
        AngleStats err;
        for (int r = 0; r < reps; ++r) {
          double secs = 0;
          AngleStats acc;
          for (const NodePayload& p : payloads) {
            const uint8_t* img = variant ? p.normal_rgba_const.data() : p.normal_rgba.data();
            const double t0 = thread_cpu_seconds();
            encode_bc3_image(img, m, out.data());
            secs += thread_cpu_seconds() - t0;
            const AngleStats e = normal_error(p.normals, out.data());
            acc.sum_deg += e.sum_deg;
            acc.count += e.count;
            acc.max_deg = std::max(acc.max_deg, e.max_deg);
          }
          times.push_back(secs / blocks * 1e6);
          err = acc;
        }
        row.us_per_block = median(times);
        row.mean_deg = err.count ? err.sum_deg / double(err.count) : 0;
        row.max_deg = err.max_deg;
        rows.push_back(row);
      }
    if (progress) std::fprintf(stderr, "  %d hole texels over %zu nodes\n", holes, nodes.size());
  }

  if (!chart_path.empty()) {
    terrain::chart::Chart c;
    c.title = "terrain-bc-bench --frontier: BC1 albedo encoders, PSNR against encode time";
    c.note = fmt_string("Hole-free 4x4 blocks of real-node albedo (splat-baked and colour relief); time = thread CPU "
                        "us per block, median of %d rep%s, one thread; squares = peer libraries on the same blocks; "
                        "dashed = the target (PSNR >= max(stb, squish), time <= stb). %s",
                        reps, reps == 1 ? "" : "s", terrain::chart::machine_note().c_str());
    c.panels = std::move(frontier_panels);
    if (const std::string e = terrain::chart::write_svg(c, chart_path); !e.empty()) {
      std::fprintf(stderr, "terrain-bc-bench: %s\n", e.c_str());
      return 1;
    }
    std::printf("\nWrote %s\n", chart_path.c_str());
  }
  if (block_stats || frontier) return 0;
  const bool cook_table = encoder_only.empty();
  // Whole surface cook per node (normals, albedo, splat, cones + compression), one thread, on up
  // to 48 nodes of every known shared DEM: per node the median over the repetitions.
  for (const Dataset& ds : kCookDatasets) {
    if (!cook_table) break;
    if (!only.empty() && std::string(ds.file).find(only) == std::string::npos) continue;
    bench::DemRaster dem;
    std::vector<bench::DemNode> nodes;
    if (!load_dataset(data_dir, ds, dem, nodes)) continue;
    if (progress) std::fprintf(stderr, "%s: cook times on %zu nodes at level %u\n", ds.file, nodes.size(), ds.level);
    for (BcQuality q : {BcQuality::fast, BcQuality::balanced, BcQuality::best}) {
      std::vector<double> payload_ms, checked_ms;
      NodeData outnode;
      SurfaceStats sum;
      for (const bench::DemNode& n : nodes) {
        std::vector<double> t, tc;
        for (int r = 0; r < reps; ++r) {
          SurfaceStats st;
          const double t0 = thread_cpu_seconds();
          const Status s = cook_surface_layers(n.input(&rules, q), n.node, n.height_offset, n.step_log2, outnode, &st);
          tc.push_back((thread_cpu_seconds() - t0) * 1e3);
          if (!s.ok()) {
            std::fprintf(stderr, "terrain-bc-bench: %s\n", s.to_string().c_str());
            return 1;
          }
          t.push_back((st.seconds_splat + st.seconds_cones + st.seconds_normals + st.seconds_albedo) * 1e3);
          sum.seconds_splat += st.seconds_splat;
          sum.seconds_cones += st.seconds_cones;
          sum.seconds_normals += st.seconds_normals;
          sum.seconds_albedo += st.seconds_albedo;
        }
        payload_ms.push_back(median(t));
        checked_ms.push_back(median(tc));
      }
      if (nodes.empty()) continue;
      std::vector<double> sorted = payload_ms;
      std::sort(sorted.begin(), sorted.end());
      // p99 by nearest rank (with < 100 nodes: the largest but one when there are >= 50).
      const double p99 = sorted[std::min(sorted.size() - 1, size_t(std::ceil(0.99 * double(sorted.size()))) - 1)];
      const char* qn = q == BcQuality::fast ? "fast" : q == BcQuality::balanced ? "balanced" : "best";
      const double runs = double(nodes.size()) * reps / 1e3;
      cook_rows.push_back({dem.name, qn, int(nodes.size()), median(payload_ms), p99, sorted.back(), median(checked_ms),
                           *std::max_element(checked_ms.begin(), checked_ms.end()), sum.seconds_splat / runs,
                           sum.seconds_cones / runs, sum.seconds_normals / runs, sum.seconds_albedo / runs});
    }
  }

  if (json) {
    std::printf("{\"encoders\": [");
    for (size_t i = 0; i < rows.size(); ++i) {
      const Row& r = rows[i];
      std::printf("%s\n  {\"dataset\": \"%s\", \"payload\": \"%s\", \"encoder\": \"%s\", \"us_per_block\": %.4f, "
                  "\"psnr_db\": %.3f, \"alpha_mismatches\": %llu, \"normal_mean_deg\": %.4f, \"normal_max_deg\": %.4f}",
                  i ? "," : "", r.dataset.c_str(), r.payload.c_str(), r.encoder.c_str(), r.us_per_block, r.psnr,
                  (unsigned long long)r.mismatches, r.mean_deg, r.max_deg);
    }
    std::printf("\n], \"cook\": [");
    for (size_t i = 0; i < cook_rows.size(); ++i)
      std::printf("%s\n  {\"dataset\": \"%s\", \"quality\": \"%s\", \"nodes\": %d, \"ms_per_node_median\": %.3f, "
                  "\"ms_per_node_p99\": %.3f, \"ms_per_node_max\": %.3f, \"ms_with_checks_median\": %.3f, "
                  "\"ms_with_checks_max\": %.3f, \"ms_splat\": %.3f, \"ms_cones\": %.3f, \"ms_normals\": %.3f, "
                  "\"ms_albedo\": %.3f}",
                  i ? "," : "", cook_rows[i].dataset.c_str(), cook_rows[i].quality.c_str(), cook_rows[i].nodes,
                  cook_rows[i].ms_median, cook_rows[i].ms_p99, cook_rows[i].ms_max, cook_rows[i].ms_checked_median,
                  cook_rows[i].ms_checked_max, cook_rows[i].ms_splat, cook_rows[i].ms_cones, cook_rows[i].ms_normals,
                  cook_rows[i].ms_albedo);
    std::printf("\n]}\n");
    return 0;
  }
  std::printf("%-28s %-17s %-15s %9s %9s %6s %9s %9s\n", "dataset", "payload", "encoder", "us/block", "PSNR dB",
              "alpha!", "mean deg", "max deg");
  for (const Row& r : rows) {
    if (r.payload.rfind("albedo", 0) == 0)
      std::printf("%-28s %-17s %-15s %9.3f %9.2f %6llu %9s %9s\n", r.dataset.c_str(), r.payload.c_str(), r.encoder.c_str(),
                  r.us_per_block, r.psnr, (unsigned long long)r.mismatches, "-", "-");
    else
      std::printf("%-28s %-17s %-15s %9.3f %9s %6s %9.3f %9.3f\n", r.dataset.c_str(), r.payload.c_str(), r.encoder.c_str(),
                  r.us_per_block, "-", "-", r.mean_deg, r.max_deg);
  }
  std::printf("\n%-28s %-9s %5s | %7s %7s %7s | %9s %9s | %7s %7s %7s %7s\n", "dataset", "quality", "nodes",
              "median", "p99", "max", "chk med", "chk max", "splat", "cones", "normals", "albedo");
  for (const CookRow& c : cook_rows)
    std::printf("%-28s %-9s %5d | %7.3f %7.3f %7.3f | %9.3f %9.3f | %7.3f %7.3f %7.3f %7.3f\n", c.dataset.c_str(),
                c.quality.c_str(), c.nodes, c.ms_median, c.ms_p99, c.ms_max, c.ms_checked_median, c.ms_checked_max,
                c.ms_splat, c.ms_cones, c.ms_normals, c.ms_albedo);
  std::printf("# per-node surface payload time in ms (splat + cones + normals + albedo, compression included; thread CPU\n"
              "# time, median over reps per node); chk = the whole call incl. the error statistics the cooker reports;\n"
              "# last four columns: mean ms per node and stage.\n");
  std::printf("\n# albedo rows: every block checked for exact punch-through (alpha! = mismatching texels); stb_dxt has no\n"
              "# 3-colour mode, so its rows encode blocks with holes with libsquish cluster fit; PSNR over non-hole texels.\n"
              "# normals: angle between decoded and float normals; R=AO (block AO, the cooker's layout) vs R constant.\n");
  std::printf("# one thread, thread CPU time, %s build, reps %d; us/block = median over reps of (encode time of all nodes / blocks)\n",
#ifdef NDEBUG
              "release",
#else
              "debug",
#endif
              reps);
  return 0;
}
