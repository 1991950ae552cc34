// Lossless codec for one node's 129x129 R16 heights: a hierarchical interpolating predictor
// (coarse-to-fine midpoints, see format/SPEC.md "Height section") followed by zstd.
// Exposed for benchmarks and tests; archive payloads use it through encode_node_payload().
#pragma once
#include <cstdint>
#include <span>
#include <vector>

#include "terrain/status.h"

namespace terrain {

// Residuals of the predictor, in the SPEC's order and byte layout, before zstd (replaces `out`).
void heights_to_residuals(std::span<const uint16_t> heights129, std::vector<uint8_t>& out);
// Inverse of heights_to_residuals. `residuals` must be exactly 2 * 129 * 129 bytes.
Status residuals_to_heights(std::span<const uint8_t> residuals, std::span<uint16_t> heights129);

// Common power-of-two factor: the largest t (0..15) such that every sample is a multiple of 2^t
// (15 for an all-zero grid). Integer-metre sources quantized at a fine step leave several low bits
// always zero; the payload then codes heights >> t and shifts back (SPEC "height_shift").
int heights_common_shift(std::span<const uint16_t> heights129);
// The same on heights >> shift; decoding shifts left by `shift`. Exact when shift <= heights_common_shift.
void heights_to_residuals(std::span<const uint16_t> heights129, int shift, std::vector<uint8_t>& out);
Status residuals_to_heights(std::span<const uint8_t> residuals, int shift, std::span<uint16_t> heights129);

}  // namespace terrain
