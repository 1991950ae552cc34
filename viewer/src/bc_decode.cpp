#include "bc_decode.h"

#include <cstring>

namespace terrain::view {
namespace {

void expand565(uint16_t c, int rgb[3]) {
  const int r = (c >> 11) & 31, g = (c >> 5) & 63, b = c & 31;
  rgb[0] = (r << 3) | (r >> 2);
  rgb[1] = (g << 2) | (g >> 4);
  rgb[2] = (b << 3) | (b >> 2);
}

// `four_colour`: BC3 colour blocks always use the 4-colour mode.
void decode_colour(const uint8_t* b, bool force_four_colour, uint8_t out[16][4]) {
  const uint16_t c0 = uint16_t(b[0] | b[1] << 8), c1 = uint16_t(b[2] | b[3] << 8);
  int p[4][4];
  expand565(c0, p[0]);
  expand565(c1, p[1]);
  p[0][3] = p[1][3] = p[2][3] = 255;
  p[3][3] = 255;
  if (force_four_colour || c0 > c1) {
    for (int k = 0; k < 3; ++k) {
      p[2][k] = (2 * p[0][k] + p[1][k]) / 3;
      p[3][k] = (p[0][k] + 2 * p[1][k]) / 3;
    }
  } else {
    for (int k = 0; k < 3; ++k) {
      p[2][k] = (p[0][k] + p[1][k]) / 2;
      p[3][k] = 0;
    }
    p[3][3] = 0;
  }
  const uint32_t bits = uint32_t(b[4]) | uint32_t(b[5]) << 8 | uint32_t(b[6]) << 16 | uint32_t(b[7]) << 24;
  for (int t = 0; t < 16; ++t) {
    const int code = (bits >> (2 * t)) & 3;
    for (int k = 0; k < 4; ++k) out[t][k] = uint8_t(p[code][k]);
  }
}

void decode_alpha(const uint8_t* b, uint8_t out[16][4]) {
  const int a0 = b[0], a1 = b[1];
  int a[8] = {a0, a1};
  if (a0 > a1) {
    for (int k = 1; k < 7; ++k) a[k + 1] = ((7 - k) * a0 + k * a1) / 7;
  } else {
    for (int k = 1; k < 5; ++k) a[k + 1] = ((5 - k) * a0 + k * a1) / 5;
    a[6] = 0;
    a[7] = 255;
  }
  uint64_t bits = 0;
  for (int k = 0; k < 6; ++k) bits |= uint64_t(b[2 + k]) << (8 * k);
  for (int t = 0; t < 16; ++t) out[t][3] = uint8_t(a[(bits >> (3 * t)) & 7]);
}

template <int BlockBytes, void (*Decode)(const uint8_t*, uint8_t[16][4])>
void decode_image(const uint8_t* blocks, int width, int height, uint8_t* out) {
  const int bw = width / 4, bh = height / 4;
  uint8_t texels[16][4];
  for (int by = 0; by < bh; ++by)
    for (int bx = 0; bx < bw; ++bx) {
      Decode(blocks + (size_t(by) * bw + bx) * BlockBytes, texels);
      for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i)
          std::memcpy(out + ((size_t(by) * 4 + j) * width + bx * 4 + i) * 4, texels[j * 4 + i], 4);
    }
}

void bc1_block(const uint8_t* b, uint8_t out[16][4]) { decode_bc1_block(b, out); }
void bc3_block(const uint8_t* b, uint8_t out[16][4]) { decode_bc3_block(b, out); }

}  // namespace

void decode_bc1_block(const uint8_t block[8], uint8_t out[16][4]) { decode_colour(block, false, out); }

void decode_bc3_block(const uint8_t block[16], uint8_t out[16][4]) {
  decode_colour(block + 8, true, out);
  decode_alpha(block, out);
}

void decode_bc1_image(const uint8_t* blocks, int width, int height, uint8_t* out) {
  decode_image<8, bc1_block>(blocks, width, height, out);
}
void decode_bc3_image(const uint8_t* blocks, int width, int height, uint8_t* out) {
  decode_image<16, bc3_block>(blocks, width, height, out);
}

}  // namespace terrain::view
