// One viewer run: node source, Vulkan context, renderer, offscreen target and the per-frame step
// shared by the headless loop, the window loop and the benchmark.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "app.h"
#include "device.h"
#include "renderer.h"
#include "sources.h"

namespace terrain::view {

struct FrameRecord {
  int frame = 0;
  double cpu_ms = 0;    // source update + staging + command recording
  double upload_ms = 0; // of which staging the delivered nodes (decoding, lighting, patch bounds and errors)
  double wait_ms = 0;   // submit to fence (the GPU frame on lavapipe)
  FrameStats gpu;
  SourceStats source;
  Camera camera;
};

struct Session {
  ViewerOptions options;
  std::unique_ptr<NodeSource> source;
  Context ctx;
  TerrainRenderer renderer;
  RenderTarget target;
  TerrainState state;
  VkCommandPool pool = VK_NULL_HANDLE;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  VkFence fence = VK_NULL_HANDLE;
  std::vector<FrameRecord> records;
  // Window mode: the submit waits for `submit_wait` (swapchain acquire) and signals `submit_signal`.
  VkSemaphore submit_wait = VK_NULL_HANDLE, submit_signal = VK_NULL_HANDLE;
  bool capture_lists = false;  // copy node list, LOD map and patch list for read_lists() (tests, bench)
  bool warned_overflow = false, warned_stitch = false;  // each warning once per session
  ~Session();
};

// Opens the source and the device. `instance_extensions`/`swapchain` for window mode.
// Returns Error::unsupported_input with "no Vulkan device" when there is none.
Status open_session(const ViewerOptions& options, const std::vector<const char*>& instance_extensions, bool swapchain,
                    std::unique_ptr<Session>& out);

// A camera that frames the whole archive from the south, unless the options place one.
Camera initial_camera(const Session& session);

// Updates the source, uploads, records and submits one frame and waits for it. `extra` (may be
// empty) records more commands after the terrain (e.g. the blit to a swapchain image); with
// `readback` the colour and depth are copied for read_color/read_depth.
template <class Extra>
Status render_frame(Session& s, const Camera& camera, bool readback, Extra&& extra, FrameRecord& record);
Status render_frame(Session& s, const Camera& camera, bool readback, FrameRecord& record);

Status write_stats_json(const Session& s, const std::string& path);

// Implementation detail of the template.
Status begin_frame(Session& s, const Camera& camera, FrameRecord& record, double& cpu_start_ms);
Status end_frame(Session& s, bool readback, FrameRecord& record, double cpu_start_ms, void (*extra)(void*, VkCommandBuffer),
                 void* extra_user);

template <class Extra>
Status render_frame(Session& s, const Camera& camera, bool readback, Extra&& extra, FrameRecord& record) {
  double start = 0;
  TERRAIN_TRY(begin_frame(s, camera, record, start));
  auto thunk = [](void* user, VkCommandBuffer cmd) { (*static_cast<std::remove_reference_t<Extra>*>(user))(cmd); };
  return end_frame(s, readback, record, start, thunk, &extra);
}

double now_ms();

}  // namespace terrain::view
