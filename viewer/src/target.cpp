#include "target.h"

#include <cstring>

#include "vk_common.h"

namespace terrain::view {

Status create_target(const Context& ctx, uint32_t width, uint32_t height, RenderTarget& out) {
  out.width = width;
  out.height = height;
  TERRAIN_TRY(create_image(ctx, kColorFormat, width, height, 1, 1,
                      VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT, VK_IMAGE_ASPECT_COLOR_BIT,
                      false, out.color));
  TERRAIN_TRY(create_image(ctx, kDepthFormat, width, height, 1, 1,
                      VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                      VK_IMAGE_ASPECT_DEPTH_BIT, false, out.depth));
  TERRAIN_TRY(create_host_buffer(ctx, VkDeviceSize(width) * height * 8, VK_BUFFER_USAGE_TRANSFER_DST_BIT, out.readback));
  set_debug_name(ctx, VK_OBJECT_TYPE_IMAGE, uint64_t(out.color.image), "target.color");
  set_debug_name(ctx, VK_OBJECT_TYPE_IMAGE, uint64_t(out.depth.image), "target.depth");
  return Status::success();
}

void destroy_target(const Context& ctx, RenderTarget& t) {
  destroy_image(ctx, t.color);
  destroy_image(ctx, t.depth);
  destroy_buffer(ctx, t.readback);
  t = RenderTarget{};
}

void record_readback(VkCommandBuffer cmd, const RenderTarget& t) {
  image_barrier(cmd, t.color, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT,
                VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_READ_BIT);
  image_barrier(cmd, t.depth, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL,
                VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_PIPELINE_STAGE_2_LATE_FRAGMENT_TESTS_BIT,
                VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT, VK_PIPELINE_STAGE_2_COPY_BIT,
                VK_ACCESS_2_TRANSFER_READ_BIT);
  VkBufferImageCopy c{};
  c.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  c.imageExtent = {t.width, t.height, 1};
  vkCmdCopyImageToBuffer(cmd, t.color.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, t.readback.buffer, 1, &c);
  c.bufferOffset = VkDeviceSize(t.width) * t.height * 4;
  c.imageSubresource.aspectMask = VK_IMAGE_ASPECT_DEPTH_BIT;
  vkCmdCopyImageToBuffer(cmd, t.depth.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, t.readback.buffer, 1, &c);
  image_barrier(cmd, t.color, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_READ_BIT,
                VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT);
  image_barrier(cmd, t.depth, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_READ_BIT,
                VK_PIPELINE_STAGE_2_EARLY_FRAGMENT_TESTS_BIT, VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
  memory_barrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_2_HOST_BIT,
                 VK_ACCESS_2_HOST_READ_BIT);
}

void read_color(const RenderTarget& t, std::vector<uint8_t>& rgba) {
  rgba.resize(size_t(t.width) * t.height * 4);
  std::memcpy(rgba.data(), t.readback.mapped, rgba.size());
}

void read_depth(const RenderTarget& t, std::vector<float>& depth) {
  depth.resize(size_t(t.width) * t.height);
  std::memcpy(depth.data(), static_cast<const uint8_t*>(t.readback.mapped) + size_t(t.width) * t.height * 4,
              depth.size() * sizeof(float));
}

}  // namespace terrain::view
