// terrain-view on archives with overview levels (format/SPEC.md section 19), written by the
// synthetic generator: many roots, the streamer's default budget, default viewer settings. From
// low and from 50 km up: no magenta pixel (cracks over the transition from overview levels to
// roots, coarsened roots and decimated root patches), terrain on screen, overview levels drawn,
// GPU lists equal to the CPU reference, no traversal overflow and no clamped stitch; without
// stitching the same views crack (the control).
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <set>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include "reference.h"
#include "session.h"
#include "synthetic_archive.h"

namespace terrain::view {
namespace {

// side x side roots, every root present, no nodes below the roots: the sparse tree's levels below
// the roots use finer steps than the roots and are not crack-free by construction (the analytic
// worlds of gpu_tests.cpp and the cooked archives cover those levels). The roots' heights are
// the fractal surface (realistic_payload), so a T-junction shows.
synthetic::Spec big_world(uint32_t side) {
  synthetic::Spec s;
  s.roots_x = s.roots_y = side;
  s.root_fill = 1.0;
  s.min_level = uint32_t(kRootLevel);
  s.realistic_payload = true;
  s.overview_levels = -1;
  s.seed = 21;
  return s;
}

std::string archive_for(uint32_t side) {
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("terrain_view_overview_" + std::to_string(side) + ".terrain");
  // Cached between runs; rewritten when this test binary (and so the generator) is newer. The
  // tests of this file run side by side under ctest -j: the first writes, the others wait for it
  // on a lock instead of writing the same 180 MB again.
  const int lock = ::open((path.string() + ".lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lock >= 0) ::flock(lock, LOCK_EX);
  std::error_code ec;
  const auto exe_time = std::filesystem::last_write_time("/proc/self/exe", ec);
  if (!std::filesystem::exists(path) || ec || std::filesystem::last_write_time(path) < exe_time) {
    const auto t0 = std::chrono::steady_clock::now();
    synthetic::Summary sum;
    // The writer stages under a name with this host and pid and renames it into place when done
    // (output_paths.h), so ctest -j running both tests of this file never meet on a shared name.
    const Status st = synthetic::write_archive(path.string(), big_world(side), &sum);
    EXPECT_TRUE(st.ok()) << st.to_string();
    std::printf("wrote %s: %llu nodes, %llu roots in %.1f s\n", path.c_str(), (unsigned long long)sum.nodes,
                (unsigned long long)sum.roots,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  if (lock >= 0) ::close(lock);  // releases the lock
  return path.string();
}

size_t magenta(const std::vector<uint8_t>& rgba) {
  size_t n = 0;
  for (size_t i = 0; i < rgba.size(); i += 4) n += rgba[i] == 255 && rgba[i + 1] == 0 && rgba[i + 2] == 255;
  return n;
}

struct View {
  const char* name;
  double fx, fy, above_m, yaw_deg, pitch_deg;  // position as a fraction of the world, height above the surface
};

constexpr uint32_t kSide = 64;  // 4096 roots (131 km): the 50 km view (+-51 km across) stays inside

class ViewerOverview : public ::testing::Test {
 protected:
  void run(bool stitch, size_t& cracked_pixels, std::set<uint32_t>& levels, size_t& frames);
};

void ViewerOverview::run(bool stitch, size_t& cracked_pixels, std::set<uint32_t>& levels, size_t& frames) {
  const std::string path = archive_for(kSide);
  ViewerOptions o;
  o.archive = path;
  o.headless = true;
  o.width = 320;
  o.height = 180;
  o.quiet = true;
  o.settings.clear[0] = 1;
  o.settings.clear[1] = 0;
  o.settings.clear[2] = 1;
  o.settings.stitch = stitch;
  // The synthetic payloads' patch cones are random bytes, not conservative cones: no cone culling.
  o.settings.cone_cull = false;
  std::unique_ptr<Session> s;
  const Status st = open_session(o, {}, false, s);
  if (is_no_device(st)) GTEST_SKIP() << "no Vulkan device";
  ASSERT_TRUE(st.ok()) << st.to_string();
  s->capture_lists = true;
  const WorldInfo& w = s->source->world();
  ASSERT_GT(top_level(w), kRootLevel);
  const synthetic::Spec spec = big_world(kSide);
  const View views[] = {{"low", 0.5, 0.45, 3000, 30, -40}, {"low_south", 0.3, 0.2, 800, 10, -42},
                        {"high_50km", 0.5, 0.5, 50000, 0, -89.9}};
  for (const View& v : views) {
    Camera c;
    c.position[0] = w.origin_x_m + v.fx * kSide * node_size_m(kRootLevel);
    c.position[1] = w.origin_y_m + v.fy * kSide * node_size_m(kRootLevel);
    c.position[2] = synthetic::surface_height_m(spec, c.position[0], c.position[1]) + v.above_m;
    c.yaw = v.yaw_deg * M_PI / 180;
    c.pitch = v.pitch_deg * M_PI / 180;
    for (int f = 0; f < 200; ++f) {
      FrameRecord rec;
      ASSERT_TRUE(render_frame(*s, c, true, rec).ok());
      ++frames;
      EXPECT_EQ(rec.gpu.traversal_overflow, 0u);
      EXPECT_EQ(rec.gpu.stitch_clamped, 0u) << v.name;
      std::vector<uint8_t> rgba;
      read_color(s->target, rgba);
      const size_t bad = magenta(rgba);
      cracked_pixels += bad;
      if (stitch) {
        EXPECT_EQ(bad, 0u) << v.name << " frame " << f << ": magenta through a crack";
      }
      NodeList nodes;
      std::vector<uint32_t> lod;
      std::vector<GpuPatch> patches;
      s->renderer.read_lists(nodes, lod, patches);
      for (const GpuPatch& p : patches) levels.insert(patch_level(p));
      const bool settled = s->source->settled() && f >= 2;
      if (stitch && (f % 10 == 0 || settled)) {  // the CPU reference of the same state
        const FrameUniforms& u = s->renderer.uniforms();
        const NodeList ref = reference_traverse(s->state, u, s->renderer.slot_cpu());
        std::vector<uint32_t> a = nodes.entries, b = ref.entries;
        std::sort(a.begin(), a.end());
        std::sort(b.begin(), b.end());
        EXPECT_EQ(a, b) << v.name << " frame " << f;
        const auto ref_lod = reference_lod_map(s->state, u, ref);
        EXPECT_EQ(lod, ref_lod) << v.name << " frame " << f;
        const PatchList ref_patches =
            reference_patches(s->state, u, ref, ref_lod, s->renderer.slot_cpu(), s->renderer.cone_sin2_table());
        EXPECT_EQ(ref_patches.patches.size(), patches.size()) << v.name << " frame " << f;
      }
      if (settled) {
        // Terrain on screen: most pixels are drawn (the views look at ground only).
        size_t drawn = 0;
        for (size_t i = 0; i < rgba.size(); i += 4) drawn += !(rgba[i] == 255 && rgba[i + 1] == 0 && rgba[i + 2] == 255);
        EXPECT_GT(drawn, rgba.size() / 4 * 9 / 10) << v.name;
        std::printf("%s (stitch %d): settled after %d frames, %u nodes, %u patches, %llu triangles, gpu %.2f ms, "
                    "resident %u, %zu magenta\n",
                    v.name, int(stitch), f + 1, rec.gpu.nodes, rec.gpu.patches_drawn,
                    (unsigned long long)rec.gpu.triangles, rec.gpu.gpu_total_ms, rec.source.resident, bad);
        break;
      }
    }
  }
  EXPECT_EQ(s->ctx.validation_errors, 0u);
}

TEST_F(ViewerOverview, ManyRootsFromLowAndFrom50KmHaveNoCracks) {
  size_t cracked = 0, frames = 0;
  std::set<uint32_t> levels;
  run(true, cracked, levels, frames);
  EXPECT_EQ(cracked, 0u);
  // Overview levels (6..) and roots (5) drawn; 64 x 64 roots have 4 overview levels (6..9).
  EXPECT_TRUE(levels.count(5)) << "roots drawn";
  EXPECT_TRUE(levels.count(9)) << "the top level drawn";
  std::printf("geometric levels drawn:");
  for (uint32_t l : levels) std::printf(" %u", l);
  std::printf(" over %zu frames\n", frames);
}

// The control: the same views without stitching do crack, so the test above can see cracks.
TEST_F(ViewerOverview, WithoutStitchingTheSameViewsCrack) {
  size_t cracked = 0, frames = 0;
  std::set<uint32_t> levels;
  run(false, cracked, levels, frames);
  EXPECT_GT(cracked, 0u);
  std::printf("without stitching: %zu magenta pixels over %zu frames\n", cracked, frames);
}

}  // namespace
}  // namespace terrain::view
