// A stand-in for a game engine that uses the installed terrain package (find_package(terrain)):
// it opens an archive, drives terrain::Streamer along a camera path, "uploads" every delivery into
// a CPU copy of the GPU atlas (one NodeData per slot), mirrors the residency index (root grid and
// tree words, terrain/surface_contract.h) and the slot table from the dirty lists the way a renderer
// would, and checks every frame that what it holds is consistent: walking the mirrored index from
// its start list the way a GPU traversal does reaches exactly the slots this program filled, each
// with that very node, the mirrors equal the streamer's state, and no slot is reused before its
// fence passed.
// Any violation prints what and where and exits 1. Per frame it prints one summary line.
//
// Usage: terrain-engine-sample <archive.terrain> <camera_path.txt> [--frames-per-segment N]
//                              [--error-px E] [--budget N] [--slots N]
// The camera flies the path there and back.
// Camera paths: one waypoint per line, "X Y Z LX LY LZ" in frame metres (samples/paths/).
// A small --budget and --error-px make even a small archive split and evict along the path;
// --slots equal to --budget (the smallest atlas) reuses evicted slots as soon as their fence allows.
#include <terrain/format.h>
#include <terrain/queries.h>
#include <terrain/streamer.h>
#include <terrain/surface_contract.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

struct Waypoint {
  double x = 0, y = 0, z = 0;     // eye
  double lx = 0, ly = 0, lz = 0;  // look-at (unused here: the sample's views carry no frustum)
};

std::vector<Waypoint> read_path(const std::string& file) {
  std::vector<Waypoint> path;
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line)) {
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    std::istringstream fields(line);
    Waypoint w;
    if (fields >> w.x >> w.y >> w.z >> w.lx >> w.ly >> w.lz) path.push_back(w);
  }
  return path;
}

// The engine's copy of what the GPU holds: atlas layers, the slot table and the residency index.
struct CpuAtlas {
  std::vector<terrain::NodeData> layers;         // slot -> uploaded node data
  std::vector<bool> filled;                      // slot holds a node (delivered, not evicted)
  std::vector<terrain::NodeKey> holder;          // the node in a filled slot
  std::vector<uint64_t> evicted_in;              // update() number that last freed the slot (0 = never)
  std::vector<terrain::SlotDescriptor> descriptors;
  std::vector<uint16_t> roots;                   // the index's root grid (an R16_UINT image on a GPU)
  std::vector<uint32_t> tree;                    // the index's tree words (a storage buffer)
};

CpuAtlas make_atlas(const terrain::Streamer& s) {
  CpuAtlas a;
  const uint32_t n = s.slot_count();
  a.layers.resize(n);
  a.filled.assign(n, false);
  a.holder.resize(n);
  a.evicted_in.assign(n, 0);
  a.descriptors.resize(n);
  // Garbage until the first update() uploads the whole index.
  a.roots.assign(size_t(s.world().roots_x) * s.world().roots_y, 0x7777);
  a.tree.assign(terrain::index_tree_words(n), 0x77777777u);
  return a;
}

// A failed check: what went wrong, in which frame. The program exits 1 after printing them.
struct Checks {
  uint64_t frame = 0;
  int failures = 0;
  void fail(const std::string& what) {
    if (failures++ < 20) std::fprintf(stderr, "engine-sample: frame %llu: %s\n", (unsigned long long)frame, what.c_str());
  }
};

std::string name(const terrain::NodeKey& k) { return terrain::node_name(k); }

// What a renderer does with one FrameUpdate: free evicted slots, copy deliveries into their slots,
// then upload dirty descriptors and the dirty parts of the residency index.
void upload(const terrain::FrameUpdate& u, const terrain::Streamer& s, CpuAtlas& a, Checks& checks) {
  for (const terrain::NodeEviction& e : u.evicted) {
    if (e.slot >= a.filled.size() || !a.filled[e.slot] || !(a.holder[e.slot] == e.key)) {
      checks.fail("eviction of " + name(e.key) + " from slot " + std::to_string(e.slot) + ", which does not hold it");
      continue;
    }
    a.filled[e.slot] = false;
    a.evicted_in[e.slot] = u.frame;
  }
  const uint32_t fence = s.config().fence_frames;
  for (const terrain::NodeDelivery& d : u.delivered) {
    if (d.slot >= a.filled.size() || d.data == nullptr) {
      checks.fail("delivery of " + name(d.key) + " with slot " + std::to_string(d.slot) + " or no data");
      continue;
    }
    if (a.filled[d.slot])
      checks.fail("delivery of " + name(d.key) + " into slot " + std::to_string(d.slot) + ", still holding " +
                  name(a.holder[d.slot]));
    if (a.evicted_in[d.slot] != 0 && u.frame < a.evicted_in[d.slot] + fence)
      checks.fail("slot " + std::to_string(d.slot) + " reused in frame " + std::to_string(u.frame) +
                  ", evicted in frame " + std::to_string(a.evicted_in[d.slot]) + " (fence " + std::to_string(fence) + ")");
    a.layers[d.slot] = *d.data;  // the "GPU upload"
    a.filled[d.slot] = true;
    a.holder[d.slot] = d.key;
  }
  const auto table = s.slots();
  for (const uint16_t slot : u.dirty_slots) a.descriptors[slot] = table[slot];
  // The residency index: the dirty root cells, the start list when it changed, the dirty slots'
  // child words (a renderer merges contiguous slots into one copy).
  const terrain::ResidencyIndex& index = s.residency();
  const uint32_t width = s.world().roots_x, n = s.slot_count();
  const terrain::DirtyRect& r = u.dirty_roots;
  for (uint32_t y = r.y0; y < r.y1 && !r.empty(); ++y)
    for (uint32_t x = r.x0; x < r.x1; ++x) a.roots[size_t(y) * width + x] = index.root_grid()[size_t(y) * width + x];
  if (u.dirty_starts)
    std::copy_n(index.tree().begin(), terrain::kIndexTreeStart + n, a.tree.begin());
  for (const uint16_t slot : u.dirty_children)
    std::copy_n(index.tree().begin() + ptrdiff_t(terrain::index_child_word(n, slot)), 2,
                a.tree.begin() + ptrdiff_t(terrain::index_child_word(n, slot)));
}

// Child c of the node in `slot` as the mirrored tree words say (a slot, kIndexNotResident or kIndexNoNode).
uint16_t child_word(const CpuAtlas& a, uint32_t slot, int c) {
  const uint32_t w = a.tree[terrain::index_child_word(uint32_t(a.filled.size()), slot) + size_t(c >> 1)];
  return uint16_t(w >> (16 * (c & 1)));
}

// Every frame: the mirrors equal the streamer's index, and walking them from the start list the way
// a GPU traversal does reaches only slots this program filled, each with the right node in it.
// Returns the number of slots reached (the resident nodes as the GPU sees them).
uint32_t check_atlas(const terrain::Streamer& s, const CpuAtlas& a, Checks& checks) {
  const terrain::ResidencyIndex& index = s.residency();
  for (size_t i = 0; i < a.roots.size(); ++i)
    if (a.roots[i] != index.root_grid()[i]) {
      checks.fail("root cell " + std::to_string(i) + ": uploaded " + std::to_string(a.roots[i]) + ", streamer has " +
                  std::to_string(index.root_grid()[i]) + " (dirty_roots missed it)");
      return 0;
    }
  for (size_t i = 0; i < a.tree.size(); ++i)
    if (a.tree[i] != index.tree()[i]) {
      checks.fail("index tree word " + std::to_string(i) + ": uploaded " + std::to_string(a.tree[i]) +
                  ", streamer has " + std::to_string(index.tree()[i]) + " (a dirty list missed it)");
      return 0;
    }
  // The traversal: from the start list down every resident child.
  std::vector<std::pair<uint32_t, terrain::NodeKey>> stack;  // slot, the node the index says is there
  std::vector<bool> reached(a.filled.size(), false);
  const uint32_t starts = a.tree[0];
  for (uint32_t i = 0; i < starts; ++i) {
    const uint32_t slot = a.tree[terrain::kIndexTreeStart + i];
    const terrain::SlotDescriptor& d = a.descriptors[slot < a.descriptors.size() ? slot : 0];
    stack.push_back({slot, terrain::NodeKey{d.level, d.x, d.y}});
    if (int(d.level) != s.archive().top_level()) checks.fail("start slot " + std::to_string(slot) + " holds a node below the top");
  }
  uint32_t count = 0;
  while (!stack.empty()) {
    const auto [v, key] = stack.back();
    stack.pop_back();
    if (v >= a.filled.size() || !a.filled[v]) {
      checks.fail("the index reaches " + name(key) + " in slot " + std::to_string(v) + ", which holds nothing");
      continue;
    }
    if (!(a.holder[v] == key)) {
      checks.fail("the index reaches " + name(key) + " in slot " + std::to_string(v) + ", which holds " + name(a.holder[v]));
      continue;
    }
    if (reached[v]) {
      checks.fail("slot " + std::to_string(v) + " reached twice");
      continue;
    }
    reached[v] = true;
    ++count;
    const terrain::SlotDescriptor& d = a.descriptors[v];
    if (d.level != key.level || d.x != key.x || d.y != key.y)
      checks.fail("slot " + std::to_string(v) + " descriptor names node " + std::to_string(d.level) + "/" +
                  std::to_string(d.x) + "/" + std::to_string(d.y) + ", the index says " + name(key));
    if (key.level == uint32_t(terrain::kRootLevel) && a.roots[size_t(key.y) * s.world().roots_x + key.x] != v)
      checks.fail("root " + name(key) + " is resident in slot " + std::to_string(v) + ", its root cell says otherwise");
    // The uploaded copy is the streamer's data for that node, byte for byte.
    const terrain::NodeData* data = s.resident_data(key);
    const terrain::NodeData& layer = a.layers[v];
    if (data == nullptr || layer.heights != data->heights || layer.normals_bc3 != data->normals_bc3 ||
        layer.albedo_bc1 != data->albedo_bc1 || layer.splat != data->splat || layer.cones_bc3 != data->cones_bc3)
      checks.fail("slot " + std::to_string(v) + " does not hold the resident data of " + name(key));
    for (int c = 0; c < 4; ++c) {
      const uint16_t w = child_word(a, v, c);
      const bool exists = key.level > 0 && (d.child_mask & (1u << c));
      if (!exists && w != terrain::kIndexNoNode)
        checks.fail("child " + std::to_string(c) + " of " + name(key) + " does not exist, its word says " + std::to_string(w));
      if (w < terrain::kIndexNoNode) stack.push_back({w, terrain::child_of(key, c)});
    }
  }
  uint32_t filled = 0;
  for (const bool f : a.filled) filled += f ? 1 : 0;
  const terrain::StreamerStats st = s.stats();
  if (filled != count || filled != st.resident)
    checks.fail("slots filled " + std::to_string(filled) + ", reached through the index " + std::to_string(count) +
                ", streamer resident " + std::to_string(st.resident));
  return count;
}

// The finest level whose node under (x, y) is in the atlas, found in the mirrored index the way a
// shader would: the start node holding the point, then down the resident child holding it; -1
// outside the resident top nodes.
int finest_resident_level(const terrain::Streamer& s, const CpuAtlas& a, double x, double y) {
  const terrain::WorldInfo& w = s.world();
  auto cell = [&](int level, double v, double origin) {
    return std::floor((v - origin) / (terrain::kLevel0NodeSizeM * double(uint64_t(1) << level)));
  };
  for (uint32_t i = 0; i < a.tree[0]; ++i) {
    uint32_t slot = a.tree[terrain::kIndexTreeStart + i];
    const terrain::SlotDescriptor& top = a.descriptors[slot];
    if (cell(top.level, x, w.origin_x_m) != double(top.x) || cell(top.level, y, w.origin_y_m) != double(top.y)) continue;
    int level = top.level;
    while (level > 0) {
      const double fx = cell(level - 1, x, w.origin_x_m), fy = cell(level - 1, y, w.origin_y_m);
      const int c = (int(fx) & 1) | (int(fy) & 1) << 1;
      const uint16_t child = child_word(a, slot, c);
      if (child >= terrain::kIndexNoNode) break;
      slot = child;
      --level;
    }
    return level;
  }
  return -1;
}

// ---- Gameplay queries ---------------------------------------------------------------------------
// What gameplay asks every frame: the ground under a character walking below the camera (from the
// resident data, and from the archive's finest data), and what the character sees along a few rays
// from its eyes. Two consistency checks make the answers part of the sample's test: a ray cast
// straight down onto the character's position hits the height height_at() gave, and where the
// resident node is the archive's finest there, the resident answer equals the archive's bit for bit.
struct QueryReport {
  bool ground = false;
  double ground_m = 0;
  bool finer_not_resident = false;
  int rays_hit = 0, rays = 0;
  double nearest_hit_m = 0;
};

QueryReport run_gameplay_queries(const terrain::Streamer& streamer, terrain::ArchiveSurface& finest,
                                 const terrain::View& camera, Checks& checks) {
  QueryReport r;
  const terrain::ResidentSurface ground = streamer.resident_surface();  // any thread may do this
  const terrain::SurfacePoint p = ground.height_at(camera.x, camera.y);
  if (!p.hit) return r;
  r.ground = true;
  r.ground_m = p.height_m;
  r.finer_not_resident = p.finer_not_resident;

  // Straight down from 50 m above: the same triangle, the same height.
  const terrain::RayHit down = ground.raycast({{camera.x, camera.y, p.height_m + 50.0}, {0, 0, -1}, 100.0});
  if (!down.hit || std::fabs(down.point[2] - p.height_m) > 1e-6)
    checks.fail("a vertical ray at the character disagrees with height_at (" + std::to_string(p.height_m) + " m)");

  terrain::SurfacePoint f;
  if (!finest.height_at(camera.x, camera.y, f).ok()) checks.fail("ArchiveSurface::height_at failed");
  else if (!p.finer_not_resident && (!f.hit || f.height_m != p.height_m))
    checks.fail("the resident answer differs from the archive's finest where that node is resident");

  // Line of sight: eight 100 m rays from 1.8 m above the ground, 5 degrees down, around the compass.
  std::array<terrain::Ray, 8> rays;
  std::array<terrain::RayHit, 8> hits;
  for (size_t i = 0; i < rays.size(); ++i) {
    const double az = double(i) * 3.14159265358979 / 4.0, down_slope = std::tan(5.0 * 3.14159265358979 / 180.0);
    rays[i] = {{camera.x, camera.y, p.height_m + 1.8}, {std::sin(az), std::cos(az), -down_slope}, 100.0};
  }
  ground.raycast(rays, hits);
  r.rays = int(rays.size());
  r.nearest_hit_m = 1e300;
  for (const terrain::RayHit& h : hits)
    if (h.hit) {
      ++r.rays_hit;
      r.nearest_hit_m = std::min(r.nearest_hit_m, h.distance_m);
    }
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  const char* usage = "usage: %s <archive.terrain> <camera_path.txt> [--frames-per-segment N] [--error-px E] "
                      "[--budget N] [--slots N]\n";
  std::vector<std::string> positional;
  int frames_per_segment = 30;
  terrain::StreamerConfig config;
  config.max_deliveries_per_frame = 32;  // the per-frame upload budget
  config.worker_threads = 2;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--frames-per-segment" && has_value) {
      frames_per_segment = std::atoi(argv[++i]);
    } else if (arg == "--error-px" && has_value) {
      config.error_target_px = std::atof(argv[++i]);
    } else if (arg == "--budget" && has_value) {
      config.budget_nodes = uint32_t(std::strtoul(argv[++i], nullptr, 10));
    } else if (arg == "--slots" && has_value) {
      config.slot_count = uint32_t(std::strtoul(argv[++i], nullptr, 10));
    } else if (!arg.empty() && arg[0] != '-') {
      positional.push_back(arg);
    } else {
      std::fprintf(stderr, usage, argv[0]);
      return 2;
    }
  }
  if (positional.size() != 2) {
    std::fprintf(stderr, usage, argv[0]);
    return 2;
  }
  const std::vector<Waypoint> path = read_path(positional[1]);
  if (path.size() < 2 || frames_per_segment < 1) {
    std::fprintf(stderr, "engine-sample: %s: need at least 2 waypoints and --frames-per-segment >= 1\n",
                 positional[1].c_str());
    return 2;
  }

  terrain::Streamer streamer;
  if (const terrain::Status st = streamer.open(positional[0], config); !st.ok()) {
    std::fprintf(stderr, "engine-sample: %s\n", st.to_string().c_str());
    return 1;
  }
  CpuAtlas atlas = make_atlas(streamer);
  std::printf("engine-sample: %s: %u x %u roots, atlas of %u slots (%.1f MB), budget %u nodes\n", positional[0].c_str(),
              streamer.world().roots_x, streamer.world().roots_y, streamer.slot_count(),
              double(atlas.layers.size() * sizeof(terrain::NodeData)) / 1e6, streamer.config().budget_nodes);

  Checks checks;
  terrain::ArchiveSurface finest(streamer.archive());
  uint64_t delivered = 0, evicted = 0;
  auto frame = [&](const terrain::View& view) {
    const terrain::FrameUpdate& u = streamer.update({&view, 1});
    checks.frame = u.frame;
    // A node that failed to load (corrupt payload, or the file truncated or unreadable since open):
    // its parent stays drawn; an engine logs it. Here it fails the run.
    for (const terrain::NodeFailure& nf : u.failed)
      checks.fail("node " + std::to_string(nf.key.level) + "/" + std::to_string(nf.key.x) + "/" + std::to_string(nf.key.y) +
                  " failed to load: " + nf.status.to_string());
    upload(u, streamer, atlas, checks);
    const uint32_t resident = check_atlas(streamer, atlas, checks);
    const QueryReport q = run_gameplay_queries(streamer, finest, view, checks);
    delivered += u.delivered.size();
    evicted += u.evicted.size();
    const terrain::StreamerStats st = streamer.stats();
    std::printf("frame %3llu  eye %9.0f %10.0f %6.0f  +%-3zu -%-3zu resident %3u  required missing %3u  pending %3u  "
                "finest level under eye %d  ground %s%.2f m%s  rays %d/%d hit\n",
                (unsigned long long)u.frame, view.x, view.y, view.z, u.delivered.size(), u.evicted.size(), resident,
                st.required_missing, st.pending, finest_resident_level(streamer, atlas, view.x, view.y),
                q.ground ? "" : "none ", q.ground_m, q.finer_not_resident ? " (finer not resident)" : "", q.rays_hit,
                q.rays);
    std::this_thread::sleep_for(std::chrono::milliseconds(8));  // the rest of the engine's frame
    return st;
  };

  terrain::View view;
  view.pixels_per_radian = terrain::pixels_per_radian(1080.0, 60.0 * 3.14159265358979 / 180.0);
  // Along the path and back to its start (so nodes evicted on the way out are streamed in again).
  std::vector<Waypoint> there_and_back = path;
  there_and_back.insert(there_and_back.end(), path.rbegin() + 1, path.rend());
  for (size_t seg = 0; seg + 1 < there_and_back.size(); ++seg) {
    for (int f = 0; f < frames_per_segment; ++f) {
      const double t = double(f) / frames_per_segment;
      const Waypoint &a = there_and_back[seg], &b = there_and_back[seg + 1];
      view.x = a.x + t * (b.x - a.x);
      view.y = a.y + t * (b.y - a.y);
      view.z = a.z + t * (b.z - a.z);
      frame(view);
    }
  }
  // Stay at the end until the streamer has everything the error target requires.
  view.x = there_and_back.back().x;
  view.y = there_and_back.back().y;
  view.z = there_and_back.back().z;
  const auto settle_until = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  bool settled = false;
  while (!settled && std::chrono::steady_clock::now() < settle_until) {
    const terrain::StreamerStats st = frame(view);
    settled = st.required_missing == 0 && st.pending == 0;
  }
  if (!settled) checks.fail("the streamer did not settle at the last waypoint within 30 s");
  const terrain::StreamerStats st = streamer.stats();
  std::printf("engine-sample: %llu frames, %llu deliveries, %llu evictions, %u resident, %u failed loads: %s\n",
              (unsigned long long)st.frame, (unsigned long long)delivered, (unsigned long long)evicted, st.resident,
              st.failed, checks.failures == 0 ? "all checks passed" : "CHECKS FAILED");
  return checks.failures == 0 ? 0 : 1;
}
