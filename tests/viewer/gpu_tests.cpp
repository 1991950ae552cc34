// GPU pipeline on the Vulkan device (lavapipe here) against the CPU reference, plus rendering
// checks: crack-free stitching for every LOD difference, holes, cone culling. Synthetic worlds, so
// every input is known exactly; real archives are covered by the CLI tests.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <set>

#include "gpu_harness.h"
#include "resources.h"
#include "vk_common.h"

namespace terrain::view::test {
namespace {

// 2 x 2 roots; root column x = 1 is never refined (stays a 2048 m node), root column 0 refines to
// level 3 everywhere and to level 0 within 300 m of `focus` (next to the x = 2048 m root edge): the
// traversal can produce every LOD difference from 1 to 5 there.
constexpr double kFocusX = 2030, kFocusY = 1000;  // local metres
constexpr double kBumpyX = 900, kBumpyY = 1100;   // a second deep spot, in rough terrain

double box_distance(const NodeKey& k, double x, double y) {
  const double size = node_size_m(int(k.level));
  const double x0 = k.x * size, y0 = k.y * size;
  const double dx = std::max({x0 - x, 0.0, x - (x0 + size)});
  const double dy = std::max({y0 - y, 0.0, y - (y0 + size)});
  return std::sqrt(dx * dx + dy * dy);
}

synthetic::Spec deep_options() {
  synthetic::Spec o = synthetic::analytic_surface();
  o.relief_m = 700;  // smooth, steep slopes: back-facing patches with narrow cones
  o.detail = 0;
  o.flat_from_x_m = 2048;  // root column 1 is flat: drawn coarsened (level 7) next to level-0 nodes
  o.error_floor_m = 0.01;
  o.keep = [](const NodeKey& k) {
    if ((k.x >> (kRootLevel - k.level)) != 0) return false;  // root column 1: no children
    if (k.level >= 3) return true;
    return box_distance(k, kFocusX, kFocusY) < 300.0 || box_distance(k, kBumpyX, kBumpyY) < 250.0;
  };
  return o;
}

// `bumpy`: with the short-wavelength terms (a rough surface: unstitched edges crack visibly).
const World& deep_world(bool bumpy = false) {
  static World* w[2] = {nullptr, nullptr};
  if (!w[bumpy]) {
    w[bumpy] = new World;
    synthetic::Spec o = deep_options();
    if (bumpy) o.detail = 1.5;
    w[bumpy]->synthetic = synthetic::make_world(o);
  }
  return *w[bumpy];
}

Camera camera_at(const WorldInfo& w, double lx, double ly, double height_above, double yaw_deg, double pitch_deg) {
  Camera c;
  c.position[0] = w.origin_x_m + lx;
  c.position[1] = w.origin_y_m + ly;
  c.position[2] = height_above;
  c.yaw = yaw_deg * M_PI / 180.0;
  c.pitch = pitch_deg * M_PI / 180.0;
  return c;
}

void dump_ppm(const Gpu& gpu, const std::vector<uint8_t>& rgba, const std::string& name) {
  const char* dir = std::getenv("TV_DUMP_DIR");
  if (!dir) return;
  std::ofstream f(std::string(dir) + "/" + name + ".ppm", std::ios::binary);
  f << "P6\n" << gpu.target.width << " " << gpu.target.height << "\n255\n";
  for (size_t i = 0; i < rgba.size(); i += 4) f.write(reinterpret_cast<const char*>(&rgba[i]), 3);
}

std::vector<uint32_t> sorted(std::vector<uint32_t> v) {
  std::sort(v.begin(), v.end());
  return v;
}
std::vector<GpuPatch> sorted(std::vector<GpuPatch> v) {
  std::sort(v.begin(), v.end(), [](const GpuPatch& a, const GpuPatch& b) {
    return std::tie(a.slot_patch_level, a.edge_deltas) < std::tie(b.slot_patch_level, b.edge_deltas);
  });
  return v;
}

uint32_t max_delta(const std::vector<GpuPatch>& patches) {
  uint32_t m = 0;
  for (const auto& p : patches)
    for (int s : {TV_EDGE_S, TV_EDGE_W, TV_EDGE_N, TV_EDGE_E}) m = std::max(m, edge_delta(p, s));
  return m;
}

// Crack-test settings: the given error target over a magenta clear colour.
FrameSettings magenta_clear(double error_target_px) {
  FrameSettings s;
  s.error_target_px = error_target_px;
  s.clear[0] = 1;
  s.clear[1] = 0;
  s.clear[2] = 1;
  return s;
}

// Every node of the world resident in `slots` slots: the uploads of the first frame.
Status make_all_resident(World& world, Gpu& gpu, uint32_t slots, std::vector<NodeUpload>& uploads) {
  world.residency.init(world.synthetic.world, memory_nodes(world.synthetic), slots, gpu.state);
  return world.residency.apply([](const NodeKey&) { return true; }, gpu.state, uploads);
}

// A GPU (or a skip) with every node of `synthetic_world` resident in `slots` slots: declares
// `world`, `gpu` and `uploads` (the first frame's uploads), as TV_REQUIRE_GPU declares `gpu`.
#define TV_ALL_RESIDENT(synthetic_world, slots, w, h, ...)       \
  World world;                                                    \
  world.synthetic = synthetic_world;                              \
  TV_REQUIRE_GPU(gpu, world.synthetic.world, slots, w, h __VA_OPT__(,) __VA_ARGS__); \
  std::vector<NodeUpload> uploads;                                \
  ASSERT_TRUE(make_all_resident(world, *gpu, slots, uploads).ok())

// The GPU's node list, LOD map and patch list of the last frame.
struct GpuLists {
  NodeList nodes;
  std::vector<uint32_t> lod;
  std::vector<GpuPatch> patches;
};
// Renders a view with its lists kept (consuming `uploads`) and reads the lists back.
Status render_view(Gpu& gpu, std::vector<NodeUpload>& uploads, const Camera& camera, const FrameSettings& s, GpuLists& out) {
  TERRAIN_TRY(render_frame(gpu, uploads, camera, s, true));
  uploads.clear();
  gpu.renderer.read_lists(out.nodes, out.lod, out.patches);
  return Status::success();
}

// The frame just rendered with `s` (stitched, magenta clear) must show no magenta; then the same
// view without stitching is the control, whose magenta pixels (cracks) are returned: a crack test
// whose control never cracks could not fail. Both images are dumped as `name`(_unstitched).
size_t cracks_only_unstitched(Gpu& gpu, std::vector<NodeUpload>& uploads, const Camera& camera, FrameSettings s,
                              const std::string& name) {
  std::vector<uint8_t> rgba;
  read_color(gpu.target, rgba);
  dump_ppm(gpu, rgba, name);
  EXPECT_EQ(count_color(rgba, 255, 0, 255), 0u) << name << ": magenta shows through a crack";
  s.stitch = false;
  const Status st = render_frame(gpu, uploads, camera, s, false);
  EXPECT_TRUE(st.ok()) << st.to_string();
  uploads.clear();
  read_color(gpu.target, rgba);
  dump_ppm(gpu, rgba, name + "_unstitched");
  return count_color(rgba, 255, 0, 255);
}

// The last frame's GPU lists (node list, LOD map, patch list) against the CPU reference of the
// same state and uniforms; returns the reference lists for the caller's own checks.
struct ReferenceLists {
  NodeList nodes;
  PatchList patches;
};
ReferenceLists expect_lists_equal_reference(Gpu& gpu) {
  NodeList gpu_nodes;
  std::vector<uint32_t> gpu_lod;
  std::vector<GpuPatch> gpu_patches;
  gpu.renderer.read_lists(gpu_nodes, gpu_lod, gpu_patches);
  const FrameUniforms& u = gpu.renderer.uniforms();
  ReferenceLists ref;
  ref.nodes = reference_traverse(gpu.state, u, gpu.renderer.slot_cpu());
  EXPECT_EQ(sorted(gpu_nodes.entries), sorted(ref.nodes.entries));
  EXPECT_EQ(gpu_nodes.level_counts, ref.nodes.level_counts);
  EXPECT_EQ(gpu_nodes.overflow, 0u);
  const std::vector<uint32_t> ref_lod = reference_lod_map(gpu.state, u, ref.nodes);
  EXPECT_EQ(gpu_lod, ref_lod);
  ref.patches = reference_patches(gpu.state, u, ref.nodes, ref_lod, gpu.renderer.slot_cpu(),
                                  gpu.renderer.cone_sin2_table());
  EXPECT_EQ(sorted(gpu_patches), sorted(ref.patches.patches));
  return ref;
}

TEST(ViewerGpu, ListsEqualCpuReference) {
  TV_ALL_RESIDENT(deep_world().synthetic, 1024, 320, 180);
  struct View {
    double x, y, h, yaw, pitch, error;
  };
  const View views[] = {
      {kFocusX - 150, kFocusY, 450, 90, -35, 0.003},  // across the root edge, every delta
      {kFocusX - 60, kFocusY - 80, 800, 45, -20, 0.05},
      {1000, 1000, 3500, 0, -89, 2.0},               // top down over root 0
      {3000, 3000, 700, 225, -3, 1.0},               // low, looking back over the world
      {500, 2000, 640, 90, 0, 1.0},                  // low and level: back slopes hide
  
  };
  uint32_t deepest = 0;
  size_t total_cone = 0;
  for (const View& v : views) {
    FrameSettings s;
    s.error_target_px = v.error;
    const Camera cam = camera_at(world.synthetic.world, v.x, v.y, v.h, v.yaw, v.pitch);
    ASSERT_TRUE(render_frame(*gpu, uploads, cam, s, true).ok());
    uploads.clear();
    const ReferenceLists ref = expect_lists_equal_reference(*gpu);
    const NodeList& ref_nodes = ref.nodes;
    const PatchList& ref_patches = ref.patches;
    const FrameStats st = gpu->renderer.read_stats();
    EXPECT_EQ(st.patches_considered, ref_patches.considered);
    EXPECT_EQ(st.culled_frustum, ref_patches.culled_frustum);
    EXPECT_EQ(st.culled_cone, ref_patches.culled_cone);
    EXPECT_GT(ref_patches.patches.size(), 0u);
    deepest = std::max(deepest, max_delta(ref_patches.patches));
    total_cone += ref_patches.culled_cone;
    if (std::getenv("TV_VERBOSE"))
      std::printf("view %d: nodes %zu patches %zu frustum %u cone %u max delta %u\n", int(&v - views),
                  ref_nodes.entries.size(), ref_patches.patches.size(), ref_patches.culled_frustum,
                  ref_patches.culled_cone, max_delta(ref_patches.patches));
    std::vector<uint8_t> rgba;
    read_color(gpu->target, rgba);
    dump_ppm(*gpu, rgba, "lists_" + std::to_string(&v - views));
  }
  EXPECT_EQ(deepest, 7u) << "the views must exercise the largest LOD difference";
  EXPECT_GT(total_cone, 0u) << "the views must exercise cone culling";
}

// Renders `views` over a magenta clear colour and returns the magenta pixels of each.
struct ViewSpec {
  double x, y, h, yaw, pitch, error;
};

TEST(ViewerGpu, NoCracksAcrossLodBoundaries) {
  TV_ALL_RESIDENT(deep_world(true).synthetic, 1024, 320, 180);
  // Looking down across the root edge at x = 2048 m, where level-0 nodes meet the flat root drawn
  // at level 7, and over the rough spot, where levels 0..5 meet.
  const ViewSpec views[] = {{kFocusX - 120, kFocusY, 420, 90, -55, 0.01}, {kFocusX + 30, kFocusY - 60, 430, 0, -70, 0.01},
                            {kBumpyX - 100, kBumpyY, 700, 90, -50, 0.01}, {kBumpyX, kBumpyY - 150, 650, 0, -60, 0.01},
                            {kBumpyX + 50, kBumpyY + 50, 900, 200, -80, 0.02}, {2048, 2048, 1500, 90, -86, 0.3},
                            // Coarse targets: big LOD steps on rough ground, cracks of several pixels unstitched.
                            {kBumpyX - 300, kBumpyY, 800, 90, -40, 6.0}, {kBumpyX + 300, kBumpyY - 300, 900, 45, -55, 12.0}};
  uint32_t deepest = 0;
  size_t unstitched_cracks = 0;
  for (const ViewSpec& v : views) {
    FrameSettings s = magenta_clear(v.error);
    GpuLists lists;
    ASSERT_TRUE(render_view(*gpu, uploads, camera_at(world.synthetic.world, v.x, v.y, v.h, v.yaw, v.pitch), s, lists).ok());
    const auto& [nodes, lod, patches] = lists;
    deepest = std::max(deepest, max_delta(patches));
    unstitched_cracks += cracks_only_unstitched(*gpu, uploads, camera_at(world.synthetic.world, v.x, v.y, v.h, v.yaw, v.pitch), s,
                                                "crack_" + std::to_string(&v - views));
  }
  EXPECT_EQ(deepest, 7u) << "the drawn patches must include a 7-level difference (level 0 next to a coarsened root)";
  EXPECT_GT(unstitched_cracks, 0u) << "control: unstitched LOD boundaries must crack";
  std::printf("cracks without stitching: %zu px over %zu views\n", unstitched_cracks, std::size(views));
}

// Per-patch decimation of roots (config.h): rough, flattening and flat root columns seen from far
// and near at several targets. The GPU patch list (with each patch's decimation and the deltas of
// edges inside a root) equals the CPU reference, no magenta shows through, and the views do
// decimate (every e = 1..4, patches of coarsened roots too) and stitch decimated patches inside roots.
synthetic::World decimation_world() {
  synthetic::Spec o = synthetic::analytic_surface();
  o.roots_x = 3;
  o.roots_y = 2;
  o.relief_m = 120;
  o.detail = 1.5;
  o.flat_from_x_m = 2600;
  o.keep = [](const NodeKey& k) { return k.level >= 3; };
  return synthetic::make_world(o);
}

TEST(ViewerGpu, DecimatedRootPatchesEqualTheReferenceWithoutCracks) {
  TV_ALL_RESIDENT(decimation_world(), 512, 320, 180);
  const ViewSpec views[] = {{2600, 2048, 900, 0, -70, 1.0},   {1500, 1500, 1200, 45, -75, 0.5},
                            {3500, 2000, 1500, 0, -80, 1.0},   {2000, 1500, 600, 90, -60, 2.0},
                            {3000, 2048, 1200, 180, -65, 0.3}, {3000, 2048, 2000, 270, -85, 4.0},
                            {4500, 2048, 1400, 90, -70, 1.5},  {2100, 1000, 500, 90, -60, 10.0},
                            // Straight down: coarsened roots whose patches decimate unequally.
                            {3000, 2048, 2500, 0, -89, 1.0},   {3000, 2048, 2500, 0, -89, 2.0},
                            {2000, 2048, 2000, 0, -89, 1.5}};
  std::set<uint32_t> decimations;
  size_t interior = 0, unstitched = 0, coarsened = 0, coarsened_interior = 0;
  for (const ViewSpec& v : views) {
    FrameSettings s = magenta_clear(v.error);
    GpuLists lists;
    ASSERT_TRUE(render_view(*gpu, uploads, camera_at(world.synthetic.world, v.x, v.y, v.h, v.yaw, v.pitch), s, lists).ok());
    const auto& [nodes, lod, patches] = lists;
    const FrameUniforms& u = gpu->renderer.uniforms();
    const NodeList ref_nodes = reference_traverse(gpu->state, u, gpu->renderer.slot_cpu());
    EXPECT_EQ(sorted(nodes.entries), sorted(ref_nodes.entries));
    const std::vector<uint32_t> ref_lod = reference_lod_map(gpu->state, gpu->renderer.uniforms(), ref_nodes);
    EXPECT_EQ(lod, ref_lod);
    const PatchList ref = reference_patches(gpu->state, u, ref_nodes, ref_lod, gpu->renderer.slot_cpu(),
                                            gpu->renderer.cone_sin2_table());
    EXPECT_EQ(sorted(patches), sorted(ref.patches)) << "view " << (&v - views);
    for (const GpuPatch& p : patches) {
      decimations.insert(patch_decimation(p));
      interior += patch_level(p) == uint32_t(kRootLevel) &&
                  ((patch_px(p) > 0 && edge_delta(p, TV_EDGE_W) > 0) || (patch_px(p) < 7 && edge_delta(p, TV_EDGE_E) > 0) ||
                   (patch_py(p) > 0 && edge_delta(p, TV_EDGE_S) > 0) || (patch_py(p) < 7 && edge_delta(p, TV_EDGE_N) > 0));
      const uint32_t c = patch_coarsening(p), last = (8u >> c) - 1;
      coarsened += c > 0 && patch_decimation(p) > 0;
      coarsened_interior += c > 0 && ((patch_px(p) > 0 && edge_delta(p, TV_EDGE_W) > 0) || (patch_px(p) < last && edge_delta(p, TV_EDGE_E) > 0) ||
                                      (patch_py(p) > 0 && edge_delta(p, TV_EDGE_S) > 0) || (patch_py(p) < last && edge_delta(p, TV_EDGE_N) > 0));
    }
    unstitched += cracks_only_unstitched(*gpu, uploads, camera_at(world.synthetic.world, v.x, v.y, v.h, v.yaw, v.pitch), s,
                                         "decimated_" + std::to_string(&v - views));
  }
  EXPECT_GT(unstitched, 0u) << "control: unstitched decimated edges must crack";
  EXPECT_EQ(decimations, (std::set<uint32_t>{0, 1, 2, 3, 4}));
  EXPECT_GT(interior, 0u) << "decimated patches must border less decimated ones inside a root";
  EXPECT_GT(coarsened, 0u) << "patches of coarsened roots must decimate";
  EXPECT_GT(coarsened_interior, 0u) << "patches of a coarsened root must border more decimated ones inside it";
  std::printf("decimated patches of coarsened roots: %zu, with a delta inside their root: %zu\n", coarsened, coarsened_interior);
}

TEST(ViewerGpu, NoCracksAtTheStreamingFrontier) {
  World world;
  world.synthetic = deep_world(true).synthetic;
  TV_REQUIRE_GPU(gpu, world.synthetic.world, 1024, 320, 180);
  world.residency.init(world.synthetic.world, memory_nodes(world.synthetic), 1024, gpu->state);
  for (int seed = 0; seed < 4; ++seed) {
    std::vector<NodeUpload> uploads;
    uint32_t h = uint32_t(seed) * 2654435761u;
    // A random resident subset (the parent rule keeps it a valid streaming state).
    ASSERT_TRUE(world.residency
                    .apply([&](const NodeKey& k) {
                      h = h * 1664525u + 1013904223u;
                      return k.level == kRootLevel || (h >> 24) % 10 < 6;
                    }, gpu->state, uploads)
                    .ok());
    const FrameSettings s = magenta_clear(0.02);
    for (const ViewSpec& v : {ViewSpec{kFocusX - 120, kFocusY, 420, 90, -55, 0.02}, ViewSpec{kBumpyX, kBumpyY, 700, 30, -60, 0.01},
                              ViewSpec{2048, 2048, 1500, 45, -86, 0.1}}) {
      ASSERT_TRUE(render_frame(*gpu, uploads, camera_at(world.synthetic.world, v.x, v.y, v.h, v.yaw, v.pitch), s, false).ok());
      uploads.clear();
      std::vector<uint8_t> rgba;
      read_color(gpu->target, rgba);
      dump_ppm(*gpu, rgba, "frontier_" + std::to_string(seed) + "_" + std::to_string(v.h));
      EXPECT_EQ(count_color(rgba, 255, 0, 255), 0u) << "seed " << seed << " view at " << v.h << " m";
    }
  }
}

TEST(ViewerGpu, CullingNeverChangesTheImage) {
  // Frustum and cone culling are conservative: the image is the same byte for byte without them
  // (the rasteriser culls back faces anyway), while they remove work.
  TV_ALL_RESIDENT(deep_world().synthetic, 1024, 320, 180);
  uint32_t frustum = 0, cone = 0;
  for (const ViewSpec& v : {ViewSpec{kFocusX - 60, kFocusY - 80, 800, 45, -20, 0.05}, ViewSpec{3000, 3000, 700, 225, -3, 1.0},
                            ViewSpec{kFocusX - 150, kFocusY, 450, 90, -35, 0.01}}) {
    const Camera cam = camera_at(world.synthetic.world, v.x, v.y, v.h, v.yaw, v.pitch);
    FrameSettings s;
    s.error_target_px = v.error;
    ASSERT_TRUE(render_frame(*gpu, uploads, cam, s, false).ok());
    uploads.clear();
    const FrameStats culled = gpu->renderer.read_stats();
    std::vector<uint8_t> with, without;
    read_color(gpu->target, with);
    s.frustum_cull = s.cone_cull = false;
    ASSERT_TRUE(render_frame(*gpu, uploads, cam, s, false).ok());
    read_color(gpu->target, without);
    const FrameStats all = gpu->renderer.read_stats();
    EXPECT_EQ(all.culled_frustum + all.culled_cone, 0u);
    EXPECT_EQ(all.patches_drawn, culled.patches_drawn + culled.culled_frustum + culled.culled_cone);
    size_t differ = 0;
    for (size_t i = 0; i < with.size(); ++i) differ += with[i] != without[i];
    EXPECT_EQ(differ, 0u);
    frustum += culled.culled_frustum;
    cone += culled.culled_cone;
  }
  EXPECT_GT(frustum, 0u);
  EXPECT_GT(cone, 0u);
}

// One frame of the deep world with every node uploaded in one batch, prepared on `threads` threads
// (RendererConfig::upload_threads), far group lit per texel: its image, lists and per-slot data.
struct UploadResult {
  std::vector<uint8_t> image;
  GpuLists lists;
  std::vector<SlotCpuData> slots;
  size_t nodes = 0;
};
void render_uploaded_with(unsigned threads, UploadResult& out) {
  RendererConfig config;
  config.prelit_far = true;
  config.upload_threads = threads;
  TV_ALL_RESIDENT(deep_world().synthetic, 1024, 320, 180, config);
  out.nodes = uploads.size();
  const Camera cam = camera_at(world.synthetic.world, kFocusX - 60, kFocusY - 80, 800, 45, -20);
  FrameSettings s;
  s.error_target_px = 0.05;
  ASSERT_TRUE(render_view(*gpu, uploads, cam, s, out.lists).ok());
  read_color(gpu->target, out.image);
  out.slots = gpu->renderer.slot_cpu();
  // The GPU appends list entries in no fixed order.
  std::sort(out.lists.nodes.entries.begin(), out.lists.nodes.entries.end());
  std::sort(out.lists.patches.begin(), out.lists.patches.end(), [](const GpuPatch& x, const GpuPatch& y) {
    return std::memcmp(&x, &y, sizeof(GpuPatch)) < 0;
  });
}

TEST(ViewerGpu, UploadsPreparedOnManyThreadsEqualOneThread) {
  // A frame's nodes are decoded, lit and measured (bounds, coarsening and patch errors) in
  // parallel: with 1, 2 and 5 threads the staged bytes must be the same, so the image, the GPU
  // lists and the per-slot data are equal byte for byte.
  UploadResult one, many[2];
  render_uploaded_with(1, one);
  render_uploaded_with(2, many[0]);
  render_uploaded_with(5, many[1]);
  if (one.image.empty()) return;  // skipped: no device
  ASSERT_GT(one.nodes, 100u);
  for (const UploadResult& r : many) {
    EXPECT_EQ(r.image, one.image);
    EXPECT_EQ(r.lists.nodes.entries, one.lists.nodes.entries);
    EXPECT_EQ(r.lists.lod, one.lists.lod);
    ASSERT_EQ(r.lists.patches.size(), one.lists.patches.size());
    EXPECT_EQ(std::memcmp(r.lists.patches.data(), one.lists.patches.data(), one.lists.patches.size() * sizeof(GpuPatch)), 0);
    ASSERT_EQ(r.slots.size(), one.slots.size());
    size_t differ = 0;
    for (size_t k = 0; k < one.slots.size(); ++k)
      differ += std::memcmp(&r.slots[k], &one.slots[k], sizeof(SlotCpuData)) != 0;
    EXPECT_EQ(differ, 0u);
  }
}

TEST(ViewerGpu, OneDrawPerMeshMatchesTheMultiDraw) {
  // Devices without multiDrawIndirect get one indirect draw per decimation mesh instead of one
  // multi-draw per shading group: the same image, byte for byte. The view looks down on
  // decimating roots, so several meshes are drawn (measured: decimations 0, 1, 3 and 4).
  TV_ALL_RESIDENT(decimation_world(), 512, 320, 180);
  const bool device_multi_draw = gpu->ctx.multi_draw_indirect;
  const Camera cam = camera_at(world.synthetic.world, 3500, 2000, 1500, 0, -80);
  FrameSettings s = magenta_clear(1.0);
  std::vector<uint8_t> images[2];
  std::set<uint32_t> decimations;
  for (int single = 0; single < 2; ++single) {
    gpu->ctx.multi_draw_indirect = device_multi_draw && single == 0;
    GpuLists lists;
    ASSERT_TRUE(render_view(*gpu, uploads, cam, s, lists).ok());
    uploads.clear();
    read_color(gpu->target, images[single]);
    for (const GpuPatch& p : lists.patches) decimations.insert(patch_decimation(p));
  }
  gpu->ctx.multi_draw_indirect = device_multi_draw;
  EXPECT_GE(decimations.size(), 3u) << "the view must draw several decimation meshes";
  ASSERT_EQ(images[0].size(), images[1].size());
  size_t differ = 0;
  for (size_t i = 0; i < images[0].size(); ++i) differ += images[0][i] != images[1][i];
  EXPECT_EQ(differ, 0u);
}

TEST(ViewerGpu, HoleVerticesDropTheirTriangles) {
  // A 60 m hole disc seen from above; level-3 nodes (4 m spacing). The defined method (discard
  // where the interpolated hole flag is > 0) and the FC5 NaN clip position are compared.
  synthetic::Spec o = synthetic::analytic_surface();
  o.roots_x = o.roots_y = 1;
  o.relief_m = 100;
  o.detail = 0;
  o.cones = false;
  o.keep = [](const NodeKey& k) { return k.level >= 3; };
  o.hole_x_m = o.origin_x_m + 1000;
  o.hole_y_m = o.origin_y_m + 1000;
  o.hole_radius_m = 60;
  TV_ALL_RESIDENT(synthetic::make_world(o), 64, 256, 256);
  const Camera cam = camera_at(world.synthetic.world, 1000, 1000, 900, 0, -90);
  FrameSettings s = magenta_clear(0.01);  // all the way to level 3
  size_t magenta[3];
  for (int mode = 0; mode < 3; ++mode) {
    s.holes = mode != 0;
    s.hole_nan = mode == 2;
    ASSERT_TRUE(render_frame(*gpu, uploads, cam, s, false).ok());
    uploads.clear();
    std::vector<uint8_t> rgba;
    read_color(gpu->target, rgba);
    dump_ppm(*gpu, rgba, "holes_" + std::to_string(mode));
    magenta[mode] = count_color(rgba, 255, 0, 255);
  }
  EXPECT_EQ(magenta[0], 0u) << "holes off: the terrain covers the view";
  // The dropped area: the disc grown by up to one quad (every triangle touching a hole vertex).
  const double px_per_m = 256.0 / (2.0 * (900.0 - 300.0) * std::tan(M_PI / 6));  // approx, terrain ~300 m
  const double disc_px = M_PI * 60.0 * 60.0 * px_per_m * px_per_m;
  EXPECT_GT(double(magenta[1]), 0.8 * disc_px);
  EXPECT_LT(double(magenta[1]), 2.0 * disc_px);
  // The NaN clip position drops the same triangles (every triangle with a hole vertex), so it
  // leaves the same area open: within 5 % of the discard method (equal on lavapipe: 1996 px).
  EXPECT_GT(double(magenta[2]), 0.8 * disc_px);
  EXPECT_LT(double(magenta[2]), 2.0 * disc_px);
  EXPECT_NEAR(double(magenta[2]), double(magenta[1]), 0.05 * double(magenta[1]));
  std::printf("holes: discard method %zu px, NaN method %zu px (disc ~%.0f px)\n", magenta[1], magenta[2], disc_px);
}

// The vertex shader's stitching (viewer/shaders/stitch.glsl, the function terrain.vert calls) run
// as a compute shader on the device for every patch, decimation, mesh vertex and edge delta 0..7
// (at each corner every pair of its two edges' deltas), compared with terrain::stitched_vertex().
const uint32_t kStitchProbe[] =
#include "stitch_probe.comp.inc"
    ;

// Runs the probe over `queries` (uvec4: entry x, delta word, vertex index, 0) into `results` (uvec2).
Status run_stitch_probe(const Context& ctx, const std::vector<uint32_t>& queries, std::vector<uint32_t>& results) {
  const uint32_t count = uint32_t(queries.size() / 4);
  Buffer in, out;
  OneShot os;
  VkDescriptorSetLayout dsl = VK_NULL_HANDLE;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkShaderModule module = VK_NULL_HANDLE;
  VkPipeline pipeline = VK_NULL_HANDLE;
  VkDescriptorPool pool = VK_NULL_HANDLE;
  struct Cleanup {
    const Context& c;
    Buffer &a, &b;
    OneShot& o;
    VkDescriptorSetLayout& d;
    VkPipelineLayout& l;
    VkShaderModule& m;
    VkPipeline& p;
    VkDescriptorPool& q;
    ~Cleanup() {
      vkDeviceWaitIdle(c.device);
      vkDestroyDescriptorPool(c.device, q, nullptr);
      vkDestroyPipeline(c.device, p, nullptr);
      vkDestroyShaderModule(c.device, m, nullptr);
      vkDestroyPipelineLayout(c.device, l, nullptr);
      vkDestroyDescriptorSetLayout(c.device, d, nullptr);
      destroy_one_shot(c, o);
      destroy_buffer(c, a);
      destroy_buffer(c, b);
    }
  } cleanup{ctx, in, out, os, dsl, layout, module, pipeline, pool};
  TERRAIN_TRY(create_host_buffer(ctx, queries.size() * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, in));
  TERRAIN_TRY(create_host_buffer(ctx, VkDeviceSize(count) * 8, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, out));
  std::memcpy(in.mapped, queries.data(), queries.size() * 4);
  TERRAIN_TRY(create_one_shot(ctx, os));
  VkDescriptorSetLayoutBinding b[2] = {};
  for (uint32_t k = 0; k < 2; ++k) {
    b[k].binding = k;
    b[k].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    b[k].descriptorCount = 1;
    b[k].stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
  }
  VkDescriptorSetLayoutCreateInfo dci{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  dci.bindingCount = 2;
  dci.pBindings = b;
  VK_TRY(vkCreateDescriptorSetLayout(ctx.device, &dci, nullptr, &dsl));
  const VkPushConstantRange push{VK_SHADER_STAGE_COMPUTE_BIT, 0, 4};
  VkPipelineLayoutCreateInfo lci{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  lci.setLayoutCount = 1;
  lci.pSetLayouts = &dsl;
  lci.pushConstantRangeCount = 1;
  lci.pPushConstantRanges = &push;
  VK_TRY(vkCreatePipelineLayout(ctx.device, &lci, nullptr, &layout));
  VkShaderModuleCreateInfo mci{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  mci.codeSize = sizeof kStitchProbe;
  mci.pCode = kStitchProbe;
  VK_TRY(vkCreateShaderModule(ctx.device, &mci, nullptr, &module));
  VkComputePipelineCreateInfo pci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  pci.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  pci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  pci.stage.module = module;
  pci.stage.pName = "main";
  pci.layout = layout;
  VK_TRY(vkCreateComputePipelines(ctx.device, VK_NULL_HANDLE, 1, &pci, nullptr, &pipeline));
  const VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 2};
  VkDescriptorPoolCreateInfo pool_ci{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  pool_ci.maxSets = 1;
  pool_ci.poolSizeCount = 1;
  pool_ci.pPoolSizes = &size;
  VK_TRY(vkCreateDescriptorPool(ctx.device, &pool_ci, nullptr, &pool));
  VkDescriptorSetAllocateInfo ai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  ai.descriptorPool = pool;
  ai.descriptorSetCount = 1;
  ai.pSetLayouts = &dsl;
  VkDescriptorSet set;
  VK_TRY(vkAllocateDescriptorSets(ctx.device, &ai, &set));
  const VkDescriptorBufferInfo infos[2] = {{in.buffer, 0, VK_WHOLE_SIZE}, {out.buffer, 0, VK_WHOLE_SIZE}};
  VkWriteDescriptorSet w[2] = {};
  for (uint32_t k = 0; k < 2; ++k) {
    w[k] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w[k].dstSet = set;
    w[k].dstBinding = k;
    w[k].descriptorCount = 1;
    w[k].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    w[k].pBufferInfo = &infos[k];
  }
  vkUpdateDescriptorSets(ctx.device, 2, w, 0, nullptr);
  TERRAIN_TRY(submit_and_wait(ctx, os, [&](VkCommandBuffer cmd) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, layout, 0, 1, &set, 0, nullptr);
    vkCmdPushConstants(cmd, layout, VK_SHADER_STAGE_COMPUTE_BIT, 0, 4, &count);
    vkCmdDispatch(cmd, (count + 63) / 64, 1, 1);
    memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_2_HOST_BIT,
                   VK_ACCESS_2_HOST_READ_BIT);
  }));
  if (ctx.validation_errors > 0)
    return Status::failure(Error::internal, std::to_string(ctx.validation_errors) + " Vulkan validation errors");
  results.resize(size_t(count) * 2);
  std::memcpy(results.data(), out.mapped, results.size() * 4);
  return Status::success();
}

TEST(ViewerGpu, VertexShaderStitchingEqualsTheContract) {
  Context ctx;
  DeviceOptions o;
  o.quiet = true;
  o.validation = std::getenv("TERRAIN_VIEW_VALIDATION") != nullptr;
  const Status made = create_context(o, ctx);
  struct Guard {
    Context& c;
    ~Guard() { destroy_context(c); }
  } guard{ctx};
  if (!made.ok() && is_no_device(made)) GTEST_SKIP() << "no Vulkan device: " << made.message;
  ASSERT_TRUE(made.ok()) << made.to_string();
  // Every patch, decimation and mesh vertex, with deltas (south, west, north, east) =
  // (a, b, (a + 3) % 8, (b + 5) % 8) for all a, b in 0..7: every delta on every edge and every
  // pair of deltas at every corner. The NEAR bit rides along in half of them (the shader must
  // mask it off).
  std::vector<uint32_t> queries;
  std::vector<NodeVertex> want;
  for (uint32_t py = 0; py < 8; ++py)
    for (uint32_t px = 0; px < 8; ++px)
      for (int e = 0; e <= TV_MAX_DECIMATE; ++e)
        for (int a = 0; a < 8; ++a)
          for (int b = 0; b < 8; ++b) {
            const EdgeDeltas d{a, b, (a + 3) % 8, (b + 5) % 8};
            const PatchMesh mesh{int(px), int(py), e, d};
            const uint32_t entry_x = 37u | px << TV_PATCH_PX_SHIFT | py << TV_PATCH_PY_SHIFT |
                                     uint32_t(kRootLevel) << TV_PATCH_LEVEL_SHIFT | uint32_t(e) << TV_PATCH_DECIM_SHIFT;
            const uint32_t deltas = uint32_t(d.south) << TV_EDGE_S | uint32_t(d.west) << TV_EDGE_W |
                                    uint32_t(d.north) << TV_EDGE_N | uint32_t(d.east) << TV_EDGE_E |
                                    ((a + b) % 2 ? TV_PATCH_NEAR_BIT : 0u);
            const int n = patch_mesh_quads(e);
            for (int j = 0; j <= n; ++j)
              for (int i = 0; i <= n; ++i) {
                for (uint32_t v : {entry_x, deltas, uint32_t(j * (n + 1) + i), 0u}) queries.push_back(v);
                want.push_back(stitched_vertex(mesh, i, j));
              }
          }
  std::vector<uint32_t> got;
  const Status ran = run_stitch_probe(ctx, queries, got);
  ASSERT_TRUE(ran.ok()) << ran.to_string();
  ASSERT_EQ(got.size(), 2 * want.size());
  size_t differ = 0, moved = 0;
  for (size_t k = 0; k < want.size(); ++k) {
    const bool same = got[2 * k] == uint32_t(want[k].i) && got[2 * k + 1] == uint32_t(want[k].j);
    if (!same && differ++ < 5)
      ADD_FAILURE() << "query " << k << ": GLSL (" << got[2 * k] << ", " << got[2 * k + 1] << "), C++ (" << want[k].i
                    << ", " << want[k].j << ")";
    const uint32_t idx = queries[4 * k + 2], n = uint32_t(TV_QUADS_PER_PATCH) >> ((queries[4 * k] >> TV_PATCH_DECIM_SHIFT) & 7u);
    const uint32_t px = (queries[4 * k] >> TV_PATCH_PX_SHIFT) & 7u, py = (queries[4 * k] >> TV_PATCH_PY_SHIFT) & 7u;
    const uint32_t step = uint32_t(TV_QUADS_PER_PATCH) / n;
    moved += want[k].i != int(px * 16 + idx % (n + 1) * step) || want[k].j != int(py * 16 + idx / (n + 1) * step);
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_EQ(want.size(), size_t(64 * 64 * (289 + 81 + 25 + 9 + 4)));
  EXPECT_GT(moved, want.size() / 10) << "the queries must exercise the collapse";
}

// ---- Material transitions and the near/far switch (issue 18) ----

// A flat world (300 m) with a straight north-south boundary between sand (id 0, west) and grass
// (id 1, east) at local x = 1000.3 m, its albedo baked from the splat as the cook bakes it.
// Nodes of level `level` exist around (1000, 1000); the error floor makes views refine to them.
synthetic::World boundary_world(uint32_t level) {
  synthetic::Spec o = synthetic::analytic_surface();
  o.roots_x = o.roots_y = 1;
  o.relief_m = 0;
  o.detail = 0;
  o.cones = false;
  o.error_floor_m = 0.01;
  o.splat_boundary_x_m = 1000.3;
  o.keep = [level](const NodeKey& k) { return k.level >= level && (k.level >= 3 || box_distance(k, 1000, 1000) < 120.0); };
  return synthetic::make_world(o);
}

TEST(ViewerGpu, MaterialTransitionsDoNotFollowTheTexelGrid) {
  // Seen from straight above with 12 px per splat texel (2^L m at level L), 32 texels of the line in
  // view, at level 0 (1 m) and
  // level 2 (4 m). Per image row the boundary's position is the count of pixels on the sand side
  // of the 50 % line, measured on log(R / G): lighting and the per-material detail noise multiply
  // all channels alike, so the ratio tells the materials apart wherever the pixel is.
  // Bounds: the 50 % line moves by height_blend (0.6 here) * (hA - hB) texels (terrain.frag), so
  // along 32 texels it must spread over at least half a texel; a line on the texel grid would step
  // by a whole texel (12 px) from one row to the next, the noise line drifts by at most a few px.
  for (uint32_t level : {0u, 2u}) {
    SCOPED_TRACE("level " + std::to_string(level));
    constexpr uint32_t kSize = 384;
    constexpr double kPxPerTexel = 12;
    const double texel_m = double(1u << level);
    const double above = kSize / kPxPerTexel * texel_m / (2.0 * std::tan(M_PI / 6));  // 32 texels across
    TV_ALL_RESIDENT(boundary_world(level), 512, kSize, kSize);
    FrameSettings s;
    s.error_target_px = 0.01;
    ASSERT_TRUE(render_frame(*gpu, uploads, camera_at(world.synthetic.world, 1000.3, 1000, 300 + above, 0, -90), s, true).ok());
    uploads.clear();
    GpuLists lists;
    gpu->renderer.read_lists(lists.nodes, lists.lod, lists.patches);
    std::vector<uint8_t> rgba;
    read_color(gpu->target, rgba);
    dump_ppm(*gpu, rgba, "transition_level" + std::to_string(level));
    auto ratio = [&](uint32_t x, uint32_t y) {
      const uint8_t* p = &rgba[(size_t(y) * kSize + x) * 4];
      return std::log((p[0] + 0.5) / (p[1] + 0.5));
    };
    // The two materials' ratios: medians of the outer 32 columns (13 texels from the line).
    std::vector<double> left, right;
    for (uint32_t y = 0; y < kSize; ++y)
      for (uint32_t x = 0; x < 32; ++x) {
        left.push_back(ratio(x, y));
        right.push_back(ratio(kSize - 1 - x, y));
      }
    std::nth_element(left.begin(), left.begin() + left.size() / 2, left.end());
    std::nth_element(right.begin(), right.begin() + right.size() / 2, right.end());
    const double la = left[left.size() / 2], lb = right[right.size() / 2];
    ASSERT_GT(std::abs(lb - la), 0.05) << "the two materials must differ in hue";
    std::vector<double> pos(kSize);
    for (uint32_t y = 0; y < kSize; ++y) {
      int n = 0;
      for (uint32_t x = 0; x < kSize; ++x) n += (ratio(x, y) - la) / (lb - la) < 0.5;
      pos[y] = n;
    }
    const auto [lo, hi] = std::minmax_element(pos.begin(), pos.end());
    double max_jump = 0;
    for (uint32_t y = 1; y < kSize; ++y) max_jump = std::max(max_jump, std::abs(pos[y] - pos[y - 1]));
    const double spread_texels = (*hi - *lo) / kPxPerTexel;
    std::printf("transition level %u: 50%% line between columns %.0f and %.0f (spread %.2f texel), largest row-to-row step %.0f px (texel %.0f px)\n",
                level, *lo, *hi, spread_texels, max_jump, kPxPerTexel);
    EXPECT_GT(*lo, kSize / 4.0) << "the line stays near the middle of the view";
    EXPECT_LT(*hi, kSize * 3 / 4.0);
    EXPECT_GE(spread_texels, 0.5) << "the line does not wander off the texel grid";
    EXPECT_LE(max_jump, 4.0) << "a hard step along the line";
    // The view was drawn with nodes of the level under test.
    EXPECT_GT(lists.nodes.level_counts[level], 0u);
  }
}

// An oblique view (40 m above flat ground, 12 degrees down) over the baked boundary world whose
// rows run from ~60 m to the world's edge, across the near-shading distances (150 .. 400 m): the
// frame with splat shading against the same frame with the baked albedo alone, its far group lit
// per pixel or per texel (`prelit_far`, the default on CPU devices). Bound 3/255 per channel
// (issue 18): below what the eye sees as a switch.
void check_near_far_band(bool prelit_far) {
  RendererConfig config;
  config.prelit_far = prelit_far;
  TV_ALL_RESIDENT(boundary_world(2), 512, 320, 240, config);
  const Camera cam = camera_at(world.synthetic.world, 1000.3, 780, 300 + 40, 0, -12);
  FrameSettings s = magenta_clear(1.0);
  std::vector<uint8_t> image[2];
  for (int splat = 0; splat < 2; ++splat) {
    s.splat = splat == 1;
    ASSERT_TRUE(render_frame(*gpu, uploads, cam, s, false).ok());
    uploads.clear();
    read_color(gpu->target, image[splat]);
    dump_ppm(*gpu, image[splat], std::string(splat ? "near_far_splat" : "near_far_baked") + (prelit_far ? "_texel" : ""));
  }
  // The band: rows whose flat ground (40 m below the camera) lies 100 .. 450 m away (slant), 50 m
  // either side of the fade (150 .. 400 m), split at 275 m into a near and a far side, each cut in
  // strips 40 px wide: every such tile (~30 .. 80 m across: the cook's 48 m variation does not
  // average out in it) must agree, and the whole band too. Terrain pixels only (not the clear colour).
  const uint32_t w = gpu->target.width, h = gpu->target.height;
  const double px_per_tan = (h / 2.0) / std::tan(cam.fovy / 2);
  auto row_distance = [&](uint32_t y) {
    const double below = 12.0 * M_PI / 180 + std::atan((y + 0.5 - h / 2.0) / px_per_tan);
    return below > 0 ? 40.0 / std::sin(below) : 1e9;
  };
  double worst = 0, all_sum[3] = {}, all_n = 0;
  size_t changed = 0;
  for (int side = 0; side < 2; ++side)
    for (uint32_t tx = 0; tx < w; tx += 40) {
      double sum[3] = {}, n = 0;
      for (uint32_t y = 0; y < h; ++y) {
        const double d = row_distance(y);
        if (d < (side ? 275.0 : 100.0) || d >= (side ? 450.0 : 275.0)) continue;
        for (uint32_t x = tx; x < tx + 40; ++x) {
          const uint8_t* a = &image[0][(size_t(y) * w + x) * 4];
          const uint8_t* b = &image[1][(size_t(y) * w + x) * 4];
          if (a[0] == 255 && a[1] == 0 && a[2] == 255) continue;  // clear colour
          changed += a[0] != b[0] || a[1] != b[1] || a[2] != b[2];
          for (int c = 0; c < 3; ++c) sum[c] += double(b[c]) - double(a[c]);
          n += 1;
        }
      }
      ASSERT_GT(n, 200.0);
      for (int c = 0; c < 3; ++c) {
        all_sum[c] += sum[c];
        worst = std::max(worst, std::abs(sum[c] / n));
      }
      all_n += n;
      std::printf("near/far %s side, columns %u..%u: mean splat - baked %+.2f %+.2f %+.2f (/255) over %.0f px\n",
                  side ? "far" : "near", tx, tx + 39, sum[0] / n, sum[1] / n, sum[2] / n, n);
    }
  std::printf("near/far band: %+.2f %+.2f %+.2f (/255); worst tile %.2f; %zu px changed by splat shading\n",
              all_sum[0] / all_n, all_sum[1] / all_n, all_sum[2] / all_n, worst, changed);
  EXPECT_GT(changed, size_t(all_n / 2)) << "splat shading must cover the band";
  for (int c = 0; c < 3; ++c) EXPECT_LE(std::abs(all_sum[c] / all_n), 3.0);
  EXPECT_LE(worst, 3.0) << "every tile, near and far of the switch, agrees";
}

TEST(ViewerGpu, NearShadingMatchesTheBakedAlbedoInMeanColour) { check_near_far_band(false); }
TEST(ViewerGpu, NearShadingMatchesTheFarColourLitPerTexel) { check_near_far_band(true); }

// The index is the streamer's sparse residency index: the tree buffer below the roots and a texel per root. A
// world wider than the device's largest 2D image in roots is refused by init with the numbers (no
// vkCreateImage beyond the limits), and a world exactly that wide opens.
TEST(ViewerGpu, AWorldWiderThanTheRootImageIsRefusedWithItsNumbers) {
  World world;
  world.synthetic = deep_world().synthetic;
  TV_REQUIRE_GPU(gpu, world.synthetic.world, 64, 32, 32);
  const uint32_t max_side = gpu->ctx.properties.limits.maxImageDimension2D;
  WorldInfo wide = world.synthetic.world;
  wide.roots_x = max_side + 1;
  wide.roots_y = 4;
  RendererConfig rc;
  rc.slot_count = 64;
  TerrainRenderer refused;
  const Status st = refused.init(gpu->ctx, wide, rc);
  refused.destroy();
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.code, Error::unsupported_input);
  EXPECT_NE(st.message.find("at most " + std::to_string(max_side) + " roots per side"), std::string::npos)
      << st.message;
  wide.roots_x = max_side;
  TerrainRenderer widest;
  const Status ok = widest.init(gpu->ctx, wide, rc);
  widest.destroy();
  EXPECT_TRUE(ok.ok()) << ok.message;
}

// The dense index of before (a texel per 64 m sector at level 0) could not hold a world wider
// than maxImageDimension2D / 32 roots (512 on lavapipe). A world 8 roots wider, with overview
// levels, refined to level 0 in its last root only: the GPU lists, LOD map and patches equal the
// CPU reference there, level-0 nodes beyond sector 16 384 included.
TEST(ViewerGpu, AWorldWiderThanTheDenseIndexDrawsItsFarEastEndToLevelZero) {
  World world;
  uint32_t old_limit = 0;
  {
    TV_REQUIRE_GPU(probe, deep_world().synthetic.world, 64, 32, 32);
    old_limit = probe->ctx.properties.limits.maxImageDimension2D >> kRootLevel;
  }
  synthetic::Spec o = synthetic::analytic_surface();
  o.roots_x = old_limit + 8;
  o.roots_y = 1;
  o.overview_levels = -1;
  o.cones = false;
  const double focus_x = (double(o.roots_x) - 0.5) * node_size_m(kRootLevel), focus_y = 1000;
  o.keep = [focus_x, focus_y](const NodeKey& k) {
    if (k.level >= uint32_t(kRootLevel)) return true;
    return box_distance(k, focus_x, focus_y) < 200.0 * double(1u << k.level);
  };
  world.synthetic = synthetic::make_world(o);
  TV_REQUIRE_GPU(gpu, world.synthetic.world, 2048, 320, 180);
  std::vector<NodeUpload> uploads;
  ASSERT_TRUE(make_all_resident(world, *gpu, 2048, uploads).ok());
  FrameSettings s;
  s.error_target_px = 0.01;
  const Camera cam = camera_at(world.synthetic.world, focus_x - 150, focus_y, 300, 90, -35);
  ASSERT_TRUE(render_frame(*gpu, uploads, cam, s, true).ok());
  const ReferenceLists ref = expect_lists_equal_reference(*gpu);  // the GPU's lists equal these
  const NodeList& nodes = ref.nodes;
  EXPECT_GT(nodes.level_counts[0], 0u) << "the view must reach level 0 in the far east root";
  uint32_t east_level0 = 0;
  for (uint32_t e : nodes.entries) {
    const SlotDescriptor& d = gpu->state.descriptor(e & TV_ENTRY_SLOT_MASK);
    if (d.level == 0 && d.x >= (old_limit << kRootLevel)) ++east_level0;
  }
  EXPECT_EQ(east_level0, nodes.level_counts[0]) << "every level-0 node lies beyond the old index texture";
  std::printf("%u x %u roots: %zu nodes listed (levels 0..5: %u %u %u %u %u %u), %zu patches\n", o.roots_x, o.roots_y,
              nodes.entries.size(), nodes.level_counts[0], nodes.level_counts[1], nodes.level_counts[2],
              nodes.level_counts[3], nodes.level_counts[4], nodes.level_counts[5], ref.patches.patches.size());
}

}  // namespace
}  // namespace terrain::view::test

