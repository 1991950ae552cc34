// Small BC1/BC3 block decoders (DXT1/DXT5) for tools, tests and CPU-side checks, plus the node
// hole mask that lives in the albedo alpha. Output pixels are RGBA8; block pixel (c, r) is
// rgba[4 * (4 * r + c)], r = 0 being the block row nearest to image row 0 (the south edge for
// node grids, see format.h).
#pragma once
#include <cstdint>

#include "terrain/format.h"

namespace terrain {

// BC1: colour0 > colour1 gives 4 opaque colours; colour0 <= colour1 gives 3 colours and index 3
// = transparent black (0,0,0,0). Interpolants are (2a+b+1)/3 and (a+b+1)/2 of the 8-bit
// expanded endpoints (GPUs may differ by 1 in the interpolated colours, never in alpha 0/255).
void decode_bc1_block(const uint8_t block[8], uint8_t rgba[64]);
// The four RGBA entries a BC1 block's 2-bit indices select (entry k at palette[4k..4k+3]), as
// decode_bc1_block gives them: texel i is entry (selector bits >> 2i) & 3.
void decode_bc1_palette(const uint8_t block[8], uint8_t palette[16]);
// BC3: BC3 alpha block (8 or 6+{0,255} interpolated values), then a BC1 colour block that always
// uses the 4-colour mode.
void decode_bc3_block(const uint8_t block[16], uint8_t rgba[64]);

// BC4 (the alpha half of BC3, its first 8 bytes): 16 values, same roundings as BC3's alpha.
void decode_bc4_block(const uint8_t block[8], uint8_t values[16]);
// Bit i set when texel i of the BC1 block decodes with alpha 0 (3-colour mode, index 3).
uint16_t bc1_transparent_mask(const uint8_t block[8]);

// Decodes blocks_x * blocks_y blocks (block rows first-to-last) into a (4*blocks_x) x (4*blocks_y)
// RGBA8 image, row-major, row 0 from the first block row. `rgba` holds 64 * blocks_x * blocks_y bytes.
void decode_bc1_image(const uint8_t* blocks, int blocks_x, int blocks_y, uint8_t* rgba);
void decode_bc3_image(const uint8_t* blocks, int blocks_x, int blocks_y, uint8_t* rgba);

// The same decoders with a choice of how interpolated entries round. `nearest` is the form above.
// `truncate` drops the rounding terms: (2a+b)/3, (a+b)/2, ((7-k)a0+k*a1)/7, ((5-k)a0+k*a1)/5, the
// exact-integer form the viewer's CPU side uses where it must equal what the Vulkan device
// (lavapipe) samples: the reference cone culling and its synthetic worlds' encoder.
enum class BcRounding : uint8_t { nearest, truncate };
void decode_bc1_block(const uint8_t block[8], uint8_t rgba[64], BcRounding rounding);
void decode_bc3_block(const uint8_t block[16], uint8_t rgba[64], BcRounding rounding);
void decode_bc4_block(const uint8_t block[8], uint8_t values[16], BcRounding rounding);
void decode_bc1_image(const uint8_t* blocks, int blocks_x, int blocks_y, uint8_t* rgba, BcRounding rounding);
void decode_bc3_image(const uint8_t* blocks, int blocks_x, int blocks_y, uint8_t* rgba, BcRounding rounding);

// Alpha of one BC1 texel (t, u) of a 33x33-block albedo grid (0 or 255).
uint8_t bc1_texel_alpha(const uint8_t* blocks, int blocks_x, int t, int u);

// Hole mask of a node: holes[j * 129 + i] = 1 when vertex (i, j) is a hole, i.e. the albedo BC1
// texel (i + kApron, j + kApron) has alpha 0; else 0. Returns the number of hole vertices.
int decode_hole_mask(const NodeData& node, uint8_t* holes /* kHeightCount */);

}  // namespace terrain
