#include "session.h"

#include <cstdio>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>

#include <malloc.h>

#include "vk_common.h"

namespace terrain::view {

double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

Session::~Session() {
  if (ctx.device) {
    vkDeviceWaitIdle(ctx.device);
    renderer.destroy();
    destroy_target(ctx, target);
    if (fence) vkDestroyFence(ctx.device, fence, nullptr);
    if (pool) vkDestroyCommandPool(ctx.device, pool, nullptr);
  }
  destroy_context(ctx);
}

Status open_session(const ViewerOptions& o, const std::vector<const char*>& instance_extensions, bool swapchain,
                    std::unique_ptr<Session>& out) {
  auto s = std::make_unique<Session>();
  s->options = o;
  // The device first: without one there is nothing to do (exit 77), whatever the archive.
  DeviceOptions d;
  d.validation = o.validation;
  d.instance_extensions = instance_extensions;
  d.swapchain = swapchain;
  d.quiet = o.quiet;
  TERRAIN_TRY(create_context(d, s->ctx));
  if (s->ctx.properties.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU) {
    // lavapipe allocates and frees tens of MB of vertex and bin memory per frame; with glibc's
    // defaults that memory goes back to the kernel each time and every frame pays page faults
    // (a third of the vertex stage measured). Keep it in the heap instead.
    mallopt(M_MMAP_THRESHOLD, 256 << 20);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
  }
  if (o.load_all) {
    TERRAIN_TRY(open_load_all_source(o.archive, 8192, s->source));
  } else {
    StreamSourceOptions so;
    so.budget_nodes = o.budget_nodes;
    so.error_target_px = o.settings.error_target_px;
    so.worker_threads = o.worker_threads;
    so.max_deliveries_per_frame = o.max_deliveries;
    so.http.cache_dir = o.cache_dir;
    so.http.cache_limit_bytes = o.cache_limit_mb << 20;
    TERRAIN_TRY(open_stream_source(o.archive, so, s->source));
  }
  // Hole method: the NaN clip position where it is known to work (lavapipe: ViewerGpu tests).
  s->options.settings.hole_nan =
      o.holes == "nan" || (o.holes == "auto" && s->ctx.device_name.find("llvmpipe") != std::string::npos);
  RendererConfig rc;
  rc.slot_count = s->source->slot_count();
  const bool cpu_device = s->ctx.properties.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
  rc.decode_bc = o.atlas == "rgba8" || (o.atlas == "auto" && cpu_device);
  rc.prelit_far = o.far_light == "texel" || (o.far_light == "auto" && cpu_device);
  rc.upload_threads = o.upload_threads;
  rc.lit_sun_azimuth_deg = o.settings.sun_azimuth_deg;
  rc.lit_sun_elevation_deg = o.settings.sun_elevation_deg;
  TERRAIN_TRY(s->renderer.init(s->ctx, s->source->world(), rc));
  TERRAIN_TRY(create_target(s->ctx, o.width, o.height, s->target));
  VkCommandPoolCreateInfo pci{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pci.queueFamilyIndex = s->ctx.queue_family;
  VK_TRY(vkCreateCommandPool(s->ctx.device, &pci, nullptr, &s->pool));
  TERRAIN_TRY(allocate_command_buffer(s->ctx, s->pool, s->cmd));
  VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  VK_TRY(vkCreateFence(s->ctx.device, &fci, nullptr, &s->fence));
  out = std::move(s);
  return Status::success();
}

Camera initial_camera(const Session& s) {
  const WorldInfo& w = s.source->world();
  const ViewerOptions& o = s.options;
  Camera c;
  c.fovy = o.fovy_deg * M_PI / 180.0;
  int32_t lo = 0, hi = 0;
  s.source->height_range(lo, hi);
  const double cx = 0.5 * (w.extent_min_x_m + w.extent_max_x_m), cy = 0.5 * (w.extent_min_y_m + w.extent_max_y_m);
  const double extent = std::max(w.extent_max_x_m - w.extent_min_x_m, w.extent_max_y_m - w.extent_min_y_m);
  const double centre[3] = {cx, cy, 0.5 * (lo + hi) / 1024.0};
  if (o.camera) {
    for (int k = 0; k < 3; ++k) c.position[k] = (*o.camera)[size_t(k)];
  } else {
    c.position[0] = cx;
    c.position[1] = cy - 0.55 * extent;
    c.position[2] = hi / 1024.0 + 0.4 * extent;
  }
  if (o.look_at) {
    const double t[3] = {(*o.look_at)[0], (*o.look_at)[1], (*o.look_at)[2]};
    look_at(c, t);
  } else if (o.yaw_deg || o.pitch_deg) {
    c.yaw = o.yaw_deg.value_or(0.0) * M_PI / 180.0;
    c.pitch = o.pitch_deg.value_or(0.0) * M_PI / 180.0;
  } else {
    look_at(c, centre);
  }
  // Near plane: a fraction of the height above the lowest terrain, within [0.1, 10] m.
  c.near_m = std::clamp((c.position[2] - lo / 1024.0) * 0.01, 0.1, 10.0);
  return c;
}

Status begin_frame(Session& s, const Camera& camera, FrameRecord& rec, double& start) {
  start = now_ms();
  rec.camera = camera;
  s.renderer.set_frame(camera, s.options.settings, s.target.width, s.target.height);
  std::vector<NodeUpload> uploads;
  TERRAIN_TRY(s.source->update(camera, s.renderer.uniforms(), s.state, uploads));
  const double upload = now_ms();
  TERRAIN_TRY(s.renderer.upload(uploads, s.state));
  rec.upload_ms = now_ms() - upload;
  rec.source = s.source->stats();
  return Status::success();
}

Status end_frame(Session& s, bool readback, FrameRecord& rec, double start, void (*extra)(void*, VkCommandBuffer),
                 void* extra_user) {
  VK_TRY(vkResetCommandBuffer(s.cmd, 0));
  VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  VK_TRY(vkBeginCommandBuffer(s.cmd, &bi));
  s.renderer.record_frame(s.cmd, s.target, s.capture_lists);
  if (readback) record_readback(s.cmd, s.target);
  if (extra) extra(extra_user, s.cmd);
  VK_TRY(vkEndCommandBuffer(s.cmd));
  rec.cpu_ms = now_ms() - start;
  const double submit = now_ms();
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.commandBufferCount = 1;
  si.pCommandBuffers = &s.cmd;
  const VkPipelineStageFlags wait_stage = VK_PIPELINE_STAGE_TRANSFER_BIT;
  if (s.submit_wait) {
    si.waitSemaphoreCount = 1;
    si.pWaitSemaphores = &s.submit_wait;
    si.pWaitDstStageMask = &wait_stage;
  }
  if (s.submit_signal) {
    si.signalSemaphoreCount = 1;
    si.pSignalSemaphores = &s.submit_signal;
  }
  VK_TRY(vkResetFences(s.ctx.device, 1, &s.fence));
  VK_TRY(vkQueueSubmit(s.ctx.queue, 1, &si, s.fence));
  VK_TRY(vkWaitForFences(s.ctx.device, 1, &s.fence, VK_TRUE, UINT64_MAX));
  rec.wait_ms = now_ms() - submit;
  rec.gpu = s.renderer.read_stats();
  rec.frame = int(s.records.size());
  // Bounds that are not supposed to bind: say so once rather than lose detail or crack silently.
  if (rec.gpu.traversal_overflow > 0 && !s.warned_overflow) {
    s.warned_overflow = true;
    std::fprintf(stderr, "terrain-view: warning: %u traversal list entries did not fit (frame %d); nodes were not split\n",
                 rec.gpu.traversal_overflow, rec.frame);
  }
  if (rec.gpu.stitch_clamped > 0 && !s.warned_stitch) {
    s.warned_stitch = true;
    std::fprintf(stderr,
                 "terrain-view: warning: %u patch edges face a neighbour more than 7 levels coarser (frame %d); "
                 "their stitch is clamped to 7 and may crack\n",
                 rec.gpu.stitch_clamped, rec.frame);
  }
  s.records.push_back(rec);
  return Status::success();
}

Status render_frame(Session& s, const Camera& camera, bool readback, FrameRecord& record) {
  double start = 0;
  TERRAIN_TRY(begin_frame(s, camera, record, start));
  return end_frame(s, readback, record, start, nullptr, nullptr);
}

Status write_stats_json(const Session& s, const std::string& path) {
  using nlohmann::json;
  json frames = json::array();
  std::vector<double> totals, traversal, culling, draw;
  for (const FrameRecord& r : s.records) {
    json f;
    f["frame"] = r.frame;
    f["camera"] = {r.camera.position[0], r.camera.position[1], r.camera.position[2]};
    f["cpu_ms"] = r.cpu_ms;
    f["upload_ms"] = r.upload_ms;
    f["frame_ms"] = r.wait_ms;
    f["gpu_traversal_ms"] = r.gpu.gpu_traverse_ms;
    f["gpu_lodmap_ms"] = r.gpu.gpu_lodmap_ms;
    f["gpu_patches_ms"] = r.gpu.gpu_patches_ms;
    f["gpu_draw_ms"] = r.gpu.gpu_draw_ms;
    f["gpu_total_ms"] = r.gpu.gpu_total_ms;
    f["nodes"] = r.gpu.nodes;
    f["nodes_per_level"] = r.gpu.level_counts;
    f["patches_considered"] = r.gpu.patches_considered;
    f["patches_drawn"] = r.gpu.patches_drawn;
    f["patches_culled_frustum"] = r.gpu.culled_frustum;
    f["patches_culled_cone"] = r.gpu.culled_cone;
    f["patches_per_decimation"] = r.gpu.patches_decimated;  // e = 0..4
    f["triangles"] = r.gpu.triangles;
    f["traversal_overflow"] = r.gpu.traversal_overflow;
    f["stitch_clamped"] = r.gpu.stitch_clamped;
    f["resident"] = r.source.resident;
    f["delivered"] = r.source.delivered;
    f["evicted"] = r.source.evicted;
    f["pending"] = r.source.pending;
    f["required_missing"] = r.source.required_missing;
    frames.push_back(f);
    totals.push_back(r.gpu.gpu_total_ms);
    traversal.push_back(r.gpu.gpu_traverse_ms);
    culling.push_back(r.gpu.gpu_lodmap_ms + r.gpu.gpu_patches_ms);
    draw.push_back(r.gpu.gpu_draw_ms);
  }
  auto median = [](std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  json j;
  j["archive"] = s.options.archive;
  j["device"] = s.ctx.device_name;
  j["size"] = {s.target.width, s.target.height};
  j["error_target_px"] = s.options.settings.error_target_px;
  j["frames"] = frames;
  j["median"] = {{"gpu_total_ms", median(totals)},
                 {"gpu_traversal_ms", median(traversal)},
                 {"gpu_culling_ms", median(culling)},
                 {"gpu_draw_ms", median(draw)}};
  std::ofstream f(path);
  if (!f) return Status::failure(Error::io_open, "cannot write " + path);
  f << j.dump(2) << "\n";
  if (!f) return Status::failure(Error::io_write, "cannot write " + path);
  return Status::success();
}

}  // namespace terrain::view
