// Gameplay queries (terrain/queries.h): resident heights equal SurfaceSampler bit for bit where the
// archive's finest node is resident, rays equal a brute-force intersection of every drawn resident
// triangle, holes are missed, and queries from another thread during eviction read only live data.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <thread>

#include "stream_check.h"
#include "synthetic_archive.h"
#include "terrain/bc_decode.h"
#include "terrain/queries.h"
#include "terrain/sample.h"
#include "test_data.h"

namespace terrain::test {
namespace {

#if defined(__SANITIZE_THREAD__) || defined(__SANITIZE_ADDRESS__)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif

std::string real_archive(const std::string& name) {
  const auto path = bin_dir().parent_path() / "test-archives" / (name + ".terrain");
  return std::filesystem::exists(path) ? path.string() : std::string();
}

// ---- Brute-force reference: every drawn triangle of every resident node ------------------------
// A resident node draws the quadrants where no child is resident (the finest resident node
// answers). Written independently of streamer/src: nodes decoded through the reader, Moeller-
// Trumbore on each triangle. Quads outside the segment's x-y bounding box cannot be hit and are
// skipped; every other triangle is tested.
struct RefHit {
  bool hit = false;
  double t = 0;
  std::array<double, 3> normal{};
  NodeKey node;
};

class BruteForce {
 public:
  BruteForce(const ArchiveReader& reader, const std::vector<NodeKey>& resident) : world_(reader.world()) {
    std::set<Key> keys;
    for (const NodeKey& k : resident) keys.insert(key_of(k));
    auto data = std::make_unique<NodeData>();
    for (const NodeKey& k : resident) {
      const int64_t index = reader.find(k);
      EXPECT_GE(index, 0);
      EXPECT_TRUE(reader.decode_node(size_t(index), *data, kSectionHeights | kSectionAlbedo).ok());
      const NodeRecord& r = reader.nodes()[size_t(index)];
      Node n;
      n.key = k;
      n.h.resize(kHeightCount);
      n.holes.resize(kHeightCount);
      for (int i = 0; i < kHeightCount; ++i)
        n.h[size_t(i)] = units_to_metres(vertex_units(r.height_offset, data->heights[size_t(i)], world_.step_log2[k.level]));
      decode_hole_mask(*data, n.holes.data());
      for (int c = 0; c < 4; ++c) n.child_resident[size_t(c)] = k.level > 0 && keys.count(key_of(child_of(k, c)));
      nodes_.push_back(std::move(n));
    }
  }

  RefHit cast(const Ray& ray) const {
    const double len = std::hypot(ray.direction[0], ray.direction[1], ray.direction[2]);
    const double o[3] = {ray.origin[0] - world_.origin_x_m, ray.origin[1] - world_.origin_y_m, ray.origin[2]};
    const double d[3] = {ray.direction[0] / len, ray.direction[1] / len, ray.direction[2] / len};
    const double T = ray.max_distance_m;
    const double bx0 = std::min(o[0], o[0] + T * d[0]), bx1 = std::max(o[0], o[0] + T * d[0]);
    const double by0 = std::min(o[1], o[1] + T * d[1]), by1 = std::max(o[1], o[1] + T * d[1]);
    RefHit best;
    best.t = T;
    for (const Node& n : nodes_) {
      const double size = node_size_m(int(n.key.level)), s = vertex_spacing_m(int(n.key.level));
      const double x0 = n.key.x * size, y0 = n.key.y * size;
      if (bx1 < x0 || bx0 > x0 + size || by1 < y0 || by0 > y0 + size) continue;
      const int i_lo = std::max(0, int(std::floor((bx0 - x0) / s)) - 1), i_hi = std::min(127, int(std::floor((bx1 - x0) / s)) + 1);
      const int j_lo = std::max(0, int(std::floor((by0 - y0) / s)) - 1), j_hi = std::min(127, int(std::floor((by1 - y0) / s)) + 1);
      for (int j = j_lo; j <= j_hi; ++j)
        for (int i = i_lo; i <= i_hi; ++i) {
          if (n.child_resident[size_t((i >= 64 ? 1 : 0) | (j >= 64 ? 2 : 0))]) continue;
          auto vtx = [&](int a, int b) {
            return std::array<double, 3>{x0 + a * s, y0 + b * s, n.h[size_t(b * kHeightSamples + a)]};
          };
          auto hole = [&](int a, int b) { return n.holes[size_t(b * kHeightSamples + a)] != 0; };
          if (!hole(i, j) && !hole(i + 1, j) && !hole(i + 1, j + 1))
            triangle(o, d, vtx(i, j), vtx(i + 1, j), vtx(i + 1, j + 1), n.key, best);
          if (!hole(i, j) && !hole(i + 1, j + 1) && !hole(i, j + 1))
            triangle(o, d, vtx(i, j), vtx(i + 1, j + 1), vtx(i, j + 1), n.key, best);
        }
    }
    return best;
  }

 private:
  struct Node {
    NodeKey key;
    std::vector<double> h;
    std::vector<uint8_t> holes;
    std::array<bool, 4> child_resident{};
  };
  using V3 = std::array<double, 3>;

  static void triangle(const double o[3], const double d[3], const V3& p0, const V3& p1, const V3& p2, const NodeKey& key,
                       RefHit& best) {
    const V3 e1{p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]}, e2{p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
    auto cross = [](const V3& a, const V3& b) {
      return V3{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    };
    auto dot = [](const V3& a, const V3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
    const V3 dv{d[0], d[1], d[2]};
    const V3 p = cross(dv, e2);
    const double det = dot(e1, p);
    if (det == 0) return;
    const V3 s{o[0] - p0[0], o[1] - p0[1], o[2] - p0[2]};
    const double u = dot(s, p) / det;
    if (u < 0 || u > 1) return;
    const V3 q = cross(s, e1);
    const double v = dot(dv, q) / det;
    if (v < 0 || u + v > 1) return;
    const double t = dot(e2, q) / det;
    if (t < 0 || t > best.t) return;
    V3 nrm = cross(e1, e2);
    const double l = std::sqrt(dot(nrm, nrm)) * (nrm[2] < 0 ? -1 : 1);
    best = {true, t, {nrm[0] / l, nrm[1] / l, nrm[2] / l}, key};
  }

  WorldInfo world_;
  std::vector<Node> nodes_;
};

// Settles a streamer with a camera `above` metres over the ground at (x, y) (over the highest node
// where there is no ground) and returns its snapshot.
ResidentSurface settle_over(Streamer& streamer, double x, double y, double above) {
  StreamChecker checker(streamer, false);
  int32_t max_units = 0;
  for (const NodeRecord& r : streamer.archive().nodes()) max_units = std::max(max_units, r.max_height);
  ArchiveSurface ground(streamer.archive());
  SurfacePoint g;
  EXPECT_TRUE(ground.height_at(x, y, g).ok());
  View v = view_at(x, y, (g.hit ? g.height_m : units_to_metres(max_units)) + above);
  EXPECT_EQ(settle(streamer, checker, {&v, 1}), "");
  return streamer.resident_surface();
}

// Random points in a disc of `radius` around (cx, cy).
std::array<double, 2> random_point(std::mt19937_64& rng, double cx, double cy, double radius) {
  std::uniform_real_distribution<double> a(0, 6.283185307179586), r(0, 1);
  const double rr = radius * std::sqrt(r(rng)), aa = a(rng);
  return {cx + rr * std::cos(aa), cy + rr * std::sin(aa)};
}

// ---- Heights ------------------------------------------------------------------------------------

// Opens `path` (two workers) and settles the streamer over the centre of the data (cx, cy).
void open_settled_over_centre(Streamer& streamer, const std::string& path, ResidentSurface& surface, double& cx,
                              double& cy) {
  StreamerConfig config;
  config.worker_threads = 2;
  ASSERT_TRUE(streamer.open(path, config).ok());
  const WorldInfo& w = streamer.world();
  cx = 0.5 * (w.extent_min_x_m + w.extent_max_x_m);
  cy = 0.5 * (w.extent_min_y_m + w.extent_max_y_m);
  surface = settle_over(streamer, cx, cy, 20);
}

void check_heights_against_sampler(const std::string& path) {
  Streamer streamer;
  ResidentSurface surface;
  double cx = 0, cy = 0;
  ASSERT_NO_FATAL_FAILURE(open_settled_over_centre(streamer, path, surface, cx, cy));
  const WorldInfo& w = streamer.world();
  ASSERT_FALSE(surface.empty());
  std::set<Key> resident;
  for (const NodeKey& k : surface.nodes()) resident.insert(key_of(k));

  ArchiveReader reader;
  ASSERT_TRUE(reader.open(path).ok());
  SurfaceSampler sampler(reader);
  ArchiveSurface archive(reader);
  std::mt19937_64 rng(5);
  int compared = 0, coarser = 0, holes = 0;
  const int points = kSanitized ? 4000 : 40000;
  for (int n = 0; n < points; ++n) {
    std::array<double, 2> p = random_point(rng, cx, cy, n % 2 ? 600 : 6000);
    if (n % 10 == 0) {  // on vertex lines and node edges of the finest levels: the shared-edge rules
      const double snap = n % 20 == 0 ? vertex_spacing_m(2) : node_size_m(3);
      p[0] = w.origin_x_m + std::round((p[0] - w.origin_x_m) / snap) * snap;
      if (n % 30 == 0) p[1] = w.origin_y_m + std::round((p[1] - w.origin_y_m) / snap) * snap;
    }
    std::optional<SurfaceSample> ref;
    ASSERT_TRUE(sampler.sample(p[0], p[1], ref).ok());
    SurfacePoint a;
    ASSERT_TRUE(archive.height_at(p[0], p[1], a).ok());
    ASSERT_EQ(a.hit, ref.has_value()) << p[0] << " " << p[1];
    if (ref) {
      ASSERT_EQ(a.height_m, ref->height_m);  // exact
      ASSERT_EQ(a.node, ref->node);
    }
    const SurfacePoint r = surface.height_at(p[0], p[1]);
    if (ref && resident.count(key_of(ref->node))) {
      ++compared;
      ASSERT_TRUE(r.hit);
      ASSERT_EQ(r.height_m, ref->height_m) << p[0] << " " << p[1];  // bit for bit
      ASSERT_EQ(r.node, ref->node);
      ASSERT_EQ(r.normal, a.normal);
      ASSERT_FALSE(r.finer_not_resident);
      ASSERT_NEAR(std::hypot(r.normal[0], r.normal[1], r.normal[2]), 1.0, 1e-12);
    } else if (ref && r.hit && r.node.level == ref->node.level) {
      // On an edge shared with the sampler's node: a resident neighbour answers with the same bits
      // (shared edge vertices have one canonical value).
      ASSERT_EQ(r.height_m, ref->height_m);
    } else if (ref && r.hit) {
      ++coarser;  // answered by a coarser resident ancestor
      ASSERT_GT(r.node.level, ref->node.level);
      ASSERT_TRUE(r.finer_not_resident) << n << " " << p[0] - w.origin_x_m << " " << p[1] - w.origin_y_m << " " << node_name(r.node) << " ref " << node_name(ref->node);
    }
    if (!ref && a.hole && resident.count(key_of(a.node))) {
      ++holes;
      ASSERT_FALSE(r.hit);
    }
  }
  EXPECT_GT(compared, points / 10) << "too few points where the finest node is resident";
  EXPECT_GT(coarser, 0) << "no point answered by a coarser node: the far points should be";
  std::cout << path << ": " << compared << " points equal to SurfaceSampler, " << coarser << " from coarser nodes, "
            << holes << " in holes\n";
}

TEST(Queries, ResidentHeightsEqualSurfaceSamplerOnJacksboro) {
  const std::string path = real_archive("jacksboro");
  if (path.empty()) GTEST_SKIP() << "jacksboro archive not cooked (cook_test_archives fixture)";
  check_heights_against_sampler(path);
}

TEST(Queries, ResidentHeightsEqualSurfaceSamplerOnKilauea) {
  const std::string path = real_archive("kilauea");
  if (path.empty()) GTEST_SKIP() << "kilauea archive not cooked (needs the shared DEMs)";
  check_heights_against_sampler(path);
}

// ---- Rays ---------------------------------------------------------------------------------------

// 2000 rays: 1400 random 100 m rays from 1.8 m above the resident surface, 300 grazing ones
// (within 1.2 degrees of horizontal), 300 random 1 km rays.
std::vector<Ray> gameplay_rays(const ResidentSurface& surface, double cx, double cy, double radius, int count,
                               uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0, 1);
  std::uniform_real_distribution<double> graze(-0.02, 0.02);
  std::vector<Ray> rays;
  while (int(rays.size()) < count) {
    const auto p = random_point(rng, cx, cy, radius);
    const SurfacePoint ground = surface.height_at(p[0], p[1]);
    if (!ground.hit) continue;
    Ray r;
    r.origin = {p[0], p[1], ground.height_m + 1.8};
    const int kind = int(rays.size()) % 20;
    r.direction = {g(rng), g(rng), kind < 3 ? graze(rng) : g(rng)};
    if (kind < 3) r.direction[2] *= std::hypot(r.direction[0], r.direction[1]);
    r.max_distance_m = kind >= 17 ? 1000.0 : 100.0;
    rays.push_back(r);
  }
  return rays;
}

void check_rays_against_brute_force(const std::string& path, int ray_count) {
  Streamer streamer;
  ResidentSurface surface;
  double cx = 0, cy = 0;
  ASSERT_NO_FATAL_FAILURE(open_settled_over_centre(streamer, path, surface, cx, cy));
  ArchiveReader reader;
  ASSERT_TRUE(reader.open(path).ok());
  const BruteForce brute(reader, surface.nodes());
  const std::vector<Ray> rays = gameplay_rays(surface, cx, cy, 3000, ray_count, 11);
  std::vector<RayHit> hits(rays.size());
  surface.raycast(rays, hits);
  int mismatches = 0, hit_count = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const RefHit ref = brute.cast(rays[i]);
    const RayHit& h = hits[i];
    const bool same = h.hit == ref.hit && (!ref.hit || (std::fabs(h.distance_m - ref.t) <= 1e-6 && h.node == ref.node &&
                                                         std::fabs(h.normal[0] - ref.normal[0]) < 1e-9 &&
                                                         std::fabs(h.normal[1] - ref.normal[1]) < 1e-9 &&
                                                         std::fabs(h.normal[2] - ref.normal[2]) < 1e-9));
    if (!same && ++mismatches <= 5)
      ADD_FAILURE() << "ray " << i << ": query " << h.hit << " t=" << h.distance_m << " node " << node_name(h.node)
                    << ", brute force " << ref.hit << " t=" << ref.t << " node " << node_name(ref.node);
    hit_count += ref.hit;
    if (h.hit) {  // the hit point lies on the surface the height query reports
      const SurfacePoint p = surface.height_at(h.point[0], h.point[1]);
      ASSERT_TRUE(p.hit);
      ASSERT_NEAR(p.height_m, h.point[2], 1e-6);
    }
  }
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(hit_count, ray_count / 4);
  EXPECT_LT(hit_count, ray_count);  // upward rays miss
  std::cout << path << ": " << rays.size() << " rays, " << hit_count << " hits, " << mismatches << " mismatches\n";
}

TEST(Queries, RaysEqualBruteForceOnJacksboro) {
  const std::string path = real_archive("jacksboro");
  if (path.empty()) GTEST_SKIP() << "jacksboro archive not cooked (cook_test_archives fixture)";
  check_rays_against_brute_force(path, 2000);
}

TEST(Queries, RaysEqualBruteForceOnKilauea) {
  const std::string path = real_archive("kilauea");
  if (path.empty()) GTEST_SKIP() << "kilauea archive not cooked (needs the shared DEMs)";
  check_rays_against_brute_force(path, 2000);
}

// ---- Holes --------------------------------------------------------------------------------------

TEST(Queries, HolesAreMissed) {
  synthetic::Spec spec = synthetic::analytic_surface();
  spec.hole_x_m = spec.origin_x_m + 1500.0;
  spec.hole_y_m = spec.origin_y_m + 2500.0;
  spec.hole_radius_m = 40.0;
  const std::string path = (scratch_dir("queries_holes") / "holes.terrain").string();
  ASSERT_TRUE(synthetic::write_archive(path, spec).ok());
  Streamer streamer;
  StreamerConfig config;
  config.worker_threads = 2;
  ASSERT_TRUE(streamer.open(path, config).ok());
  const ResidentSurface surface = settle_over(streamer, spec.hole_x_m, spec.hole_y_m, 10);
  ArchiveReader reader;
  ASSERT_TRUE(reader.open(path).ok());
  SurfaceSampler sampler(reader);
  std::set<Key> resident;
  for (const NodeKey& k : surface.nodes()) resident.insert(key_of(k));

  // Straight down through the hole: no height, a hole flag, a miss; just outside: hits.
  const SurfacePoint centre = surface.height_at(spec.hole_x_m, spec.hole_y_m);
  EXPECT_FALSE(centre.hit);
  EXPECT_TRUE(centre.hole);
  std::mt19937_64 rng(3);
  int inside = 0, outside = 0;
  for (int n = 0; n < 2000; ++n) {
    const auto p = random_point(rng, spec.hole_x_m, spec.hole_y_m, 120);
    const double r = std::hypot(p[0] - spec.hole_x_m, p[1] - spec.hole_y_m);
    const Ray down{{p[0], p[1], 2000.0}, {0, 0, -1}, 5000.0};
    const RayHit h = surface.raycast(down);
    const SurfacePoint q = surface.height_at(p[0], p[1]);
    std::optional<SurfaceSample> ref;
    ASSERT_TRUE(sampler.sample(p[0], p[1], ref).ok());
    ASSERT_EQ(h.hit, q.hit);
    if (ref && resident.count(key_of(ref->node))) {
      ASSERT_TRUE(q.hit);
    }
    if (r < spec.hole_radius_m - 2) {
      ++inside;
      ASSERT_FALSE(h.hit) << r;
      ASSERT_TRUE(q.hole);
    }
    if (r > spec.hole_radius_m + 2 * vertex_spacing_m(int(q.node.level)) + 1) {
      ++outside;
      ASSERT_TRUE(h.hit) << r;
      ASSERT_NEAR(h.point[2], q.height_m, 1e-6);
    }
  }
  EXPECT_GT(inside, 100);
  EXPECT_GT(outside, 100);
  // Oblique rays over the hole agree with the brute force (which drops hole triangles itself).
  const BruteForce brute(reader, surface.nodes());
  const std::vector<Ray> rays = gameplay_rays(surface, spec.hole_x_m, spec.hole_y_m, 100, 300, 4);
  int mismatches = 0;
  for (const Ray& ray : rays) {
    const RayHit h = surface.raycast(ray);
    const RefHit ref = brute.cast(ray);
    mismatches += h.hit != ref.hit || (h.hit && std::fabs(h.distance_m - ref.t) > 1e-6);
  }
  EXPECT_EQ(mismatches, 0);
}

// ---- Threads ------------------------------------------------------------------------------------

// A thread hammers height and ray queries on fresh snapshots while this thread moves the camera
// and update() evicts. Every answer is checked afterwards against the node's own data decoded
// from the archive: an evicted node's freed (and reused) buffer would give another node's heights.
TEST(Queries, QueriesDuringEvictionReadOnlyLiveData) {
  const synthetic::Spec spec = deep_sparse_spec();
  const std::string path = synthetic_archive(spec);
  Streamer streamer;
  StreamerConfig config;
  config.worker_threads = 2;
  config.budget_nodes = 160;
  ASSERT_TRUE(streamer.open(path, config).ok());
  const WorldInfo w = streamer.world();
  const double span_x = w.roots_x * node_size_m(kRootLevel), span_y = w.roots_y * node_size_m(kRootLevel);
  View v = view_at(w.origin_x_m + 0.1 * span_x, w.origin_y_m + 0.1 * span_y, 0);
  v.z = synthetic::surface_height_m(spec, v.x, v.y) + 30;
  streamer.update({&v, 1});

  struct Answer {
    double x, y, height;
    NodeKey node;
  };
  std::atomic<bool> stop{false};
  std::vector<Answer> answers;
  uint64_t queries = 0, snapshots = 0;
  std::thread hammer([&] {
    std::mt19937_64 rng(9);
    std::uniform_real_distribution<double> ux(w.origin_x_m, w.origin_x_m + span_x), uy(w.origin_y_m, w.origin_y_m + span_y);
    std::vector<std::array<double, 2>> points(64);
    std::vector<SurfacePoint> out(points.size());
    while (!stop.load()) {
      const ResidentSurface surface = streamer.resident_surface();
      ++snapshots;
      for (auto& p : points) p = {ux(rng), uy(rng)};
      surface.heights_at(points, out);
      for (size_t i = 0; i < points.size(); ++i)
        if (out[i].hit && answers.size() < 20000 && (queries + i) % 7 == 0)
          answers.push_back({points[i][0], points[i][1], out[i].height_m, out[i].node});
      const RayHit h = surface.raycast({{points[0][0], points[0][1], 5000.0}, {0.01, 0.02, -1}, 10000.0});
      if (h.hit && answers.size() < 20000) {
        const SurfacePoint q = surface.height_at(h.point[0], h.point[1]);
        if (q.hit && !(std::fabs(q.height_m - h.point[2]) <= 1e-6)) answers.push_back({h.point[0], h.point[1], -1e9, h.node});
      }
      queries += points.size() + 1;
    }
  });
  uint64_t evictions = 0;
  // At least the planned frames, and on until 100 evictions have happened (a slow machine or a
  // sanitizer delivers fewer nodes per frame).
  for (int frame = 0; frame < 4000 && (frame < (kSanitized ? 150 : 400) || evictions <= 100); ++frame) {
    const double a = frame * 0.05;
    v.x = w.origin_x_m + span_x * (0.5 + 0.4 * std::cos(a));
    v.y = w.origin_y_m + span_y * (0.5 + 0.4 * std::sin(a));
    if (frame % 50 == 25) v.x = w.origin_x_m + span_x * 0.9;  // teleport
    v.z = synthetic::surface_height_m(spec, v.x, v.y) + 30;
    evictions += streamer.update({&v, 1}).evicted.size();
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  stop = true;
  hammer.join();
  streamer.close();  // snapshots outlive the streamer; the answers were copied anyway
  EXPECT_GT(evictions, 100u);
  EXPECT_GT(queries, 1000u);
  EXPECT_GT(snapshots, 10u);
  ASSERT_GT(answers.size(), 100u);

  // Each answer equals its node's surface, from a vertical brute-force ray on that node alone.
  ArchiveReader reader;
  ASSERT_TRUE(reader.open(path).ok());
  std::map<Key, std::unique_ptr<BruteForce>> single;
  int wrong = 0;
  for (const Answer& a : answers) {
    auto& b = single[key_of(a.node)];
    if (!b) b = std::make_unique<BruteForce>(reader, std::vector<NodeKey>{a.node});
    const RefHit ref = b->cast({{a.x, a.y, 1e5}, {0, 0, -1}, 2e5});
    wrong += !ref.hit || std::fabs((1e5 - ref.t) - a.height) > 1e-6;
  }
  EXPECT_EQ(wrong, 0) << "of " << answers.size() << " answers";
}

}  // namespace
}  // namespace terrain::test
