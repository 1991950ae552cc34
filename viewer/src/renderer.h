// The terrain pass (FC5 sections 4-7 on Vulkan): texture-array atlases filled from node
// deliveries, the root grid, tree buffer and descriptor buffer mirrored from the residency state, and per
// frame: traversal -> LOD map -> patch list (compute) -> one indexed-indirect instanced draw.
// One frame in flight: the caller waits for a frame's fence before the next upload()/record_frame().
#pragma once
#include <array>
#include <map>
#include <cstdint>
#include <span>
#include <vector>

#include "camera.h"
#include "far_light.h"
#include "node_prep.h"
#include "resources.h"
#include "target.h"
#include "terrain_state.h"

namespace terrain::view {

struct RendererConfig {
  uint32_t slot_count = 512;  // atlas layers (the streamer's slot_count())
  // Normal and albedo atlases as RGBA8, decoded from the BC payload at upload, instead of BC3/BC1.
  // 4x the memory, but a CPU rasteriser (lavapipe) decodes a BC block for every bilinear tap, which
  // costs more than all the rest of the far shading (see viewer/README.md).
  bool decode_bc = false;
  // The far group lit per texel at upload (far_light.h) with this sun, into a third RGBA8 atlas;
  // implies decode_bc. Frames with another sun, and debug views, light per pixel as without it.
  bool prelit_far = false;
  // Threads that prepare a frame's delivered nodes (decoding, lighting, bounds and errors); 0 = one
  // per hardware thread.
  unsigned upload_threads = 0;
  double lit_sun_azimuth_deg = kDefaultSunAzimuthDeg, lit_sun_elevation_deg = kDefaultSunElevationDeg;
};

struct FrameSettings {
  double error_target_px = 2.0;
  bool frustum_cull = true;
  bool cone_cull = true;
  bool holes = true;          // drop triangles of hole vertices
  bool hole_nan = false;      // ... by a NaN clip position (undefined behaviour, checked on lavapipe
                              // by a test); false: fragment discard (defined, but disables early depth)
  bool splat = true;          // near splat shading
  bool stitch = true;         // false only in tests: shows the cracks stitching closes
  bool decimate = true;       // per-patch decimation of roots (config.h "Patch decimation")
  int debug = TV_DEBUG_NONE;
  // Profiling (terrain-view-bench --profile): draw the same patches with less of the pipeline to
  // split the draw time. kFull: everything; kFlat: constant-colour fragments (vertex + setup +
  // raster + depth); kVertexOnly: rasterizer discard (vertex shading + primitive assembly + clipping).
  enum class DrawProfile { kFull, kFlat, kVertexOnly };
  DrawProfile profile = DrawProfile::kFull;
  float clear[3] = {0.55f, 0.68f, 0.85f};  // sRGB-encoded, 0..1
  double cone_margin_deg = 0.0;
  double near_start_m = 150, near_end_m = 400;   // splat shading fades into the baked albedo
  double sun_azimuth_deg = kDefaultSunAzimuthDeg, sun_elevation_deg = kDefaultSunElevationDeg;
  double fog_density = 1.0 / 60000.0;
};

struct FrameStats {
  uint32_t nodes = 0;
  std::array<uint32_t, kMaxLevels> level_counts{};  // levels 6+: coarsened roots are counted at 5
  uint32_t traversal_overflow = 0;  // list entries that did not fit (0 by construction; warned)
  uint32_t stitch_clamped = 0;      // patch edges facing a neighbour coarser by d > 7 (may crack; warned)
  uint32_t patches_considered = 0, patches_drawn = 0, culled_frustum = 0, culled_cone = 0;
  uint32_t patches_near = 0;  // of patches_drawn, in the near (splat) shading group
  std::array<uint32_t, TV_MESHES> patches_decimated{};  // of patches_drawn, per decimation e
  uint64_t triangles = 0;
  double gpu_traverse_ms = 0, gpu_lodmap_ms = 0, gpu_patches_ms = 0, gpu_draw_ms = 0, gpu_total_ms = 0;
  bool timings_valid = false;
};

class TerrainRenderer {
 public:
  TerrainRenderer() = default;
  ~TerrainRenderer();
  TerrainRenderer(const TerrainRenderer&) = delete;
  TerrainRenderer& operator=(const TerrainRenderer&) = delete;

  Status init(const Context& ctx, const WorldInfo& world, const RendererConfig& config);
  void destroy();

  // Stages node payloads (into their atlas layers) and the dirty parts of `state` (descriptors,
  // index rectangles); the copies are recorded at the start of the next record_frame().
  Status upload(std::span<const NodeUpload> nodes, TerrainState& state);

  // Sets camera and settings for the next record_frame().
  void set_frame(const Camera& camera, const FrameSettings& settings, uint32_t width, uint32_t height);
  const FrameUniforms& uniforms() const { return uniforms_; }
  const float* cone_sin2_table() const { return cone_table_; }

  // Uploads, traversal, LOD map, patches, draw into `target` (cleared), then copies counters (and,
  // with capture_lists, the node list, LOD map and patch list) for reading after the fence.
  void record_frame(VkCommandBuffer cmd, const RenderTarget& target, bool capture_lists);

  FrameStats read_stats() const;
  // Valid after a frame recorded with capture_lists.
  void read_lists(NodeList& nodes, std::vector<uint32_t>& lod_map, std::vector<GpuPatch>& patches) const;
  // Per-slot bounds and cones as uploaded (for the CPU reference).
  const std::vector<SlotCpuData>& slot_cpu() const { return slot_cpu_; }

 private:
  struct PendingImageCopy {
    int image;  // index into atlas images
    VkBufferImageCopy region;
  };
  struct PendingBufferCopy {
    VkBuffer dst;
    VkBufferCopy region;
  };
  Status stage_bytes(const void* data, size_t size, size_t align, VkDeviceSize& offset);
  // Room for `size` bytes in the staging buffer (grown as needed) at `offset`, to be written by the caller.
  Status stage_reserve(size_t size, size_t align, VkDeviceSize& offset);
  Status create_pipelines();
  // Graphics pipeline specialised for (debug view, shading group, wire overlay, far lighting per
  // texel), made on first use.
  VkPipeline graphics_pipeline(int debug, bool near, bool wire, bool prelit = false);
  // Whether this frame's far group can read the lit atlas: it was lit with this frame's sun, and the
  // frame shows the terrain's colours (not a debug view).
  bool far_prelit() const {
    return config_.prelit_far && (settings_.debug == TV_DEBUG_NONE || settings_.debug == TV_DEBUG_WIRE) &&
           settings_.sun_azimuth_deg == config_.lit_sun_azimuth_deg &&
           settings_.sun_elevation_deg == config_.lit_sun_elevation_deg;
  }

  const Context* ctx_ = nullptr;
  WorldInfo world_;
  RendererConfig config_;
  uint32_t sectors_x_ = 0, sectors_y_ = 0;
  size_t lod_map_uints_ = 0;
  uint32_t top_level_ = kRootLevel;  // of the state last uploaded  // LOD map window (at most 512 x 512 sectors) + one cell per root

  // Atlases: 0 heights R16_UINT, 1 normals BC3, 2 albedo BC1 sRGB, 3 splat R8_UINT, 4 cones BC3, 5 index,
  // 6 lit far colour RGBA8 (prelit_far; else one texel).
  std::array<Image, 7> images_;
  TexelLighting lit_light_;  // the light of the lit atlas (prelit_far only)
  bool images_initialised_ = false;
  VkSampler linear_ = VK_NULL_HANDLE, nearest_ = VK_NULL_HANDLE;

  Buffer uniforms_buf_, palette_buf_, node_desc_, patch_bounds_, coarse_errors_, patch_errors_, patch_work_, node_list_, lod_map_, draw_, patches_,
      lists_, tree_, index_buffer_, stats_readback_, lists_readback_;
  bool lists_captured_ = false;
  Buffer staging_;
  VkDeviceSize staging_used_ = 0;
  std::vector<PendingImageCopy> pending_images_;
  std::vector<PendingBufferCopy> pending_buffers_;
  std::vector<uint8_t> scratch_;

  VkDescriptorSetLayout set_layout_ = VK_NULL_HANDLE;
  VkPipelineLayout pipeline_layout_ = VK_NULL_HANDLE;
  VkDescriptorPool descriptor_pool_ = VK_NULL_HANDLE;
  VkDescriptorSet set_ = VK_NULL_HANDLE;
  VkPipeline traverse_ = VK_NULL_HANDLE, lodmap_ = VK_NULL_HANDLE, patches_pipe_ = VK_NULL_HANDLE;
  VkShaderModule vs_ = VK_NULL_HANDLE, fs_ = VK_NULL_HANDLE;
  std::map<int, VkPipeline> graphics_;  // key: (profile * 16 + debug) * 8 + discard * 4 + near * 2 + wire
  VkQueryPool queries_ = VK_NULL_HANDLE;
  bool timestamps_ = false;

  FrameUniforms uniforms_{};
  FrameSettings settings_{};
  float cone_table_[256] = {};
  std::vector<SlotCpuData> slot_cpu_;
};

}  // namespace terrain::view
