// Vulkan instance, physical-device choice and logical device (one queue for graphics + compute +
// transfer). Device choice: $TERRAIN_VIEW_DEVICE (index or a substring of the name) if set, else
// the first discrete GPU, else the first device with Vulkan 1.3; the choice is printed.
#pragma once
#include <vulkan/vulkan.h>

#include <string>
#include <vector>

#include "terrain/status.h"

namespace terrain::view {

struct DeviceOptions {
  bool validation = false;                     // enable VK_LAYER_KHRONOS_validation (if present)
  std::vector<const char*> instance_extensions;  // e.g. from glfwGetRequiredInstanceExtensions
  bool swapchain = false;                      // needs VK_KHR_swapchain
  bool quiet = false;                          // do not print the device choice
};

struct Context {
  VkInstance instance = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  uint32_t queue_family = 0;
  VkPhysicalDeviceProperties properties{};
  VkPhysicalDeviceMemoryProperties memory{};
  std::string device_name;
  uint32_t validation_errors = 0;  // messages of severity error seen by the debug messenger
  bool multi_draw_indirect = false;  // drawCount > 1 in one indirect draw (else one call per draw)
};

// Error::unsupported_input with "no Vulkan device" in the message when the loader finds no
// driver or no suitable device (callers exit 77 in tests).
Status create_context(const DeviceOptions& options, Context& out);
void destroy_context(Context& ctx);
bool is_no_device(const Status& s);

}  // namespace terrain::view
