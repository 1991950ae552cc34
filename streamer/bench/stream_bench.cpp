// terrain-stream-bench: replays camera paths over archives through the streamer and through a
// naive synchronous loader in the same run, and prints what a user needs to judge the streamer:
// teleport-to-settled time, frames whose wanted / required set was not resident, the caller's
// per-frame cost, bytes read, decode speed next to raw zstd, and memory against the budget.
#include <malloc.h>
#include <time.h>
#include <unistd.h>
#include <zstd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "latency_proxy.h"
#include "naive_loader.h"
#include "synthetic_archive.h"
#include "terrain/archive_reader.h"
#include "terrain/sample.h"
#include "terrain/cpu_clock.h"
#include "terrain/remote_source.h"
#include "terrain/streamer.h"

namespace terrain::bench {
namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }
// CPU time of the calling thread (unaffected by other processes taking the cores).
double thread_cpu_ms() { return terrain::thread_cpu_seconds() * 1e3; }

constexpr const char* kNaiveDescription =
    "synchronous ArchiveReader::decode_node of every wanted, non-resident node on the caller's thread inside its update(), "
    "in split (priority) order, each into a new NodeData, with the same reader, wanted-set rule and budget; evicts by freeing";

struct Options {
  std::vector<std::string> archives;
  std::string make_synthetic;
  uint32_t budget = 512;
  uint32_t threads = 2;
  uint32_t fetches = 0;  // StreamerConfig::max_fetches (0: automatic)
  uint32_t max_deliveries = 128;
  double fps = 60;
  double seconds = 6;
  int teleports = 8;
  double target_px = 2;
  uint64_t seed = 1;
  bool json = false;
  bool quiet = false;
  std::vector<double> rtt_ms;  // --rtt-ms: round trips to add (an http:// archive through a LatencyProxy)
  std::vector<double> mbit;    // --mbit: link bandwidths (0: unlimited)
};

// ---- Memory ----------------------------------------------------------------------------------
uint64_t heap_in_use() {
  const struct mallinfo2 mi = mallinfo2();
  return uint64_t(mi.uordblks) + uint64_t(mi.hblkhd);
}
uint64_t rss_anon_bytes() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("RssAnon:", 0) == 0) return std::stoull(line.substr(8)) * 1024;
  return 0;
}

std::string load_average() {
  std::ifstream f("/proc/loadavg");
  std::string a;
  f >> a;
  return a.empty() ? "?" : a;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}
double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(p * double(v.size() - 1) + 0.5))];
}

// ---- Camera paths ----------------------------------------------------------------------------
struct Path {
  std::string name;
  bool teleports = false;        // each view is a teleport target, held until settled
  std::vector<View> views;       // per frame (flights) or per teleport
};

class Ground {
 public:
  explicit Ground(const ArchiveReader& reader) : sampler_(reader) {}
  double height(double x, double y, double fallback) {
    std::optional<SurfaceSample> s;
    if (sampler_.sample(x, y, s).ok() && s) return s->height_m;
    return fallback;
  }

 private:
  SurfaceSampler sampler_;
};

// The streamer's configuration the options ask for.
StreamerConfig streamer_config(const Options& o) {
  StreamerConfig config;
  config.budget_nodes = o.budget;
  config.worker_threads = o.threads;
  config.max_fetches = o.fetches;
  config.error_target_px = o.target_px;
  config.max_deliveries_per_frame = o.max_deliveries;
  return config;
}

std::vector<Path> make_paths(const ArchiveReader& reader, const Options& o) {
  const WorldInfo& w = reader.world();
  // Paths start over the finest nodes of the archive (where detail, and so streaming, is).
  uint32_t finest = uint32_t(kRootLevel);
  for (const NodeRecord& r : reader.nodes()) finest = std::min(finest, r.key.level);
  std::vector<const NodeRecord*> fine;
  for (const NodeRecord& r : reader.nodes())
    if (r.key.level == finest) fine.push_back(&r);
  std::mt19937_64 rng(o.seed);
  Ground ground(reader);
  auto random_point = [&](double& x, double& y, double& top) {
    const NodeRecord& r = *fine[rng() % fine.size()];
    const double size = node_size_m(int(r.key.level));
    std::uniform_real_distribution<double> u(0.1 * size, 0.9 * size);
    x = w.origin_x_m + r.key.x * size + u(rng);
    y = w.origin_y_m + r.key.y * size + u(rng);
    top = units_to_metres(r.max_height);
  };
  const double cx = 0.5 * (w.extent_min_x_m + w.extent_max_x_m), cy = 0.5 * (w.extent_min_y_m + w.extent_max_y_m);
  std::vector<Path> paths;

  Path tp{"teleport", true, {}};
  for (int i = 0; i < o.teleports; ++i) {
    double x, y, top;
    random_point(x, y, top);
    const double alt = std::uniform_real_distribution<double>(5, 60)(rng);
    tp.views.push_back(View{x, y, ground.height(x, y, top) + alt});
  }
  paths.push_back(tp);

  struct Kind {
    const char* name;
    double speed, altitude;
  };
  for (const Kind k : {Kind{"flight 50 m/s", 50, 40}, Kind{"flight 300 m/s", 300, 120}, Kind{"walk 2 m/s", 2, 1.8}}) {
    Path p{k.name, false, {}};
    double x, y, top;
    random_point(x, y, top);
    // Towards the middle of the data, so the path stays over terrain for as long as possible.
    const double heading = std::atan2(cy - y, cx - x) + std::uniform_real_distribution<double>(-0.4, 0.4)(rng);
    const int frames = int(o.seconds * o.fps);
    double z = top;
    for (int f = 0; f < frames; ++f) {
      x += std::cos(heading) * k.speed / o.fps;
      y += std::sin(heading) * k.speed / o.fps;
      z = ground.height(x, y, z);
      p.views.push_back(View{x, y, z + k.altitude});
    }
    paths.push_back(p);
  }
  return paths;
}

// ---- Results ---------------------------------------------------------------------------------
struct Result {
  std::string path, loader;
  int frames = 0;
  int wanted_missing_frames = 0;  // a wanted node (prefetch included) not resident after update()
  int gap_frames = 0;             // a node the error target requires not resident after update()
  std::vector<double> settle_ms;  // teleports: update() of the jump to the update() that completes the wanted set
  std::vector<double> required_ms;  // teleports: ... that completes the required set
  std::vector<int> settle_frames;
  std::vector<uint32_t> settled_wanted;
  std::vector<double> work_ms;        // teleports: CPU time of all decode work + the caller's update()s until settled
  std::vector<double> teleport_loads; // teleports: nodes loaded (decodes begun) until settled
  std::vector<double> caller_ms;      // teleports: the caller's share of work_ms (update()s; naive: all of it)
  std::vector<double> update_ms;      // caller's thread cost per frame, wall clock
  std::vector<double> update_cpu_ms;  // ... CPU time of the caller's thread
  uint64_t bytes_read = 0;
  uint64_t loads = 0;
  uint64_t failed = 0;         // node loads that failed (bad payload, short read): reported, never retried
  std::string first_failure;   // the first of them, as the loader reported it
  bool invariants_ok = true;
};

nlohmann::json to_json(const Result& r) {
  nlohmann::json j;
  j["path"] = r.path;
  j["loader"] = r.loader;
  j["frames"] = r.frames;
  j["wanted_missing_frames"] = r.wanted_missing_frames;
  j["gap_frames"] = r.gap_frames;
  if (!r.settle_ms.empty()) {
    j["settle_ms"] = r.settle_ms;
    j["settle_ms_median"] = median(r.settle_ms);
    j["settle_ms_max"] = *std::max_element(r.settle_ms.begin(), r.settle_ms.end());
    j["required_ms"] = r.required_ms;
    j["settle_frames"] = r.settle_frames;
    j["settled_wanted_nodes"] = r.settled_wanted;
    j["work_cpu_ms"] = r.work_ms;
    j["work_cpu_ms_median"] = median(r.work_ms);
    j["teleport_loads"] = r.teleport_loads;
    j["caller_cpu_ms"] = r.caller_ms;
  }
  j["update_ms_median"] = median(r.update_ms);
  j["update_ms_p99"] = percentile(r.update_ms, 0.99);
  j["update_ms_max"] = r.update_ms.empty() ? 0 : *std::max_element(r.update_ms.begin(), r.update_ms.end());
  j["update_cpu_ms_median"] = median(r.update_cpu_ms);
  j["update_cpu_ms_max"] = r.update_cpu_ms.empty() ? 0 : *std::max_element(r.update_cpu_ms.begin(), r.update_cpu_ms.end());
  j["bytes_read"] = r.bytes_read;
  j["loads"] = r.loads;
  j["failed_loads"] = r.failed;
  if (!r.first_failure.empty()) j["first_failure"] = r.first_failure;
  j["invariants_ok"] = r.invariants_ok;
  return j;
}

// Cheap per-frame checks of the streamer's invariants through its public API.
bool invariants_hold(const Streamer& s, const std::vector<NodeKey>& roots) {
  const StreamerStats st = s.stats();
  if (st.resident > s.config().budget_nodes) return false;
  for (const NodeKey& r : roots)
    if (s.slot_of(r) < 0) return false;
  for (const NodeKey& k : s.resident_nodes())
    if (k.level < uint32_t(kRootLevel) && s.slot_of(parent_of(k)) < 0) return false;
  return true;
}

struct MemoryPeak {
  uint64_t heap_base = 0, heap_peak = 0, rss_base = 0, rss_peak = 0;
  void start() {
    heap_base = heap_peak = heap_in_use();
    rss_base = rss_peak = rss_anon_bytes();
  }
  void sample() {
    heap_peak = std::max(heap_peak, heap_in_use());
    rss_peak = std::max(rss_peak, rss_anon_bytes());
  }
};

class Pacer {
 public:
  explicit Pacer(double fps) : period_(fps > 0 ? std::chrono::duration<double>(1.0 / fps) : std::chrono::duration<double>(0)) {}
  void wait() {
    if (period_.count() <= 0) {
      std::this_thread::sleep_for(std::chrono::microseconds(500));  // unpaced: just let workers run
      return;
    }
    next_ += std::chrono::duration_cast<Clock::duration>(period_);
    const auto now = Clock::now();
    if (next_ < now) next_ = now;  // behind: do not try to catch up
    std::this_thread::sleep_until(next_);
  }
  void reset() { next_ = Clock::now(); }

 private:
  std::chrono::duration<double> period_;
  Clock::time_point next_ = Clock::now();
};

// Runs every path through the streamer. `delivered` collects the nodes loaded (for the decode comparison).
std::vector<Result> run_streamer(const std::string& archive, const std::vector<Path>& paths, const StreamerConfig& config,
                                 double fps, MemoryPeak& mem, StreamerStats& final_stats, std::set<uint32_t>* delivered,
                                 std::string& error) {
  std::vector<Result> results;
  mem.start();
  Streamer s;
  if (Status st = s.open(archive, config); !st.ok()) {
    error = st.to_string();
    return results;
  }
  std::vector<NodeKey> roots;
  for (const NodeRecord& r : s.archive().nodes())
    if (r.key.level == uint32_t(s.archive().top_level())) roots.push_back(r.key);  // the top nodes: always resident
  Pacer pacer(fps);
  auto frame = [&](const View& v, Result& res) {
    const auto t0 = Clock::now();
    const double c0 = thread_cpu_ms();
    const FrameUpdate& u = s.update({&v, 1});
    res.update_cpu_ms.push_back(thread_cpu_ms() - c0);
    res.update_ms.push_back(ms_since(t0));
    ++res.frames;
    for (const NodeDelivery& d : u.delivered) {
      ++res.loads;
      if (delivered) delivered->insert(uint32_t(s.archive().find(d.key)));
    }
    for (const NodeFailure& f : u.failed) {
      if (res.failed++ == 0) res.first_failure = f.status.to_string();
    }
    const StreamerStats st = s.stats();
    res.wanted_missing_frames += st.wanted_missing > 0;
    res.gap_frames += st.required_missing > 0;
    res.invariants_ok = res.invariants_ok && invariants_hold(s, roots);
    mem.sample();
    return st;
  };
  auto settle = [&](const View& v) {  // untimed: bring the start of a path to a steady state
    Result scratch;
    for (int i = 0; i < 100000; ++i) {
      if (frame(v, scratch).wanted_missing == 0) break;
      pacer.wait();
    }
    return scratch;
  };
  for (const Path& p : paths) {
    Result res;
    res.path = p.name;
    res.loader = "streamer";
    uint64_t bytes0 = s.stats().bytes_read;
    if (p.teleports) {
      for (const View& v : p.views) {
        pacer.reset();
        const StreamerStats before = s.stats();
        const size_t first_frame = res.update_cpu_ms.size();
        const auto t0 = Clock::now();
        double required = -1;
        for (int f = 1;; ++f) {
          const StreamerStats st = frame(v, res);
          if (required < 0 && st.required_missing == 0) required = ms_since(t0);
          if (st.wanted_missing == 0) {
            res.settle_ms.push_back(ms_since(t0));
            res.required_ms.push_back(required);
            res.settle_frames.push_back(f);
            res.settled_wanted.push_back(st.wanted);
            double caller_ms = 0;
            for (size_t i = first_frame; i < res.update_cpu_ms.size(); ++i) caller_ms += res.update_cpu_ms[i];
            res.work_ms.push_back(1e3 * (st.decode_cpu_seconds - before.decode_cpu_seconds) + caller_ms);
            res.teleport_loads.push_back(double(st.loads_started - before.loads_started));
            res.caller_ms.push_back(caller_ms);
            break;
          }
          pacer.wait();
        }
      }
    } else {
      const Result settled = settle(p.views.front());
      res = Result{};
      res.path = p.name;
      res.loader = "streamer";
      res.failed = settled.failed;  // failures while settling count too
      res.first_failure = settled.first_failure;
      bytes0 = s.stats().bytes_read;
      pacer.reset();
      for (const View& v : p.views) {
        frame(v, res);
        pacer.wait();
      }
    }
    res.bytes_read = s.stats().bytes_read - bytes0;
    results.push_back(res);
  }
  final_stats = s.stats();
  return results;
}

std::vector<Result> run_naive(const ArchiveReader& reader, const std::vector<Path>& paths, const StreamerConfig& config,
                              MemoryPeak& mem) {
  std::vector<Result> results;
  mem.start();
  NaiveLoader naive(reader, config);
  uint64_t peak_buffers = 0;
  for (const Path& p : paths) {
    Result res;
    res.path = p.name;
    res.loader = "naive";
    auto frame = [&](const View& v) {
      const auto t0 = Clock::now();
      const double c0 = thread_cpu_ms();
      const NaiveLoader::FrameStats fs = naive.update({&v, 1});
      res.update_cpu_ms.push_back(thread_cpu_ms() - c0);
      const double ms = ms_since(t0);
      res.update_ms.push_back(ms);
      ++res.frames;
      res.loads += fs.loaded;
      res.failed += fs.failed;
      if (fs.failed > 0 && res.first_failure.empty()) res.first_failure = fs.first_failure;
      res.bytes_read += fs.bytes_read;
      peak_buffers = std::max(peak_buffers, naive.buffer_bytes());
      mem.sample();
      return ms;
    };
    if (p.teleports) {
      for (const View& v : p.views) {
        // Synchronous: the set is complete when update() returns.
        const uint64_t loads0 = res.loads;
        const double ms = frame(v);
        res.settle_ms.push_back(ms);
        res.required_ms.push_back(ms);
        res.settle_frames.push_back(1);
        res.settled_wanted.push_back(naive.wanted());
        res.work_ms.push_back(res.update_cpu_ms.back());
        res.teleport_loads.push_back(double(res.loads - loads0));
        res.caller_ms.push_back(res.update_cpu_ms.back());
      }
    } else {
      frame(p.views.front());
      const uint64_t settle_failed = res.failed;
      const std::string settle_failure = res.first_failure;
      res = Result{};
      res.path = p.name;
      res.loader = "naive";
      res.failed = settle_failed;  // failures while settling count too
      res.first_failure = settle_failure;
      for (const View& v : p.views) frame(v);  // no pacing: nothing runs in the background
    }
    results.push_back(res);
  }
  return results;
}

// ---- Decode speed: the format's decode against raw zstd of the same payload bytes -------------
struct DecodeSpeed {
  uint64_t nodes = 0, stored_bytes = 0, raw_bytes = 0, zstd_stored_bytes = 0, zstd_raw_bytes = 0;
  double decode_s = 0, zstd_s = 0;
};

uint32_t load_u32(const uint8_t* p) { return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24; }

DecodeSpeed measure_decode(const ArchiveReader& reader, const std::set<uint32_t>& nodes) {
  DecodeSpeed d;
  auto data = std::make_unique<NodeData>();
  std::vector<uint8_t> out(64 * 1024), p;
  ZSTD_DCtx* dctx = ZSTD_createDCtx();
  for (int rep = 0; rep < 3; ++rep) {  // best of 3 (first pass also warms caches)
    double dec = 0, zs = 0;
    uint64_t stored = 0, raw = 0, zstored = 0, zraw = 0;
    for (uint32_t i : nodes) {
      auto t0 = Clock::now();
      if (!reader.decode_node(i, *data).ok()) continue;
      dec += std::chrono::duration<double>(Clock::now() - t0).count();
      if (!reader.read_payload(i, p).ok()) continue;  // outside the timing: the bytes zstd is timed on
      stored += p.size();
      raw += sizeof(NodeData::heights) + sizeof(NodeData::normals_bc3) + sizeof(NodeData::albedo_bc1) +
             sizeof(NodeData::splat) + sizeof(NodeData::cones_bc3);
      // format/SPEC.md section 9.1: 64-byte table, five 12-byte entries from offset 4, data back to back.
      size_t at = 64;
      t0 = Clock::now();
      for (int k = 0; k < 5 && p.size() >= 64; ++k) {
        const uint8_t* e = p.data() + 4 + 12 * k;
        const uint8_t codec = e[1];
        const uint32_t stored_size = load_u32(e + 4), raw_size = load_u32(e + 8);
        if (at + stored_size > p.size()) break;
        if (codec != 0 && raw_size <= out.size()) {
          const size_t n = ZSTD_decompressDCtx(dctx, out.data(), out.size(), p.data() + at, stored_size);
          if (!ZSTD_isError(n)) {
            zstored += stored_size;
            zraw += n;
          }
        }
        at += stored_size;
      }
      zs += std::chrono::duration<double>(Clock::now() - t0).count();
    }
    if (rep == 0 || dec < d.decode_s) {
      d.decode_s = dec;
      d.stored_bytes = stored;
      d.raw_bytes = raw;
    }
    if (rep == 0 || zs < d.zstd_s) {
      d.zstd_s = zs;
      d.zstd_stored_bytes = zstored;
      d.zstd_raw_bytes = zraw;
    }
  }
  ZSTD_freeDCtx(dctx);
  d.nodes = nodes.size();
  return d;
}

void warm_page_cache(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::vector<char> buf(1 << 20);
  while (f.read(buf.data(), std::streamsize(buf.size())) || f.gcount() > 0) {
  }
}

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

int bench_archive(const std::string& archive, const Options& o, nlohmann::json& json_out) {
  ArchiveReader reader;
  if (Status s = open_archive(reader, archive); !s.ok()) {
    std::fprintf(stderr, "terrain-stream-bench: %s\n", s.to_string().c_str());
    return 1;
  }
  uint32_t roots = 0;
  for (const NodeRecord& r : reader.nodes()) roots += r.key.level == uint32_t(kRootLevel);
  const StreamerConfig config = streamer_config(o);
  const bool progress = !o.quiet && isatty(2);
  if (progress) std::fprintf(stderr, "%s: preparing paths...\n", archive.c_str());
  const std::vector<Path> paths = make_paths(reader, o);
  warm_page_cache(archive);

  std::string error;
  MemoryPeak smem, umem, nmem;
  StreamerStats sstats, ustats;
  std::set<uint32_t> delivered;
  if (progress) std::fprintf(stderr, "%s: streamer, %.0f fps...\n", archive.c_str(), o.fps);
  std::vector<Result> results = run_streamer(archive, paths, config, o.fps, smem, sstats, &delivered, error);
  if (!error.empty()) {
    std::fprintf(stderr, "terrain-stream-bench: %s\n", error.c_str());
    return 1;
  }
  if (progress) std::fprintf(stderr, "%s: streamer, unpaced teleports...\n", archive.c_str());
  {
    std::vector<Path> tp = {paths.front()};
    auto r = run_streamer(archive, tp, config, 0, umem, ustats, nullptr, error);
    if (!error.empty()) std::fprintf(stderr, "terrain-stream-bench: unpaced run: %s\n", error.c_str());
    for (auto& x : r) {
      x.loader = "streamer, unpaced";
      results.push_back(x);
    }
  }
  if (progress) std::fprintf(stderr, "%s: streamer, delivery cap = budget...\n", archive.c_str());
  const std::string uncapped_name = "streamer, cap " + std::to_string(o.budget);
  {
    // Same teleports with the per-frame delivery bound lifted to the budget: what the cap costs.
    StreamerConfig uncapped = config;
    uncapped.max_deliveries_per_frame = o.budget;
    std::vector<Path> tp = {paths.front()};
    MemoryPeak m;
    StreamerStats ss;
    auto r = run_streamer(archive, tp, uncapped, o.fps, m, ss, nullptr, error);
    if (!error.empty()) std::fprintf(stderr, "terrain-stream-bench: %s run: %s\n", uncapped_name.c_str(), error.c_str());
    for (auto& x : r) {
      x.loader = uncapped_name;
      results.push_back(x);
    }
  }
  if (progress) std::fprintf(stderr, "%s: naive loader...\n", archive.c_str());
  {
    auto r = run_naive(reader, paths, config, nmem);
    results.insert(results.end(), r.begin(), r.end());
  }
  if (progress) std::fprintf(stderr, "%s: decode speed...\n", archive.c_str());
  const DecodeSpeed ds = measure_decode(reader, delivered);

  const double node_bytes = double(sizeof(NodeData));
  const double budget_bytes = double(o.budget) * node_bytes;
  const double stream_heap = double(smem.heap_peak - smem.heap_base);
  const double naive_heap = double(nmem.heap_peak - nmem.heap_base);
  const double worker_mb_s = sstats.decode_seconds > 0 ? double(sstats.bytes_decoded) / sstats.decode_seconds / 1e6 : 0;

  // Headline comparisons.
  auto find = [&](const std::string& path, const std::string& loader) -> const Result* {
    for (const Result& r : results)
      if (r.path == path && r.loader == loader) return &r;
    return nullptr;
  };
  const Result* st = find("teleport", "streamer");
  const Result* su = find("teleport", "streamer, unpaced");
  const Result* nt = find("teleport", "naive");
  const double speedup_paced = median(nt->settle_ms) / std::max(1e-9, median(st->settle_ms));
  const double speedup_unpaced = su ? median(nt->settle_ms) / std::max(1e-9, median(su->settle_ms)) : 0;
  const Result* sc = find("teleport", uncapped_name);
  const double speedup_uncapped = sc ? median(nt->settle_ms) / std::max(1e-9, median(sc->settle_ms)) : 0;
  // Where the ceiling is. Both loaders decode the same nodes with the same reader, so a teleport
  // costs about the same CPU work W either way; on C cores no loader settles faster than W / C,
  // and the streamer additionally delivers at most `cap` nodes per update, one update per frame,
  // starting with the update after the teleport's.
  const double cores = std::max(1u, std::thread::hardware_concurrency());
  const double naive_work = median(nt->work_ms), stream_work = su ? median(su->work_ms) : median(st->work_ms);
  const double ceiling_unpaced = stream_work > 0 ? cores * naive_work / stream_work : 0;
  std::vector<double> paced_bound;
  const double period_ms = 1e3 / o.fps;
  for (size_t i = 0; i < st->work_ms.size(); ++i) {
    const double delivery_frames = std::ceil(st->teleport_loads[i] / double(o.max_deliveries));
    const double decode_frames = std::ceil(st->work_ms[i] / cores / period_ms);
    paced_bound.push_back(std::max({1.0, delivery_frames, decode_frames}) * period_ms);
  }
  const double ceiling_paced = median(nt->settle_ms) / std::max(1e-9, median(paced_bound));
  int flight_gap_frames = 0;
  bool invariants = true;
  uint64_t failed_loads = 0;
  std::string first_failure;
  for (const Result& r : results) {
    failed_loads += r.failed;
    if (first_failure.empty()) first_failure = r.first_failure;
  }
  for (const Result& r : results)
    if (r.loader == "streamer") {
      invariants = invariants && r.invariants_ok;
      if (r.path != "teleport") flight_gap_frames += r.gap_frames;
    }

  nlohmann::json j;
  j["archive"] = archive;
  j["naive_loader"] = kNaiveDescription;
  j["load_average_1min"] = load_average();
  j["heap_measured"] = heap_in_use() > 0;
  j["nodes"] = reader.nodes().size();
  j["roots"] = roots;
  j["file_bytes"] = reader.file_size();
  j["budget_nodes"] = o.budget;
  j["worker_threads"] = o.threads;
  j["max_deliveries_per_frame"] = o.max_deliveries;
  j["fps"] = o.fps;
  j["error_target_px"] = o.target_px;
  j["prefetch_ratio"] = config.prefetch_ratio;
  j["slot_count"] = std::min<uint32_t>(o.budget + config.fence_frames * config.max_deliveries_per_frame, kMaxSlots);
  for (const Result& r : results) j["results"].push_back(to_json(r));
  j["decode"] = {{"nodes", ds.nodes},
                 {"stored_bytes", ds.stored_bytes},
                 {"raw_bytes", ds.raw_bytes},
                 {"format_decode_mb_s_raw", ds.decode_s > 0 ? double(ds.raw_bytes) / ds.decode_s / 1e6 : 0},
                 {"format_decode_mb_s_stored", ds.decode_s > 0 ? double(ds.stored_bytes) / ds.decode_s / 1e6 : 0},
                 {"zstd_mb_s_raw", ds.zstd_s > 0 ? double(ds.zstd_raw_bytes) / ds.zstd_s / 1e6 : 0},
                 {"zstd_mb_s_stored", ds.zstd_s > 0 ? double(ds.zstd_stored_bytes) / ds.zstd_s / 1e6 : 0},
                 {"zstd_stored_bytes", ds.zstd_stored_bytes},
                 {"streamer_worker_mb_s_raw", worker_mb_s}};
  j["memory"] = {{"node_bytes", sizeof(NodeData)},
                 {"budget_bytes", budget_bytes},
                 {"streamer_heap_peak_bytes", stream_heap},
                 {"streamer_heap_vs_budget", stream_heap / budget_bytes},
                 {"streamer_rss_anon_peak_bytes", double(smem.rss_peak - smem.rss_base)},
                 {"streamer_buffer_bytes", sstats.buffer_bytes},
                 {"naive_heap_peak_bytes", naive_heap}};
  j["summary"] = {{"teleport_settle_ms_median", median(st->settle_ms)},
                  {"teleport_settle_ms_max", *std::max_element(st->settle_ms.begin(), st->settle_ms.end())},
                  {"speedup_vs_naive_paced", speedup_paced},
                  {"speedup_vs_naive_unpaced", speedup_unpaced},
                  {"speedup_vs_naive_paced_cap_budget", speedup_uncapped},
                  {"work_cpu_ms_median_naive", naive_work},
                  {"work_cpu_ms_median_streamer", stream_work},
                  {"speedup_ceiling_unpaced", ceiling_unpaced},
                  {"settle_ms_lower_bound_paced_median", median(paced_bound)},
                  {"speedup_ceiling_paced", ceiling_paced},
                  {"flight_and_walk_gap_frames", flight_gap_frames},
                  {"failed_loads", failed_loads},
                  {"runs_that_could_not_open", error.empty() ? 0 : 1},
                  {"invariants_ok", invariants}};
  json_out.push_back(j);

  if (!o.json) {
    std::printf("\n%s: %zu nodes (%u roots), %.1f MB; budget %u nodes, %u workers, %u deliveries/frame, %.0f fps, "
                "target %.1f px (prefetch x%.2f), warm page cache, %u cores, load average %s\n",
                archive.c_str(), reader.nodes().size(), roots, double(reader.file_size()) / 1e6, o.budget, o.threads,
                o.max_deliveries, o.fps,
                o.target_px, config.prefetch_ratio, std::thread::hardware_concurrency(), load_average().c_str());
    std::printf("%-16s %-18s %7s %26s %14s %10s %17s %12s %8s %6s %6s\n", "path", "loader", "frames", "settle ms med/max (frames)",
                "wanted-missing", "gap frames", "update ms p50/max", "update cpu max", "MB read", "loads", "failed");
    for (const Result& r : results) {
      std::string settle = "-";
      if (!r.settle_ms.empty()) {
        std::vector<double> fr(r.settle_frames.begin(), r.settle_frames.end());
        settle = fmt("%.1f", median(r.settle_ms)) + " / " + fmt("%.1f", *std::max_element(r.settle_ms.begin(), r.settle_ms.end())) +
                 " (" + fmt("%.0f", median(fr)) + ")";
      }
      const double umax = r.update_ms.empty() ? 0 : *std::max_element(r.update_ms.begin(), r.update_ms.end());
      const double cmax = r.update_cpu_ms.empty() ? 0 : *std::max_element(r.update_cpu_ms.begin(), r.update_cpu_ms.end());
      std::printf("%-16s %-18s %7d %26s %14d %10d %17s %12.2f %8.1f %6llu %6llu\n", r.path.c_str(), r.loader.c_str(), r.frames,
                  settle.c_str(), r.wanted_missing_frames, r.gap_frames,
                  (fmt("%.3f", median(r.update_ms)) + " / " + fmt("%.2f", umax)).c_str(), cmax, double(r.bytes_read) / 1e6,
                  (unsigned long long)r.loads, (unsigned long long)r.failed);
    }
    if (st) {
      std::vector<double> w(st->settled_wanted.begin(), st->settled_wanted.end());
      std::printf("teleport: settled wanted set median %.0f nodes; required set complete after %.1f ms (median)\n", median(w),
                  median(st->required_ms));
    }
    if (median(nt->settle_ms) >= 1.0)
      std::printf("speed-up over the naive loader (teleport to settled, median): %.2fx at %.0f fps (%u deliveries/frame), "
                  "%.2fx at %.0f fps with %u deliveries/frame, %.2fx unpaced\n",
                  speedup_paced, o.fps, o.max_deliveries, speedup_uncapped, o.fps, o.budget, speedup_unpaced);
    else
      std::printf("speed-up over the naive loader: n/a (the naive loader settles teleports in under 1 ms here: the "
                  "archive stays resident)\n");
    const Result* sw = su ? su : st;
    std::printf("work per teleport until settled (CPU ms, median): naive %.1f (its update()), streamer %.1f (workers' decode "
                "%.1f + caller's update()s %.1f over %.0f frames); loads per teleport (median): naive %.0f, streamer %.0f\n",
                naive_work, stream_work, median(sw->work_ms) - median(sw->caller_ms), median(sw->caller_ms),
                median(std::vector<double>(sw->settle_frames.begin(), sw->settle_frames.end())), median(nt->teleport_loads),
                median(sw->teleport_loads));
    std::printf("ceiling: on %.0f cores no loader doing the streamer's work settles faster than work / cores: at most %.2fx "
                "unpaced; at %.0f fps with %u deliveries/frame the streamer settles no earlier than max(ceil(loads / cap), "
                "ceil(work / cores / frame)) frames after the teleport's update = %.1f ms (median): at most %.2fx\n",
                cores, ceiling_unpaced, o.fps, o.max_deliveries, median(paced_bound), ceiling_paced);
    std::printf("naive loader: %s\n", kNaiveDescription);
    std::printf("decode (%llu nodes, 1 thread): format %.0f MB/s raw (%.0f MB/s stored); raw zstd of the same sections %.0f MB/s "
                "raw (%.0f MB/s stored); in the streamer's workers %.0f MB/s raw per thread\n",
                (unsigned long long)ds.nodes, ds.decode_s > 0 ? double(ds.raw_bytes) / ds.decode_s / 1e6 : 0,
                ds.decode_s > 0 ? double(ds.stored_bytes) / ds.decode_s / 1e6 : 0,
                ds.zstd_s > 0 ? double(ds.zstd_raw_bytes) / ds.zstd_s / 1e6 : 0,
                ds.zstd_s > 0 ? double(ds.zstd_stored_bytes) / ds.zstd_s / 1e6 : 0, worker_mb_s);
    if (heap_in_use() > 0)
      std::printf("memory: budget x node = %.1f MB; streamer heap peak %.1f MB (%.3f x), RssAnon peak +%.1f MB; naive heap peak "
                  "%.1f MB\n",
                  budget_bytes / 1e6, stream_heap / 1e6, stream_heap / budget_bytes, double(smem.rss_peak - smem.rss_base) / 1e6,
                  naive_heap / 1e6);
    else
      std::printf("memory: budget x node = %.1f MB; heap n/a (allocator without mallinfo2, e.g. a sanitizer build), "
                  "RssAnon peak +%.1f MB, streamer decode buffers %.1f MB\n",
                  budget_bytes / 1e6, double(smem.rss_peak - smem.rss_base) / 1e6, double(sstats.buffer_bytes) / 1e6);
    std::printf("invariants (roots resident, parent closure, budget) every frame: %s; gap frames on flights and walk: %d\n"
                "(gap frame: after update() some node the error target requires is not resident, so a coarser resident "
                "ancestor is drawn there; wanted-missing also counts prefetched nodes)\n",
                invariants ? "held" : "BROKEN", flight_gap_frames);
  }
  // Failed loads make every figure above describe a different (smaller) archive: the run failed.
  if (failed_loads > 0)
    std::fprintf(stderr, "terrain-stream-bench: %s: %llu node loads failed (first: %s)\n", archive.c_str(),
                 (unsigned long long)failed_loads, first_failure.c_str());
  if (!error.empty()) std::fprintf(stderr, "terrain-stream-bench: %s: a streamer run could not open the archive\n", archive.c_str());
  return invariants && failed_loads == 0 && error.empty() ? 0 : 1;
}


// ---- Over a link: the streamer reading an http:// archive through a LatencyProxy ---------------
// Per round trip and bandwidth: the open (time, requests, bytes), the teleports (time until the
// wanted set and until the required set are resident; the physical limit: the bytes that crossed
// the link divided by its bandwidth plus one round trip, as if every request went out at once),
// and the 300 m/s flight paced at --fps (gap frames: a required node not resident). Columns:
// settle_ms / req_ms: until the wanted / required set is resident; x: settle_ms over limit_ms
// (teleports that fetched anything); reqs and KB: HTTP requests and bytes per teleport. Before the
// streamer, a reader opened by page (SPEC 20: header, then page table and metadata): pg_open_ms,
// reqs, KB; then its descent from the top to the finest node under the first teleport, every
// level's page prefetched at once: descend_ms and the directory pages it read.
int bench_links(const std::string& url, const Options& o, nlohmann::json& json_out) {
  std::string host, path;
  int port = 0;
  if (!tools::parse_http_url(url, host, port, path)) {
    std::fprintf(stderr, "terrain-stream-bench: --rtt-ms needs http:// archives (the proxy speaks plain TCP): %s\n",
                 url.c_str());
    return 2;
  }
  ArchiveReader reader;
  if (Status s = open_archive(reader, url); !s.ok()) {
    std::fprintf(stderr, "terrain-stream-bench: %s\n", s.to_string().c_str());
    return 1;
  }
  const std::vector<Path> paths = make_paths(reader, o);
  const Path& teleports = paths[0];
  const Path& flight = paths[2];  // flight 300 m/s
  const StreamerConfig config = streamer_config(o);
  const std::string reads_in_flight = o.fetches ? std::to_string(o.fetches) : std::to_string(kRemoteFetches) + " (automatic)";
  if (!o.json)
    std::printf("\n%s over a link (LatencyProxy: rtt/2 each way, one link per direction shared by the connections), "
                "%u workers, %s reads in flight, budget %u, %d teleports (medians), %s paced at %.0f fps for %.0f s\n\n"
                "%6s %6s | %10s %4s %6s %10s %5s | %8s %5s %8s | %9s %9s %9s %6s %6s %8s %5s | %10s\n",
                url.c_str(), o.threads, reads_in_flight.c_str(), o.budget, o.teleports, flight.name.c_str(), o.fps, o.seconds, "rtt_ms", "Mbit",
                "pg_open_ms", "reqs", "KB", "descend_ms", "pages", "open_ms", "reqs", "open_KB", "settle_ms", "req_ms", "limit_ms", "x", "reqs", "KB", "amp", "gap frames");
  int rc = 0;
  for (const double rtt : o.rtt_ms)
    for (const double mbit : o.mbit) {
      tools::LatencyProxy proxy;
      std::string error;
      if (!proxy.start(host, port, tools::LinkModel{rtt, mbit}, error)) {
        std::fprintf(stderr, "terrain-stream-bench: %s\n", error.c_str());
        return 1;
      }
      const std::string through = proxy.proxied(url);
      // A reader by page, and the page of the finest node under the first teleport.
      const auto tp = Clock::now();
      ArchiveReader paged;
      if (Status st = open_archive(paged, through, {}, DirectoryLoad::by_page); !st.ok()) {
        std::fprintf(stderr, "terrain-stream-bench: %s\n", st.to_string().c_str());
        return 1;
      }
      const double page_open_ms = ms_since(tp);
      const tools::ProxyStats paged_open = proxy.stats();
      // From the top down to the finest node under the first teleport, as a runtime reading by
      // page would descend: every level's page at once (prefetch: the page table names them), then
      // one lookup per level, which reads nothing more.
      const View& first = teleports.views.front();
      const auto tq = Clock::now();
      std::vector<NodeKey> descent;
      for (int level = reader.top_level(); level >= 0; --level)
        descent.push_back({uint32_t(level), uint32_t(std::max(0.0, (first.x - reader.world().origin_x_m) / node_size_m(level))),
                        uint32_t(std::max(0.0, (first.y - reader.world().origin_y_m) / node_size_m(level)))});
      if (Status st = paged.prefetch(descent); !st.ok()) {
        std::fprintf(stderr, "terrain-stream-bench: %s\n", st.to_string().c_str());
        return 1;
      }
      for (const NodeKey& key : descent) {
        int64_t index = -1;
        if (Status st = paged.lookup(key, index); !st.ok()) {
          std::fprintf(stderr, "terrain-stream-bench: %s\n", st.to_string().c_str());
          return 1;
        }
        if (index < 0) break;
      }
      const double page_ms = ms_since(tq);
      const uint64_t pages_read = paged.directory_pages_read();
      const tools::ProxyStats before_open = proxy.stats();
      Streamer s;
      const auto t0 = Clock::now();
      if (Status st = s.open(through, config); !st.ok()) {
        std::fprintf(stderr, "terrain-stream-bench: %s\n", st.to_string().c_str());
        return 1;
      }
      const double open_ms = ms_since(t0);
      tools::ProxyStats opened = proxy.stats();
      opened.requests -= before_open.requests;
      opened.bytes_down -= before_open.bytes_down;
      std::vector<double> settle, required, limit, ratio, reqs, kb;
      // Read amplification over the teleports: bytes that crossed the link (HTTP headers included)
      // per stored payload byte the streamer read.
      const uint64_t payload_before = s.stats().bytes_read, link_before = proxy.stats().bytes_down;
      bool ok = true;
      for (const View& v : teleports.views) {
        const tools::ProxyStats before = proxy.stats();
        const auto t1 = Clock::now();
        double req = -1;
        for (int f = 0;; ++f) {
          s.update({&v, 1});
          const StreamerStats st = s.stats();
          if (req < 0 && st.required_missing == 0) req = ms_since(t1);
          if (st.wanted_missing == 0) break;
          if (ms_since(t1) > 120000) {
            ok = false;
            break;
          }
          std::this_thread::sleep_for(std::chrono::microseconds(500));
        }
        const double ms = ms_since(t1);
        const tools::ProxyStats after = proxy.stats();
        const double bytes = double(after.bytes_down - before.bytes_down);
        const double lim = (mbit > 0 ? bytes * 8 / (mbit * 1e6) * 1e3 : 0.0) + rtt;
        settle.push_back(ms);
        required.push_back(req);
        limit.push_back(lim);
        if (after.requests > before.requests && lim > 0) ratio.push_back(ms / lim);  // teleports that fetched something
        reqs.push_back(double(after.requests - before.requests));
        kb.push_back(bytes / 1024);
      }
      const uint64_t payload_bytes = s.stats().bytes_read - payload_before;
      const double amplification =
          payload_bytes ? double(proxy.stats().bytes_down - link_before) / double(payload_bytes) : 0.0;
      // The flight, paced: from a settled start.
      int gaps = 0, frames = 0;
      {
        const View& start = flight.views.front();
        for (int i = 0; i < 200000; ++i) {
          s.update({&start, 1});
          if (s.stats().wanted_missing == 0) break;
          std::this_thread::sleep_for(std::chrono::microseconds(500));
        }
        Pacer pacer(o.fps);
        pacer.reset();
        for (const View& v : flight.views) {
          s.update({&v, 1});
          gaps += s.stats().required_missing > 0;
          ++frames;
          pacer.wait();
        }
      }
      const StreamerStats final_stats = s.stats();
      const uint32_t fetches_used = s.config().max_fetches;
      s.close();
      proxy.stop();
      if (!ok || final_stats.failed > 0) rc = 1;
      if (!o.json)
        std::printf("%6.0f %6s | %10.1f %4llu %6.1f %10.1f %5llu | %8.1f %5llu %8.1f | %9.1f %9.1f %9.1f %6.1f %6.0f %8.0f %5.2f | %4d of %d%s\n", rtt,
                    mbit > 0 ? fmt("%.0f", mbit).c_str() : "inf", page_open_ms, (unsigned long long)paged_open.requests,
                    double(paged_open.bytes_down) / 1024, page_ms, (unsigned long long)pages_read, open_ms, (unsigned long long)opened.requests,
                    double(opened.bytes_down) / 1024, median(settle), median(required), median(limit), ratio.empty() ? 0.0 : median(ratio),
                    median(reqs), median(kb), amplification, gaps, frames,
                    !ok ? "  (a teleport did not settle in 120 s)"
                        : final_stats.failed ? "  (failed nodes)" : "");
      json_out.push_back({{"archive", url}, {"rtt_ms", rtt}, {"mbit", mbit}, {"open_ms", open_ms},
                          {"by_page_open_ms", page_open_ms}, {"by_page_open_requests", paged_open.requests},
                          {"by_page_open_bytes", paged_open.bytes_down}, {"descend_ms", page_ms}, {"descend_pages", pages_read},
                          {"open_requests", opened.requests}, {"open_bytes", opened.bytes_down},
                          {"settle_ms", median(settle)}, {"required_ms", median(required)},
                          {"limit_ms", median(limit)}, {"settle_over_limit", ratio.empty() ? 0.0 : median(ratio)},
                          {"requests_per_teleport", median(reqs)}, {"kb_per_teleport", median(kb)},
                          {"read_amplification", amplification}, {"max_fetches", fetches_used},
                          {"flight_gap_frames", gaps}, {"flight_frames", frames}, {"failed", final_stats.failed}});
    }
  return rc;
}

}  // namespace
}  // namespace terrain::bench

int main(int argc, char** argv) {
  using namespace terrain;
  bench::Options o;
  CLI::App app{"terrain-stream-bench: camera paths through the streamer and a naive synchronous loader"};
  app.add_option("archives", o.archives, "archives to replay (.terrain files or http(s):// URLs)");
  app.add_option("--make-synthetic", o.make_synthetic,
                 "write a synthetic archive (fractal heights, 9 roots, deep sparse trees, ~6000 nodes) to this path if it does not "
                 "exist, and benchmark it too");
  app.add_option("--budget", o.budget, "resident node budget")->capture_default_str();
  app.add_option("--threads", o.threads, "streamer worker threads")->capture_default_str();
  app.add_option("--fetches", o.fetches, "streamer reads in flight (StreamerConfig::max_fetches; 0: automatic, 16 for a URL, the worker count for a file)")
      ->capture_default_str();
  app.add_option("--max-deliveries", o.max_deliveries, "streamer deliveries per frame (per-frame upload bound)")
      ->capture_default_str();
  app.add_option("--fps", o.fps, "frame rate of the replay (camera time step and pacing)")->capture_default_str();
  app.add_option("--seconds", o.seconds, "length of each flight and walk, seconds")->capture_default_str();
  app.add_option("--teleports", o.teleports, "number of teleports")->capture_default_str();
  app.add_option("--target-px", o.target_px, "screen-space error target, pixels")->capture_default_str();
  app.add_option("--seed", o.seed, "camera path seed")->capture_default_str();
  app.add_flag("--json", o.json, "print JSON on stdout instead of the table");
  app.add_flag("--quiet", o.quiet, "no progress on stderr");
  app.add_option("--rtt-ms", o.rtt_ms,
                 "instead of the paths: read each http:// archive through a proxy adding these round trips (ms, "
                 "comma-separated): open, teleports against the link's physical limit, the 300 m/s flight")
      ->delimiter(',');
  app.add_option("--mbit", o.mbit, "with --rtt-ms: the link's bandwidths, Mbit/s (comma-separated; 0 = unlimited)")
      ->delimiter(',');
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (!o.make_synthetic.empty()) {
    if (!std::filesystem::exists(o.make_synthetic)) {
      synthetic::Spec spec;
      spec.roots_x = 3;
      spec.roots_y = 3;
      spec.root_fill = 1.0;
      spec.child_probability = 0.85;
      spec.error_scale = 1.0;  // with a 2 px target the settled wanted set fills the 512 budget
      spec.realistic_payload = true;
      spec.zstd_level = 9;
      spec.seed = 42;
      if (!o.quiet) std::fprintf(stderr, "writing synthetic archive %s...\n", o.make_synthetic.c_str());
      synthetic::Summary sum;
      if (Status s = synthetic::write_archive(o.make_synthetic, spec, &sum); !s.ok()) {
        std::fprintf(stderr, "terrain-stream-bench: %s\n", s.to_string().c_str());
        return 1;
      }
    }
    o.archives.insert(o.archives.begin(), o.make_synthetic);
  }
  if (o.archives.empty()) {
    std::fprintf(stderr, "terrain-stream-bench: give at least one ARCHIVE or --make-synthetic PATH (see --help)\n");
    return 2;
  }
  if (o.budget < 1 || o.threads < 1 || o.max_deliveries < 1 || !(o.fps > 0) || !(o.seconds > 0) || o.teleports < 1 || !(o.target_px > 0)) {
    std::fprintf(stderr, "terrain-stream-bench: budget, threads, fps, seconds, teleports and target-px must be positive\n");
    return 2;
  }
  nlohmann::json all = nlohmann::json::array();
  int rc = 0;
  if (!o.rtt_ms.empty() && o.mbit.empty()) o.mbit = {0};
  for (const std::string& a : o.archives)
    rc = std::max(rc, o.rtt_ms.empty() ? bench::bench_archive(a, o, all) : bench::bench_links(a, o, all));
  if (o.json) std::printf("%s\n", all.dump(2).c_str());
  return rc;
}
