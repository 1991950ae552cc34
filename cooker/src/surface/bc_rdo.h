// Rate-distortion pass over a node's encoded BC blocks: where the error allows it, a
// block half is replaced by one an earlier block already holds, or takes an earlier block's index
// bits, so that zstd stores it as a short match instead of literals (the idea of Binomial's
// bc7enc_rdo, on our normals and albedo). It only chooses among valid blocks: any decoder reads
// the result, and the format is unchanged.
#pragma once
#include <cstdint>

namespace terrain::cook {

struct RdoCounts {
  uint64_t blocks = 0;
  uint64_t half_copies = 0;   // an 8-byte half (an albedo block) taken whole from an earlier block
  uint64_t index_copies = 0;  // own (or refitted) endpoints, an earlier block's index bits
};

// lambda: squared error (8-bit channel units, summed over the block's 16 texels) accepted per
// byte of literals a substitution is expected to save; 0 leaves the blocks as they are.
//
// Normals (BC3 blocks of a 132x132 RGBA8 image, A = x, G = y, R = the block's AO, B = 0): the
// alpha half and the colour half are chosen separately against x and y. A colour half is only
// taken from a block with the same R and B endpoint bits (the AO stays exact).
void rdo_normal_blocks(const uint8_t* rgba, float lambda, uint8_t* blocks, RdoCounts* counts = nullptr);

// Albedo (BC1 blocks of a 132x132 RGBA8 image, alpha < 128 = hole): a block is taken whole from an
// earlier block with the same transparency mask, or (4-colour blocks) keeps its endpoints and takes
// an earlier block's selectors, against the squared RGB error of its texels with data; the hole
// texels stay exactly transparent. The image's squared error grows by at most 10 % in all (a block
// may spend whatever is left, in stream order), so its PSNR drops by at most 0.41 dB.
void rdo_albedo_blocks(const uint8_t* rgba, float lambda, uint8_t* blocks, RdoCounts* counts = nullptr);

// Tests: whether the normal pass may search its sources 8 at a time with AVX2 (on by default where
// the CPU has it); returns the previous setting. Either way the pass gives the same bytes.
bool rdo_avx2_scan(bool enabled);
// Tests: whether the normal pass gives a block the previous block's bytes without searching where
// that block decodes exactly to its x and y (the search's own choice there; on by default);
// returns the previous setting. Either way the pass gives the same bytes.
bool rdo_neighbour_shortcut(bool enabled);

}  // namespace terrain::cook
