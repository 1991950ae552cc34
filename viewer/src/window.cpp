#define GLFW_INCLUDE_VULKAN
#include "window.h"

#include <GLFW/glfw3.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "session.h"
#include "vk_common.h"

namespace terrain::view {
namespace {

struct Swapchain {
  VkSwapchainKHR swapchain = VK_NULL_HANDLE;
  VkFormat format = VK_FORMAT_UNDEFINED;
  VkExtent2D extent{};
  std::vector<VkImage> images;
};

Status create_swapchain(const Context& ctx, VkSurfaceKHR surface, GLFWwindow* window, Swapchain& sc) {
  VkSurfaceCapabilitiesKHR caps;
  VK_TRY(vkGetPhysicalDeviceSurfaceCapabilitiesKHR(ctx.physical, surface, &caps));
  uint32_t n = 0;
  vkGetPhysicalDeviceSurfaceFormatsKHR(ctx.physical, surface, &n, nullptr);
  std::vector<VkSurfaceFormatKHR> formats(n);
  vkGetPhysicalDeviceSurfaceFormatsKHR(ctx.physical, surface, &n, formats.data());
  if (formats.empty()) return Status::failure(Error::internal, "the window surface offers no format");
  VkSurfaceFormatKHR chosen = formats[0];
  for (auto& f : formats)
    if (f.format == VK_FORMAT_B8G8R8A8_UNORM || f.format == VK_FORMAT_R8G8B8A8_UNORM) chosen = f;  // the target is sRGB-encoded already
  int w = 0, h = 0;
  glfwGetFramebufferSize(window, &w, &h);
  VkExtent2D extent = caps.currentExtent;
  if (extent.width == UINT32_MAX) extent = {uint32_t(std::max(w, 16)), uint32_t(std::max(h, 16))};
  if (!(caps.supportedUsageFlags & VK_IMAGE_USAGE_TRANSFER_DST_BIT))
    return Status::failure(Error::internal, "the swapchain images cannot be blitted to");
  VkSwapchainCreateInfoKHR ci{VK_STRUCTURE_TYPE_SWAPCHAIN_CREATE_INFO_KHR};
  ci.surface = surface;
  ci.minImageCount = std::max(caps.minImageCount, 2u);
  if (caps.maxImageCount) ci.minImageCount = std::min(ci.minImageCount, caps.maxImageCount);
  ci.imageFormat = chosen.format;
  ci.imageColorSpace = chosen.colorSpace;
  ci.imageExtent = extent;
  ci.imageArrayLayers = 1;
  ci.imageUsage = VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT;
  ci.imageSharingMode = VK_SHARING_MODE_EXCLUSIVE;
  ci.preTransform = caps.currentTransform;
  ci.compositeAlpha = VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR;
  ci.presentMode = VK_PRESENT_MODE_FIFO_KHR;
  ci.clipped = VK_TRUE;
  ci.oldSwapchain = sc.swapchain;
  VkSwapchainKHR created;
  VK_TRY(vkCreateSwapchainKHR(ctx.device, &ci, nullptr, &created));
  if (sc.swapchain) vkDestroySwapchainKHR(ctx.device, sc.swapchain, nullptr);
  sc.swapchain = created;
  sc.format = chosen.format;
  sc.extent = extent;
  vkGetSwapchainImagesKHR(ctx.device, sc.swapchain, &n, nullptr);
  sc.images.resize(n);
  vkGetSwapchainImagesKHR(ctx.device, sc.swapchain, &n, sc.images.data());
  return Status::success();
}

void record_blit(VkCommandBuffer cmd, const RenderTarget& t, VkImage dst, VkExtent2D extent) {
  image_barrier(cmd, t.color, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT,
                VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT, VK_PIPELINE_STAGE_2_BLIT_BIT, VK_ACCESS_2_TRANSFER_READ_BIT);
  Image swap;
  swap.image = dst;
  image_barrier(cmd, swap, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                VK_PIPELINE_STAGE_2_BLIT_BIT, 0, VK_PIPELINE_STAGE_2_BLIT_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT);
  VkImageBlit b{};
  b.srcSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  b.srcOffsets[1] = {int32_t(t.width), int32_t(t.height), 1};
  b.dstSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  b.dstOffsets[1] = {int32_t(extent.width), int32_t(extent.height), 1};
  vkCmdBlitImage(cmd, t.color.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, dst, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &b,
                 VK_FILTER_LINEAR);
  image_barrier(cmd, swap, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_PRESENT_SRC_KHR,
                VK_PIPELINE_STAGE_2_BLIT_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_2_NONE, 0);
  image_barrier(cmd, t.color, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_2_BLIT_BIT, VK_ACCESS_2_TRANSFER_READ_BIT,
                VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT);
}

struct Input {
  double last_x = 0, last_y = 0;
  bool dragging = false;
  double speed_scale = 1.0;
  int debug = -1;  // key pressed this frame
  bool print_camera = false;
};

void scroll_callback(GLFWwindow* w, double, double dy) {
  auto* in = static_cast<Input*>(glfwGetWindowUserPointer(w));
  in->speed_scale *= std::pow(1.25, dy);
}

void key_callback(GLFWwindow* w, int key, int, int action, int) {
  if (action != GLFW_PRESS) return;
  auto* in = static_cast<Input*>(glfwGetWindowUserPointer(w));
  if (key >= GLFW_KEY_0 && key <= GLFW_KEY_8) in->debug = key - GLFW_KEY_0;
  if (key == GLFW_KEY_C) in->print_camera = true;
  if (key == GLFW_KEY_ESCAPE) glfwSetWindowShouldClose(w, GLFW_TRUE);
}

}  // namespace

int run_window(const ViewerOptions& options) {
  if (!glfwInit()) {
    std::fprintf(stderr, "terrain-view: cannot open a window (no display? run under xvfb-run, or use --headless)\n");
    return 1;
  }
  if (!glfwVulkanSupported()) {
    glfwTerminate();
    std::fprintf(stderr, "terrain-view: no Vulkan device: GLFW finds no Vulkan loader/driver\n");
    return 77;
  }
  uint32_t ext_count = 0;
  const char** exts = glfwGetRequiredInstanceExtensions(&ext_count);
  std::vector<const char*> instance_extensions(exts, exts + ext_count);
  glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
  GLFWwindow* window = glfwCreateWindow(int(options.width), int(options.height), "terrain-view", nullptr, nullptr);
  if (!window) {
    glfwTerminate();
    std::fprintf(stderr, "terrain-view: cannot create a window\n");
    return 1;
  }
  int code = 0;
  {
    std::unique_ptr<Session> session;
    Status st = open_session(options, instance_extensions, true, session);
    if (!st.ok()) {
      std::fprintf(stderr, "terrain-view: %s\n", st.message.c_str());
      glfwDestroyWindow(window);
      glfwTerminate();
      return is_no_device(st) ? 77 : 1;
    }
    Session& s = *session;
    VkSurfaceKHR surface = VK_NULL_HANDLE;
    Swapchain sc;
    VkSemaphore acquired = VK_NULL_HANDLE, rendered = VK_NULL_HANDLE;
    VkSemaphoreCreateInfo sci{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
    VkBool32 present_ok = VK_FALSE;
    if (glfwCreateWindowSurface(s.ctx.instance, window, nullptr, &surface) != VK_SUCCESS ||
        vkGetPhysicalDeviceSurfaceSupportKHR(s.ctx.physical, s.ctx.queue_family, surface, &present_ok) != VK_SUCCESS ||
        !present_ok)
      st = Status::failure(Error::internal, "the device cannot present to this window");
    if (st.ok()) st = create_swapchain(s.ctx, surface, window, sc);
    if (st.ok() && (vkCreateSemaphore(s.ctx.device, &sci, nullptr, &acquired) != VK_SUCCESS ||
                    vkCreateSemaphore(s.ctx.device, &sci, nullptr, &rendered) != VK_SUCCESS))
      st = Status::failure(Error::internal, "vkCreateSemaphore failed");
    Input input;
    glfwSetWindowUserPointer(window, &input);
    glfwSetScrollCallback(window, scroll_callback);
    glfwSetKeyCallback(window, key_callback);
    Camera camera = initial_camera(s);
    std::vector<PathKey> path;
    if (st.ok() && !options.path_file.empty()) st = load_camera_path(options.path_file, camera.fovy, path);
    int32_t lo = 0, hi = 0;
    s.source->height_range(lo, hi);
    double last = glfwGetTime();
    int frame = 0;
    while (st.ok() && !glfwWindowShouldClose(window) && (options.frames == 0 || frame < options.frames)) {
      glfwPollEvents();
      const double now = glfwGetTime(), dt = std::min(now - last, 0.25);
      last = now;
      if (!path.empty()) {
        const int n = options.frames > 0 ? options.frames : int(path.size());
        const double near = camera.near_m;
        camera = sample_path(path, n <= 1 ? 0.0 : double(frame % n) / double(n - 1));
        camera.near_m = near;
      } else {
        double mx, my;
        glfwGetCursorPos(window, &mx, &my);
        const bool down = glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
        if (down && input.dragging) {
          camera.yaw += (mx - input.last_x) * 0.003;
          camera.pitch = std::clamp(camera.pitch - (my - input.last_y) * 0.003, -1.55, 1.55);
        }
        input.dragging = down;
        input.last_x = mx;
        input.last_y = my;
        const double above = std::max(camera.position[2] - lo / 1024.0, 2.0);
        double speed = std::max(above, 10.0) * 0.6 * input.speed_scale * dt;
        if (glfwGetKey(window, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS) speed *= 5;
        double f[3];
        camera_forward(camera, f);
        const double r[2] = {std::cos(camera.yaw), -std::sin(camera.yaw)};
        auto key = [&](int k) { return glfwGetKey(window, k) == GLFW_PRESS ? 1.0 : 0.0; };
        const double fwd = key(GLFW_KEY_W) - key(GLFW_KEY_S), side = key(GLFW_KEY_D) - key(GLFW_KEY_A);
        const double up = key(GLFW_KEY_E) - key(GLFW_KEY_Q);
        for (int k = 0; k < 3; ++k) camera.position[k] += f[k] * fwd * speed;
        camera.position[0] += r[0] * side * speed;
        camera.position[1] += r[1] * side * speed;
        camera.position[2] += up * speed;
        camera.near_m = std::clamp(above * 0.01, 0.1, 10.0);
      }
      if (input.debug >= 0) {
        s.options.settings.debug = input.debug;
        input.debug = -1;
      }
      if (input.print_camera) {
        std::printf("%.3f %.3f %.3f %.2f %.2f\n", camera.position[0], camera.position[1], camera.position[2],
                    camera.yaw * 180 / M_PI, camera.pitch * 180 / M_PI);
        std::fflush(stdout);
        input.print_camera = false;
      }
      uint32_t image = 0;
      VkResult r = vkAcquireNextImageKHR(s.ctx.device, sc.swapchain, UINT64_MAX, acquired, VK_NULL_HANDLE, &image);
      if (r == VK_ERROR_OUT_OF_DATE_KHR) {
        vkDeviceWaitIdle(s.ctx.device);
        st = create_swapchain(s.ctx, surface, window, sc);
        continue;
      }
      if (r != VK_SUCCESS && r != VK_SUBOPTIMAL_KHR) {
        st = vk_status(r, "vkAcquireNextImageKHR", __FILE__, __LINE__);
        break;
      }
      s.submit_wait = acquired;
      s.submit_signal = rendered;
      FrameRecord rec;
      const VkImage dst = sc.images[image];
      const VkExtent2D extent = sc.extent;
      st = render_frame(s, camera, false, [&](VkCommandBuffer cmd) { record_blit(cmd, s.target, dst, extent); }, rec);
      if (!st.ok()) break;
      VkPresentInfoKHR pi{VK_STRUCTURE_TYPE_PRESENT_INFO_KHR};
      pi.waitSemaphoreCount = 1;
      pi.pWaitSemaphores = &rendered;
      pi.swapchainCount = 1;
      pi.pSwapchains = &sc.swapchain;
      pi.pImageIndices = &image;
      r = vkQueuePresentKHR(s.ctx.queue, &pi);
      if (r == VK_ERROR_OUT_OF_DATE_KHR || r == VK_SUBOPTIMAL_KHR) {
        vkDeviceWaitIdle(s.ctx.device);
        st = create_swapchain(s.ctx, surface, window, sc);
      } else if (r != VK_SUCCESS) {
        st = vk_status(r, "vkQueuePresentKHR", __FILE__, __LINE__);
      }
      char title[160];
      std::snprintf(title, sizeof title, "terrain-view  %.1f ms  %u nodes  %u patches  %u resident", rec.gpu.gpu_total_ms,
                    rec.gpu.nodes, rec.gpu.patches_drawn, rec.source.resident);
      glfwSetWindowTitle(window, title);
      ++frame;
    }
    if (s.ctx.device) vkDeviceWaitIdle(s.ctx.device);
    if (st.ok() && !options.stats_json.empty()) st = write_stats_json(s, options.stats_json);
    if (!st.ok()) {
      std::fprintf(stderr, "terrain-view: %s\n", st.message.c_str());
      code = 1;
    }
    if (acquired) vkDestroySemaphore(s.ctx.device, acquired, nullptr);
    if (rendered) vkDestroySemaphore(s.ctx.device, rendered, nullptr);
    if (sc.swapchain) vkDestroySwapchainKHR(s.ctx.device, sc.swapchain, nullptr);
    if (surface) vkDestroySurfaceKHR(s.ctx.instance, surface, nullptr);
    s.submit_wait = s.submit_signal = VK_NULL_HANDLE;
  }
  glfwDestroyWindow(window);
  glfwTerminate();
  return code;
}

}  // namespace terrain::view
