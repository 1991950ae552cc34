#include "shaders.h"

#include "vk_common.h"

namespace terrain::view {
namespace {

const uint32_t kTraverse[] =
#include "traverse.comp.inc"
    ;
const uint32_t kLodMap[] =
#include "lodmap.comp.inc"
    ;
const uint32_t kPatches[] =
#include "patches.comp.inc"
    ;
const uint32_t kTerrainVert[] =
#include "terrain.vert.inc"
    ;
const uint32_t kTerrainFrag[] =
#include "terrain.frag.inc"
    ;

}  // namespace

std::span<const uint32_t> shader_code(ShaderId id) {
  switch (id) {
    case ShaderId::traverse: return kTraverse;
    case ShaderId::lodmap: return kLodMap;
    case ShaderId::patches: return kPatches;
    case ShaderId::terrain_vert: return kTerrainVert;
    case ShaderId::terrain_frag: return kTerrainFrag;
  }
  return {};
}

Status create_shader_module(VkDevice device, ShaderId id, VkShaderModule& out) {
  const auto code = shader_code(id);
  VkShaderModuleCreateInfo ci{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  ci.codeSize = code.size_bytes();
  ci.pCode = code.data();
  VK_TRY(vkCreateShaderModule(device, &ci, nullptr, &out));
  return Status::success();
}

}  // namespace terrain::view
