// A small Vulkan harness for viewer tests: a device, the terrain renderer and an offscreen target;
// one call renders a frame and waits. Tests skip when no Vulkan device exists.
#pragma once
#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "device.h"
#include "reference.h"
#include "renderer.h"
#include "residency.h"
#include "synthetic_nodes.h"

namespace terrain::view::test {

struct Gpu {
  Context ctx;
  OneShot one_shot;
  TerrainRenderer renderer;
  RenderTarget target;
  TerrainState state;
  ~Gpu();
};

// Null with `skip` set when there is no Vulkan device; null with a failure otherwise. `config`'s
// slot_count is replaced by `slot_count`.
std::unique_ptr<Gpu> make_gpu(const WorldInfo& world, uint32_t slot_count, uint32_t width, uint32_t height,
                              bool& skip, Status& error, RendererConfig config = {});

// Uploads, renders one frame and waits.
Status render_frame(Gpu& gpu, const std::vector<NodeUpload>& uploads, const Camera& camera,
                    const FrameSettings& settings, bool capture_lists);

// Residency over a synthetic world (keeps the node data alive).
struct World {
  synthetic::World synthetic;
  StaticResidency residency;
};

// Pixels exactly equal to the sRGB colour (r, g, b).
size_t count_color(const std::vector<uint8_t>& rgba, uint8_t r, uint8_t g, uint8_t b);

}  // namespace terrain::view::test

#define TV_REQUIRE_GPU(gpu, world, slots, w, h, ...)                              \
  bool tv_skip_ = false;                                                          \
  ::terrain::Status tv_error_;                                                    \
  auto gpu = ::terrain::view::test::make_gpu(world, slots, w, h, tv_skip_, tv_error_ __VA_OPT__(,) __VA_ARGS__); \
  if (tv_skip_) GTEST_SKIP() << "no Vulkan device: " << tv_error_.message;        \
  ASSERT_TRUE(gpu) << tv_error_.message
