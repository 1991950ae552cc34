#include "terrain/bc_decode.h"

#include <cstring>

namespace terrain {
namespace {

void expand565(uint16_t c, int rgb[3]) {
  const int r = (c >> 11) & 31, g = (c >> 5) & 63, b = c & 31;
  rgb[0] = (r << 3) | (r >> 2);
  rgb[1] = (g << 2) | (g >> 4);
  rgb[2] = (b << 3) | (b >> 2);
}

// The colour palette shared by BC1 and BC3. `allow_punch_through` is false for BC3 (always 4 colours).
void colour_palette(const uint8_t* b, bool allow_punch_through, BcRounding rounding, uint8_t palette[4][4]) {
  const int bias = rounding == BcRounding::nearest ? 1 : 0;
  const uint16_t c0 = uint16_t(b[0] | (b[1] << 8));
  const uint16_t c1 = uint16_t(b[2] | (b[3] << 8));
  int e0[3], e1[3];
  expand565(c0, e0);
  expand565(c1, e1);
  for (int k = 0; k < 3; ++k) {
    palette[0][k] = uint8_t(e0[k]);
    palette[1][k] = uint8_t(e1[k]);
  }
  palette[0][3] = palette[1][3] = 255;
  if (c0 > c1 || !allow_punch_through) {
    for (int k = 0; k < 3; ++k) {
      palette[2][k] = uint8_t((2 * e0[k] + e1[k] + bias) / 3);
      palette[3][k] = uint8_t((e0[k] + 2 * e1[k] + bias) / 3);
    }
    palette[2][3] = palette[3][3] = 255;
  } else {
    for (int k = 0; k < 3; ++k) palette[2][k] = uint8_t((e0[k] + e1[k] + bias) / 2);
    palette[2][3] = 255;
    palette[3][0] = palette[3][1] = palette[3][2] = palette[3][3] = 0;
  }
}

// Colour part shared by BC1 and BC3.
void decode_colour(const uint8_t* b, bool allow_punch_through, BcRounding rounding, uint8_t rgba[64]) {
  uint8_t palette[4][4];
  colour_palette(b, allow_punch_through, rounding, palette);
  const uint32_t indices = uint32_t(b[4]) | (uint32_t(b[5]) << 8) | (uint32_t(b[6]) << 16) | (uint32_t(b[7]) << 24);
  for (int p = 0; p < 16; ++p) std::memcpy(rgba + 4 * p, palette[(indices >> (2 * p)) & 3], 4);
}

}  // namespace

void decode_bc1_block(const uint8_t block[8], uint8_t rgba[64], BcRounding rounding) {
  decode_colour(block, true, rounding, rgba);
}
void decode_bc1_block(const uint8_t block[8], uint8_t rgba[64]) { decode_bc1_block(block, rgba, BcRounding::nearest); }
void decode_bc1_palette(const uint8_t block[8], uint8_t palette[16]) {
  uint8_t p[4][4];
  colour_palette(block, true, BcRounding::nearest, p);
  std::memcpy(palette, p, 16);
}

void decode_bc4_block(const uint8_t block[8], uint8_t values[16], BcRounding rounding) {
  const bool nearest = rounding == BcRounding::nearest;
  const int a0 = block[0], a1 = block[1];
  uint8_t alpha[8];
  alpha[0] = uint8_t(a0);
  alpha[1] = uint8_t(a1);
  if (a0 > a1) {
    for (int k = 1; k <= 6; ++k) alpha[1 + k] = uint8_t(((7 - k) * a0 + k * a1 + (nearest ? 3 : 0)) / 7);
  } else {
    for (int k = 1; k <= 4; ++k) alpha[1 + k] = uint8_t(((5 - k) * a0 + k * a1 + (nearest ? 2 : 0)) / 5);
    alpha[6] = 0;
    alpha[7] = 255;
  }
  uint64_t bits = 0;
  for (int i = 0; i < 6; ++i) bits |= uint64_t(block[2 + i]) << (8 * i);
  for (int p = 0; p < 16; ++p) values[p] = alpha[(bits >> (3 * p)) & 7];
}
void decode_bc4_block(const uint8_t block[8], uint8_t values[16]) { decode_bc4_block(block, values, BcRounding::nearest); }

void decode_bc3_block(const uint8_t block[16], uint8_t rgba[64], BcRounding rounding) {
  decode_colour(block + 8, false, rounding, rgba);
  uint8_t alpha[16];
  decode_bc4_block(block, alpha, rounding);
  for (int p = 0; p < 16; ++p) rgba[4 * p + 3] = alpha[p];
}
void decode_bc3_block(const uint8_t block[16], uint8_t rgba[64]) { decode_bc3_block(block, rgba, BcRounding::nearest); }

namespace {
template <int kBlockBytes, void (*Decode)(const uint8_t*, uint8_t*, BcRounding)>
void decode_image(const uint8_t* blocks, int blocks_x, int blocks_y, BcRounding rounding, uint8_t* rgba) {
  const size_t width = size_t(blocks_x) * 4;
  uint8_t px[64];
  for (int by = 0; by < blocks_y; ++by)
    for (int bx = 0; bx < blocks_x; ++bx) {
      Decode(blocks + (size_t(by) * size_t(blocks_x) + size_t(bx)) * kBlockBytes, px, rounding);
      for (int r = 0; r < 4; ++r)
        std::memcpy(rgba + ((size_t(by) * 4 + size_t(r)) * width + size_t(bx) * 4) * 4, px + 16 * r, 16);
    }
}
}  // namespace

void decode_bc1_image(const uint8_t* blocks, int blocks_x, int blocks_y, uint8_t* rgba, BcRounding rounding) {
  decode_image<8, decode_bc1_block>(blocks, blocks_x, blocks_y, rounding, rgba);
}
void decode_bc3_image(const uint8_t* blocks, int blocks_x, int blocks_y, uint8_t* rgba, BcRounding rounding) {
  decode_image<16, decode_bc3_block>(blocks, blocks_x, blocks_y, rounding, rgba);
}
void decode_bc1_image(const uint8_t* blocks, int blocks_x, int blocks_y, uint8_t* rgba) {
  decode_bc1_image(blocks, blocks_x, blocks_y, rgba, BcRounding::nearest);
}
void decode_bc3_image(const uint8_t* blocks, int blocks_x, int blocks_y, uint8_t* rgba) {
  decode_bc3_image(blocks, blocks_x, blocks_y, rgba, BcRounding::nearest);
}

uint16_t bc1_transparent_mask(const uint8_t block[8]) {
  const uint16_t c0 = uint16_t(block[0] | (block[1] << 8)), c1 = uint16_t(block[2] | (block[3] << 8));
  if (c0 > c1) return 0;
  const uint32_t idx = uint32_t(block[4]) | (uint32_t(block[5]) << 8) | (uint32_t(block[6]) << 16) | (uint32_t(block[7]) << 24);
  uint16_t m = 0;
  for (int i = 0; i < 16; ++i)
    if (((idx >> (2 * i)) & 3) == 3) m = uint16_t(m | (1u << i));
  return m;
}

uint8_t bc1_texel_alpha(const uint8_t* blocks, int blocks_x, int t, int u) {
  const uint8_t* b = blocks + (size_t(u / 4) * size_t(blocks_x) + size_t(t / 4)) * 8;
  const uint16_t c0 = uint16_t(b[0] | (b[1] << 8));
  const uint16_t c1 = uint16_t(b[2] | (b[3] << 8));
  if (c0 > c1) return 255;
  const int p = (u % 4) * 4 + (t % 4);
  const int index = (b[4 + p / 4] >> (2 * (p % 4))) & 3;
  return index == 3 ? 0 : 255;
}

int decode_hole_mask(const NodeData& node, uint8_t* holes) {
  int count = 0;
  for (int j = 0; j < kHeightSamples; ++j)
    for (int i = 0; i < kHeightSamples; ++i) {
      const bool hole = bc1_texel_alpha(node.albedo_bc1.data(), kTexelBlocks, i + kApron, j + kApron) == 0;
      holes[j * kHeightSamples + i] = hole ? 1 : 0;
      count += hole ? 1 : 0;
    }
  return count;
}

}  // namespace terrain
