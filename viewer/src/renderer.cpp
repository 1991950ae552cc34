#include "renderer.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <new>
#include <string>

#include "parallel.h"
#include "shaders.h"
#include "terrain/bc_decode.h"
#include "vk_common.h"

namespace terrain::view {
namespace {

enum AtlasImage { kHeights = 0, kNormals = 1, kAlbedo = 2, kSplat = 3, kCones = 4, kRoots = 5, kLit = 6 };

enum Binding : uint32_t {
  kBindFrame = 0,
  kBindNodeDesc = 1,
  kBindPatchBounds = 2,
  kBindRootTex = 3,
  kBindNodeList = 4,
  kBindPatchWork = 5,
  kBindLodMap = 6,
  kBindDraw = 7,
  kBindPatches = 8,
  kBindHeights = 9,
  kBindNormals = 10,
  kBindAlbedo = 11,
  kBindSplat = 12,
  kBindCones = 13,
  kBindPalette = 14,
  kBindCoarseErrors = 15,
  kBindPatchErrors = 16,
  kBindLists = 17,
  kBindTree = 18,
  kBindLit = 19,
  kBindCount = 20,
};

// The patch meshes of every decimation e, one after the other: (16 >> e)^2 quads each.
constexpr uint32_t mesh_indices(uint32_t e) { return (uint32_t(TV_QUADS_PER_PATCH) >> e) * (uint32_t(TV_QUADS_PER_PATCH) >> e) * 6; }
constexpr uint32_t kMeshIndices = mesh_indices(0) + mesh_indices(1) + mesh_indices(2) + mesh_indices(3) + mesh_indices(4);
static_assert(TV_MESHES == 5);
constexpr uint32_t kTimestamps = 5;

float srgb_to_linear(uint8_t v) {
  const double c = v / 255.0;
  return float(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
}

struct PaletteBlock {
  GpuMaterial materials[TV_MAX_MATERIALS];
  float cone_sin2[256];
};

}  // namespace

TerrainRenderer::~TerrainRenderer() { destroy(); }

Status TerrainRenderer::init(const Context& ctx, const WorldInfo& world, const RendererConfig& config) {
  destroy();
  ctx_ = &ctx;
  world_ = world;
  config_ = config;
  if (config.prelit_far) lit_light_ = texel_lighting(scene_light(config.lit_sun_azimuth_deg, config.lit_sun_elevation_deg));
  if (config.slot_count == 0 || config.slot_count > TV_SLOT_INVALID)
    return Status::failure(Error::invalid_argument, "renderer: slot_count must be 1..65534");
  if (world.roots_x == 0 || world.roots_y == 0) return Status::failure(Error::invalid_argument, "renderer: empty world");
  top_level_ = uint32_t(top_level(world));
  sectors_x_ = level_grid_width(world.roots_x, 0);
  sectors_y_ = level_grid_width(world.roots_y, 0);
  // The root grid is an image of a texel per root (the residency index below the roots is the tree
  // buffer, terrain/surface_contract.h): a world wider than the device's largest 2D image cannot be
  // drawn (archives reach kStreamerMaxRootsPerSide roots per side; Vulkan guarantees 4096 texels).
  // Said before any allocation.
  const uint32_t max_side = ctx.properties.limits.maxImageDimension2D;
  if (world.roots_x > max_side || world.roots_y > max_side)
    return Status::failure(Error::unsupported_input,
                           "the archive is " + std::to_string(world.roots_x) + " x " + std::to_string(world.roots_y) +
                               " roots and this device (" + ctx.device_name + ") allows images of " +
                               std::to_string(max_side) + " texels per side: at most " + std::to_string(max_side) +
                               " roots per side");
  lod_map_uints_ = size_t(std::min<uint32_t>(world.roots_x, TV_LODMAP_WINDOW_ROOTS) << kRootLevel) *
                       (std::min<uint32_t>(world.roots_y, TV_LODMAP_WINDOW_ROOTS) << kRootLevel) +
                   size_t(world.roots_x) * world.roots_y;
  const uint32_t slots = config.slot_count;
  slot_cpu_.assign(slots, SlotCpuData{});

  // Atlases.
  const VkImageUsageFlags tex_usage = VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
  TERRAIN_TRY(create_image(ctx, VK_FORMAT_R16_UINT, kHeightSamples, kHeightSamples, slots, 1, tex_usage,
                      VK_IMAGE_ASPECT_COLOR_BIT, true, images_[kHeights]));
  const bool decode = config.decode_bc || config.prelit_far;
  TERRAIN_TRY(create_image(ctx, decode ? VK_FORMAT_R8G8B8A8_UNORM : VK_FORMAT_BC3_UNORM_BLOCK, kTexels, kTexels,
                      slots, 1, tex_usage, VK_IMAGE_ASPECT_COLOR_BIT, true, images_[kNormals]));
  // Albedo is sRGB-encoded; the shader linearises it after filtering (cheaper than sRGB sampling).
  TERRAIN_TRY(create_image(ctx, decode ? VK_FORMAT_R8G8B8A8_UNORM : VK_FORMAT_BC1_RGBA_UNORM_BLOCK, kTexels, kTexels,
                      slots, 1, tex_usage, VK_IMAGE_ASPECT_COLOR_BIT, true, images_[kAlbedo]));
  TERRAIN_TRY(create_image(ctx, VK_FORMAT_R8_UINT, kSplatSamples, kSplatSamples, slots, 1, tex_usage,
                      VK_IMAGE_ASPECT_COLOR_BIT, true, images_[kSplat]));
  TERRAIN_TRY(create_image(ctx, VK_FORMAT_BC3_UNORM_BLOCK, kPatchesPerSide, kPatchesPerSide, slots, 1, tex_usage,
                      VK_IMAGE_ASPECT_COLOR_BIT, true, images_[kCones]));
  TERRAIN_TRY(create_image(ctx, VK_FORMAT_R16_UINT, world.roots_x, world.roots_y, 1, 1, tex_usage, VK_IMAGE_ASPECT_COLOR_BIT,
                      false, images_[kRoots]));
  // The lit far atlas (far_light.h), or a one-texel stand-in that keeps its binding valid.
  TERRAIN_TRY(create_image(ctx, VK_FORMAT_R8G8B8A8_UNORM, config.prelit_far ? kTexels : 1, config.prelit_far ? kTexels : 1,
                      config.prelit_far ? slots : 1, 1, tex_usage, VK_IMAGE_ASPECT_COLOR_BIT, true, images_[kLit]));
  const char* names[7] = {"atlas.heights", "atlas.normals", "atlas.albedo", "atlas.splat", "atlas.cones", "roots", "atlas.lit"};
  for (int i = 0; i < 7; ++i) set_debug_name(ctx, VK_OBJECT_TYPE_IMAGE, uint64_t(images_[size_t(i)].image), names[i]);

  VkSamplerCreateInfo sci{VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO};
  sci.magFilter = sci.minFilter = VK_FILTER_LINEAR;
  sci.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
  sci.addressModeU = sci.addressModeV = sci.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
  sci.maxLod = 0;
  VK_TRY(vkCreateSampler(ctx.device, &sci, nullptr, &linear_));
  sci.magFilter = sci.minFilter = VK_FILTER_NEAREST;
  sci.maxLod = VK_LOD_CLAMP_NONE;
  VK_TRY(vkCreateSampler(ctx.device, &sci, nullptr, &nearest_));

  // Buffers.
  const VkBufferUsageFlags storage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                                     VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
  TERRAIN_TRY(create_host_buffer(ctx, sizeof(FrameUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, uniforms_buf_));
  TERRAIN_TRY(create_host_buffer(ctx, sizeof(PaletteBlock), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, palette_buf_));
  TERRAIN_TRY(create_device_buffer(ctx, VkDeviceSize(slots) * sizeof(GpuNodeDesc), storage, node_desc_));
  TERRAIN_TRY(create_device_buffer(ctx, VkDeviceSize(slots) * TV_PATCHES_PER_NODE * sizeof(GpuPatchBounds), storage,
                              patch_bounds_));
  TERRAIN_TRY(create_device_buffer(ctx, VkDeviceSize(slots) * 16, storage, coarse_errors_));
  TERRAIN_TRY(create_device_buffer(ctx, VkDeviceSize(slots) * TV_PATCH_ERRORS_PER_NODE * 16, storage, patch_errors_));
  TERRAIN_TRY(create_device_buffer(ctx, VkDeviceSize(slots) * TV_PATCHES_PER_NODE * 4, storage, patch_work_));
  TERRAIN_TRY(create_device_buffer(ctx, VkDeviceSize(TV_NL_HEADER + slots) * 4,
                              storage | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT, node_list_));
  TERRAIN_TRY(create_device_buffer(ctx, VkDeviceSize(lod_map_uints_) * 4, storage, lod_map_));
  TERRAIN_TRY(create_device_buffer(ctx, VkDeviceSize(slots) * 2 * 4, storage, lists_));
  TERRAIN_TRY(create_device_buffer(ctx, VkDeviceSize(index_tree_words(slots)) * 4, storage, tree_));
  TERRAIN_TRY(create_device_buffer(ctx, TV_DRAW_UINTS * 4, storage | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT, draw_));
  // Patch range r (shading group x decimation) from instance r * capacity (config.h, shading groups).
  const VkDeviceSize patch_list_bytes = TV_PATCH_RANGES * VkDeviceSize(slots) * TV_PATCHES_PER_NODE * sizeof(GpuPatch);
  TERRAIN_TRY(create_device_buffer(ctx, patch_list_bytes, storage, patches_));
  TERRAIN_TRY(create_device_buffer(ctx, kMeshIndices * 2, VK_BUFFER_USAGE_INDEX_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                              index_buffer_));
  TERRAIN_TRY(create_host_buffer(ctx, (TV_NL_HEADER + TV_DRAW_UINTS) * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT, stats_readback_));
  TERRAIN_TRY(create_host_buffer(ctx,
                            VkDeviceSize(TV_NL_HEADER + slots) * 4 + VkDeviceSize(lod_map_uints_) * 4 +
                                patch_list_bytes,
                            VK_BUFFER_USAGE_TRANSFER_DST_BIT, lists_readback_));
  TERRAIN_TRY(create_host_buffer(ctx, 8u << 20, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, staging_));

  // Palette (sRGB -> linear) and the cone table are written at set_frame(); the grid indices now.
  PaletteBlock* pb = new (palette_buf_.mapped) PaletteBlock{};
  // Without an orthophoto the baked albedo is the palette blend times a variation the near
  // shading carries over (detail.w = 1, terrain.frag); a photo is no palette colour (0).
  const size_t photo_at = world.cook_info_json.find("\"albedo\":\"");
  const bool photo = photo_at != std::string::npos && world.cook_info_json.size() > photo_at + 10 &&
                     world.cook_info_json[photo_at + 10] != '"';
  for (size_t m = 0; m < TV_MAX_MATERIALS; ++m) {
    GpuMaterial& g = pb->materials[m];
    if (m < world.palette.size()) {
      const Material& src = world.palette[m];
      for (int k = 0; k < 3; ++k) g.albedo_roughness[k] = srgb_to_linear(src.albedo_srgb[size_t(k)]);
      g.albedo_roughness[3] = src.roughness;
      g.detail[0] = src.detail_scale_m;
      g.detail[1] = src.detail_strength;
      g.detail[2] = src.height_blend;
      g.detail[3] = photo ? 0.0f : 1.0f;
    } else {  // ids outside the palette show as neutral grey
      g.albedo_roughness[0] = g.albedo_roughness[1] = g.albedo_roughness[2] = 0.25f;
      g.detail[0] = 4;
    }
  }
  std::vector<uint16_t> indices;
  indices.reserve(kMeshIndices);
  for (int e = 0; e < TV_MESHES; ++e) {
    const int n = TV_QUADS_PER_PATCH >> e;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const uint16_t v00 = uint16_t(j * (n + 1) + i), v10 = uint16_t(v00 + 1);
        const uint16_t v01 = uint16_t(v00 + n + 1), v11 = uint16_t(v01 + 1);
        // Split along the SW->NE diagonal, counter-clockwise seen from above (format/SPEC.md).
        for (uint16_t v : {v00, v10, v11, v00, v11, v01}) indices.push_back(v);
      }
  }
  VkDeviceSize off = 0;
  TERRAIN_TRY(stage_bytes(indices.data(), indices.size() * 2, 16, off));
  pending_buffers_.push_back({index_buffer_.buffer, {off, 0, indices.size() * 2}});

  TERRAIN_TRY(create_pipelines());

  timestamps_ = ctx.properties.limits.timestampComputeAndGraphics && ctx.properties.limits.timestampPeriod > 0;
  if (timestamps_) {
    VkQueryPoolCreateInfo qci{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    qci.queryType = VK_QUERY_TYPE_TIMESTAMP;
    qci.queryCount = kTimestamps;
    VK_TRY(vkCreateQueryPool(ctx.device, &qci, nullptr, &queries_));
  }
  return Status::success();
}

Status TerrainRenderer::create_pipelines() {
  const Context& ctx = *ctx_;
  VkDescriptorSetLayoutBinding b[kBindCount];
  for (uint32_t i = 0; i < kBindCount; ++i) {
    b[i] = {};
    b[i].binding = i;
    b[i].descriptorCount = 1;
    b[i].stageFlags = VK_SHADER_STAGE_COMPUTE_BIT | VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT;
    b[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  }
  b[kBindFrame].descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
  b[kBindPalette].descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
  for (uint32_t t : {kBindRootTex, kBindHeights, kBindNormals, kBindAlbedo, kBindSplat, kBindCones, kBindLit})
    b[t].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  VkDescriptorSetLayoutCreateInfo lci{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  lci.bindingCount = kBindCount;
  lci.pBindings = b;
  VK_TRY(vkCreateDescriptorSetLayout(ctx.device, &lci, nullptr, &set_layout_));
  VkPipelineLayoutCreateInfo plci{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  plci.setLayoutCount = 1;
  plci.pSetLayouts = &set_layout_;
  VK_TRY(vkCreatePipelineLayout(ctx.device, &plci, nullptr, &pipeline_layout_));

  // Pool sizes counted from the layout itself, so they cannot drift from the bindings.
  VkDescriptorPoolSize sizes[3] = {{VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 0},
                                   {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 0},
                                   {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 0}};
  for (const VkDescriptorSetLayoutBinding& binding : b)
    for (VkDescriptorPoolSize& size : sizes)
      if (size.type == binding.descriptorType) size.descriptorCount += binding.descriptorCount;
  VkDescriptorPoolCreateInfo dpci{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  dpci.maxSets = 1;
  dpci.poolSizeCount = 3;
  dpci.pPoolSizes = sizes;
  VK_TRY(vkCreateDescriptorPool(ctx.device, &dpci, nullptr, &descriptor_pool_));
  VkDescriptorSetAllocateInfo dsai{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  dsai.descriptorPool = descriptor_pool_;
  dsai.descriptorSetCount = 1;
  dsai.pSetLayouts = &set_layout_;
  VK_TRY(vkAllocateDescriptorSets(ctx.device, &dsai, &set_));

  VkDescriptorBufferInfo bi[kBindCount] = {};
  VkDescriptorImageInfo ii[kBindCount] = {};
  VkWriteDescriptorSet w[kBindCount];
  auto buf = [&](uint32_t binding, const Buffer& buffer) { bi[binding] = {buffer.buffer, 0, VK_WHOLE_SIZE}; };
  buf(kBindFrame, uniforms_buf_);
  buf(kBindPalette, palette_buf_);
  buf(kBindNodeDesc, node_desc_);
  buf(kBindPatchBounds, patch_bounds_);
  buf(kBindNodeList, node_list_);
  buf(kBindLodMap, lod_map_);
  buf(kBindDraw, draw_);
  buf(kBindPatches, patches_);
  buf(kBindCoarseErrors, coarse_errors_);
  buf(kBindPatchErrors, patch_errors_);
  buf(kBindPatchWork, patch_work_);
  buf(kBindLists, lists_);
  buf(kBindTree, tree_);
  auto img = [&](uint32_t binding, const Image& image, VkSampler sampler) {
    ii[binding] = {sampler, image.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  };
  img(kBindRootTex, images_[kRoots], nearest_);
  img(kBindHeights, images_[kHeights], nearest_);
  img(kBindNormals, images_[kNormals], linear_);
  img(kBindAlbedo, images_[kAlbedo], linear_);
  img(kBindSplat, images_[kSplat], nearest_);
  img(kBindCones, images_[kCones], nearest_);
  img(kBindLit, images_[kLit], linear_);
  for (uint32_t i = 0; i < kBindCount; ++i) {
    w[i] = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    w[i].dstSet = set_;
    w[i].dstBinding = i;
    w[i].descriptorCount = 1;
    w[i].descriptorType = b[i].descriptorType;
    if (b[i].descriptorType == VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER)
      w[i].pImageInfo = &ii[i];
    else
      w[i].pBufferInfo = &bi[i];
  }
  vkUpdateDescriptorSets(ctx.device, kBindCount, w, 0, nullptr);

  auto compute = [&](ShaderId id, VkPipeline& out) -> Status {
    VkShaderModule module;
    TERRAIN_TRY(create_shader_module(ctx.device, id, module));
    VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    ci.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
    ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    ci.stage.module = module;
    ci.stage.pName = "main";
    ci.layout = pipeline_layout_;
    VkResult r = vkCreateComputePipelines(ctx.device, VK_NULL_HANDLE, 1, &ci, nullptr, &out);
    vkDestroyShaderModule(ctx.device, module, nullptr);
    VK_TRY(r);
    return Status::success();
  };
  TERRAIN_TRY(compute(ShaderId::traverse, traverse_));
  TERRAIN_TRY(compute(ShaderId::lodmap, lodmap_));
  TERRAIN_TRY(compute(ShaderId::patches, patches_pipe_));

  TERRAIN_TRY(create_shader_module(ctx.device, ShaderId::terrain_vert, vs_));
  TERRAIN_TRY(create_shader_module(ctx.device, ShaderId::terrain_frag, fs_));
  return Status::success();
}

VkPipeline TerrainRenderer::graphics_pipeline(int debug, bool near, bool wire, bool prelit) {
  const bool discard = !settings_.hole_nan;
  const int profile = int(settings_.profile);
  const int key = ((profile * 16 + debug) * 2 + (prelit ? 1 : 0)) * 8 + (discard ? 4 : 0) + (near ? 2 : 0) + (wire ? 1 : 0);
  if (auto it = graphics_.find(key); it != graphics_.end()) return it->second;
  const Context& ctx = *ctx_;
  struct Spec {
    VkBool32 wire;
    int32_t debug;
    VkBool32 near;
    VkBool32 discard;
    VkBool32 flat;
    VkBool32 prelit;
  } spec_data{wire ? VK_TRUE : VK_FALSE, debug, near ? VK_TRUE : VK_FALSE, discard ? VK_TRUE : VK_FALSE,
              settings_.profile == FrameSettings::DrawProfile::kFlat ? VK_TRUE : VK_FALSE, prelit ? VK_TRUE : VK_FALSE};
  const VkSpecializationMapEntry entries[6] = {{0, offsetof(Spec, wire), sizeof(VkBool32)},
                                               {1, offsetof(Spec, debug), sizeof(int32_t)},
                                               {2, offsetof(Spec, near), sizeof(VkBool32)},
                                               {3, offsetof(Spec, discard), sizeof(VkBool32)},
                                               {4, offsetof(Spec, flat), sizeof(VkBool32)},
                                               {5, offsetof(Spec, prelit), sizeof(VkBool32)}};
  VkSpecializationInfo spec{6, entries, sizeof(Spec), &spec_data};
  VkPipelineShaderStageCreateInfo stages[2] = {{VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO},
                                               {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO}};
  stages[0].stage = VK_SHADER_STAGE_VERTEX_BIT;
  stages[0].module = vs_;
  stages[0].pName = "main";
  stages[1].stage = VK_SHADER_STAGE_FRAGMENT_BIT;
  stages[1].module = fs_;
  stages[1].pName = "main";
  stages[1].pSpecializationInfo = &spec;
  VkPipelineVertexInputStateCreateInfo vi{VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
  VkPipelineInputAssemblyStateCreateInfo ia{VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
  ia.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
  VkPipelineViewportStateCreateInfo vp{VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
  vp.viewportCount = 1;
  vp.scissorCount = 1;
  VkPipelineRasterizationStateCreateInfo rs{VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
  rs.rasterizerDiscardEnable = settings_.profile == FrameSettings::DrawProfile::kVertexOnly ? VK_TRUE : VK_FALSE;
  rs.polygonMode = wire ? VK_POLYGON_MODE_LINE : VK_POLYGON_MODE_FILL;
  rs.cullMode = VK_CULL_MODE_BACK_BIT;
  rs.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
  rs.lineWidth = 1.0f;
  rs.depthBiasEnable = wire ? VK_TRUE : VK_FALSE;
  rs.depthBiasConstantFactor = wire ? 4.0f : 0.0f;  // reversed Z: positive pulls lines toward the eye
  rs.depthBiasSlopeFactor = wire ? 1.0f : 0.0f;
  VkPipelineMultisampleStateCreateInfo ms{VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO};
  ms.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
  VkPipelineDepthStencilStateCreateInfo ds{VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
  ds.depthTestEnable = VK_TRUE;
  ds.depthWriteEnable = wire ? VK_FALSE : VK_TRUE;
  ds.depthCompareOp = VK_COMPARE_OP_GREATER_OR_EQUAL;  // reversed Z
  VkPipelineColorBlendAttachmentState att{};
  att.colorWriteMask = 0xF;
  VkPipelineColorBlendStateCreateInfo cb{VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO};
  cb.attachmentCount = 1;
  cb.pAttachments = &att;
  VkDynamicState dyn[2] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
  VkPipelineDynamicStateCreateInfo dy{VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO};
  dy.dynamicStateCount = 2;
  dy.pDynamicStates = dyn;
  VkFormat color_format = kColorFormat;
  VkPipelineRenderingCreateInfo rci{VK_STRUCTURE_TYPE_PIPELINE_RENDERING_CREATE_INFO};
  rci.colorAttachmentCount = 1;
  rci.pColorAttachmentFormats = &color_format;
  rci.depthAttachmentFormat = kDepthFormat;
  VkGraphicsPipelineCreateInfo gci{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO};
  gci.pNext = &rci;
  gci.stageCount = 2;
  gci.pStages = stages;
  gci.pVertexInputState = &vi;
  gci.pInputAssemblyState = &ia;
  gci.pViewportState = &vp;
  gci.pRasterizationState = &rs;
  gci.pMultisampleState = &ms;
  gci.pDepthStencilState = &ds;
  gci.pColorBlendState = &cb;
  gci.pDynamicState = &dy;
  gci.layout = pipeline_layout_;
  VkPipeline pipeline = VK_NULL_HANDLE;
  VK_CHECK(vkCreateGraphicsPipelines(ctx.device, VK_NULL_HANDLE, 1, &gci, nullptr, &pipeline));
  graphics_[key] = pipeline;
  return pipeline;
}

void TerrainRenderer::destroy() {
  if (!ctx_) return;
  const Context& ctx = *ctx_;
  vkDeviceWaitIdle(ctx.device);
  for (VkPipeline p : {traverse_, lodmap_, patches_pipe_})
    if (p) vkDestroyPipeline(ctx.device, p, nullptr);
  traverse_ = lodmap_ = patches_pipe_ = VK_NULL_HANDLE;
  for (auto& [key, p] : graphics_) vkDestroyPipeline(ctx.device, p, nullptr);
  graphics_.clear();
  if (vs_) vkDestroyShaderModule(ctx.device, vs_, nullptr);
  if (fs_) vkDestroyShaderModule(ctx.device, fs_, nullptr);
  vs_ = fs_ = VK_NULL_HANDLE;
  if (pipeline_layout_) vkDestroyPipelineLayout(ctx.device, pipeline_layout_, nullptr);
  if (descriptor_pool_) vkDestroyDescriptorPool(ctx.device, descriptor_pool_, nullptr);
  if (set_layout_) vkDestroyDescriptorSetLayout(ctx.device, set_layout_, nullptr);
  pipeline_layout_ = VK_NULL_HANDLE;
  descriptor_pool_ = VK_NULL_HANDLE;
  set_layout_ = VK_NULL_HANDLE;
  if (queries_) vkDestroyQueryPool(ctx.device, queries_, nullptr);
  queries_ = VK_NULL_HANDLE;
  if (linear_) vkDestroySampler(ctx.device, linear_, nullptr);
  if (nearest_) vkDestroySampler(ctx.device, nearest_, nullptr);
  linear_ = nearest_ = VK_NULL_HANDLE;
  for (Image& i : images_) destroy_image(ctx, i);
  for (Buffer* b : {&uniforms_buf_, &palette_buf_, &node_desc_, &patch_bounds_, &coarse_errors_, &patch_errors_, &patch_work_, &node_list_, &lod_map_,
                    &lists_, &tree_, &draw_, &patches_, &index_buffer_, &stats_readback_, &lists_readback_, &staging_})
    destroy_buffer(ctx, *b);
  images_initialised_ = false;
  pending_images_.clear();
  pending_buffers_.clear();
  staging_used_ = 0;
  ctx_ = nullptr;
}

Status TerrainRenderer::stage_bytes(const void* data, size_t size, size_t align, VkDeviceSize& offset) {
  TERRAIN_TRY(stage_reserve(size, align, offset));
  std::memcpy(static_cast<uint8_t*>(staging_.mapped) + offset, data, size);
  return Status::success();
}

Status TerrainRenderer::stage_reserve(size_t size, size_t align, VkDeviceSize& offset) {
  VkDeviceSize at = (staging_used_ + align - 1) / align * align;
  if (at + size > staging_.size) {
    // Grow: the previous frame has finished (one frame in flight), so only this frame's staged
    // bytes need to move to the new buffer; pending copies refer to offsets, not the buffer.
    Buffer bigger;
    TERRAIN_TRY(create_host_buffer(*ctx_, std::max<VkDeviceSize>(staging_.size * 2, at + size + (1u << 20)),
                              VK_BUFFER_USAGE_TRANSFER_SRC_BIT, bigger));
    std::memcpy(bigger.mapped, staging_.mapped, size_t(staging_used_));
    destroy_buffer(*ctx_, staging_);
    staging_ = bigger;
  }
  staging_used_ = at + size;
  offset = at;
  return Status::success();
}

Status TerrainRenderer::upload(std::span<const NodeUpload> nodes, TerrainState& state) {
  for (const NodeUpload& n : nodes)
    if (n.slot >= config_.slot_count || !n.data)
      return Status::failure(Error::invalid_argument, "renderer: upload into slot " + std::to_string(n.slot) +
                                                          " outside the atlas (" + std::to_string(config_.slot_count) + ")");
  // Each node's staged bytes, one 16-aligned part after the other: the atlas layers, then the
  // patch bounds and errors the viewer derives (node_prep.h prepare_slot).
  const bool decode = config_.decode_bc || config_.prelit_far;
  constexpr size_t kLayer = size_t(kTexels) * kTexels * 4;
  struct Part {
    int image;  // atlas image, or -1 for a buffer part
    size_t size;
    uint32_t w, h;
  };
  enum : size_t { kPartHeights, kPartNormals, kPartAlbedo, kPartSplat, kPartCones, kPartBounds, kPartCoarse, kPartPatch, kPartLit };
  std::vector<Part> parts = {{kHeights, sizeof(NodeData::heights), kHeightSamples, kHeightSamples},
                             {kNormals, decode ? kLayer : sizeof(NodeData::normals_bc3), kTexels, kTexels},
                             {kAlbedo, decode ? kLayer : sizeof(NodeData::albedo_bc1), kTexels, kTexels},
                             {kSplat, sizeof(NodeData::splat), kSplatSamples, kSplatSamples},
                             {kCones, sizeof(NodeData::cones_bc3), kPatchesPerSide, kPatchesPerSide},
                             {-1, sizeof(SlotCpuData::bounds), 0, 0},
                             {-1, 16, 0, 0},
                             {-1, sizeof(SlotCpuData::patch_error), 0, 0}};
  if (config_.prelit_far) parts.push_back({kLit, kLayer, kTexels, kTexels});
  std::vector<size_t> part_at(parts.size());
  size_t node_bytes = 0;
  for (size_t k = 0; k < parts.size(); ++k) {
    part_at[k] = node_bytes;
    node_bytes += (parts[k].size + 15) / 16 * 16;
  }
  VkDeviceSize base = 0;
  TERRAIN_TRY(stage_reserve(node_bytes * nodes.size(), 16, base));
  uint8_t* const staged = static_cast<uint8_t*>(staging_.mapped) + base;

  // The CPU work of each node (BC decoding, lighting, bounds and errors) on every core: nodes are
  // independent, and the device is idle meanwhile (one frame in flight). A batch naming a slot
  // twice (the later upload wins) runs in order.
  std::vector<uint16_t> slots(nodes.size());
  for (size_t k = 0; k < nodes.size(); ++k) slots[k] = uint16_t(nodes[k].slot);
  std::sort(slots.begin(), slots.end());
  const bool distinct = std::adjacent_find(slots.begin(), slots.end()) == slots.end();
  parallel_for(
      nodes.size(),
      [&](size_t k) {
        const NodeData& d = *nodes[k].data;
        uint8_t* const at = staged + k * node_bytes;
        auto part = [&](size_t p) { return at + part_at[p]; };
        std::memcpy(part(kPartHeights), d.heights.data(), sizeof(d.heights));
        if (decode) {
          terrain::decode_bc3_image(d.normals_bc3.data(), kTexelBlocks, kTexelBlocks, part(kPartNormals));
          terrain::decode_bc1_image(d.albedo_bc1.data(), kTexelBlocks, kTexelBlocks, part(kPartAlbedo));
          if (config_.prelit_far)
            light_texels(part(kPartNormals), part(kPartAlbedo), kTexels * kTexels, lit_light_, part(kPartLit));
        } else {
          std::memcpy(part(kPartNormals), d.normals_bc3.data(), sizeof(d.normals_bc3));
          std::memcpy(part(kPartAlbedo), d.albedo_bc1.data(), sizeof(d.albedo_bc1));
        }
        std::memcpy(part(kPartSplat), d.splat.data(), sizeof(d.splat));
        std::memcpy(part(kPartCones), d.cones_bc3.data(), sizeof(d.cones_bc3));
        // The slot's descriptor (from the state) tells the quantization of these heights.
        SlotCpuData& cpu = slot_cpu_[nodes[k].slot];
        cpu = prepare_slot(d, state.descriptor(nodes[k].slot));
        std::memcpy(part(kPartBounds), cpu.bounds.data(), sizeof(cpu.bounds));
        std::memcpy(part(kPartCoarse), cpu.coarse_error.data(), 16);
        std::memcpy(part(kPartPatch), cpu.patch_error.data(), sizeof(cpu.patch_error));
      },
      distinct ? config_.upload_threads : 1u);

  static_assert(sizeof(SlotCpuData::patch_error) == TV_PATCH_ERRORS_PER_NODE * 16);
  const VkDeviceSize buffer_size[3] = {sizeof(SlotCpuData::bounds), 16, sizeof(SlotCpuData::patch_error)};
  const VkBuffer buffers[3] = {patch_bounds_.buffer, coarse_errors_.buffer, patch_errors_.buffer};
  for (size_t k = 0; k < nodes.size(); ++k) {
    const uint32_t slot = nodes[k].slot;
    for (size_t p = 0; p < parts.size(); ++p) {
      const VkDeviceSize off = base + k * node_bytes + part_at[p];
      if (parts[p].image >= 0) {
        VkBufferImageCopy c{};
        c.bufferOffset = off;
        c.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, slot, 1};
        c.imageExtent = {parts[p].w, parts[p].h, 1};
        pending_images_.push_back({parts[p].image, c});
      } else {
        const size_t b = p - kPartBounds;
        pending_buffers_.push_back({buffers[b], {off, VkDeviceSize(slot) * buffer_size[b], buffer_size[b]}});
      }
    }
  }
  TerrainState::Dirty dirty = state.take_dirty();
  // The residency index's tree words (terrain/surface_contract.h): the header and start list when
  // they changed, and the child words of the slots that changed, contiguous slots in one copy.
  {
    const std::span<const uint32_t> tree = state.index().tree();
    const uint32_t cap = state.slot_count();
    auto copy_words = [&](size_t first, size_t count) -> Status {
      VkDeviceSize off;
      TERRAIN_TRY(stage_bytes(&tree[first], count * 4, 16, off));
      pending_buffers_.push_back({tree_.buffer, {off, VkDeviceSize(first) * 4, VkDeviceSize(count) * 4}});
      return Status::success();
    };
    if (dirty.index.starts) TERRAIN_TRY(copy_words(0, kIndexTreeStart + size_t(cap)));
    const std::vector<uint16_t>& kids = dirty.index.children;
    for (size_t i = 0; i < kids.size();) {
      size_t j = i + 1;
      while (j < kids.size() && kids[j] == kids[j - 1] + 1) ++j;
      TERRAIN_TRY(copy_words(index_child_word(cap, kids[i]), 2 * (j - i)));
      i = j;
    }
    top_level_ = uint32_t(state.top_level());
  }
  // Descriptors: contiguous runs of dirty slots become one copy each.
  for (size_t i = 0; i < dirty.slots.size();) {
    size_t j = i + 1;
    while (j < dirty.slots.size() && dirty.slots[j] == dirty.slots[j - 1] + 1) ++j;
    const uint32_t first = dirty.slots[i], count = uint32_t(j - i);
    VkDeviceSize off;
    TERRAIN_TRY(stage_bytes(&state.descriptors()[first], size_t(count) * sizeof(GpuNodeDesc), 16, off));
    pending_buffers_.push_back(
        {node_desc_.buffer, {off, VkDeviceSize(first) * sizeof(GpuNodeDesc), VkDeviceSize(count) * sizeof(GpuNodeDesc)}});
    i = j;
  }
  if (const DirtyRect& r = dirty.index.roots; !r.empty()) {
    const uint32_t w = r.x1 - r.x0, h = r.y1 - r.y0;
    scratch_.resize(size_t(w) * h * 2);
    for (uint32_t y = 0; y < h; ++y)
      std::memcpy(scratch_.data() + size_t(y) * w * 2, &state.index().root_grid()[size_t(r.y0 + y) * state.roots_x() + r.x0],
                  size_t(w) * 2);
    VkDeviceSize off;
    TERRAIN_TRY(stage_bytes(scratch_.data(), scratch_.size(), 16, off));
    VkBufferImageCopy c{};
    c.bufferOffset = off;
    c.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    c.imageOffset = {int32_t(r.x0), int32_t(r.y0), 0};
    c.imageExtent = {w, h, 1};
    pending_images_.push_back({kRoots, c});
  }
  return Status::success();
}

void TerrainRenderer::set_frame(const Camera& camera, const FrameSettings& s, uint32_t width, uint32_t height) {
  settings_ = s;
  FrameUniforms& u = uniforms_;
  fill_view_uniforms(camera, world_, width, height, u);
  u.lod[0] = float(s.error_target_px);
  u.lod[1] = float(s.cone_margin_deg);
  u.lod[2] = float(s.near_start_m);
  u.lod[3] = float(s.near_end_m);
  u.world[0] = world_.roots_x;
  u.world[1] = world_.roots_y;
  u.world[2] = sectors_x_;
  u.world[3] = sectors_y_;
  uint32_t flags = 0;
  if (s.frustum_cull) flags |= TV_FLAG_FRUSTUM_CULL;
  if (s.cone_cull) flags |= TV_FLAG_CONE_CULL;
  if (s.holes) flags |= TV_FLAG_HOLES;
  if (s.hole_nan) flags |= TV_FLAG_HOLE_NAN;
  if (s.splat && (s.debug == TV_DEBUG_NONE || s.debug == TV_DEBUG_WIRE)) flags |= TV_FLAG_SPLAT;
  if (!s.stitch) flags |= TV_FLAG_NO_STITCH;
  if (s.decimate) flags |= TV_FLAG_DECIMATE;
  u.misc[0] = top_level_;
  lod_window(world_, camera.position[0], camera.position[1], u.lodwin);
  u.misc[1] = flags;
  u.misc[2] = uint32_t(s.debug);
  u.misc[3] = config_.slot_count * TV_PATCHES_PER_NODE;
  const SceneLight light = scene_light(s.sun_azimuth_deg, s.sun_elevation_deg);
  std::copy_n(light.sun_dir, 3, u.sun_dir);
  std::copy_n(light.sun_color, 4, u.sun_color);
  std::copy_n(light.sky_color, 3, u.sky_color);
  u.fog[0] = 0.52f;
  u.fog[1] = 0.62f;
  u.fog[2] = 0.76f;
  u.fog[3] = float(s.fog_density);
  ::terrain::view::cone_sin2_table(s.cone_margin_deg, cone_table_);
}

void TerrainRenderer::record_frame(VkCommandBuffer cmd, const RenderTarget& target, bool capture_lists) {
  const Context& ctx = *ctx_;
  std::memcpy(uniforms_buf_.mapped, &uniforms_, sizeof(FrameUniforms));
  std::memcpy(static_cast<PaletteBlock*>(palette_buf_.mapped)->cone_sin2, cone_table_, sizeof(cone_table_));
  if (timestamps_) vkCmdResetQueryPool(cmd, queries_, 0, kTimestamps);

  // ---- Uploads ----
  const VkPipelineStageFlags2 shader_stages = VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT |
                                              VK_PIPELINE_STAGE_2_VERTEX_SHADER_BIT |
                                              VK_PIPELINE_STAGE_2_FRAGMENT_SHADER_BIT;
  const VkImageLayout read_layout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
  if (!images_initialised_) {
    for (Image& img : images_)
      image_barrier(cmd, img, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                    VK_PIPELINE_STAGE_2_NONE, 0, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT);
  } else if (!pending_images_.empty()) {
    for (Image& img : images_)
      image_barrier(cmd, img, VK_IMAGE_ASPECT_COLOR_BIT, read_layout, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, shader_stages,
                    VK_ACCESS_2_SHADER_READ_BIT, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT);
  }
  for (const PendingImageCopy& p : pending_images_)
    vkCmdCopyBufferToImage(cmd, staging_.buffer, images_[size_t(p.image)].image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1,
                           &p.region);
  for (const PendingBufferCopy& p : pending_buffers_) vkCmdCopyBuffer(cmd, staging_.buffer, p.dst, 1, &p.region);
  if (!images_initialised_ || !pending_images_.empty()) {
    for (Image& img : images_)
      image_barrier(cmd, img, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, read_layout,
                    VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT, shader_stages, VK_ACCESS_2_SHADER_READ_BIT);
  }
  images_initialised_ = true;
  pending_images_.clear();
  pending_buffers_.clear();
  staging_used_ = 0;
  memory_barrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT | VK_PIPELINE_STAGE_2_CLEAR_BIT | VK_PIPELINE_STAGE_2_ALL_GRAPHICS_BIT,
                 VK_ACCESS_2_TRANSFER_WRITE_BIT | VK_ACCESS_2_MEMORY_READ_BIT,
                 VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT |
                     VK_PIPELINE_STAGE_2_INDEX_INPUT_BIT | VK_PIPELINE_STAGE_2_VERTEX_SHADER_BIT,
                 VK_ACCESS_2_SHADER_READ_BIT | VK_ACCESS_2_SHADER_WRITE_BIT | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT |
                     VK_ACCESS_2_INDEX_READ_BIT);

  // ---- Compute: traversal -> LOD map -> patches ----
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_layout_, 0, 1, &set_, 0, nullptr);
  if (timestamps_) vkCmdWriteTimestamp2(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, queries_, 0);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, traverse_);
  vkCmdDispatch(cmd, 1, 1, 1);
  const VkAccessFlags2 rw = VK_ACCESS_2_SHADER_READ_BIT | VK_ACCESS_2_SHADER_WRITE_BIT;
  memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_WRITE_BIT,
                 VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT,
                 rw | VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT);
  if (timestamps_) vkCmdWriteTimestamp2(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, queries_, 1);
  // The LOD map is scattered by the listed nodes: sectors no node draws stay 0 (cleared here, in
  // the timed LOD-map step).
  vkCmdFillBuffer(cmd, lod_map_.buffer, 0, VK_WHOLE_SIZE, 0);
  memory_barrier(cmd, VK_PIPELINE_STAGE_2_CLEAR_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT,
                 rw);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, lodmap_);
  vkCmdDispatchIndirect(cmd, node_list_.buffer, TV_NL_DISPATCH * 4);  // one workgroup per listed node
  memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_WRITE_BIT,
                 VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, rw);
  if (timestamps_) vkCmdWriteTimestamp2(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, queries_, 2);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, patches_pipe_);
  vkCmdDispatchIndirect(cmd, node_list_.buffer, TV_NL_PATCH_DISPATCH * 4);  // one thread per patch work item
  memory_barrier(cmd, VK_PIPELINE_STAGE_2_COMPUTE_SHADER_BIT, VK_ACCESS_2_SHADER_WRITE_BIT,
                 VK_PIPELINE_STAGE_2_DRAW_INDIRECT_BIT | VK_PIPELINE_STAGE_2_VERTEX_SHADER_BIT |
                     VK_PIPELINE_STAGE_2_COPY_BIT,
                 VK_ACCESS_2_INDIRECT_COMMAND_READ_BIT | VK_ACCESS_2_SHADER_READ_BIT | VK_ACCESS_2_TRANSFER_READ_BIT);
  if (timestamps_) vkCmdWriteTimestamp2(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, queries_, 3);

  // ---- Draw ----
  image_barrier(cmd, target.color, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, VK_ACCESS_2_MEMORY_READ_BIT,
                VK_PIPELINE_STAGE_2_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_2_COLOR_ATTACHMENT_WRITE_BIT);
  image_barrier(cmd, target.depth, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, VK_ACCESS_2_MEMORY_READ_BIT,
                VK_PIPELINE_STAGE_2_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_2_LATE_FRAGMENT_TESTS_BIT,
                VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT | VK_ACCESS_2_DEPTH_STENCIL_ATTACHMENT_READ_BIT);
  VkRenderingAttachmentInfo color{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
  color.imageView = target.color.view;
  color.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
  color.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
  color.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
  // The target holds sRGB-encoded values (UNORM): the clear colour goes in as given.
  for (int k = 0; k < 3; ++k) color.clearValue.color.float32[k] = std::clamp(settings_.clear[k], 0.0f, 1.0f);
  color.clearValue.color.float32[3] = 1.0f;
  VkRenderingAttachmentInfo depth{VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO};
  depth.imageView = target.depth.view;
  depth.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
  depth.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
  depth.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
  depth.clearValue.depthStencil = {0.0f, 0};  // reversed Z: 0 = infinitely far
  VkRenderingInfo ri{VK_STRUCTURE_TYPE_RENDERING_INFO};
  ri.renderArea = {{0, 0}, {target.width, target.height}};
  ri.layerCount = 1;
  ri.colorAttachmentCount = 1;
  ri.pColorAttachments = &color;
  ri.pDepthAttachment = &depth;
  vkCmdBeginRendering(cmd, &ri);
  VkViewport viewport{0, 0, float(target.width), float(target.height), 0.0f, 1.0f};
  VkRect2D scissor{{0, 0}, {target.width, target.height}};
  vkCmdSetViewport(cmd, 0, 1, &viewport);
  vkCmdSetScissor(cmd, 0, 1, &scissor);
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline_layout_, 0, 1, &set_, 0, nullptr);
  vkCmdBindIndexBuffer(cmd, index_buffer_.buffer, 0, VK_INDEX_TYPE_UINT16);
  // Two shading groups, one indexed-indirect instanced draw each (the near one is empty when
  // splat shading is off or a debug view is shown).
  const int debug = settings_.debug;
  const bool shaded = debug == TV_DEBUG_NONE || debug == TV_DEBUG_WIRE;
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, graphics_pipeline(debug, shaded, false));
  const uint32_t stride = 5 * 4;  // VkDrawIndexedIndirectCommand
  // One draw per decimation mesh: a single multi-draw where the device has the feature.
  auto draw_group = [&](uint32_t first_uint) {
    if (ctx_->multi_draw_indirect) {
      vkCmdDrawIndexedIndirect(cmd, draw_.buffer, first_uint * 4, TV_MESHES, stride);
    } else {
      for (uint32_t m = 0; m < TV_MESHES; ++m) vkCmdDrawIndexedIndirect(cmd, draw_.buffer, first_uint * 4 + m * stride, 1, stride);
    }
  };
  draw_group(TV_DRAW_NEAR);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, graphics_pipeline(debug, false, false, far_prelit()));
  draw_group(TV_DRAW_FAR);
  if (debug == TV_DEBUG_WIRE) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, graphics_pipeline(debug, false, true));
    draw_group(TV_DRAW_NEAR);
    draw_group(TV_DRAW_FAR);
  }
  vkCmdEndRendering(cmd);
  if (timestamps_) vkCmdWriteTimestamp2(cmd, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT, queries_, 4);

  // ---- Counters (and lists) for the host ----
  VkBufferCopy c{0, 0, TV_NL_HEADER * 4};
  vkCmdCopyBuffer(cmd, node_list_.buffer, stats_readback_.buffer, 1, &c);
  c = {0, TV_NL_HEADER * 4, TV_DRAW_UINTS * 4};
  vkCmdCopyBuffer(cmd, draw_.buffer, stats_readback_.buffer, 1, &c);
  lists_captured_ = capture_lists;
  if (capture_lists) {
    const VkDeviceSize nl = VkDeviceSize(TV_NL_HEADER + config_.slot_count) * 4;
    const VkDeviceSize lm = VkDeviceSize(lod_map_uints_) * 4;
    const VkDeviceSize pl = TV_PATCH_RANGES * VkDeviceSize(config_.slot_count) * TV_PATCHES_PER_NODE * sizeof(GpuPatch);
    c = {0, 0, nl};
    vkCmdCopyBuffer(cmd, node_list_.buffer, lists_readback_.buffer, 1, &c);
    c = {0, nl, lm};
    vkCmdCopyBuffer(cmd, lod_map_.buffer, lists_readback_.buffer, 1, &c);
    c = {0, nl + lm, pl};
    vkCmdCopyBuffer(cmd, patches_.buffer, lists_readback_.buffer, 1, &c);
  }
  memory_barrier(cmd, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_2_HOST_BIT,
                 VK_ACCESS_2_HOST_READ_BIT);
  (void)ctx;
}

FrameStats TerrainRenderer::read_stats() const {
  FrameStats s;
  const uint32_t* nl = static_cast<const uint32_t*>(stats_readback_.mapped);
  const uint32_t* dr = nl + TV_NL_HEADER;
  s.nodes = nl[TV_NL_COUNT];
  for (int l = 0; l < kMaxLevels; ++l) s.level_counts[size_t(l)] = nl[TV_NL_LEVEL_COUNTS + l];
  s.traversal_overflow = nl[TV_NL_OVERFLOW];
  s.stitch_clamped = dr[TV_CNT_DEEP];
  for (uint32_t r = 0; r < TV_PATCH_RANGES; ++r) {
    const uint32_t count = dr[r * 5 + 1], e = r % TV_MESHES;
    if (r < TV_MESHES) s.patches_near += count;
    s.patches_drawn += count;
    s.patches_decimated[e] += count;
    s.triangles += uint64_t(count) * (mesh_indices(e) / 3);
  }
  s.patches_considered = dr[TV_CNT_CONSIDERED];
  s.culled_frustum = dr[TV_CNT_FRUSTUM];
  s.culled_cone = dr[TV_CNT_CONE];
  if (timestamps_) {
    uint64_t t[kTimestamps];
    if (vkGetQueryPoolResults(ctx_->device, queries_, 0, kTimestamps, sizeof(t), t, sizeof(uint64_t),
                              VK_QUERY_RESULT_64_BIT) == VK_SUCCESS) {
      const double ms = double(ctx_->properties.limits.timestampPeriod) * 1e-6;
      s.gpu_traverse_ms = double(t[1] - t[0]) * ms;
      s.gpu_lodmap_ms = double(t[2] - t[1]) * ms;
      s.gpu_patches_ms = double(t[3] - t[2]) * ms;
      s.gpu_draw_ms = double(t[4] - t[3]) * ms;
      s.gpu_total_ms = double(t[4] - t[0]) * ms;
      s.timings_valid = true;
    }
  }
  return s;
}

void TerrainRenderer::read_lists(NodeList& nodes, std::vector<uint32_t>& lod_map, std::vector<GpuPatch>& patches) const {
  const uint8_t* base = static_cast<const uint8_t*>(lists_readback_.mapped);
  const uint32_t* nl = reinterpret_cast<const uint32_t*>(base);
  nodes = NodeList{};
  const uint32_t count = std::min(nl[TV_NL_COUNT], config_.slot_count);
  nodes.entries.assign(nl + TV_NL_HEADER, nl + TV_NL_HEADER + count);
  for (int l = 0; l < kMaxLevels; ++l) nodes.level_counts[size_t(l)] = nl[TV_NL_LEVEL_COUNTS + l];
  nodes.overflow = nl[TV_NL_OVERFLOW];
  const size_t nl_bytes = size_t(TV_NL_HEADER + config_.slot_count) * 4;
  const uint32_t* lm = reinterpret_cast<const uint32_t*>(base + nl_bytes);
  lod_map.assign(lm, lm + lod_map_uints_);
  const GpuPatch* pl = reinterpret_cast<const GpuPatch*>(base + nl_bytes + lod_map_uints_ * 4);
  const uint32_t* dr = static_cast<const uint32_t*>(stats_readback_.mapped) + TV_NL_HEADER;
  const size_t capacity = size_t(config_.slot_count) * TV_PATCHES_PER_NODE;
  patches.clear();
  for (uint32_t r = 0; r < TV_PATCH_RANGES; ++r)
    patches.insert(patches.end(), pl + capacity * r, pl + capacity * r + std::min<size_t>(dr[r * 5 + 1], capacity));
}

}  // namespace terrain::view
