// Offscreen render target (sRGB colour + reversed-Z depth) and its host readback.
#pragma once
#include <cstdint>
#include <vector>

#include "resources.h"

namespace terrain::view {

// UNORM holding sRGB-encoded values (the fragment shader encodes): an sRGB attachment costs
// lavapipe more than the whole terrain shading.
inline constexpr VkFormat kColorFormat = VK_FORMAT_R8G8B8A8_UNORM;
inline constexpr VkFormat kDepthFormat = VK_FORMAT_D32_SFLOAT;

struct RenderTarget {
  Image color, depth;
  Buffer readback;  // colour (w*h*4) then depth (w*h floats)
  uint32_t width = 0, height = 0;
};

Status create_target(const Context& ctx, uint32_t width, uint32_t height, RenderTarget& out);
void destroy_target(const Context& ctx, RenderTarget& t);
// Records copies of colour and depth into the readback buffer (images end in their attachment
// layouts again, so the target can be rendered to next frame).
void record_readback(VkCommandBuffer cmd, const RenderTarget& t);
// After the frame's fence: RGBA8 (sRGB-encoded) rows top to bottom, and depth (reversed Z: 0 = far).
void read_color(const RenderTarget& t, std::vector<uint8_t>& rgba);
void read_depth(const RenderTarget& t, std::vector<float>& depth);

}  // namespace terrain::view
