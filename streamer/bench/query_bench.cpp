// terrain-query-bench: gameplay queries per second on one core (terrain/queries.h) on a real archive,
// next to SurfaceSampler (heights; rays marched with it) and a brute-force ray reference (every
// drawn triangle of every resident node). The streamer settles with a camera 2 m above the ground
// over a node of the archive's finest level (or --x/--y); queries fall within --radius of it.
//   terrain-query-bench build/release/test-archives/kilauea.terrain --runs 5
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <time.h>

#include "terrain/bc_decode.h"
#include "terrain/queries.h"
#include "terrain/sample.h"
#include "terrain/cpu_clock.h"
#include "terrain/remote_source.h"
#include "terrain/streamer.h"

namespace {

using namespace terrain;
using Clock = std::chrono::steady_clock;

struct Options {
  std::string archive;
  int runs = 5;
  double radius = 250;
  double x = NAN, y = NAN;
  uint32_t budget = 512;
  double error_px = 2.0;
};

[[noreturn]] void usage(int code) {
  std::printf(
      "usage: terrain-query-bench ARCHIVE [--runs N] [--radius M] [--x X --y Y] [--budget N] [--error-px PX]\n"
      "  Height and ray queries per second on one core from the resident surface, next to\n"
      "  SurfaceSampler and a brute-force ray reference; prints medians of N runs (default 5).\n");
  std::exit(code);
}

[[noreturn]] void bad_value(const std::string& flag, const char* value, const char* expected) {
  std::fprintf(stderr, "terrain-query-bench: %s expects %s, got '%s'\n", flag.c_str(), expected, value);
  std::exit(2);
}

// The whole of `text` as a decimal integer in [lo, hi], else a usage error naming the flag.
long integer_value(const std::string& flag, const char* text, long lo, long hi) {
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(text, &end, 10);
  if (end == text || *end != '\0' || errno == ERANGE || v < lo || v > hi) {
    const std::string expected = "an integer in " + std::to_string(lo) + ".." + std::to_string(hi);
    bad_value(flag, text, expected.c_str());
  }
  return v;
}

// The whole of `text` as a finite number (positive when `positive`), else a usage error.
double number_value(const std::string& flag, const char* text, bool positive) {
  char* end = nullptr;
  const double v = std::strtod(text, &end);
  if (end == text || *end != '\0' || !std::isfinite(v) || (positive && !(v > 0)))
    bad_value(flag, text, positive ? "a positive number" : "a finite number");
  return v;
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* {
      if (i + 1 >= argc) usage(2);
      return argv[++i];
    };
    if (a == "--help" || a == "-h") usage(0);
    if (a == "--runs") o.runs = int(integer_value(a, value(), 1, 1000));
    else if (a == "--radius") o.radius = number_value(a, value(), true);
    else if (a == "--x") o.x = number_value(a, value(), false);
    else if (a == "--y") o.y = number_value(a, value(), false);
    else if (a == "--budget") o.budget = uint32_t(integer_value(a, value(), 1, kMaxSlots));
    else if (a == "--error-px") o.error_px = number_value(a, value(), true);
    else if (!a.empty() && a[0] != '-' && o.archive.empty()) o.archive = a;
    else usage(2);
  }
  if (o.archive.empty()) usage(2);
  return o;
}


// Median over `runs` of items per second of `work` (which returns how many items it did), per
// second of this thread's CPU time (a shared machine's other load does not count; "per core").
double median_rate(int runs, const std::function<size_t()>& work) {
  std::vector<double> rates;
  for (int r = 0; r < runs; ++r) {
    const double t0 = thread_cpu_seconds();
    const size_t n = work();
    const double s = thread_cpu_seconds() - t0;
    rates.push_back(double(n) / s);
  }
  std::sort(rates.begin(), rates.end());
  return rates[rates.size() / 2];
}

// Queries that read the archive themselves (SurfaceSampler, ArchiveSurface, the brute force) and
// failed: a node that could not be read or decoded (bad payload, file truncated since open).
struct ReadFailures {
  uint64_t count = 0;
  std::string first;
  void note(const Status& s) {
    if (!s.ok() && count++ == 0) first = s.to_string();
  }
};

// Every drawn triangle of every resident node (no culling at all), Moeller-Trumbore.
class BruteForce {
 public:
  BruteForce(const ArchiveReader& reader, const std::vector<NodeKey>& resident, ReadFailures& failures)
      : world_(reader.world()) {
    auto data = std::make_unique<NodeData>();
    for (const NodeKey& k : resident) {
      const size_t index = size_t(reader.find(k));
      const Status s = reader.decode_node(index, *data, kSectionHeights | kSectionAlbedo);
      failures.note(s);
      if (!s.ok()) continue;
      const NodeRecord& r = reader.nodes()[index];
      Node n{k, std::vector<double>(kHeightCount), std::vector<uint8_t>(kHeightCount), {}};
      for (int i = 0; i < kHeightCount; ++i)
        n.h[size_t(i)] = units_to_metres(vertex_units(r.height_offset, data->heights[size_t(i)], world_.step_log2[k.level]));
      decode_hole_mask(*data, n.holes.data());
      for (int c = 0; c < 4; ++c)
        n.covered[size_t(c)] = k.level > 0 && std::find(resident.begin(), resident.end(), child_of(k, c)) != resident.end();
      nodes_.push_back(std::move(n));
    }
  }
  bool cast(const Ray& ray, double& t_out) const {
    const double len = std::hypot(ray.direction[0], ray.direction[1], ray.direction[2]);
    const double o[3] = {ray.origin[0] - world_.origin_x_m, ray.origin[1] - world_.origin_y_m, ray.origin[2]};
    const double d[3] = {ray.direction[0] / len, ray.direction[1] / len, ray.direction[2] / len};
    double best = ray.max_distance_m;
    bool hit = false;
    for (const Node& n : nodes_) {
      const double size = node_size_m(int(n.key.level)), s = vertex_spacing_m(int(n.key.level));
      const double x0 = n.key.x * size, y0 = n.key.y * size;
      for (int j = 0; j < kQuadsPerSide; ++j)
        for (int i = 0; i < kQuadsPerSide; ++i) {
          if (n.covered[size_t((i >= 64 ? 1 : 0) | (j >= 64 ? 2 : 0))]) continue;
          auto at = [&](int a, int b) { return size_t(b * kHeightSamples + a); };
          const double p00[3] = {x0 + i * s, y0 + j * s, n.h[at(i, j)]};
          const double p10[3] = {x0 + (i + 1) * s, y0 + j * s, n.h[at(i + 1, j)]};
          const double p11[3] = {x0 + (i + 1) * s, y0 + (j + 1) * s, n.h[at(i + 1, j + 1)]};
          const double p01[3] = {x0 + i * s, y0 + (j + 1) * s, n.h[at(i, j + 1)]};
          const auto& H = n.holes;
          if (!(H[at(i, j)] || H[at(i + 1, j)] || H[at(i + 1, j + 1)])) hit |= triangle(o, d, p00, p10, p11, best);
          if (!(H[at(i, j)] || H[at(i + 1, j + 1)] || H[at(i, j + 1)])) hit |= triangle(o, d, p00, p11, p01, best);
        }
    }
    t_out = best;
    return hit;
  }

 private:
  struct Node {
    NodeKey key;
    std::vector<double> h;
    std::vector<uint8_t> holes;
    std::array<bool, 4> covered;
  };
  static bool triangle(const double o[3], const double d[3], const double a[3], const double b[3], const double c[3],
                       double& best) {
    const double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double p[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
    const double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
    if (det == 0) return false;
    const double s[3] = {o[0] - a[0], o[1] - a[1], o[2] - a[2]};
    const double u = (s[0] * p[0] + s[1] * p[1] + s[2] * p[2]) / det;
    if (u < 0 || u > 1) return false;
    const double q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]};
    const double v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det;
    if (v < 0 || u + v > 1) return false;
    const double t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
    if (t < 0 || t > best) return false;
    best = t;
    return true;
  }
  WorldInfo world_;
  std::vector<Node> nodes_;
};

// A ray marched in `step` metre steps with SurfaceSampler (what a game without ray queries does).
bool march(SurfaceSampler& sampler, const Ray& ray, double step, ReadFailures& failures) {
  const double len = std::hypot(ray.direction[0], ray.direction[1], ray.direction[2]);
  for (double t = 0; t <= ray.max_distance_m; t += step) {
    const double x = ray.origin[0] + t * ray.direction[0] / len, y = ray.origin[1] + t * ray.direction[1] / len;
    std::optional<SurfaceSample> s;
    const Status st = sampler.sample(x, y, s);
    failures.note(st);
    if (!st.ok()) return false;  // counted; the run will fail
    if (s && s->height_m >= ray.origin[2] + t * ray.direction[2] / len) return true;
  }
  return false;
}

}  // namespace

int main(int argc, char** argv) {
  const Options opt = parse(argc, argv);
  Streamer streamer;
  StreamerConfig config;
  config.budget_nodes = opt.budget;
  config.error_target_px = opt.error_px;
  if (Status s = streamer.open(opt.archive, config); !s.ok()) {
    std::fprintf(stderr, "terrain-query-bench: %s\n", s.to_string().c_str());
    return 1;
  }
  const WorldInfo& w = streamer.world();
  ArchiveReader reader;
  if (Status s = open_archive(reader, opt.archive); !s.ok()) {
    std::fprintf(stderr, "terrain-query-bench: %s\n", s.to_string().c_str());
    return 1;
  }
  ReadFailures read_failures;
  uint64_t stream_failures = 0;
  std::string first_stream_failure;
  // Default camera: over the middle node (directory order) of the archive's finest level.
  const auto nodes = reader.nodes();
  const uint32_t finest = nodes.front().key.level;
  const size_t n_finest = size_t(std::count_if(nodes.begin(), nodes.end(), [&](const NodeRecord& r) { return r.key.level == finest; }));
  const NodeKey mid = nodes[n_finest / 2].key;
  const double cx = std::isnan(opt.x) ? w.origin_x_m + (mid.x + 0.5) * node_size_m(int(finest)) : opt.x;
  const double cy = std::isnan(opt.y) ? w.origin_y_m + (mid.y + 0.5) * node_size_m(int(finest)) : opt.y;
  ArchiveSurface archive(reader);
  SurfacePoint ground;
  (void)archive.height_at(cx, cy, ground);
  View v;
  v.x = cx;
  v.y = cy;
  v.z = (ground.hit ? ground.height_m : 0) + 2;
  const auto settle_start = Clock::now();
  for (int f = 0; f < 20000; ++f) {
    const FrameUpdate& u = streamer.update({&v, 1});
    for (const NodeFailure& nf : u.failed)
      if (stream_failures++ == 0) first_stream_failure = nf.status.to_string();
    if (streamer.stats().wanted_missing == 0 && f > 2) break;
    if (std::chrono::duration<double>(Clock::now() - settle_start).count() > 60) break;
  }
  const ResidentSurface surface = streamer.resident_surface();
  std::array<uint32_t, kLevelCount> per_level{};
  for (const NodeKey& k : surface.nodes()) ++per_level[k.level];

  // Query sets.
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> ua(0, 6.283185307179586), ur(0, 1), graze(-0.02, 0.02);
  std::normal_distribution<double> g(0, 1);
  auto point = [&] {
    const double r = opt.radius * std::sqrt(ur(rng)), a = ua(rng);
    return std::array<double, 2>{cx + r * std::cos(a), cy + r * std::sin(a)};
  };
  std::vector<std::array<double, 2>> points(1 << 20);
  for (auto& p : points) p = point();
  auto make_rays = [&](size_t n, double length, bool grazing) {
    std::vector<Ray> rays;
    while (rays.size() < n) {
      const auto p = point();
      const SurfacePoint q = surface.height_at(p[0], p[1]);
      if (!q.hit) continue;
      Ray r{{p[0], p[1], q.height_m + 1.8}, {g(rng), g(rng), g(rng)}, length};
      if (grazing) r.direction[2] = graze(rng) * std::hypot(r.direction[0], r.direction[1]);
      rays.push_back(r);
    }
    return rays;
  };
  const std::vector<Ray> rays100 = make_rays(200000, 100, false), grazing = make_rays(100000, 100, true),
                         rays1k = make_rays(50000, 1000, false);

  std::vector<SurfacePoint> out(points.size());
  std::vector<RayHit> hits(rays100.size());
  size_t count_hits = 0;
  struct Row {
    std::string query, method;
    double rate;
    std::string note;
  };
  std::vector<Row> rows;
  auto hit_share = [](size_t h, size_t n) {
    char b[64];
    std::snprintf(b, sizeof b, "%.1f %% hit", 100.0 * double(h) / double(n));
    return std::string(b);
  };

  // Once a load or read has failed the rates describe a different archive: the measurements stop
  // there (failing queries would only be timed failing) and the run reports the failure.
  auto failing = [&] { return stream_failures > 0 || read_failures.count > 0; };
  // Heights.
  const double r_height = median_rate(opt.runs, [&] {
    surface.heights_at(points, out);
    return points.size();
  });
  count_hits = size_t(std::count_if(out.begin(), out.end(), [](const SurfacePoint& p) { return p.hit; }));
  rows.push_back({"height", "ResidentSurface::heights_at", r_height, hit_share(count_hits, points.size())});
  const double r_single = median_rate(opt.runs, [&] {
    double sum = 0;
    for (const auto& p : points) sum += surface.height_at(p[0], p[1]).height_m;
    if (sum == 1.2345) std::printf(" ");
    return points.size();
  });
  rows.push_back({"height", "ResidentSurface::height_at", r_single, ""});
  const bool settled_badly = failing();
  const size_t n_sampler = 200000;
  SurfaceSampler sampler(reader);
  const double r_sampler = settled_badly ? 0 : median_rate(opt.runs, [&] {
    for (size_t i = 0; i < n_sampler; ++i) {
      std::optional<SurfaceSample> s;
      read_failures.note(sampler.sample(points[i][0], points[i][1], s));
    }
    return n_sampler;
  });
  if (!settled_badly) rows.push_back({"height", "SurfaceSampler::sample (finest)", r_sampler, ""});
  const double r_archive = failing() ? 0 : median_rate(opt.runs, [&] {
    SurfacePoint p;
    for (size_t i = 0; i < n_sampler; ++i) read_failures.note(archive.height_at(points[i][0], points[i][1], p));
    return n_sampler;
  });
  if (r_archive > 0) rows.push_back({"height", "ArchiveSurface::height_at (finest)", r_archive, ""});

  // Rays.
  auto ray_rows = [&](const std::string& name, const std::vector<Ray>& rays, size_t n_brute, size_t n_march) {
    if (failing()) return;
    hits.resize(rays.size());
    const double r = median_rate(opt.runs, [&] {
      surface.raycast(rays, hits);
      return rays.size();
    });
    const size_t h = size_t(std::count_if(hits.begin(), hits.end(), [](const RayHit& x) { return x.hit; }));
    rows.push_back({name, "ResidentSurface::raycast", r, hit_share(h, rays.size())});
    if (failing()) return;
    const double rm = median_rate(std::min(opt.runs, 3), [&] {
      for (size_t i = 0; i < n_march; ++i) (void)march(sampler, rays[i], 0.5, read_failures);
      return n_march;
    });
    if (failing()) return;
    rows.push_back({name, "SurfaceSampler march, 0.5 m steps", rm, "approximate"});
    if (n_brute) {
      static std::unique_ptr<BruteForce> brute;
      if (!brute) brute = std::make_unique<BruteForce>(reader, surface.nodes(), read_failures);
      size_t agree = 0;
      const double rb = median_rate(1, [&] {
        for (size_t i = 0; i < n_brute; ++i) {
          double t = 0;
          const bool bh = brute->cast(rays[i], t);
          agree += bh == hits[i].hit && (!bh || std::fabs(t - hits[i].distance_m) <= 1e-6);
        }
        return n_brute;
      });
      char note[64];
      std::snprintf(note, sizeof note, "%zu/%zu agree", agree, n_brute);
      rows.push_back({name, "brute force, every resident triangle", rb, note});
    }
  };
  ray_rows("ray 100 m", rays100, 20, 20000);
  ray_rows("ray 100 m grazing", grazing, 10, 20000);
  ray_rows("ray 1 km", rays1k, 10, 2000);

  std::printf("archive %s: %zu resident nodes (per level 0..5:", opt.archive.c_str(), surface.nodes().size());
  for (uint32_t n : per_level) std::printf(" %u", n);
  std::printf("), camera %.1f m above the ground at (%.1f, %.1f) after %d updates, queries within %.0f m of it,\n"
              "one thread, rates per second of thread CPU time, median of %d runs\n",
              v.z - (ground.hit ? ground.height_m : 0), cx, cy, int(streamer.stats().frame), opt.radius, opt.runs);
  std::printf("| %-18s | %-37s | %14s | %-14s |\n", "query", "method", "per second", "");
  std::printf("|%s|%s|%s|%s|\n", std::string(20, '-').c_str(), std::string(39, '-').c_str(),
              std::string(16, '-').c_str(), std::string(16, '-').c_str());
  for (const Row& r : rows) {
    char rate[32];
    if (r.rate >= 1e6)
      std::snprintf(rate, sizeof rate, "%.2f M", r.rate / 1e6);
    else if (r.rate >= 1e3)
      std::snprintf(rate, sizeof rate, "%.1f k", r.rate / 1e3);
    else
      std::snprintf(rate, sizeof rate, "%.2f", r.rate);
    std::printf("| %-18s | %-37s | %14s | %-14s |\n", r.query.c_str(), r.method.c_str(), rate, r.note.c_str());
  }
  std::printf("failed loads: %llu streamer node loads, %llu archive reads by the queries that read the file\n",
              (unsigned long long)stream_failures, (unsigned long long)read_failures.count);
  // The rates above then describe a different (smaller) archive: the run failed.
  if (stream_failures > 0 || read_failures.count > 0) {
    std::fprintf(stderr, "terrain-query-bench: %s: %llu streamer node loads and %llu archive reads failed (first: %s)\n",
                 opt.archive.c_str(), (unsigned long long)stream_failures, (unsigned long long)read_failures.count,
                 (stream_failures > 0 ? first_stream_failure : read_failures.first).c_str());
    return 1;
  }
  return 0;
}
