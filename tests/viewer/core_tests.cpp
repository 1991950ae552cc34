// CPU side of the viewer, no Vulkan device: the reference traversal, LOD map, patch list and
// stitching (watertight for every LOD difference), residency invariants, camera precision, BC.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <set>

#include "camera.h"
#include "far_light.h"
#include "reference.h"
#include "residency.h"
#include "synthetic_nodes.h"
#include "terrain/bc_decode.h"

namespace terrain::view {
namespace {

// A world of `roots` x `roots` root nodes with every node down to `finest` existing.
WorldInfo small_world(uint32_t roots) {
  WorldInfo w;
  w.roots_x = w.roots_y = roots;
  w.origin_x_m = 400000;
  w.origin_y_m = 5000000;
  w.step_log2.fill(2);
  return w;
}

NodeRecord record(uint32_t level, uint32_t x, uint32_t y, float error) {
  NodeRecord r;
  r.key = {level, x, y};
  r.geometric_error_m = error;
  r.min_height = 0;
  r.max_height = 100 * 1024;
  return r;
}

Camera look_down(const WorldInfo& w, double lx, double ly, double h) {
  Camera c;
  c.position[0] = w.origin_x_m + lx;
  c.position[1] = w.origin_y_m + ly;
  c.position[2] = h;
  c.pitch = -M_PI / 2 + 0.01;
  return c;
}

FrameUniforms uniforms_for(const Camera& c, const WorldInfo& w, double error_px, uint32_t flags = 0) {
  FrameUniforms u{};
  fill_view_uniforms(c, w, 640, 360, u);
  u.lod[0] = float(error_px);
  u.world[0] = w.roots_x;
  u.world[1] = w.roots_y;
  u.world[2] = w.roots_x << kRootLevel;
  u.world[3] = w.roots_y << kRootLevel;
  u.misc[0] = uint32_t(top_level(w));
  u.misc[1] = flags;
  lod_window(w, c.position[0], c.position[1], u.lodwin);
  return u;
}

// Counts how many listed nodes draw each sector.
std::vector<int> coverage(const TerrainState& st, const NodeList& list) {
  const uint32_t sx = st.roots_x() << kRootLevel, sy = st.roots_y() << kRootLevel;
  std::vector<int> cover(size_t(sx) * sy, 0);
  for (uint32_t e : list.entries) {
    const SlotDescriptor& d = st.descriptor(e & TV_ENTRY_SLOT_MASK);
    const uint32_t mask = (e >> TV_ENTRY_QUAD_SHIFT) & 0xFu, size = 1u << d.level;
    for (uint32_t j = 0; j < size; ++j)
      for (uint32_t i = 0; i < size; ++i) {
        const uint32_t q = d.level == 0 ? 0u : uint32_t(i >= size / 2) | uint32_t(j >= size / 2) << 1;
        if (mask & (1u << q)) ++cover[size_t((d.y << d.level) + j) * sx + (d.x << d.level) + i];
      }
  }
  return cover;
}

TEST(ViewerReference, SplitsOnlyWhenNoChildIsStillStreaming) {
  const WorldInfo w = small_world(1);
  TerrainState st;
  st.init(w, 8);
  NodeRecord root = record(5, 0, 0, 50.0f);
  root.child_mask = 0xF;
  st.set_slot(0, slot_descriptor_of(root, w));
  st.set_node({5, 0, 0}, 0);
  for (uint32_t c = 0; c < 4; ++c) {
    const NodeKey k = child_of({5, 0, 0}, int(c));
    st.set_slot(1 + c, slot_descriptor_of(record(4, k.x, k.y, 10.0f), w));
    st.set_node(k, uint16_t(1 + c));
  }
  const FrameUniforms u = uniforms_for(look_down(w, 1024, 1024, 3000), w, 1.0);
  ASSERT_TRUE(wants_split(st.descriptor(0), u));
  const std::vector<SlotCpuData> cpu(8);  // coarsening errors 0: irrelevant here
  NodeList all = reference_traverse(st, u, cpu);
  EXPECT_EQ(all.level_counts[5], 0u);
  EXPECT_EQ(all.level_counts[4], 4u);

  st.set_node({4, 1, 0}, uint16_t(TV_SLOT_EMPTY));  // one child still loading: no split at all
  EXPECT_EQ(st.child(0, 1), uint16_t(TV_SLOT_EMPTY));
  NodeList waiting = reference_traverse(st, u, cpu);
  ASSERT_EQ(waiting.entries.size(), 1u);
  EXPECT_EQ(waiting.entries[0], 0u | 0xFu << TV_ENTRY_QUAD_SHIFT);

  // Child 1 does not exist (the parent's child mask says so) or failed to load: the root keeps
  // its quarter either way.
  for (int absent = 0; absent < 2; ++absent) {
    root.child_mask = absent == 0 ? 0xD : 0xF;
    st.set_slot(0, slot_descriptor_of(root, w));
    if (absent == 1) st.set_node({4, 1, 0}, uint16_t(TV_SLOT_INVALID));
    EXPECT_EQ(st.child(0, 1), uint16_t(TV_SLOT_INVALID));
    NodeList partial = reference_traverse(st, u, cpu);
    EXPECT_EQ(partial.level_counts[4], 3u);
    EXPECT_EQ(partial.level_counts[5], 1u);
    EXPECT_TRUE(std::count(partial.entries.begin(), partial.entries.end(), 0u | (1u << 1) << TV_ENTRY_QUAD_SHIFT));
    for (int c : coverage(st, partial)) EXPECT_EQ(c, 1);
  }

  const FrameUniforms far = uniforms_for(look_down(w, 1024, 1024, 3.0e6), w, 1.0);
  EXPECT_FALSE(wants_split(st.descriptor(0), far));  // 50 m seen from 3000 km: well under a pixel
}

TEST(ViewerReference, SplitTestIsTheStreamersScreenSpaceError) {
  // e = error * ppr / distance(eye, box) > target  (terrain/streamer.h), away from exact ties.
  const WorldInfo w = small_world(4);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> pos(-2000, 10000), err(0.01, 30), tgt(0.3, 8);
  int agree = 0, checked = 0;
  for (int it = 0; it < 20000; ++it) {
    const int level = 1 + int(rng() % 5);
    const uint32_t n = w.roots_x << (kRootLevel - level);
    NodeRecord r = record(uint32_t(level), uint32_t(rng() % n), uint32_t(rng() % n), float(err(rng)));
    r.min_height = int32_t(rng() % 200000);
    r.max_height = r.min_height + int32_t(rng() % 400000);
    const SlotDescriptor d = slot_descriptor_of(r, w);
    Camera c = look_down(w, pos(rng), pos(rng), pos(rng) * 0.2 + 500);
    const FrameUniforms u = uniforms_for(c, w, tgt(rng));
    const double size = node_size_m(level);
    const double lx = c.position[0] - w.origin_x_m, ly = c.position[1] - w.origin_y_m, z = c.position[2];
    const double dx = std::max({d.x * size - lx, 0.0, lx - (d.x + 1) * size});
    const double dy = std::max({d.y * size - ly, 0.0, ly - (d.y + 1) * size});
    const double dz = std::max({d.min_height / 1024.0 - z, 0.0, z - d.max_height / 1024.0});
    const double dist = std::max(std::sqrt(dx * dx + dy * dy + dz * dz), 0.001);
    const double e = double(d.geometric_error_m) * double(u.cam_frac[3]) / dist;
    if (std::abs(e / double(u.lod[0]) - 1.0) < 1e-4) continue;
    ++checked;
    agree += (e > double(u.lod[0])) == wants_split(d, u);
  }
  EXPECT_EQ(agree, checked);
  EXPECT_GT(checked, 19000);
}

// Builds the stitched triangles of every patch (integer half-metre xy) and checks the mesh is
// watertight: every directed edge of a non-degenerate triangle has its reverse exactly once,
// except on the outer border of the covered area; and the triangles' areas add up to that area.
struct MeshCheck {
  size_t triangles = 0, open_edges = 0, border_edges = 0;
  double area = 0, expected_area = 0;
};

MeshCheck check_watertight(const PatchList& patches, double world_w_hm, double world_h_hm) {
  // Directed edges as (from, to) vertex keys (x << 32 | y, exact half metres), sorted for lookups.
  using Edge = std::pair<uint64_t, uint64_t>;
  std::vector<Edge> edges;
  MeshCheck m;
  auto key = [](int64_t x, int64_t y) { return uint64_t(x) << 32 | uint64_t(y); };
  for (const GpuPatch& p : patches.patches) {
    auto pos = [&](int i, int j) {
      int64_t hx, hy;
      int ti, tj;
      patch_vertex(p, i, j, hx, hy, ti, tj);
      return std::make_pair(hx, hy);
    };
    const int n = int(patch_quads(p));
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const auto v00 = pos(i, j), v10 = pos(i + 1, j), v11 = pos(i + 1, j + 1), v01 = pos(i, j + 1);
        for (auto tri : {std::array{v00, v10, v11}, std::array{v00, v11, v01}}) {
          const double a2 = double(tri[1].first - tri[0].first) * double(tri[2].second - tri[0].second) -
                            double(tri[2].first - tri[0].first) * double(tri[1].second - tri[0].second);
          EXPECT_GE(a2, 0.0) << "a stitched triangle flipped";
          if (a2 == 0) continue;
          ++m.triangles;
          m.area += a2 / 2;
          for (int k = 0; k < 3; ++k) {
            const auto& u = tri[size_t(k)];
            const auto& v = tri[size_t((k + 1) % 3)];
            edges.push_back({key(u.first, u.second), key(v.first, v.second)});
          }
        }
      }
  }
  std::sort(edges.begin(), edges.end());
  const auto W = int64_t(world_w_hm), H = int64_t(world_h_hm);
  for (size_t i = 0; i < edges.size(); ++i) {
    const Edge& e = edges[i];
    EXPECT_FALSE(i > 0 && edges[i - 1] == e) << "an edge is used twice in the same direction (overlap)";
    if (std::binary_search(edges.begin(), edges.end(), Edge{e.second, e.first})) continue;
    const int64_t x0 = int64_t(e.first >> 32), y0 = int64_t(e.first & 0xFFFFFFFFu);
    const int64_t x1 = int64_t(e.second >> 32), y1 = int64_t(e.second & 0xFFFFFFFFu);
    const bool border = (x0 == x1 && (x0 == 0 || x0 == W)) || (y0 == y1 && (y0 == 0 || y0 == H));
    if (border) ++m.border_edges; else ++m.open_edges;
  }
  m.expected_area = world_w_hm * world_h_hm;
  return m;
}

// A synthetic world with every node resident in 512 slots, and the slots' CPU data (the input of
// the reference traversal); null when residency fails.
struct ResidentScene {
  synthetic::World sw;
  TerrainState st;
  std::vector<SlotCpuData> cpu;
  float cone_table[256];
};
std::unique_ptr<ResidentScene> resident_scene(const synthetic::Spec& o) {
  auto scene = std::make_unique<ResidentScene>();
  scene->sw = synthetic::make_world(o);
  StaticResidency res;
  res.init(scene->sw.world, test::memory_nodes(scene->sw), 512, scene->st);
  std::vector<NodeUpload> uploads;
  if (!res.apply([](const NodeKey&) { return true; }, scene->st, uploads).ok()) return nullptr;
  scene->cpu.resize(512);
  for (auto& up : uploads) scene->cpu[up.slot] = prepare_slot(*up.data, scene->st.descriptor(up.slot));
  cone_sin2_table(0, scene->cone_table);
  return scene;
}

TEST(ViewerReference, StitchedMeshIsWatertightForEveryLodDifference) {
  // Root (0,0) refined to level 0 around one corner point, root (1,0) never refined: the traversal
  // produces neighbours differing by 1..5 levels. Culling off: the whole world is meshed.
  synthetic::Spec o = synthetic::analytic_surface();
  o.roots_x = 3;
  o.roots_y = 1;
  o.cones = false;
  o.flat_from_x_m = 2048;  // roots 1, 2 are flat: root 1 coarsens to level 7 next to level-0
                           // nodes, root 2 (no splitting neighbour) to level 8
  o.keep = [](const NodeKey& k) {
    if ((k.x >> (kRootLevel - k.level)) != 0) return false;
    const double size = node_size_m(int(k.level));
    const double cx = 2040, cy = 1030;
    const double dx = std::max({k.x * size - cx, 0.0, cx - (k.x + 1) * size});
    const double dy = std::max({k.y * size - cy, 0.0, cy - (k.y + 1) * size});
    return dx * dx + dy * dy < 150.0 * 150.0;
  };
  const auto scene = resident_scene(o);
  ASSERT_TRUE(scene);
  const auto& [sw, st, cpu, table] = *scene;
  Camera cam;
  cam.position[0] = sw.world.origin_x_m + 2040;
  cam.position[1] = sw.world.origin_y_m + 1030;
  cam.position[2] = 700;
  std::set<uint32_t> deltas;
  std::set<uint32_t> levels;
  for (double target : {0.01, 0.02, 0.03, 0.06, 0.1, 0.2, 0.4, 3.0, 30.0}) {
    const FrameUniforms u = uniforms_for(cam, sw.world, target, 0);
    const NodeList list = reference_traverse(st, u, cpu);
    const auto lod = reference_lod_map(st, u, list);
    const PatchList patches = reference_patches(st, u, list, lod, cpu, table);
    for (const auto& p : patches.patches) {
      levels.insert(patch_level(p));
      for (int s : {TV_EDGE_S, TV_EDGE_W, TV_EDGE_N, TV_EDGE_E}) deltas.insert(edge_delta(p, s));
    }
    const MeshCheck m = check_watertight(patches, 3 * 4096.0, 4096.0);
    EXPECT_EQ(m.open_edges, 0u) << "target " << target;
    EXPECT_GT(m.border_edges, 0u);
    EXPECT_DOUBLE_EQ(m.area, m.expected_area);
    for (int c : coverage(st, list)) EXPECT_EQ(c, 1);
  }
  EXPECT_EQ(deltas, (std::set<uint32_t>{0, 1, 2, 3, 4, 5, 6, 7}));
  EXPECT_TRUE(levels.count(0) && levels.count(5) && levels.count(7) && levels.count(8)) << "levels 7, 8: coarsened roots";
}

// The reference patch list of a frame seen from local (x, y) metres at height h, decimation on.
struct ReferenceFrame {
  FrameUniforms u;
  std::vector<uint32_t> lod;
  PatchList patches;
};
ReferenceFrame reference_frame(const ResidentScene& scene, double x, double y, double h, double target) {
  Camera cam;
  cam.position[0] = scene.sw.world.origin_x_m + x;
  cam.position[1] = scene.sw.world.origin_y_m + y;
  cam.position[2] = h;
  ReferenceFrame f;
  f.u = uniforms_for(cam, scene.sw.world, target, TV_FLAG_DECIMATE);
  const NodeList list = reference_traverse(scene.st, f.u, scene.cpu);
  f.lod = reference_lod_map(scene.st, f.u, list);
  f.patches = reference_patches(scene.st, f.u, list, f.lod, scene.cpu, scene.cone_table);
  return f;
}

// Distance (m) from local point (x, y, h) to the box of root patch p (coarsened or not: its
// (1 << c)^2 root patches' bounds).
double root_patch_distance(const ResidentScene& scene, const GpuPatch& p, double x, double y, double h) {
  const uint32_t c = patch_coarsening(p);
  const GpuNodeDesc& d = scene.st.descriptor(patch_slot(p));
  int32_t lo = INT32_MAX, hi = INT32_MIN;
  for (uint32_t q = patch_py(p) << c; q < (patch_py(p) + 1) << c; ++q)
    for (uint32_t r = patch_px(p) << c; r < (patch_px(p) + 1) << c; ++r) {
      lo = std::min(lo, scene.cpu[patch_slot(p)].bounds[q * 8 + r].min_units);
      hi = std::max(hi, scene.cpu[patch_slot(p)].bounds[q * 8 + r].max_units);
    }
  const double size = node_size_m(kRootLevel) / 8 * double(1u << c);
  const double x0 = d.x * node_size_m(kRootLevel) + patch_px(p) * size - x;
  const double y0 = d.y * node_size_m(kRootLevel) + patch_py(p) * size - y;
  const double dx = std::max({x0, 0.0, -(x0 + size)}), dy = std::max({y0, 0.0, -(y0 + size)});
  const double dz = std::max({lo / 1024.0 - h, 0.0, h - hi / 1024.0});
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// Per-patch decimation of roots (config.h "Patch decimation"): patches of roots drawn coarsened or
// not, drawn with every 2nd..16th vertex of their grid next to full patches of the same root, finer
// nodes and coarsened roots, stay watertight, and each decimation keeps the patch's total error
// within the target at the patch's distance.
TEST(ViewerReference, DecimatedRootPatchesStayWatertightAndWithinTheTarget) {
  std::set<uint32_t> decimations, interior_deltas;
  size_t checked = 0;
  size_t beside_coarsened = 0;  // decimated patches on a root edge facing a coarsened root
  size_t coarsened_decimated = 0;  // decimated patches of coarsened roots
  // Flat east (rough root column 0, flattening across column 1, flat column 2), then mirrored: the
  // coarser roots then lie west of the finer ones, whose west edges collapse (rounding down, onto
  // their own corners) while their inner edges stitch too.
  for (const bool flat_west : {false, true}) {
  synthetic::Spec o = synthetic::analytic_surface();
  o.roots_x = 3;
  o.roots_y = 2;
  o.cones = false;
  o.relief_m = 120;
  if (flat_west)
    o.flat_until_x_m = 3 * 2048 - 2600;
  else
    o.flat_from_x_m = 2600;
  o.keep = [](const NodeKey& k) { return k.level >= 3; };
  const auto scene = resident_scene(o);
  ASSERT_TRUE(scene);
  const auto& [sw, st, cpu, table] = *scene;
  // (2100, 1000, 200) at 10 px: a root decimated next to a coarsened root (cracked before the cap).
  for (auto [x, y, h] : {std::array{2600.0, 2048.0, 400.0}, std::array{1000.0, 500.0, 900.0},
                         std::array{-3000.0, 2048.0, 1500.0}, std::array{2100.0, 1000.0, 200.0},
                         std::array{-1000.0, 4000.0, 3000.0}, std::array{4000.0, -300.0, 300.0},
                         std::array{4000.0, -1000.0, 600.0}, std::array{4500.0, 0.0, 200.0},
                         std::array{3500.0, -2000.0, 1000.0}, std::array{4096.0, 4500.0, 400.0}})
    for (double target : {0.3, 1.0, 3.0, 10.0}) {
      if (flat_west) x = 3 * 2048 - x;
      const auto [u, lod, patches] = reference_frame(*scene, x, y, h, target);
      for (const auto& p : patches.patches) {
        const uint32_t e = patch_decimation(p);
        decimations.insert(e);
        if (e > 0 && patch_px(p) == 7) {
          const GpuNodeDesc& d = st.descriptor(patch_slot(p));
          const uint32_t east = (d.x + 1) << kRootLevel, row = (d.y << kRootLevel) + patch_py(p) * 4;
          const uint32_t sectors_x = st.roots_x() << kRootLevel;
          if (east < sectors_x && lod[size_t(lod_index(u, east, row))] > kRootLevel + 1) ++beside_coarsened;
        }
        if (e > 0) {
          const uint32_t c = patch_coarsening(p);
          ASSERT_EQ(patch_node_level(p), kRootLevel) << "only roots decimate";
          coarsened_decimated += c > 0;
          // The bound the decimation promises: total error * pixels per radian <= target * distance.
          const double dist = root_patch_distance(*scene, p, x, y, h);
          const double err = double(cpu[patch_slot(p)].patch_error[patch_error_index(c, patch_px(p), patch_py(p))][e - 1]);
          EXPECT_LE(err * double(u.cam_frac[3]), target * dist * (1 + 1e-5));
          ++checked;
        }
        if (patch_px(p) > 0 && patch_px(p) < 7 && edge_delta(p, TV_EDGE_W) > 0) interior_deltas.insert(edge_delta(p, TV_EDGE_W));
      }
      const MeshCheck m = check_watertight(patches, 3 * 4096.0, 2 * 4096.0);
      EXPECT_EQ(m.open_edges, 0u) << "target " << target << " camera " << x << "," << y;
      EXPECT_DOUBLE_EQ(m.area, m.expected_area);
    }
  }
  EXPECT_EQ(decimations, (std::set<uint32_t>{0, 1, 2, 3, 4}));
  EXPECT_FALSE(interior_deltas.empty()) << "decimated root patches must border less decimated ones inside a root";
  EXPECT_GT(checked, 100u);
  EXPECT_GT(beside_coarsened, 0u) << "decimated root patches must face coarsened roots";
  EXPECT_GT(coarsened_decimated, 0u) << "patches of coarsened roots must decimate too";
}

// Patches with hole vertices decimate too, but only as far as a root may coarsen (c + e <= 3, quads
// of at most 128 m: the holes' drawn outline moves by at most one such quad, as for coarsened
// roots), and within the target over what the coarse mesh draws: every vertex of a coarse
// triangle without a hole corner, recomputed here from the node's heights and hole mask.
TEST(ViewerReference, PatchesWithHolesDecimateWithinTheTargetOverWhatTheyDraw) {
  synthetic::Spec o = synthetic::analytic_surface();
  o.roots_x = 3;
  o.roots_y = 2;
  o.cones = false;
  o.relief_m = 120;
  o.flat_from_x_m = 2600;
  o.hole_x_m = o.origin_x_m + 3000;  // a 250 m disc across the flattening and the flat root columns
  o.hole_y_m = o.origin_y_m + 1900;
  o.hole_radius_m = 250;
  o.keep = [](const NodeKey& k) { return k.level >= 3; };
  const auto scene = resident_scene(o);
  ASSERT_TRUE(scene);
  const auto& [sw, st, cpu, table] = *scene;
  size_t checked = 0, deep = 0;
  for (const auto& [x, y, h] : {std::array{3000.0, 2048.0, 3000.0}, std::array{3000.0, -2000.0, 1500.0},
                                std::array{6000.0, 2048.0, 2000.0}, std::array{1000.0, 2048.0, 5000.0},
                                std::array{3000.0, 1900.0, 8000.0}})
    for (double target : {0.5, 1.0, 3.0}) {
      const auto [u, lod, patches] = reference_frame(*scene, x, y, h, target);
      for (const auto& p : patches.patches) {
        const uint32_t c = patch_coarsening(p), e = patch_decimation(p);
        if (e == 0) continue;
        const GpuNodeDesc& d = st.descriptor(patch_slot(p));
        const synthetic::Node* node = nullptr;
        for (const auto& n : sw.nodes)
          if (n.record.key.level == uint32_t(kRootLevel) && n.record.key.x == d.x && n.record.key.y == d.y) node = &n;
        ASSERT_NE(node, nullptr);
        std::vector<uint8_t> holes(kHeightCount);
        decode_hole_mask(node->data, holes.data());
        const int span = TV_QUADS_PER_PATCH << c, i0 = int(patch_px(p)) * span, j0 = int(patch_py(p)) * span;
        const int step = 1 << (c + e);
        auto hole = [&](int i, int j) { return holes[size_t(j0 + j) * kHeightSamples + size_t(i0 + i)] != 0; };
        auto height = [&](int i, int j) {
          const uint16_t r = node->data.heights[size_t(j0 + j) * kHeightSamples + size_t(i0 + i)];
          return double(vertex_units(node->record.height_offset, r, sw.world.step_log2[kRootLevel])) / 1024.0;
        };
        bool any_hole = false;
        for (int j = 0; j <= span; ++j)
          for (int i = 0; i <= span; ++i) any_hole = any_hole || hole(i, j);
        if (!any_hole) continue;
        EXPECT_LE(c + e, 3u) << "a patch with holes decimates at most as far as a root coarsens";
        double worst = 0;
        for (int j = 0; j <= span; ++j)
          for (int i = 0; i <= span; ++i) {
            const int ci = std::min(i / step, span / step - 1) * step, cj = std::min(j / step, span / step - 1) * step;
            const double a = double(i - ci) / step, b = double(j - cj) / step;
            const bool upper = a < b;  // SW->NE split: (00, 10, 11) below the diagonal, (00, 11, 01) above
            if (hole(i, j) || hole(ci, cj) || hole(ci + step, cj + step) || (upper ? hole(ci, cj + step) : hole(ci + step, cj)))
              continue;
            const double h00 = height(ci, cj), h10 = height(ci + step, cj), h01 = height(ci, cj + step),
                         h11 = height(ci + step, cj + step);
            const double drawn = upper ? h00 + a * (h11 - h01) + b * (h01 - h00) : h00 + a * (h10 - h00) + b * (h11 - h10);
            worst = std::max(worst, std::abs(drawn - height(i, j)));
          }
        const double dist = root_patch_distance(*scene, p, x, y, h);
        EXPECT_LE((worst + double(node->record.geometric_error_m)) * double(u.cam_frac[3]), target * dist * (1 + 1e-5))
            << "camera " << x << "," << y << "," << h << " target " << target;
        ++checked;
        deep += c + e == 3;
      }
    }
  EXPECT_GT(checked, 20u) << "patches with holes must decimate";
  EXPECT_GT(deep, 0u) << "some as far as 128 m quads";
  std::printf("decimated patches with holes: %zu, %zu of them to 128 m quads\n", checked, deep);
}

// What the renderer's upload prepares per slot (node_prep.h prepare_slot), recomputed here by brute
// force from the node's heights and hole mask, without node_prep's helpers: per-patch bounds over
// the 17 x 17 vertices, and for roots every coarsening and patch decimation error as the largest
// vertical distance between a vertex and the coarse SW->NE triangle over it (holes: only vertices
// the coarse mesh draws; kNeverDecimate beyond a root's coarsening), plus the geometric error.
TEST(ViewerNodePrep, PreparedSlotsMatchABruteForceRecomputation) {
  synthetic::Spec o = synthetic::analytic_surface();
  o.roots_x = 2;
  o.roots_y = 2;
  o.relief_m = 120;
  o.flat_from_x_m = 2600;
  o.hole_x_m = o.origin_x_m + 1900;
  o.hole_y_m = o.origin_y_m + 1900;
  o.hole_radius_m = 250;
  o.keep = [](const NodeKey& k) { return k.level >= 4; };
  const auto scene = resident_scene(o);
  ASSERT_TRUE(scene);
  const auto& [sw, st, cpu, table] = *scene;
  size_t roots = 0, hole_patches = 0, compared = 0;
  for (uint32_t slot = 0; slot < st.slot_count(); ++slot) {
    const SlotDescriptor& d = st.descriptor(slot);
    const synthetic::Node* node = nullptr;
    for (const auto& n : sw.nodes)
      if (n.record.key == NodeKey{d.level, d.x, d.y} && st.slot_of(n.record.key) == slot) node = &n;
    if (!node) continue;
    const SlotCpuData& got = cpu[slot];
    std::vector<uint8_t> holes(kHeightCount);
    decode_hole_mask(node->data, holes.data());
    auto units = [&](int i, int j) {
      return int32_t(d.height_offset) + (int32_t(node->data.heights[size_t(j) * kHeightSamples + size_t(i)]) << d.step_log2);
    };
    auto metres = [&](int i, int j) { return double(units(i, j)) / 1024.0; };
    auto hole = [&](int i, int j) { return holes[size_t(j) * kHeightSamples + size_t(i)] != 0; };
    for (int q = 0; q < 8; ++q)
      for (int p = 0; p < 8; ++p) {
        int32_t lo = INT32_MAX, hi = INT32_MIN;
        for (int j = 16 * q; j <= 16 * q + 16; ++j)
          for (int i = 16 * p; i <= 16 * p + 16; ++i) {
            lo = std::min(lo, units(i, j));
            hi = std::max(hi, units(i, j));
          }
        ASSERT_EQ(got.bounds[size_t(q * 8 + p)].min_units, lo) << "slot " << slot << " patch " << p << "," << q;
        ASSERT_EQ(got.bounds[size_t(q * 8 + p)].max_units, hi) << "slot " << slot << " patch " << p << "," << q;
      }
    if (d.level != kRootLevel) {  // errors are the roots' only
      for (float e : got.coarse_error) EXPECT_EQ(e, 0.0f);
      for (const auto& pe : got.patch_error)
        for (float e : pe) EXPECT_EQ(e, 0.0f);
      continue;
    }
    ++roots;
    // Largest |vertex - coarse surface| over [i0, i0 + span]^2 at stride s; `whole_triangle`: skip
    // vertices of coarse triangles with a hole corner (else only hole vertices themselves).
    auto worst = [&](int i0, int j0, int span, int s, bool whole_triangle) {
      double w = 0;
      for (int j = 0; j <= span; ++j)
        for (int i = 0; i <= span; ++i) {
          const int ci = std::min(i / s, span / s - 1) * s, cj = std::min(j / s, span / s - 1) * s;
          const double a = double(i - ci) / s, b = double(j - cj) / s;
          const bool upper = a < b;  // (00, 11, 01) above the diagonal, (00, 10, 11) on and below it
          const int I = i0 + i, J = j0 + j, CI = i0 + ci, CJ = j0 + cj;
          if (hole(I, J)) continue;
          if (whole_triangle && (hole(CI, CJ) || hole(CI + s, CJ + s) || (upper ? hole(CI, CJ + s) : hole(CI + s, CJ))))
            continue;
          const double h00 = metres(CI, CJ), h10 = metres(CI + s, CJ), h01 = metres(CI, CJ + s), h11 = metres(CI + s, CJ + s);
          const double drawn = upper ? h00 + a * (h11 - h01) + b * (h01 - h00) : h00 + a * (h10 - h00) + b * (h11 - h10);
          w = std::max(w, std::abs(drawn - metres(I, J)));
        }
      return w;
    };
    const double g = d.geometric_error_m;
    auto near = [&](float actual, double expected) { return std::abs(double(actual) - expected) <= 1e-4 + 1e-6 * expected; };
    for (int c = 1; c <= 3; ++c)
      EXPECT_TRUE(near(got.coarse_error[size_t(c)], g + worst(0, 0, 128, 1 << c, false)))
          << "slot " << slot << " coarsening " << c << ": " << got.coarse_error[size_t(c)];
    for (int c = 0; c <= 3; ++c)
      for (int q = 0; q < (8 >> c); ++q)
        for (int p = 0; p < (8 >> c); ++p) {
          const int span = 16 << c, i0 = p * span, j0 = q * span;
          bool any_hole = false;
          for (int j = j0; j <= j0 + span; ++j)
            for (int i = i0; i <= i0 + span; ++i) any_hole = any_hole || hole(i, j);
          hole_patches += any_hole && c == 0;
          for (int e = 1; e <= 4; ++e) {
            const float actual = got.patch_error[patch_error_index(uint32_t(c), uint32_t(p), uint32_t(q))][size_t(e - 1)];
            if (any_hole && c + e > 3) {
              EXPECT_GE(actual, 1e29f) << "a patch with holes never decimates beyond a root's coarsening";
              continue;
            }
            EXPECT_TRUE(near(actual, g + worst(i0, j0, span, 1 << (c + e), any_hole)))
                << "slot " << slot << " c " << c << " patch " << p << "," << q << " e " << e << ": " << actual;
            ++compared;
          }
        }
  }
  EXPECT_EQ(roots, 4u);
  EXPECT_GT(hole_patches, 0u) << "some root patches must hold holes";
  EXPECT_GT(compared, 4u * 4 * 64) << "every root patch of every coarsening compared";
}

TEST(ViewerReference, LodMapMatchesCoverage) {
  synthetic::Spec o = synthetic::analytic_surface();
  o.roots_x = 3;
  o.roots_y = 2;
  o.cones = false;
  o.keep = [](const NodeKey& k) { return k.level >= 3 || (k.x % 5 == 0 && k.y % 3 == 0 && k.level >= 1); };
  synthetic::World sw = synthetic::make_world(o);
  TerrainState st;
  StaticResidency res;
  res.init(sw.world, test::memory_nodes(sw), 2048, st);
  std::vector<NodeUpload> uploads;
  std::mt19937 rng(3);
  // A random streaming frontier: every node resident with probability 0.7 (parents first).
  ASSERT_TRUE(res.apply([&](const NodeKey& k) { return k.level == kRootLevel || rng() % 10 < 7; }, st, uploads).ok());
  std::vector<SlotCpuData> cpu(2048);
  for (auto& up : uploads) cpu[up.slot] = prepare_slot(*up.data, st.descriptor(up.slot));
  for (int view = 0; view < 20; ++view) {
    Camera cam;
    cam.position[0] = sw.world.origin_x_m + double(rng() % 6144);
    cam.position[1] = sw.world.origin_y_m + double(rng() % 4096);
    cam.position[2] = 200 + double(rng() % 3000);
    cam.yaw = double(rng() % 360) * M_PI / 180;
    const FrameUniforms u = uniforms_for(cam, sw.world, 0.5 + double(rng() % 4));
    const NodeList list = reference_traverse(st, u, cpu);
    const auto lod = reference_lod_map(st, u, list);
    const auto cover = coverage(st, list);
    for (size_t i = 0; i < cover.size(); ++i) {
      ASSERT_EQ(cover[i], 1) << "sector " << i;
      ASSERT_GE(lod[i], 1u);
      ASSERT_LE(lod[i], 6u + TV_MAX_COARSEN);
    }
  }
}

TEST(ViewerReference, ResidencyKeepsParentsOfResidentNodes) {
  synthetic::Spec o = synthetic::analytic_surface();
  o.roots_x = o.roots_y = 1;
  o.cones = false;
  o.keep = [](const NodeKey& k) { return k.level >= 3; };
  synthetic::World sw = synthetic::make_world(o);
  TerrainState st;
  StaticResidency res;
  const std::vector<MemoryNode> nodes = test::memory_nodes(sw);
  res.init(sw.world, nodes, 64, st);
  std::vector<NodeUpload> uploads;
  // Wants level-3 nodes but not their level-4 parents: they must stay out.
  ASSERT_TRUE(res.apply([](const NodeKey& k) { return k.level != 4; }, st, uploads).ok());
  EXPECT_EQ(res.resident_count(), 1u);
  EXPECT_EQ(st.slot_of({4, 0, 0}), uint16_t(TV_SLOT_EMPTY));
  EXPECT_EQ(st.slot_of({3, 0, 0}), uint16_t(TV_SLOT_EMPTY));
  uploads.clear();
  ASSERT_TRUE(res.apply([](const NodeKey&) { return true; }, st, uploads).ok());
  EXPECT_EQ(res.resident_count(), 21u);
  EXPECT_EQ(uploads.size(), 20u);
  // The same set again: nothing to upload, nothing evicted.
  uploads.clear();
  ASSERT_TRUE(res.apply([](const NodeKey&) { return true; }, st, uploads).ok());
  EXPECT_TRUE(uploads.empty());
  EXPECT_EQ(res.resident_count(), 21u);
  // 21 nodes wanted in 8 slots: a clear error naming the slot count, not a partial success.
  TerrainState small;
  StaticResidency tight;
  tight.init(sw.world, nodes, 8, small);
  uploads.clear();
  const Status full = tight.apply([](const NodeKey&) { return true; }, small, uploads);
  EXPECT_FALSE(full.ok());
  EXPECT_NE(full.message.find("8 atlas slots"), std::string::npos) << full.message;
}

TEST(ViewerCamera, CameraRelativePositionsStayExactAtUtmCoordinates) {
  // A vertex 0.5 m from a camera at UTM northing 5 000 000 m: camera-relative float coordinates
  // keep the offset exact to float precision of the offset itself (not of the 5e6 m coordinate).
  WorldInfo w = small_world(8);
  Camera c;
  c.position[0] = w.origin_x_m + 12345.3;
  c.position[1] = w.origin_y_m + 6789.7;
  c.position[2] = 100;
  FrameUniforms u{};
  fill_view_uniforms(c, w, 640, 360, u);
  const int64_t hx = int64_t(std::llround(12345.5 * 2)), hy = int64_t(std::llround(6789.5 * 2));
  const float rx = float(int32_t(hx) - u.cam_hm[0]) * 0.5f - u.cam_frac[0];
  const float ry = float(int32_t(hy) - u.cam_hm[1]) * 0.5f - u.cam_frac[1];
  EXPECT_NEAR(rx, 0.2, 1e-6);
  EXPECT_NEAR(ry, -0.2, 1e-6);
  // Naive float world coordinates would lose the 0.2 m offset (float spacing at 5e6 m is 0.5 m).
  const float naive = float(w.origin_y_m + 6789.5) - float(c.position[1]);
  EXPECT_GT(std::abs(double(naive) + 0.2), 0.1);
}

// The viewer decodes with the format library's truncating form (what the device samples).
TEST(ViewerBc, DecodesPunchThroughAndAlphaBlocks) {
  // BC1 3-colour mode (c0 <= c1): index 3 is transparent black.
  const uint8_t bc1[8] = {0x00, 0x00, 0xFF, 0xFF, 0b11100100, 0xFF, 0x00, 0x00};
  uint8_t out[64];  // texel t at out[4 * t]
  decode_bc1_block(bc1, out, BcRounding::truncate);
  EXPECT_EQ(out[4 * 0 + 3], 255);  // index 0: black
  EXPECT_EQ(out[4 * 1 + 0], 255);  // index 1: white
  EXPECT_EQ(out[4 * 2 + 0], 127);  // index 2: (0 + 255) / 2
  EXPECT_EQ(out[4 * 3 + 3], 0);    // index 3: transparent
  EXPECT_EQ(out[4 * 4 + 3], 0);
  // BC3 alpha, 8-value mode: a0 = 200, a1 = 60, index 2 = (6*200 + 60) / 7 = 180.
  uint8_t bc3[16] = {200, 60, 0b10, 0, 0, 0, 0, 0, 0xFF, 0xFF, 0x00, 0x00, 0, 0, 0, 0};
  decode_bc3_block(bc3, out, BcRounding::truncate);
  EXPECT_EQ(out[4 * 0 + 3], 180);
  EXPECT_EQ(out[4 * 1 + 3], 200);
  EXPECT_EQ(out[4 * 0 + 0], 255);
}


// The lit atlas (far_light.h): every texel's stored code is the one nearest, under the shader's
// decoding fit, to terrain.frag's per-pixel light of that texel (recomputed here in double from the
// shader's formula), so the stored value is within half a code step of it; holes stay transparent
// black. 20 000 random texels, all normal directions (including x^2 + y^2 > 1) and both suns.
TEST(ViewerFarLight, StoredCodeIsTheNearestToTheShadersLight) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> byte(0, 255);
  const int n = 20000;
  std::vector<uint8_t> normals(4 * n), albedo(4 * n), lit(4 * n);
  for (int i = 0; i < 4 * n; ++i) normals[size_t(i)] = uint8_t(byte(rng)), albedo[size_t(i)] = uint8_t(byte(rng));
  for (int i = 0; i < n; ++i) albedo[size_t(4 * i + 3)] = i % 10 == 0 ? 0 : 255;  // a tenth are holes
  for (const double az : {kDefaultSunAzimuthDeg, 300.0}) {
    const SceneLight light = scene_light(az, kDefaultSunElevationDeg);
    light_texels(normals.data(), albedo.data(), n, texel_lighting(light), lit.data());
    double worst = 0;
    for (int i = 0; i < n; ++i) {
      const uint8_t* nt = &normals[size_t(4 * i)];
      const uint8_t* at = &albedo[size_t(4 * i)];
      const uint8_t* o = &lit[size_t(4 * i)];
      if (at[3] == 0) {
        EXPECT_TRUE(o[0] == 0 && o[1] == 0 && o[2] == 0 && o[3] == 0) << "hole texel " << i;
        continue;
      }
      ASSERT_EQ(o[3], 255);
      const double x = (nt[3] - 128.0) / 127.0, y = (nt[1] - 128.0) / 127.0, r2 = x * x + y * y;
      double nv[3] = {x, y, r2 > 1 ? 0.0 : std::sqrt(1 - r2)};
      const double len = std::sqrt(nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2]);
      for (double& c : nv) c /= len;
      const double ndl = std::max(0.0, nv[0] * light.sun_dir[0] + nv[1] * light.sun_dir[1] + nv[2] * light.sun_dir[2]);
      const double ambient = (0.55 + 0.45 * nv[2]) * light.sun_color[3] * (0.4 + 0.6 * nt[0] / 255.0);
      for (int c = 0; c < 3; ++c) {
        const double a = at[c] / 255.0, albedo_linear = a * (a * (a * 0.305306011 + 0.682171111) + 0.012522878);
        const double want = albedo_linear * (light.sun_color[c] * ndl + light.sky_color[c] * ambient) / TV_LIT_SCALE;
        const double got = srgb_code_to_linear_fit(o[c]);
        // Half the step to the neighbouring code on the side of `want`.
        const int next = want > got ? std::min(o[c] + 1, 255) : std::max(o[c] - 1, 0);
        const double half_step = 0.5 * std::abs(double(srgb_code_to_linear_fit(uint8_t(next))) - got);
        const double beyond = std::abs(want - got) - half_step;
        if (!(want > 1.0 && o[c] == 255)) worst = std::max(worst, beyond);
      }
    }
    EXPECT_LE(worst, 1e-6) << "azimuth " << az << ": a stored code is not the nearest";
  }
}

}  // namespace
}  // namespace terrain::view
