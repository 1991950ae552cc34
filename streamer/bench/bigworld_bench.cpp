// terrain-bigworld-bench: the streamer on synthetic worlds of growing root count with overview
// levels (format/SPEC.md section 19, issue 15). Per world: generation and open time, the streamer's
// own memory besides the resident payloads (bytes per archive node, the residency index
// included), update() CPU (thread CPU time) median and max during a paced 300 m/s flight and
// after teleports, settle time of each teleport, gap frames, and the invariants every frame.
#include <malloc.h>
#include <time.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <set>
#include <thread>

#include "synthetic_archive.h"
#include "terrain/cpu_clock.h"
#include "terrain/streamer.h"

namespace {

using namespace terrain;
using Clock = std::chrono::steady_clock;

double thread_cpu_ms() { return terrain::thread_cpu_seconds() * 1e3; }
uint64_t heap_in_use() {
  const struct mallinfo2 mi = mallinfo2();
  return uint64_t(mi.uordblks) + uint64_t(mi.hblkhd);
}
double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}
double maximum(const std::vector<double>& v) { return v.empty() ? 0 : *std::max_element(v.begin(), v.end()); }

synthetic::Spec spec_for(uint32_t side) {
  synthetic::Spec s;
  s.roots_x = s.roots_y = side;
  s.root_fill = 1.0;
  s.child_probability = 0.3;  // shallow subtrees down to level 3: ~2.5 nodes per root
  s.min_level = 3;
  s.error_scale = 2.5;
  s.seed = 15;
  s.overview_levels = -1;
  return s;
}

// Top nodes resident, parent closure, budget: what streamer.h promises after every update().
bool invariants_hold(const Streamer& s, const std::set<uint64_t>& tops) {
  const std::vector<NodeKey> resident = s.resident_nodes();
  if (resident.size() > s.config().budget_nodes) return false;
  auto id = [](const NodeKey& k) { return (uint64_t(k.level) << 58) | (uint64_t(k.y) << 29) | k.x; };
  std::set<uint64_t> ids;
  for (const NodeKey& k : resident) ids.insert(id(k));
  for (uint64_t t : tops)
    if (!ids.count(t)) return false;
  const auto top = uint32_t(s.archive().top_level());
  for (const NodeKey& k : resident)
    if (k.level < top && !ids.count(id(parent_of(k)))) return false;
  return true;
}

struct Row {
  uint32_t roots = 0;
  size_t nodes = 0;
  int top_level = 0;
  size_t top_nodes = 0;
  double generate_s = 0, file_mb = 0, open_ms = 0;
  double own_bytes_per_node = 0, reader_bytes_per_node = 0;
  double flight_median_ms = 0, flight_max_ms = 0, teleport_median_ms = 0, teleport_max_ms = 0;
  double settle_median_ms = 0, settle_max_ms = 0;
  int frames = 0, gap_frames = 0;
  bool invariants = true;
};

Row run(uint32_t side, const std::string& dir, double seconds, int teleports) {
  Row row;
  const synthetic::Spec spec = spec_for(side);
  const std::string path = dir + "/bigworld-" + std::to_string(side) + "x" + std::to_string(side) + ".terrain";
  if (!std::filesystem::exists(path)) {
    const auto g0 = Clock::now();
    synthetic::Summary sum;
    if (Status st = synthetic::write_archive(path, spec, &sum); !st.ok()) {
      std::fprintf(stderr, "%s\n", st.to_string().c_str());
      std::exit(1);
    }
    row.generate_s = std::chrono::duration<double>(Clock::now() - g0).count();
  }
  row.file_mb = double(std::filesystem::file_size(path)) / 1e6;

  StreamerConfig config;  // default budget 512
  config.worker_threads = 2;
  // Memory besides payloads: heap after open minus the decode buffers (payloads), minus the
  // reader's own decoded directory (measured by opening a reader alone).
  uint64_t reader_bytes = 0;
  {
    const uint64_t h0 = heap_in_use();
    ArchiveReader r;
    if (!r.open(path).ok()) std::exit(1);
    reader_bytes = heap_in_use() - h0;
  }
  auto own_bytes = [&](double* open_ms, size_t* nodes) {
    const StreamerConfig& c = config;
    const uint64_t h0 = heap_in_use();
    Streamer s;
    const auto t0 = Clock::now();
    if (Status st = s.open(path, c); !st.ok()) {
      std::fprintf(stderr, "%s\n", st.to_string().c_str());
      std::exit(1);
    }
    if (open_ms) *open_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    View v{0, 0, 0};
    s.update({&v, 1});  // the first update publishes the snapshot (its key list counts)
    if (nodes) *nodes = s.archive().nodes().size();
    return double(heap_in_use() - h0) - double(s.stats().buffer_bytes) - double(reader_bytes);
  };
  double open_ms = 0;
  const double own = own_bytes(&open_ms, &row.nodes);
  row.open_ms = open_ms;
  row.own_bytes_per_node = own / double(row.nodes);
  row.reader_bytes_per_node = double(reader_bytes) / double(row.nodes);

  // The flight and teleports.
  Streamer s;
  if (!s.open(path, config).ok()) std::exit(1);
  row.roots = 0;
  std::set<uint64_t> tops;
  row.top_level = s.archive().top_level();
  for (const NodeRecord& r : s.archive().nodes()) {
    row.roots += r.key.level == uint32_t(kRootLevel);
    if (r.key.level == uint32_t(row.top_level))
      tops.insert((uint64_t(r.key.level) << 58) | (uint64_t(r.key.y) << 29) | r.key.x);
  }
  row.top_nodes = tops.size();
  const double W = side * node_size_m(kRootLevel);
  const double o = spec.origin_x_m, n = spec.origin_y_m;
  auto view = [&](double x, double y, double above) { return View{x, y, synthetic::surface_height_m(spec, x, y) + above}; };
  const double fps = 60, dt = 1.0 / fps;
  std::vector<double> flight_ms, teleport_ms, settle_ms;
  auto frame = [&](const View& v, std::vector<double>& cpu) {
    const double c0 = thread_cpu_ms();
    s.update({&v, 1});
    cpu.push_back(thread_cpu_ms() - c0);
    ++row.frames;
    row.gap_frames += s.stats().required_missing > 0;
    row.invariants = row.invariants && invariants_hold(s, tops);
  };
  // Settle at the start, then fly diagonally at 300 m/s, 120 m above the ground, paced at 60 fps.
  {
    const View v = view(o + 0.05 * W, n + 0.05 * W, 120);
    std::vector<double> ignored;
    for (int i = 0; i < 600 && (i == 0 || s.stats().wanted_missing > 0); ++i) {
      frame(v, ignored);
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    row.gap_frames = 0;  // the start is a teleport, not part of the flight
  }
  const int frames = int(seconds * fps);
  auto next = Clock::now();
  const double step = 300.0 * dt / std::sqrt(2.0);
  for (int f = 0; f < frames; ++f) {
    const double x = o + 0.05 * W + step * f, y = n + 0.05 * W + step * f;
    frame(view(x, y, 120), flight_ms);
    next += std::chrono::microseconds(int64_t(1e6 * dt));
    std::this_thread::sleep_until(next);
  }
  const int flight_gaps = row.gap_frames;
  // Teleports: random points, 60 m up; frames paced at 60 fps until the wanted set is resident.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.02, 0.98);
  for (int t = 0; t < teleports; ++t) {
    const View v = view(o + u(rng) * W, n + u(rng) * W, 60);
    const auto t0 = Clock::now();
    next = t0;
    for (int i = 0; i < 6000; ++i) {
      frame(v, teleport_ms);
      if (s.stats().wanted_missing == 0) break;
      next += std::chrono::microseconds(int64_t(1e6 * dt));
      std::this_thread::sleep_until(next);
    }
    settle_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
  }
  row.gap_frames = flight_gaps;  // gap frames of the flight (after a teleport, gaps until settled are expected)
  row.flight_median_ms = median(flight_ms);
  row.flight_max_ms = maximum(flight_ms);
  row.teleport_median_ms = median(teleport_ms);
  row.teleport_max_ms = maximum(teleport_ms);
  row.settle_median_ms = median(settle_ms);
  row.settle_max_ms = maximum(settle_ms);
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"terrain-bigworld-bench: the streamer on synthetic worlds of 10^2..10^5 roots with overview levels"};
  std::vector<uint32_t> sides{10, 100, 317};
  std::string dir = "/tmp/terrain-bigworld";
  double seconds = 20;
  int teleports = 8;
  app.add_option("--sides", sides, "root grid sides (side x side roots)")->capture_default_str();
  app.add_option("--dir", dir, "where the synthetic archives are written (reused when present)")->capture_default_str();
  app.add_option("--seconds", seconds, "length of the 300 m/s flight")->capture_default_str();
  app.add_option("--teleports", teleports, "number of teleports")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  std::filesystem::create_directories(dir);
  std::printf("| roots | nodes | top level (nodes) | file MB | generate s | open ms | streamer B/node | reader B/node |"
              " update() ms flight median / max | update() ms teleports median / max | settle ms median / max | gap frames (flight) | invariants |\n"
              "|---:|---:|---|---:|---:|---:|---:|---:|---|---|---|---:|---|\n");
  for (uint32_t side : sides) {
    const Row r = run(side, dir, seconds, teleports);
    std::printf("| %u | %zu | %d (%zu) | %.1f | %.1f | %.1f | %.1f | %.1f | %.3f / %.3f | %.3f / %.3f | %.0f / %.0f | %d of %d | %s |\n",
                r.roots, r.nodes, r.top_level, r.top_nodes, r.file_mb, r.generate_s, r.open_ms, r.own_bytes_per_node,
                r.reader_bytes_per_node, r.flight_median_ms, r.flight_max_ms, r.teleport_median_ms,
                r.teleport_max_ms, r.settle_median_ms, r.settle_max_ms, r.gap_frames, int(seconds * 60), r.invariants ? "held" : "BROKEN");
    std::fflush(stdout);
  }
  return 0;
}
