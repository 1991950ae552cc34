// The viewer's SPIR-V, compiled from viewer/shaders by glslc at build time and embedded.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <span>

#include "terrain/status.h"

namespace terrain::view {

enum class ShaderId { traverse, lodmap, patches, terrain_vert, terrain_frag };

std::span<const uint32_t> shader_code(ShaderId id);
Status create_shader_module(VkDevice device, ShaderId id, VkShaderModule& out);

}  // namespace terrain::view
