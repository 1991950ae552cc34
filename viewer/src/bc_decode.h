// Block-compression decoders (BC1 with punch-through alpha, BC3) for the CPU side of the viewer:
// the reference culling reads the patch cones, the hole check reads the albedo alpha. The
// interpolation follows the BC spec's exact-integer form ((2*c0 + c1) / 3 on 8-bit expanded
// endpoints); tests check it against what the Vulkan device samples.
#pragma once
#include <cstdint>

namespace terrain::view {

// 16 texels, row-major within the block (texel (i, j) at out[j * 4 + i]), RGBA8.
void decode_bc1_block(const uint8_t block[8], uint8_t out[16][4]);
void decode_bc3_block(const uint8_t block[16], uint8_t out[16][4]);

// Decodes a whole image of (width/4) x (height/4) blocks, block rows in order; `out` holds
// width * height * 4 bytes, texel (x, y) at (y * width + x) * 4.
void decode_bc1_image(const uint8_t* blocks, int width, int height, uint8_t* out);
void decode_bc3_image(const uint8_t* blocks, int width, int height, uint8_t* out);

}  // namespace terrain::view
