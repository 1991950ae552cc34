// The viewer on real archives cooked from ../shared/data (fixture viewer_archives), streamed by the
// streamer: zero magenta pixels (cracks) from views where terrain fills the screen, including the
// first frames after a jump (the streaming frontier), GPU lists equal to the CPU reference (with
// the cooker's real patch cones), and sane screenshots.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>

#include "reference.h"
#include "session.h"
#include "test_data.h"

namespace terrain::view {
namespace {

std::filesystem::path archive_dir() { return test::test_archives_dir(); }  // fixture cook_test_archives

std::filesystem::path archive(const std::string& name) { return archive_dir() / (name + ".terrain"); }

#define REQUIRE_ARCHIVE(path) \
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "archive not found: " << (path) << " (fixture cook_test_archives)"

// A quiet headless 320x180 view of the archive at `path`.
ViewerOptions headless_options(const std::filesystem::path& path) {
  ViewerOptions o;
  o.archive = path.string();
  o.headless = true;
  o.width = 320;
  o.height = 180;
  o.quiet = true;
  return o;
}

ViewerOptions crack_options(const std::filesystem::path& path) {
  ViewerOptions o = headless_options(path);
  o.settings.clear[0] = 1;
  o.settings.clear[1] = 0;
  o.settings.clear[2] = 1;
  o.settings.holes = false;  // cooked holes (nodata) are not cracks; HoleVerticesDropTheirTriangles covers them
  o.settings.error_target_px = 1.0;
  o.max_deliveries = 3;  // a few nodes per frame: many frames at the streaming frontier
  return o;
}

std::unique_ptr<Session> open_or_skip(const ViewerOptions& o, bool& skip) {
  std::unique_ptr<Session> s;
  Status st = open_session(o, {}, false, s);
  skip = is_no_device(st);
  if (!st.ok() && !skip) ADD_FAILURE() << st.message;
  return st.ok() ? std::move(s) : nullptr;
}

size_t magenta(const std::vector<uint8_t>& rgba) {
  size_t n = 0;
  for (size_t i = 0; i < rgba.size(); i += 4) n += rgba[i] == 255 && rgba[i + 1] == 0 && rgba[i + 2] == 255;
  return n;
}

void dump_ppm(const RenderTarget& t, const std::vector<uint8_t>& rgba, const std::string& name) {
  std::ofstream f(test::build_dir() / "viewer-test-images" / (name + ".ppm"), std::ios::binary);  // tests/viewer/CMakeLists.txt
  f << "P6\n" << t.width << " " << t.height << "\n255\n";
  for (size_t i = 0; i < rgba.size(); i += 4) f.write(reinterpret_cast<const char*>(&rgba[i]), 3);
}

std::vector<GpuPatch> sorted(std::vector<GpuPatch> v) {
  std::sort(v.begin(), v.end(), [](const GpuPatch& a, const GpuPatch& b) {
    return std::tie(a.slot_patch_level, a.edge_deltas) < std::tie(b.slot_patch_level, b.edge_deltas);
  });
  return v;
}

// Looks down over the data footprint from above its highest root, so terrain fills the view.
std::vector<Camera> views_over_data(const Session& s) {
  const WorldInfo& w = s.source->world();
  int32_t lo = 0, hi = 0;
  s.source->height_range(lo, hi);
  const double cx = 0.5 * (w.extent_min_x_m + w.extent_max_x_m), cy = 0.5 * (w.extent_min_y_m + w.extent_max_y_m);
  const double r = 0.5 * std::min(w.extent_max_x_m - w.extent_min_x_m, w.extent_max_y_m - w.extent_min_y_m);
  std::vector<Camera> out;
  const double yaw[] = {0, 90, 200, 315};
  const double pitch[] = {-62, -70, -80, -89};
  const double above[] = {0.28, 0.2, 0.35, 0.45};
  for (int k = 0; k < 4; ++k) {
    Camera c;
    c.position[0] = cx + (k == 1 ? -0.1 * r : 0.05 * r);
    c.position[1] = cy + (k == 2 ? 0.1 * r : -0.05 * r);
    c.position[2] = hi / 1024.0 + above[k] * r;
    c.yaw = yaw[k] * M_PI / 180;
    c.pitch = pitch[k] * M_PI / 180;
    c.near_m = 0.5;
    out.push_back(c);
  }
  return out;
}

// `streams`: the archive has levels below the roots, so some frames render before nodes arrive.
// `decimates`: the views draw decimated root patches (config.h "Patch decimation").
// `control`: each settled view drawn again without stitching must show cracks somewhere (a crack
// test whose control never cracks could not fail).
// `make_views`: the views (default: down over the data's footprint).
void check_archive_without_cracks(const std::string& name, size_t min_levels, bool streams, bool decimates = false,
                                  bool control = false,
                                  std::vector<Camera> (*make_views)(const Session&) = views_over_data) {
  const auto path = archive(name);
  REQUIRE_ARCHIVE(path);
  bool skip = false;
  auto s = open_or_skip(crack_options(path), skip);
  if (skip) GTEST_SKIP() << "no Vulkan device";
  ASSERT_TRUE(s);
  s->capture_lists = true;
  std::set<uint32_t> levels;
  size_t decimated = 0;
  size_t frames = 0, compared = 0, frontier = 0, cone_culled = 0, unstitched_cracks = 0;
  const auto views = make_views(*s);
  for (size_t v = 0; v < views.size(); ++v) {
    // Every frame after the jump, from the first (coarse nodes only, the streaming frontier) until
    // the streamer settles.
    for (int f = 0; f < 60; ++f) {
      FrameRecord rec;
      ASSERT_TRUE(render_frame(*s, views[v], true, rec).ok());
      std::vector<uint8_t> rgba;
      read_color(s->target, rgba);
      ++frames;
      frontier += rec.source.required_missing > 0;
      const size_t bad = magenta(rgba);
      EXPECT_EQ(bad, 0u) << name << " view " << v << " frame " << f << ": magenta through a crack";
      if (bad) dump_ppm(s->target, rgba, "crack_" + name + "_" + std::to_string(v) + "_" + std::to_string(f));
      NodeList nodes;
      std::vector<uint32_t> lod;
      std::vector<GpuPatch> patches;
      s->renderer.read_lists(nodes, lod, patches);
      for (const auto& p : patches) {
        levels.insert(patch_level(p));
        decimated += patch_decimation(p) > 0;
      }
      if (f % 5 == 0) {  // the CPU reference on the same state (real patch cones)
        const FrameUniforms& u = s->renderer.uniforms();
        const NodeList ref = reference_traverse(s->state, u, s->renderer.slot_cpu());
        std::vector<uint32_t> a = nodes.entries, b = ref.entries;
        std::sort(a.begin(), a.end());
        std::sort(b.begin(), b.end());
        EXPECT_EQ(a, b) << name << " view " << v << " frame " << f;
        const auto ref_lod = reference_lod_map(s->state, s->renderer.uniforms(), ref);
        EXPECT_EQ(lod, ref_lod);
        const PatchList ref_patches =
            reference_patches(s->state, u, ref, ref_lod, s->renderer.slot_cpu(), s->renderer.cone_sin2_table());
        EXPECT_EQ(sorted(patches), sorted(ref_patches.patches)) << name << " view " << v << " frame " << f;
        ++compared;
      }
      if (s->source->settled() && f >= 2) break;
    }
    std::vector<uint8_t> rgba;
    read_color(s->target, rgba);
    dump_ppm(s->target, rgba, "view_" + name + "_" + std::to_string(v));
    // The cooker's patch cones are conservative: culling by them changes no pixel.
    cone_culled += s->records.back().gpu.culled_cone;
    s->options.settings.cone_cull = false;
    FrameRecord rec;
    ASSERT_TRUE(render_frame(*s, views[v], true, rec).ok());
    std::vector<uint8_t> unculled;
    read_color(s->target, unculled);
    EXPECT_EQ(rgba, unculled) << name << " view " << v << ": cone culling changed the image";
    s->options.settings.cone_cull = true;
    if (control) {
      s->options.settings.stitch = false;
      ASSERT_TRUE(render_frame(*s, views[v], true, rec).ok());
      std::vector<uint8_t> unstitched;
      read_color(s->target, unstitched);
      unstitched_cracks += magenta(unstitched);
      dump_ppm(s->target, unstitched, "view_" + name + "_" + std::to_string(v) + "_unstitched");
      s->options.settings.stitch = true;
    }
  }
  if (control) {
    EXPECT_GT(unstitched_cracks, 0u) << name << ": the unstitched control shows no crack: the views test nothing";
  }
  EXPECT_GE(levels.size(), min_levels) << name << ": the views should cross LOD boundaries";
  if (decimates) {
    EXPECT_GT(decimated, 0u) << name << ": the views should draw decimated root patches";
  }
  if (streams) {
    EXPECT_GT(frontier, 0u) << name << ": some frames should render while required nodes are still loading";
  }
  std::printf("%s: %zu frames without cracks (%zu at the streaming frontier), %zu compared with the CPU reference, "
              "%zu geometric levels drawn, %zu patches cone-culled without changing a pixel, %zu decimated patches drawn, "
              "%zu magenta pixels unstitched\n",
              name.c_str(), frames, frontier, compared, levels.size(), cone_culled, decimated, unstitched_cracks);
}

// Kilauea (30 m data) is mostly roots: its LOD boundaries are root coarsenings and decimated root patches.
TEST(ViewerArchives, KilaueaHasNoCracks) { check_archive_without_cracks("kilauea", 2, false, true); }
TEST(ViewerArchives, SloveniaHasNoCracks) { check_archive_without_cracks("slovenia", 4, true); }
TEST(ViewerArchives, TahoeHasNoCracks) { check_archive_without_cracks("tahoe", 4, true); }
// Issue 51: the 1 m lidar tile inside a 30 m DEM, cooked as one world (two grid families, the seam
// blended over 60 m, each family refined by its own rules): no crack anywhere, across the seam
// either, from the first frame after each jump; without stitching the same views crack.
// From 150 m inside each edge of the lidar tile (1 km square at the middle of the 4.95 km world),
// 100 m above the highest ground, looking out across the seam and its 60 m blend band.
std::vector<Camera> views_across_the_lidar_edges(const Session& s) {
  const WorldInfo& w = s.source->world();
  int32_t lo = 0, hi = 0;
  s.source->height_range(lo, hi);
  const double cx = 0.5 * (w.extent_min_x_m + w.extent_max_x_m), cy = 0.5 * (w.extent_min_y_m + w.extent_max_y_m);
  std::vector<Camera> out;
  for (int k = 0; k < 4; ++k) {
    const double yaw = k * M_PI / 2;  // north, east, south, west
    Camera c;
    c.position[0] = cx + 350 * std::sin(yaw);
    c.position[1] = cy + 350 * std::cos(yaw);
    c.position[2] = hi / 1024.0 + 100;
    c.yaw = yaw;
    c.pitch = -(55 + 4 * k) * M_PI / 180;  // the top edge 25-37 degrees down: ground, no sky
    c.near_m = 0.5;
    out.push_back(c);
  }
  return out;
}

TEST(ViewerArchives, LidarInsideA30mDemHasNoCracksAcrossTheSeam) {
  check_archive_without_cracks("lidar_world", 4, true, false, true, views_across_the_lidar_edges);
}

// Low, level views over real relief: the cooker's patch cones cull back-facing patches, and the
// image is byte for byte the one drawn without cone culling.
TEST(ViewerArchives, RealPatchConesCullWithoutChangingTheImage) {
  size_t culled = 0, views = 0;
  for (const char* name : {"kilauea", "slovenia", "tahoe"}) {
    const auto path = archive(name);
    if (!std::filesystem::exists(path)) continue;
    ViewerOptions o = crack_options(path);
    o.max_deliveries = 128;
    o.settings.holes = true;  // cones leave out hole triangles, so they must not be drawn
    bool skip = false;
    auto s = open_or_skip(o, skip);
    if (skip) GTEST_SKIP() << "no Vulkan device";
    ASSERT_TRUE(s);
    const WorldInfo& w = s->source->world();
    int32_t lo = 0, hi = 0;
    s->source->height_range(lo, hi);
    const double cx = 0.5 * (w.extent_min_x_m + w.extent_max_x_m), cy = 0.5 * (w.extent_min_y_m + w.extent_max_y_m);
    const double r = 0.5 * std::min(w.extent_max_x_m - w.extent_min_x_m, w.extent_max_y_m - w.extent_min_y_m);
    for (int k = 0; k < 4; ++k) {
      Camera c;
      const double a = k * M_PI / 2;
      c.position[0] = cx - 0.8 * r * std::sin(a);
      c.position[1] = cy - 0.8 * r * std::cos(a);
      c.position[2] = hi / 1024.0 + 0.02 * r;  // just above the highest ground, looking level
      c.yaw = a;
      c.pitch = -0.08;
      FrameRecord rec;
      // Until nothing more arrives, so both renders see the same resident set.
      int quiet = 0;
      for (int f = 0; f < 60 && quiet < 2; ++f) {
        ASSERT_TRUE(render_frame(*s, c, true, rec).ok());
        quiet = rec.source.delivered == 0 && rec.source.evicted == 0 ? quiet + 1 : 0;
      }
      std::vector<uint8_t> culled_image, full_image;
      read_color(s->target, culled_image);
      culled += rec.gpu.culled_cone;
      s->options.settings.cone_cull = false;
      ASSERT_TRUE(render_frame(*s, c, true, rec).ok());
      read_color(s->target, full_image);
      s->options.settings.cone_cull = true;
      size_t differ = 0;
      for (size_t i = 0; i < culled_image.size(); i += 4)
        differ += std::memcmp(&culled_image[i], &full_image[i], 3) != 0;
      EXPECT_EQ(differ, 0u) << name << " view " << k << " (" << rec.source.delivered << " nodes delivered meanwhile)";
      if (differ) {
        dump_ppm(s->target, culled_image, std::string("cone_on_") + name + std::to_string(k));
        dump_ppm(s->target, full_image, std::string("cone_off_") + name + std::to_string(k));
      }
      ++views;
    }
  }
  if (views == 0) GTEST_SKIP() << "no archives in " << archive_dir();
  std::printf("%zu views, %zu patches culled by their cones\n", views, culled);
  EXPECT_GT(culled, 0u) << "low views over real relief should see back-facing patches";
}

TEST(ViewerArchives, KilaueaScreenshotLooksLikeTerrain) {
  const auto path = archive("kilauea");
  REQUIRE_ARCHIVE(path);
  const ViewerOptions o = headless_options(path);
  bool skip = false;
  auto s = open_or_skip(o, skip);
  if (skip) GTEST_SKIP() << "no Vulkan device";
  ASSERT_TRUE(s);
  const Camera cam = initial_camera(*s);
  FrameRecord rec;
  for (int f = 0; f < 30 && !(f > 1 && s->source->settled()); ++f) ASSERT_TRUE(render_frame(*s, cam, true, rec).ok());
  std::vector<uint8_t> rgba;
  read_color(s->target, rgba);
  dump_ppm(s->target, rgba, "kilauea_default");
  // Terrain = pixels that are not the clear (sky) colour.
  const uint8_t sky[3] = {uint8_t(std::lround(o.settings.clear[0] * 255)), uint8_t(std::lround(o.settings.clear[1] * 255)),
                          uint8_t(std::lround(o.settings.clear[2] * 255))};
  size_t terrain = 0;
  double sum[3] = {0, 0, 0}, sum2 = 0;
  for (size_t i = 0; i < rgba.size(); i += 4) {
    if (rgba[i] == sky[0] && rgba[i + 1] == sky[1] && rgba[i + 2] == sky[2]) continue;
    ++terrain;
    for (int k = 0; k < 3; ++k) sum[k] += rgba[i + size_t(k)];
    const double l = 0.3 * rgba[i] + 0.59 * rgba[i + 1] + 0.11 * rgba[i + 2];
    sum2 += l * l;
  }
  const double n = double(std::max<size_t>(terrain, 1));
  const double mean[3] = {sum[0] / n, sum[1] / n, sum[2] / n};
  const double luma = 0.3 * mean[0] + 0.59 * mean[1] + 0.11 * mean[2];
  const double sd = std::sqrt(std::max(sum2 / n - luma * luma, 0.0));
  std::printf("kilauea: terrain %.0f%% of the image, mean rgb %.0f %.0f %.0f, luminance sd %.1f\n",
              100.0 * double(terrain) / double(rgba.size() / 4), mean[0], mean[1], mean[2], sd);
  EXPECT_GT(double(terrain), 0.25 * double(rgba.size() / 4)) << "terrain should fill a good part of the default view";
  EXPECT_GT(luma, 40.0) << "too dark";
  EXPECT_LT(luma, 220.0) << "washed out";
  EXPECT_GT(sd, 4.0) << "no shading variation";
  EXPECT_GT(mean[1], mean[2]) << "vegetation and lava, not water or sky: green above blue on average";
  EXPECT_GT(rec.gpu.patches_drawn, 0u);
  EXPECT_EQ(rec.gpu.traversal_overflow, 0u);
}

TEST(ViewerArchives, EveryDebugViewDrawsItsOwnPicture) {
  const auto path = archive("slovenia");
  REQUIRE_ARCHIVE(path);
  ViewerOptions o = crack_options(path);
  o.max_deliveries = 128;
  o.settings.holes = true;
  bool skip = false;
  auto s = open_or_skip(o, skip);
  if (skip) GTEST_SKIP() << "no Vulkan device";
  ASSERT_TRUE(s);
  const Camera cam = views_over_data(*s)[0];
  FrameRecord rec;
  for (int f = 0; f < 30 && !(f > 1 && s->source->settled()); ++f) ASSERT_TRUE(render_frame(*s, cam, true, rec).ok());
  std::vector<std::vector<uint8_t>> pictures;
  const char* names[] = {"none", "lod", "nodes", "patches", "cones", "holes", "normals", "splat", "wire"};
  for (int view = TV_DEBUG_NONE; view <= TV_DEBUG_WIRE; ++view) {
    s->options.settings.debug = view;
    ASSERT_TRUE(render_frame(*s, cam, true, rec).ok());
    std::vector<uint8_t> rgba;
    read_color(s->target, rgba);
    dump_ppm(s->target, rgba, std::string("debug_") + names[view]);
    EXPECT_LT(magenta(rgba), rgba.size() / 4 / 2) << names[view] << ": mostly empty";
    for (size_t k = 0; k < pictures.size(); ++k) EXPECT_NE(rgba, pictures[k]) << names[view] << " looks like " << names[k];
    pictures.push_back(std::move(rgba));
  }
}


// Far lighting per texel (src/far_light.h, auto on CPU devices) against per pixel, on real archives
// (Jacksboro's DEM ships with Debian, so this runs without ../shared) from three cameras: the
// default overview, one from above, one level just over the ground. Splat shading is off, so every
// patch is in the far group; the same patches are drawn and only the far colour's path differs.
// Bounds, per channel over terrain pixels: mean |difference| <= 1/255, mean signed difference
// within +-0.25/255 (no shift in colour), 99th percentile <= 4/255. The lit colour is stored in 8
// bits at a quarter of its range, sRGB-coded (half a code there is about one code of output), and
// filtering lit texels instead of lighting filtered ones differs where neighbours differ in both
// light and albedo. A frame with another sun than the baked one lights per pixel: bit-identical.
TEST(ViewerArchives, FarLightPerTexelMatchesPerPixel) {
  size_t views = 0;
  for (const char* name : {"kilauea", "slovenia", "tahoe", "jacksboro"}) {
    const auto path = archive(name);
    if (!std::filesystem::exists(path)) continue;
    std::unique_ptr<Session> s[2];
    for (int texel = 0; texel < 2; ++texel) {
      ViewerOptions o = headless_options(path);
      o.width = 640;
      o.height = 360;
      o.max_deliveries = 4096;
      o.load_all = true;
      o.far_light = texel ? "texel" : "pixel";
      o.settings.splat = false;
      bool skip = false;
      s[texel] = open_or_skip(o, skip);
      if (skip) GTEST_SKIP() << "no Vulkan device";
      ASSERT_TRUE(s[texel]);
    }
    std::vector<Camera> cams = {initial_camera(*s[0]), views_over_data(*s[0])[0]};
    {
      Camera c = views_over_data(*s[0])[0];
      int32_t lo = 0, hi = 0;
      s[0]->source->height_range(lo, hi);
      c.position[2] = hi / 1024.0 + 50;
      c.pitch = -0.1;
      cams.push_back(c);
    }
    for (size_t v = 0; v < cams.size(); ++v) {
      std::vector<uint8_t> image[2];
      uint32_t far_patches = 0;
      for (int texel = 0; texel < 2; ++texel) {
        FrameRecord rec;
        for (int f = 0; f < 3; ++f) ASSERT_TRUE(render_frame(*s[texel], cams[v], true, rec).ok());
        read_color(s[texel]->target, image[texel]);
        far_patches = rec.gpu.patches_drawn - rec.gpu.patches_near;
      }
      // Another sun: the per-texel session must light per pixel, exactly as the other.
      for (int texel = 0; texel < 2; ++texel) s[texel]->options.settings.sun_azimuth_deg += 90;
      std::vector<uint8_t> other_sun[2];
      for (int texel = 0; texel < 2; ++texel) {
        FrameRecord rec;
        ASSERT_TRUE(render_frame(*s[texel], cams[v], true, rec).ok());
        read_color(s[texel]->target, other_sun[texel]);
        s[texel]->options.settings.sun_azimuth_deg -= 90;
      }
      EXPECT_EQ(other_sun[0], other_sun[1]) << name << " view " << v << ": a frame with another sun lights per pixel";
      std::vector<int> diffs;
      double sum = 0, signed_sum = 0;
      const auto& clear = s[0]->options.settings.clear;
      const uint8_t sky[3] = {uint8_t(std::lround(clear[0] * 255)), uint8_t(std::lround(clear[1] * 255)),
                              uint8_t(std::lround(clear[2] * 255))};
      for (size_t i = 0; i < image[0].size(); i += 4) {
        if (std::memcmp(&image[0][i], sky, 3) == 0 && std::memcmp(&image[1][i], sky, 3) == 0) continue;
        for (size_t c = 0; c < 3; ++c) {
          const int d = int(image[1][i + c]) - int(image[0][i + c]);
          diffs.push_back(std::abs(d));
          sum += diffs.back();
          signed_sum += d;
        }
      }
      ASSERT_GT(diffs.size(), image[0].size() / 8) << name << " view " << v << ": terrain should fill a sixth of the view";
      std::sort(diffs.begin(), diffs.end());
      const double mean = sum / double(diffs.size()), bias = signed_sum / double(diffs.size());
      const int p99 = diffs[diffs.size() * 99 / 100], max = diffs.back();
      std::printf("%s view %zu (%u far patches): per texel - per pixel: mean %+.3f, |mean| %.3f, p99 %d, max %d (/255) "
                  "over %zu channels\n", name, v, far_patches, bias, mean, p99, max, diffs.size());
      EXPECT_LE(mean, 1.0) << name << " view " << v;
      EXPECT_LE(std::abs(bias), 0.25) << name << " view " << v;
      EXPECT_LE(p99, 4) << name << " view " << v;
      EXPECT_GT(max, 0) << name << " view " << v << ": the per-texel path was not drawn";
      if (mean > 1.0 || p99 > 4) {
        dump_ppm(s[0]->target, image[0], std::string("far_pixel_") + name + std::to_string(v));
        dump_ppm(s[1]->target, image[1], std::string("far_texel_") + name + std::to_string(v));
      }
      ++views;
    }
  }
  if (views == 0) GTEST_SKIP() << "no archives in " << archive_dir();
}

}  // namespace
}  // namespace terrain::view
