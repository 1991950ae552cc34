#include "gpu_harness.h"

#include "vk_common.h"

namespace terrain::view::test {

Gpu::~Gpu() {
  if (ctx.device) vkDeviceWaitIdle(ctx.device);
  renderer.destroy();
  if (ctx.device) {
    destroy_target(ctx, target);
    destroy_one_shot(ctx, one_shot);
  }
  destroy_context(ctx);
}

std::unique_ptr<Gpu> make_gpu(const WorldInfo& world, uint32_t slot_count, uint32_t width, uint32_t height, bool& skip,
                              Status& error, RendererConfig rc) {
  auto gpu = std::make_unique<Gpu>();
  DeviceOptions o;
  o.quiet = true;
  o.validation = std::getenv("TERRAIN_VIEW_VALIDATION") != nullptr;
  error = create_context(o, gpu->ctx);
  if (!error.ok()) {
    skip = is_no_device(error);
    return nullptr;
  }
  rc.slot_count = slot_count;
  if (!(error = gpu->renderer.init(gpu->ctx, world, rc)).ok()) return nullptr;
  if (!(error = create_target(gpu->ctx, width, height, gpu->target)).ok()) return nullptr;
  if (!(error = create_one_shot(gpu->ctx, gpu->one_shot)).ok()) return nullptr;
  return gpu;
}

Status render_frame(Gpu& gpu, const std::vector<NodeUpload>& uploads, const Camera& camera,
                    const FrameSettings& settings, bool capture_lists) {
  TERRAIN_TRY(gpu.renderer.upload(uploads, gpu.state));
  gpu.renderer.set_frame(camera, settings, gpu.target.width, gpu.target.height);
  TERRAIN_TRY(submit_and_wait(gpu.ctx, gpu.one_shot, [&](VkCommandBuffer cmd) {
    gpu.renderer.record_frame(cmd, gpu.target, capture_lists);
    record_readback(cmd, gpu.target);
  }));
  // With TERRAIN_VIEW_VALIDATION set, any validation error fails the frame.
  if (gpu.ctx.validation_errors > 0)
    return Status::failure(Error::internal, std::to_string(gpu.ctx.validation_errors) + " Vulkan validation errors");
  return Status::success();
}

size_t count_color(const std::vector<uint8_t>& rgba, uint8_t r, uint8_t g, uint8_t b) {
  size_t n = 0;
  for (size_t i = 0; i + 3 < rgba.size(); i += 4) n += rgba[i] == r && rgba[i + 1] == g && rgba[i + 2] == b;
  return n;
}

}  // namespace terrain::view::test
