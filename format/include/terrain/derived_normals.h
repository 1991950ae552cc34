// Normals section codec 4, `normals_derived` (SPEC 16.7): the normal texels of a node rebuilt from
// its own heights, so the payload stores only what the heights cannot give: the 2-texel apron
// (the neighbours' cells) and the block ambient occlusion.
#pragma once
#include <array>
#include <cstdint>

#include "terrain/format.h"

namespace terrain {

inline constexpr int kNormalsApronTexels = kTexels * kTexels - 128 * 128;  // 1040
inline constexpr int kNormalsBlocks = (kTexels / 4) * (kTexels / 4);        // 1089

// What a codec-4 normals section stores (its zstd frame holds these bytes in this order, SPEC 16.7).
struct NormalsDerivation {
  // Metres of rise per height unit and per vertex spacing: step(L) / s(L), in (0, kMaxRisePerUnit].
  float rise_per_unit = 0;
  // Apron texels (t or u in {0, 1, 130, 131}), row-major south to north, west to east: x8 then y8
  // (the A and G bytes of SPEC 16.2).
  std::array<uint8_t, 2 * kNormalsApronTexels> apron{};
  // Block ambient occlusion q (0..31) of the 33 x 33 blocks, row-major.
  std::array<uint8_t, kNormalsBlocks> ao{};
};
inline constexpr uint32_t kNormalsDerivationBytes = 4 + 2 * kNormalsApronTexels + kNormalsBlocks;  // 3173
// Largest rise_per_unit a reader accepts: 32x the largest a valid archive has (a step of 2^14
// units = 16 m over level 0's 0.5 m spacing).
inline constexpr float kMaxRisePerUnit = 1024.0f;

// Serialised form (little-endian float bits) and its parse; parse fails on a size other than
// kNormalsDerivationBytes, a rise outside (0, kMaxRisePerUnit], or an AO value above 31.
void store_normals_derivation(const NormalsDerivation& d, uint8_t out[kNormalsDerivationBytes]);
bool load_normals_derivation(const uint8_t* bytes, size_t size, NormalsDerivation& out);

// The 132 x 132 normal texels (RGBA8: R = AO byte, G = y8, B = 0, A = x8, SPEC 16.2) of a node from
// its heights (129 x 129 units, row-major) and hole mask (129 x 129, 1 = hole; may be null): the
// interior texels' cell gradients with SPEC 16.2's rule (a hole vertex is a missing corner), the
// apron and AO from `d`.
void derive_normal_texels(const uint16_t* heights, const uint8_t* holes, const NormalsDerivation& d,
                          uint8_t rgba[kTexels * kTexels * 4]);

// The BC3 encoding of such texels that every reader uses for codec 4 (deterministic, integer only):
// per block, alpha endpoints min/max of x8; colour endpoints R = the block's AO, B = 0, G the best
// of two six-bit endpoint pairs (the nearest to its min/max of y8, and the tightest covering them).
void encode_derived_normals_bc3(const uint8_t rgba[kTexels * kTexels * 4], uint8_t bc3[kNormalsBytes]);
// The same, a texel at a time: the definition the SSE2 form (x86-64) is tested against.
void encode_derived_normals_bc3_reference(const uint8_t rgba[kTexels * kTexels * 4], uint8_t bc3[kNormalsBytes]);

}  // namespace terrain
