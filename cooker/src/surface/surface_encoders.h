// Image-level encoding helpers shared by cook_surface_layers(), the tests and terrain-bc-bench.
#pragma once
#include <cstdint>

#include "bc_blocks.h"
#include "surface_layers.h"

namespace terrain::cook {

// Encoder chosen by the quality knob (format/SPEC.md section 16.6 explains the defaults).
Bc1Method albedo_method(BcQuality q);
Bc3Method normals_method(BcQuality q);

// 132x132 RGBA8 -> 33x33 blocks (block rows south to north, like the texels).
void encode_bc1_image(const uint8_t* rgba, Bc1Method method, uint8_t* out_blocks);

struct AlbedoCheck {
  uint64_t alpha_mismatches = 0;  // texels whose decoded alpha differs from the hole flag
  uint64_t holes = 0;
  double sq_err = 0;              // over the colour channels of non-hole texels
  uint64_t samples = 0;
};
AlbedoCheck check_albedo(const uint8_t* rgba, const uint8_t* bc1_blocks);
// Holes and alpha mismatches only (sq_err and samples stay 0), read from the block bits: a BC1
// texel is transparent exactly when its block has colour0 <= colour1 and its index is 3.
AlbedoCheck check_albedo_alpha(const uint8_t* rgba, const uint8_t* bc1_blocks);
double psnr_db(double sq_err, uint64_t samples);

}  // namespace terrain::cook
