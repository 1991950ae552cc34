// Small exact BC encoders for the synthetic worlds (synthetic_archive.h): each picks its indices
// against the palette terrain/bc_decode.h decodes (BcRounding::truncate, as lavapipe samples), so
// the stored blocks decode to known values. Blocks are 4x4 texels, row-major.
#pragma once
#include <cstdint>

namespace terrain::synthetic {

// BC1; a block with a texel of alpha < 128 uses the 3-colour mode with index 3 = hole.
void encode_bc1(const uint8_t rgba[16][4], uint8_t out[8]);

// BC3 alpha (8-value mode); `conservative`: every texel decodes to >= its target (see the .cpp).
void encode_bc3_alpha(const uint8_t target[16], bool conservative, uint8_t out[8]);

// BC3 colour block (4-colour mode).
void encode_bc3_colour(const uint8_t rgba[16][4], uint8_t out[8]);

}  // namespace terrain::synthetic
