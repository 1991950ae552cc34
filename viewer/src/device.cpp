#include "device.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>

#include <dlfcn.h>

#include "vk_common.h"

namespace terrain::view {
namespace {

VKAPI_ATTR VkBool32 VKAPI_CALL debug_callback(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                              VkDebugUtilsMessageTypeFlagsEXT, const VkDebugUtilsMessengerCallbackDataEXT* data,
                                              void* user) {
  if (severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) {
    std::fprintf(stderr, "terrain-view: validation %s: %s\n",
                 severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT ? "error" : "warning", data->pMessage);
    if (severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) ++static_cast<Context*>(user)->validation_errors;
  }
  return VK_FALSE;
}

bool has_layer(const char* name) {
  uint32_t n = 0;
  vkEnumerateInstanceLayerProperties(&n, nullptr);
  std::vector<VkLayerProperties> layers(n);
  vkEnumerateInstanceLayerProperties(&n, layers.data());
  for (auto& l : layers)
    if (std::strcmp(l.layerName, name) == 0) return true;
  return false;
}

bool suitable(VkPhysicalDevice pd, uint32_t& family) {
  VkPhysicalDeviceProperties props;
  vkGetPhysicalDeviceProperties(pd, &props);
  if (props.apiVersion < VK_API_VERSION_1_3) return false;
  VkPhysicalDeviceFeatures f;
  vkGetPhysicalDeviceFeatures(pd, &f);
  if (!f.textureCompressionBC) return false;
  uint32_t n = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, nullptr);
  std::vector<VkQueueFamilyProperties> fams(n);
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &n, fams.data());
  for (uint32_t i = 0; i < n; ++i)
    if ((fams[i].queueFlags & VK_QUEUE_GRAPHICS_BIT) && (fams[i].queueFlags & VK_QUEUE_COMPUTE_BIT)) {
      family = i;
      return true;
    }
  return false;
}

}  // namespace

bool is_no_device(const Status& s) { return !s.ok() && s.message.find("no Vulkan device") != std::string::npos; }

Status create_context(const DeviceOptions& options, Context& ctx) {
#if defined(__SANITIZE_ADDRESS__)
  // LeakSanitizer reports a few hundred bytes Mesa's lavapipe never frees; the loader unloads the
  // driver before the report, which leaves the frames unnamed and unsuppressible. Keeping the
  // driver mapped lets tests/viewer/lsan.supp name it. Sanitizer builds only.
  static void* keep_driver = dlopen("libvulkan_lvp.so", RTLD_NOW | RTLD_NODELETE);
  (void)keep_driver;
#endif
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "terrain-view";
  app.apiVersion = VK_API_VERSION_1_3;
  std::vector<const char*> layers, extensions = options.instance_extensions;
  const bool validation = options.validation && has_layer("VK_LAYER_KHRONOS_validation");
  if (options.validation && !validation)
    std::fprintf(stderr, "terrain-view: validation requested but VK_LAYER_KHRONOS_validation is not installed\n");
  if (validation) {
    layers.push_back("VK_LAYER_KHRONOS_validation");
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
  }
  VkInstanceCreateInfo ici{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  ici.pApplicationInfo = &app;
  ici.enabledLayerCount = uint32_t(layers.size());
  ici.ppEnabledLayerNames = layers.data();
  ici.enabledExtensionCount = uint32_t(extensions.size());
  ici.ppEnabledExtensionNames = extensions.data();
  VkResult r = vkCreateInstance(&ici, nullptr, &ctx.instance);
  if (r == VK_ERROR_INCOMPATIBLE_DRIVER || r == VK_ERROR_INITIALIZATION_FAILED)
    return Status::failure(Error::unsupported_input, "no Vulkan device: vkCreateInstance returned " +
                                                         std::string(vk_result_name(r)) + " (is a Vulkan driver installed?)");
  VK_TRY(r);
  if (validation) {
    VkDebugUtilsMessengerCreateInfoEXT mci{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
    mci.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    mci.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT;
    mci.pfnUserCallback = debug_callback;
    mci.pUserData = &ctx;
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(ctx.instance, "vkCreateDebugUtilsMessengerEXT"));
    if (create) VK_TRY(create(ctx.instance, &mci, nullptr, &ctx.messenger));
  }

  uint32_t n = 0;
  vkEnumeratePhysicalDevices(ctx.instance, &n, nullptr);
  std::vector<VkPhysicalDevice> devices(n);
  vkEnumeratePhysicalDevices(ctx.instance, &n, devices.data());
  if (n == 0) return Status::failure(Error::unsupported_input, "no Vulkan device: the loader found no physical device");

  int chosen = -1;
  uint32_t family = 0;
  const char* override_env = std::getenv("TERRAIN_VIEW_DEVICE");
  std::string listing;
  for (uint32_t i = 0; i < n; ++i) {
    VkPhysicalDeviceProperties p;
    vkGetPhysicalDeviceProperties(devices[i], &p);
    listing += "  " + std::to_string(i) + ": " + p.deviceName + "\n";
  }
  if (override_env && *override_env) {
    char* end = nullptr;
    const long idx = std::strtol(override_env, &end, 10);
    for (uint32_t i = 0; i < n; ++i) {
      VkPhysicalDeviceProperties p;
      vkGetPhysicalDeviceProperties(devices[i], &p);
      const bool match = (end && *end == 0) ? long(i) == idx : std::strstr(p.deviceName, override_env) != nullptr;
      if (match) {
        if (!suitable(devices[i], family))
          return Status::failure(Error::unsupported_input, std::string("TERRAIN_VIEW_DEVICE selects '") + p.deviceName +
                                                               "', which lacks Vulkan 1.3, BC textures or a graphics+compute queue");
        chosen = int(i);
        break;
      }
    }
    if (chosen < 0)
      return Status::failure(Error::invalid_argument,
                             std::string("TERRAIN_VIEW_DEVICE='") + override_env + "' matches no device; devices:\n" + listing);
  } else {
    for (int pass = 0; pass < 2 && chosen < 0; ++pass)
      for (uint32_t i = 0; i < n && chosen < 0; ++i) {
        VkPhysicalDeviceProperties p;
        vkGetPhysicalDeviceProperties(devices[i], &p);
        if (pass == 0 && p.deviceType != VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU) continue;
        if (suitable(devices[i], family)) chosen = int(i);
      }
  }
  if (chosen < 0)
    return Status::failure(Error::unsupported_input,
                           "no Vulkan device with Vulkan 1.3, BC textures and a graphics+compute queue; devices:\n" + listing);
  ctx.physical = devices[size_t(chosen)];
  ctx.queue_family = family;
  vkGetPhysicalDeviceProperties(ctx.physical, &ctx.properties);
  vkGetPhysicalDeviceMemoryProperties(ctx.physical, &ctx.memory);
  ctx.device_name = ctx.properties.deviceName;
  if (!options.quiet)
    std::fprintf(stderr, "terrain-view: device %d '%s' (Vulkan %u.%u.%u)%s\n", chosen, ctx.device_name.c_str(),
                 VK_API_VERSION_MAJOR(ctx.properties.apiVersion), VK_API_VERSION_MINOR(ctx.properties.apiVersion),
                 VK_API_VERSION_PATCH(ctx.properties.apiVersion),
                 override_env && *override_env ? " [TERRAIN_VIEW_DEVICE]" : "");

  VkPhysicalDeviceFeatures supported;
  vkGetPhysicalDeviceFeatures(ctx.physical, &supported);
  VkPhysicalDeviceVulkan13Features f13{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES};
  f13.dynamicRendering = VK_TRUE;
  f13.synchronization2 = VK_TRUE;
  VkPhysicalDeviceFeatures2 f2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  f2.pNext = &f13;
  f2.features.textureCompressionBC = VK_TRUE;
  f2.features.fillModeNonSolid = supported.fillModeNonSolid;
  f2.features.multiDrawIndirect = supported.multiDrawIndirect;
  ctx.multi_draw_indirect = supported.multiDrawIndirect == VK_TRUE;
  const float priority = 1.0f;
  VkDeviceQueueCreateInfo qci{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  qci.queueFamilyIndex = family;
  qci.queueCount = 1;
  qci.pQueuePriorities = &priority;
  std::vector<const char*> dev_ext;
  if (options.swapchain) dev_ext.push_back(VK_KHR_SWAPCHAIN_EXTENSION_NAME);
  VkDeviceCreateInfo dci{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  dci.pNext = &f2;
  dci.queueCreateInfoCount = 1;
  dci.pQueueCreateInfos = &qci;
  dci.enabledExtensionCount = uint32_t(dev_ext.size());
  dci.ppEnabledExtensionNames = dev_ext.data();
  VK_TRY(vkCreateDevice(ctx.physical, &dci, nullptr, &ctx.device));
  vkGetDeviceQueue(ctx.device, family, 0, &ctx.queue);
  return Status::success();
}

void destroy_context(Context& ctx) {
  if (ctx.device) vkDestroyDevice(ctx.device, nullptr);
  if (ctx.messenger) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(ctx.instance, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy) destroy(ctx.instance, ctx.messenger, nullptr);
  }
  if (ctx.instance) vkDestroyInstance(ctx.instance, nullptr);
  ctx = Context{};
}

}  // namespace terrain::view
