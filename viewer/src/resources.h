// Buffers, images, barriers and one-shot command submission over a Context.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>

#include "device.h"
#include "terrain/status.h"

namespace terrain::view {

struct Buffer {
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  VkDeviceSize size = 0;
  void* mapped = nullptr;  // host-visible buffers stay mapped
};

struct Image {
  VkImage image = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  VkImageView view = VK_NULL_HANDLE;
  VkFormat format = VK_FORMAT_UNDEFINED;
  uint32_t width = 0, height = 0, layers = 1, mips = 1;
};

// Host-visible, coherent, persistently mapped (on lavapipe all memory is; on a discrete GPU these
// live in system memory, which is fine for the small per-frame buffers of the viewer).
Status create_host_buffer(const Context& ctx, VkDeviceSize size, VkBufferUsageFlags usage, Buffer& out);
// Device-local when available.
Status create_device_buffer(const Context& ctx, VkDeviceSize size, VkBufferUsageFlags usage, Buffer& out);
void destroy_buffer(const Context& ctx, Buffer& b);

// 2D image (array when layers > 1, or when `array_view` is set) with one view over all layers/mips.
Status create_image(const Context& ctx, VkFormat format, uint32_t width, uint32_t height, uint32_t layers, uint32_t mips,
                    VkImageUsageFlags usage, VkImageAspectFlags aspect, bool array_view, Image& out);
void destroy_image(const Context& ctx, Image& img);

// Whole-image layout transition (all mips and layers) with a full pipeline barrier (sync2).
void image_barrier(VkCommandBuffer cmd, const Image& img, VkImageAspectFlags aspect, VkImageLayout from, VkImageLayout to,
                   VkPipelineStageFlags2 src_stage, VkAccessFlags2 src_access, VkPipelineStageFlags2 dst_stage,
                   VkAccessFlags2 dst_access);
void memory_barrier(VkCommandBuffer cmd, VkPipelineStageFlags2 src_stage, VkAccessFlags2 src_access,
                    VkPipelineStageFlags2 dst_stage, VkAccessFlags2 dst_access);

// Records with `record` into a transient command buffer, submits and waits.
struct OneShot {
  VkCommandPool pool = VK_NULL_HANDLE;
};
Status create_one_shot(const Context& ctx, OneShot& out);
void destroy_one_shot(const Context& ctx, OneShot& os);
template <class F>
Status submit_and_wait(const Context& ctx, const OneShot& os, F&& record);
Status submit_and_wait_cmd(const Context& ctx, VkCommandBuffer cmd);

Status allocate_command_buffer(const Context& ctx, VkCommandPool pool, VkCommandBuffer& out);

void set_debug_name(const Context& ctx, VkObjectType type, uint64_t handle, const char* name);

template <class F>
Status submit_and_wait(const Context& ctx, const OneShot& os, F&& record) {
  VkCommandBuffer cmd;
  TERRAIN_TRY(allocate_command_buffer(ctx, os.pool, cmd));
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  vkBeginCommandBuffer(cmd, &bi);
  record(cmd);
  vkEndCommandBuffer(cmd);
  const Status s = submit_and_wait_cmd(ctx, cmd);
  vkFreeCommandBuffers(ctx.device, os.pool, 1, &cmd);
  return s;
}

}  // namespace terrain::view
