#include "vk_common.h"

#include <cstdio>
#include <cstdlib>

namespace terrain::view {

const char* vk_result_name(VkResult r) {
  switch (r) {
#define TV_CASE(x) \
  case x:          \
    return #x;
    TV_CASE(VK_SUCCESS)
    TV_CASE(VK_NOT_READY)
    TV_CASE(VK_TIMEOUT)
    TV_CASE(VK_EVENT_SET)
    TV_CASE(VK_EVENT_RESET)
    TV_CASE(VK_INCOMPLETE)
    TV_CASE(VK_ERROR_OUT_OF_HOST_MEMORY)
    TV_CASE(VK_ERROR_OUT_OF_DEVICE_MEMORY)
    TV_CASE(VK_ERROR_INITIALIZATION_FAILED)
    TV_CASE(VK_ERROR_DEVICE_LOST)
    TV_CASE(VK_ERROR_MEMORY_MAP_FAILED)
    TV_CASE(VK_ERROR_LAYER_NOT_PRESENT)
    TV_CASE(VK_ERROR_EXTENSION_NOT_PRESENT)
    TV_CASE(VK_ERROR_FEATURE_NOT_PRESENT)
    TV_CASE(VK_ERROR_INCOMPATIBLE_DRIVER)
    TV_CASE(VK_ERROR_TOO_MANY_OBJECTS)
    TV_CASE(VK_ERROR_FORMAT_NOT_SUPPORTED)
    TV_CASE(VK_ERROR_FRAGMENTED_POOL)
    TV_CASE(VK_ERROR_OUT_OF_POOL_MEMORY)
    TV_CASE(VK_ERROR_SURFACE_LOST_KHR)
    TV_CASE(VK_ERROR_NATIVE_WINDOW_IN_USE_KHR)
    TV_CASE(VK_SUBOPTIMAL_KHR)
    TV_CASE(VK_ERROR_OUT_OF_DATE_KHR)
#undef TV_CASE
    default:
      return "VK_ERROR_(unknown)";
  }
}

void vk_fatal(VkResult r, const char* call, const char* file, int line) {
  std::fprintf(stderr, "terrain-view: fatal Vulkan error %s (%d) from %s at %s:%d\n", vk_result_name(r), int(r), call,
               file, line);
  std::abort();
}

Status vk_status(VkResult r, const char* call, const char* file, int line) {
  return Status::failure(Error::internal, std::string("vulkan: ") + call + " returned " + vk_result_name(r) + " at " +
                                              file + ":" + std::to_string(line));
}

}  // namespace terrain::view
