// BC1 / BC3 / BC4 block encoding for the surface layers. What it wrote is checked with the format
// library's decoder (punch-through holes, cone margins, error statistics).
//
// Encoders: libsquish (range fit, cluster fit, iterative cluster fit; the only library encoder
// with BC1 punch-through), stb_dxt (fast, 4-colour only) and ours (bc1_encoder.cpp, bc4_encoder.cpp). Every BC1
// block is verified after encoding: a texel decodes transparent exactly when it is a hole.
#pragma once
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "terrain/bc_decode.h"
#include "terrain/format.h"

namespace terrain::cook {

// Decoding (decode_bc1/bc3/bc4_block, bc1_transparent_mask) is the format library's
// terrain/bc_decode.h: one decoder for cooker, runtime and tests.
// ---- BC1 --------------------------------------------------------------------------------
enum class Bc1Method : uint8_t {
  stb,               // stb_dxt, one refinement step
  stb_hq,            // stb_dxt STB_DXT_HIGHQUAL (two refinement steps)
  squish_range,      // libsquish range fit (uniform RGB metric)
  squish_cluster,    // libsquish cluster fit (uniform RGB metric)
  squish_iterative,  // libsquish iterative cluster fit (uniform RGB metric)
  // This project's encoder (bc1_encoder.cpp): endpoints from the colours' principal axis.
  axis_fit,          // one endpoint refit; our 3-colour fit for hole blocks
  axis_fit_hard,     // one refit, up to 4 on hard blocks (mean sq. error > 8 per channel)
  best_of_axis_fit_and_squish,  // per block the better of (two refits, hard-block refits, 3-colour try) and
                                // libsquish cluster fit
  ordering_search,   // `axis_fit_hard` plus two sweeps of our ordering search (a cheap cluster fit) on every
                     // block with error: >= libsquish cluster-fit PSNR on every bench set in a fraction of
                     // its time, but slower than `axis_fit_hard` (not a default; cooker/README.md)
};
const char* bc1_method_name(Bc1Method m);

// Encodes 16 RGBA8 texels; a texel with alpha < 128 is a hole. The result always satisfies:
// every hole texel decodes transparent, every other texel decodes opaque (stb and our encoder
// are used for hole-free blocks only; blocks with holes go to libsquish, and a block that fails
// the check is re-encoded by a small exact 3-colour fallback).
void encode_bc1_block(const uint8_t rgba[64], Bc1Method method, uint8_t out[8]);

// ---- BC3 (world-space normals: RGB colour block + alpha block) -------------------------
enum class Bc3Method : uint8_t {
  stb,             // stb_dxt (alpha: min/max, colour: PCA + 1 refinement, uniform RGB)
  stb_hq,          // stb_dxt high quality
  squish_cluster,  // libsquish kDxt5 cluster fit, colour metric weighted toward G
  g_axis_fit,      // this project's alpha encoder + G-weighted axis fit, one refinement (bc1_encoder.cpp)
  g_axis_fit_hq,   // the same with two refinements and a wider endpoint search
};
const char* bc3_method_name(Bc3Method m);
void encode_bc3_block(const uint8_t rgba[64], Bc3Method method, uint8_t out[16]);

// ---- Block encoders of this project (bc1_encoder.cpp, bc4_encoder.cpp) -----------------
// Effort of the opaque BC1 encoder (thresholds: squared RGB error summed over the block, i.e.
// 48 x the mean squared error per channel). terrain-bc-bench --frontier sweeps the thresholds to
// chart speed against PSNR.
// `iterations`: endpoint refits (1 = fast default, 2 = better).
// `refine_hard`: blocks whose error stays high (several colour clusters) get up to 4 refits while
// they improve. `ordering_sweeps` > 0: every block with error above `ordering_threshold` then runs
// the ordering search (sorted along the principal axis, partitions ranked by their rounded
// least-squares error, see bc1_encoder.cpp). `three_colour_threshold` >= 0: blocks above it also
// try the 3-colour mode (index 3 unused). Smooth blocks cost the same either way.
struct Bc1OpaqueEffort {
  int iterations = 1;
  bool refine_hard = false;
  int ordering_sweeps = 0;
  float ordering_threshold = 16.0f;      // blocks above this error run the ordering search
  float three_colour_threshold = -1.0f;  // blocks above this error also try 3 colours (< 0: never)
};
// The 3-colour try of the `best_of_axis_fit_and_squish` setting: from a mean squared error of 4 per channel (it gains
// up to 0.1 dB on splat albedo but doubles the time, so only the best setting uses it).
inline constexpr float kBc1ThreeColourThreshold = 48.0f * 4.0f;
// The default's hard-block refits plus the given search and 3-colour settings.
inline Bc1OpaqueEffort hard_block_effort(int ordering_sweeps, float ordering_threshold, float three_colour_threshold) {
  Bc1OpaqueEffort e;
  e.refine_hard = true;
  e.ordering_sweeps = ordering_sweeps;
  e.ordering_threshold = ordering_threshold;
  e.three_colour_threshold = three_colour_threshold;
  return e;
}
// Opaque 4-colour BC1 (alpha ignored); never uses index 3 of a 3-colour block.
void encode_bc1_opaque(const uint8_t rgba[64], uint8_t out[8], const Bc1OpaqueEffort& effort);
// 3-colour punch-through block: texel i transparent iff bit i of `holes` (not all 16 set).
void encode_bc1_holes(const uint8_t rgba[64], uint16_t holes, uint8_t out[8], int iterations = 2);
// Colour block for normals: minimises w_r*dR^2 + w_g*dG^2 + w_b*dB^2 (G carries the normal).
void encode_bc1_weighted(const uint8_t rgba[64], const float weights[3], uint8_t out[8]);
// Colour block when R and B are constant and exactly representable (normal maps): exhaustive-ish
// 1D fit of G. Returns false (nothing written) when the block does not qualify.
bool encode_bc1_g_only(const uint8_t rgba[64], uint8_t out[8], int iterations = 1);
// The 8 values a BC4 block with endpoints a0, a1 decodes to, exactly as decode_bc4_block (nearest
// rounding) computes them (the encoder and the rate-distortion pass, bc_rdo.cpp).
void bc4_palette(int a0, int a1, int pal[8]);
// Nearest 8-value-mode entry of BC4 endpoints a0 > a1 for each value: selectors, positions u
// (0 = a1 .. 7 = a0) and the summed squared error. bc4_assign8 is the SSE2 restatement where it
// is compiled in; both write the same values (tests compare them over every endpoint pair).
int bc4_assign8(const uint8_t v[16], int a0, int a1, uint8_t sel[16], int u_out[16]);
int bc4_assign8_scalar(const uint8_t v[16], int a0, int a1, uint8_t sel[16], int u_out[16]);
// BC4 block of 16 values minimising squared error (tries both endpoint orders / modes).
void encode_bc4(const uint8_t values[16], uint8_t out[8]);
// The same with the refit's 9 candidate pairs ranked one by one: the definition encode_bc4's SSE2
// ranking is tested against.
void encode_bc4_scalar(const uint8_t values[16], uint8_t out[8]);
// BC4 block whose decoded values are >= the targets (and as small as possible): conservative
// storage of cone angles (255 always works, so it never fails).
void encode_bc4_upper(const uint8_t targets[16], uint8_t out[8]);

// The opaque, weighted and G-only encoders have one definition in plain scalar C++ and an SSE2
// restatement that writes the same bytes; the functions above take the SSE2 one when it is
// compiled in (bc1_simd_compiled()). These force the scalar one (tests, terrain-bc-bench).
bool bc1_simd_compiled();
void encode_bc1_opaque_scalar(const uint8_t rgba[64], uint8_t out[8], const Bc1OpaqueEffort& effort);
void encode_bc1_weighted_scalar(const uint8_t rgba[64], const float weights[3], uint8_t out[8]);
bool encode_bc1_g_only_scalar(const uint8_t rgba[64], uint8_t out[8], int iterations = 1);

// The 33 x 33 blocks of a 132 x 132 RGBA8 image in stream order, each through encode(block, out)
// into `block_bytes` bytes; a block equal to the one before it takes that block's bytes without
// encoding (the encoders are functions of the block alone; flat ground, the sea, repeats its
// blocks). encode_bc1_image and encode_bc3_image.
template <class Encode>
void encode_image_blocks(const uint8_t* rgba, size_t block_bytes, uint8_t* out_blocks, Encode&& encode) {
  uint8_t block[64], previous[64];
  const uint8_t* previous_out = nullptr;
  for (int by = 0; by < kTexelBlocks; ++by)
    for (int bx = 0; bx < kTexelBlocks; ++bx) {
      for (int r = 0; r < 4; ++r) std::memcpy(block + r * 16, rgba + (size_t((by * 4 + r) * kTexels + bx * 4)) * 4, 16);
      uint8_t* out = out_blocks + size_t(by * kTexelBlocks + bx) * block_bytes;
      if (previous_out && std::memcmp(block, previous, sizeof block) == 0) {
        std::memcpy(out, previous_out, block_bytes);
        continue;
      }
      encode(block, out);
      std::memcpy(previous, block, sizeof block);
      previous_out = out;
    }
}

}  // namespace terrain::cook
