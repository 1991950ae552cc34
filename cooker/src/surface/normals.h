// World-space normals and the ambient-occlusion term of the 132x132 normal texels, their channel
// packing (format/SPEC.md section 16) and BC3 encoding.
#pragma once
#include <array>
#include <cstdint>

#include "bc_blocks.h"
#include "surface_layers.h"

namespace terrain::cook {

inline constexpr int kTexelCount = kTexels * kTexels;

struct NormalTexels {
  std::array<float, kTexelCount * 3> n{};                 // unit (x east, y north, z up), texel (t, u) at [(u*132+t)*3]
  std::array<float, kTexelBlocks * kTexelBlocks> ao{};    // per 4x4 block: 0 (occluded) .. 1 (open)
};

// Texel (t, u) covers the cell between vertices (t-2, u-2) and (t-1, u-1): its normal is the
// area-weighted mean of the two drawn triangles of that cell (= the cell-centre gradient).
void compute_normal_texels(const SurfaceInput& in, NormalTexels& out);

// Ambient occlusion per 4x4 texel block (constant over the block, so it costs the G channel no
// precision): the block's 5x5 vertices against the ring of vertices 2 spacings further out (the 9x9
// border): depth = max(0, mean(ring) - mean(inner)), ao = 1 / (1 + (depth / 4s)^2), i.e. cos^2 of
// the elevation angle of the surrounding ring seen from the block. Blocks align across node edges
// (texel t of a node is texel t + 128 of its western neighbour), so the values agree there.
// Channel layout: A = x, G = y (v8 = 128 + 127 * c), R = block AO quantised to a 5-bit value
// (exactly representable in BC1 endpoints; 255 = open), B = 0.
void pack_normal_texels(const NormalTexels& in, std::array<uint8_t, kTexelCount * 4>& rgba, bool ao_in_red = true);
// The same, a texel at a time: the definition the 4-texel SSE2 form is tested against.
void pack_normal_texels_per_texel(const NormalTexels& in, std::array<uint8_t, kTexelCount * 4>& rgba,
                                  bool ao_in_red = true);
// Normal rebuilt from a decoded (or uncompressed) texel exactly as the shader does.
void unpack_normal(const uint8_t rgba[4], float n[3]);

void encode_bc3_image(const uint8_t* rgba, Bc3Method method, uint8_t* out_blocks);

// Decodes each BC block of a kTexels x kTexels image (`decode(block, rgba64)`, blocks of
// `block_bytes`) and calls visit(k, rgba4) for its 16 texels, k being the texel's image index.
// The error checks of the normals (BC3) and the albedo (BC1) walk their images this way.
template <class Decode, class Visit>
void for_each_decoded_texel(const uint8_t* blocks, size_t block_bytes, Decode&& decode, Visit&& visit) {
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      uint8_t dec[64];
      decode(blocks + size_t(by * kTexelBlocks + bx) * block_bytes, dec);
      for (int i = 0; i < 16; ++i) visit(size_t((by * 4 + i / 4) * kTexels + bx * 4 + i % 4), dec + 4 * i);
    }
}

struct AngleStats {
  double sum_deg = 0, max_deg = 0;
  uint64_t count = 0;
};
// Angular error of the decoded BC3 normals against the float normals.
AngleStats normal_error(const NormalTexels& ref, const uint8_t* bc3_blocks);
// The same, a texel at a time: the definition normal_error (4 lanes) is tested against.
AngleStats normal_error_per_texel(const NormalTexels& ref, const uint8_t* bc3_blocks);

}  // namespace terrain::cook
