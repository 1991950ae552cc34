// Vulkan error checks, two strengths (niagara style):
//  VK_TRY(call)   -- for start-up and resource creation: on failure returns a terrain::Status from
//                    the enclosing function naming file:line, the call and the VkResult.
//  VK_CHECK(call) -- for calls that cannot fail in a correct program: prints the same and aborts,
//                    in every build type.
#pragma once
#include <vulkan/vulkan.h>

#include <string>

#include "terrain/status.h"

namespace terrain::view {

const char* vk_result_name(VkResult r);
[[noreturn]] void vk_fatal(VkResult r, const char* call, const char* file, int line);
Status vk_status(VkResult r, const char* call, const char* file, int line);

}  // namespace terrain::view

#define VK_TRY(call)                                                                  \
  do {                                                                                \
    VkResult vk_try_result_ = (call);                                                 \
    if (vk_try_result_ != VK_SUCCESS)                                                 \
      return ::terrain::view::vk_status(vk_try_result_, #call, __FILE__, __LINE__);   \
  } while (0)

#define VK_CHECK(call)                                                                \
  do {                                                                                \
    VkResult vk_check_result_ = (call);                                               \
    if (vk_check_result_ != VK_SUCCESS)                                               \
      ::terrain::view::vk_fatal(vk_check_result_, #call, __FILE__, __LINE__);         \
  } while (0)
