#include "resources.h"

#include "vk_common.h"

namespace terrain::view {
namespace {

Status find_memory(const Context& ctx, uint32_t type_bits, VkMemoryPropertyFlags want, VkMemoryPropertyFlags fallback,
                   uint32_t& out) {
  for (VkMemoryPropertyFlags flags : {want, fallback})
    for (uint32_t i = 0; i < ctx.memory.memoryTypeCount; ++i)
      if ((type_bits & (1u << i)) && (ctx.memory.memoryTypes[i].propertyFlags & flags) == flags) {
        out = i;
        return Status::success();
      }
  return Status::failure(Error::internal, "vulkan: no memory type fits");
}

// Allocates memory for `req` (of a type with `want`, else `fallback`) for a buffer or image to bind.
Status allocate_memory(const Context& ctx, const VkMemoryRequirements& req, VkMemoryPropertyFlags want,
                       VkMemoryPropertyFlags fallback, VkDeviceMemory& out) {
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  TERRAIN_TRY(find_memory(ctx, req.memoryTypeBits, want, fallback, ai.memoryTypeIndex));
  VK_TRY(vkAllocateMemory(ctx.device, &ai, nullptr, &out));
  return Status::success();
}

Status create_buffer(const Context& ctx, VkDeviceSize size, VkBufferUsageFlags usage, VkMemoryPropertyFlags want,
                     VkMemoryPropertyFlags fallback, bool map, Buffer& out) {
  VkBufferCreateInfo bci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bci.size = size;
  bci.usage = usage;
  VK_TRY(vkCreateBuffer(ctx.device, &bci, nullptr, &out.buffer));
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(ctx.device, out.buffer, &req);
  TERRAIN_TRY(allocate_memory(ctx, req, want, fallback, out.memory));
  VK_TRY(vkBindBufferMemory(ctx.device, out.buffer, out.memory, 0));
  out.size = size;
  if (map) VK_TRY(vkMapMemory(ctx.device, out.memory, 0, VK_WHOLE_SIZE, 0, &out.mapped));
  return Status::success();
}

}  // namespace

Status create_host_buffer(const Context& ctx, VkDeviceSize size, VkBufferUsageFlags usage, Buffer& out) {
  const VkMemoryPropertyFlags f = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  return create_buffer(ctx, size, usage, f, f, true, out);
}

Status create_device_buffer(const Context& ctx, VkDeviceSize size, VkBufferUsageFlags usage, Buffer& out) {
  return create_buffer(ctx, size, usage, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0, false, out);
}

void destroy_buffer(const Context& ctx, Buffer& b) {
  if (b.buffer) vkDestroyBuffer(ctx.device, b.buffer, nullptr);
  if (b.memory) vkFreeMemory(ctx.device, b.memory, nullptr);
  b = Buffer{};
}

Status create_image(const Context& ctx, VkFormat format, uint32_t width, uint32_t height, uint32_t layers, uint32_t mips,
                    VkImageUsageFlags usage, VkImageAspectFlags aspect, bool array_view, Image& out) {
  const VkImageCreateInfo ici{.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
                              .imageType = VK_IMAGE_TYPE_2D,
                              .format = format,
                              .extent = {width, height, 1},
                              .mipLevels = mips,
                              .arrayLayers = layers,
                              .samples = VK_SAMPLE_COUNT_1_BIT,
                              .tiling = VK_IMAGE_TILING_OPTIMAL,
                              .usage = usage,
                              .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED};
  VK_TRY(vkCreateImage(ctx.device, &ici, nullptr, &out.image));
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(ctx.device, out.image, &req);
  TERRAIN_TRY(allocate_memory(ctx, req, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0, out.memory));
  VK_TRY(vkBindImageMemory(ctx.device, out.image, out.memory, 0));
  VkImageViewCreateInfo vci{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
  vci.image = out.image;
  vci.viewType = (layers > 1 || array_view) ? VK_IMAGE_VIEW_TYPE_2D_ARRAY : VK_IMAGE_VIEW_TYPE_2D;
  vci.format = format;
  vci.subresourceRange = {aspect, 0, mips, 0, layers};
  VK_TRY(vkCreateImageView(ctx.device, &vci, nullptr, &out.view));
  out.format = format;
  out.width = width;
  out.height = height;
  out.layers = layers;
  out.mips = mips;
  return Status::success();
}

void destroy_image(const Context& ctx, Image& img) {
  if (img.view) vkDestroyImageView(ctx.device, img.view, nullptr);
  if (img.image) vkDestroyImage(ctx.device, img.image, nullptr);
  if (img.memory) vkFreeMemory(ctx.device, img.memory, nullptr);
  img = Image{};
}

void image_barrier(VkCommandBuffer cmd, const Image& img, VkImageAspectFlags aspect, VkImageLayout from, VkImageLayout to,
                   VkPipelineStageFlags2 src_stage, VkAccessFlags2 src_access, VkPipelineStageFlags2 dst_stage,
                   VkAccessFlags2 dst_access) {
  VkImageMemoryBarrier2 b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER_2};
  b.srcStageMask = src_stage;
  b.srcAccessMask = src_access;
  b.dstStageMask = dst_stage;
  b.dstAccessMask = dst_access;
  b.oldLayout = from;
  b.newLayout = to;
  b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = img.image;
  b.subresourceRange = {aspect, 0, img.mips, 0, img.layers};
  VkDependencyInfo di{VK_STRUCTURE_TYPE_DEPENDENCY_INFO};
  di.imageMemoryBarrierCount = 1;
  di.pImageMemoryBarriers = &b;
  vkCmdPipelineBarrier2(cmd, &di);
}

void memory_barrier(VkCommandBuffer cmd, VkPipelineStageFlags2 src_stage, VkAccessFlags2 src_access,
                    VkPipelineStageFlags2 dst_stage, VkAccessFlags2 dst_access) {
  VkMemoryBarrier2 b{VK_STRUCTURE_TYPE_MEMORY_BARRIER_2};
  b.srcStageMask = src_stage;
  b.srcAccessMask = src_access;
  b.dstStageMask = dst_stage;
  b.dstAccessMask = dst_access;
  VkDependencyInfo di{VK_STRUCTURE_TYPE_DEPENDENCY_INFO};
  di.memoryBarrierCount = 1;
  di.pMemoryBarriers = &b;
  vkCmdPipelineBarrier2(cmd, &di);
}

Status create_one_shot(const Context& ctx, OneShot& out) {
  VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT | VK_COMMAND_POOL_CREATE_TRANSIENT_BIT;
  pci.queueFamilyIndex = ctx.queue_family;
  VK_TRY(vkCreateCommandPool(ctx.device, &pci, nullptr, &out.pool));
  return Status::success();
}

void destroy_one_shot(const Context& ctx, OneShot& os) {
  if (os.pool) vkDestroyCommandPool(ctx.device, os.pool, nullptr);
  os = OneShot{};
}

Status allocate_command_buffer(const Context& ctx, VkCommandPool pool, VkCommandBuffer& out) {
  VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  ai.commandPool = pool;
  ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  ai.commandBufferCount = 1;
  VK_TRY(vkAllocateCommandBuffers(ctx.device, &ai, &out));
  return Status::success();
}

Status submit_and_wait_cmd(const Context& ctx, VkCommandBuffer cmd) {
  VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  VkFence fence;
  VK_TRY(vkCreateFence(ctx.device, &fci, nullptr, &fence));
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  VkResult r = vkQueueSubmit(ctx.queue, 1, &si, fence);
  if (r == VK_SUCCESS) r = vkWaitForFences(ctx.device, 1, &fence, VK_TRUE, UINT64_MAX);
  vkDestroyFence(ctx.device, fence, nullptr);
  VK_TRY(r);
  return Status::success();
}

void set_debug_name(const Context& ctx, VkObjectType type, uint64_t handle, const char* name) {
  if (!ctx.messenger) return;  // names matter only with the validation layer
  auto fn = reinterpret_cast<PFN_vkSetDebugUtilsObjectNameEXT>(
      vkGetDeviceProcAddr(ctx.device, "vkSetDebugUtilsObjectNameEXT"));
  if (!fn) return;
  VkDebugUtilsObjectNameInfoEXT ni{VK_STRUCTURE_TYPE_DEBUG_UTILS_OBJECT_NAME_INFO_EXT};
  ni.objectType = type;
  ni.objectHandle = handle;
  ni.pObjectName = name;
  fn(ctx.device, &ni);
}

}  // namespace terrain::view
