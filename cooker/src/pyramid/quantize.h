// Crack-free height quantization by construction.
//
// A vertex's canonical value (integer units of 2^-10 m) is decided once, by the COARSEST level
// whose lattice contains it, rounded to that level's step 2^step_log2[L]. Steps never decrease
// towards the roots, so a value rounded at level L is a multiple of every finer level's step and
// every node that holds the vertex (neighbours, parent, children) stores it exactly with its
// offset (the node's minimum, itself such a multiple): the shader's dequantized floats are
// bit-identical on both sides of every edge.
#pragma once
#include <array>
#include <cmath>
#include <cstdint>

#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::cook {

// Level-0 lattice index (0.5 m steps from the grid origin) -> coarsest level whose lattice holds it.
inline int vertex_level(int64_t gx, int64_t gy) {
  const uint64_t bits = uint64_t(gx | gy);
  if (bits == 0) return kRootLevel;
  const int tz = __builtin_ctzll(bits);
  return tz < kRootLevel ? tz : kRootLevel;
}

// Height (metres) rounded to a multiple of 2^step_log2 units (all scalings are powers of two,
// hence exact: the result depends on h_m and the step only).
inline int64_t quantize_units(double h_m, int step_log2) {
  return int64_t(std::floor(h_m * std::ldexp(1024.0, -step_log2) + 0.5)) * (int64_t(1) << step_log2);
}
// The same with the scale 2^(10 - step_log2) precomputed (hot loops).
inline int64_t quantize_units(double h_m, double scale, int step_log2) {
  const double v = h_m * scale + 0.5;  // |v| < 2^25 for any height the archive holds
  const int64_t t = int64_t(v);
  return (double(t) > v ? t - 1 : t) * (int64_t(1) << step_log2);
}

// A row of window vertices at once, each as compute_window's per-vertex loop does it: where ok[i],
// units[i] = quantize_units(h[i], scale[i], s) with step[i] = 2^s, and hole[i] = 0; elsewhere
// units 0 and hole 1 (h[i] is not read there). 4 lanes at a time (double arithmetic throughout: the
// products by powers of two are exact, so the bits are quantize_units'). False when a vertex with
// data lies beyond +-kMaxHeightUnits (or is NaN): units and holes are then undefined and the
// caller's per-vertex loop names the vertex.
bool quantize_row(const double* h, const uint8_t* ok, const double* scale, const double* step, int n, int32_t* units,
                  uint8_t* hole);

// The largest power of two of units <= metres, at least 1 unit, at most 2^14 (kMaxStepLog2).
int step_at_most(double metres);
// The coarsest step the tolerance allows: step_at_most(tolerance / 32) (2^4 units = 15.6 mm at
// 0.5 m). Rounding then costs at most 1/64 of the tolerance, and no bits are spent on sensor noise
// far below it.
int tolerance_step(double tolerance_m);

// The step of a level, chosen just before the level is cooked, from an upper bound on the surface
// range of its nodes (metres): the smallest step with every node's range in 16 bits (the caller
// takes the larger of it and tolerance_step()). A node's
// values are rounded at its own and coarser levels, by up to half the root step each way, so the
// root step widens the range (`root_step` < 0: this is the root level, use its own step). The
// caller caps it at the next coarser level's step (steps never decrease towards the roots; a
// child's range bound never exceeds its parent's, so the cap does not bind in practice).
int required_step(double range_bound_m, int root_step);

// Packs a node's 129x129 canonical units (rows of `stride` elements from the south-west vertex)
// into R16 values and the record's height_offset, min_height, max_height and hole flag. `hole`
// marks vertices without terrain (stored as r = 0). Returns `internal` when a value does not fit
// (the step choice guarantees it does) and `no_data` when every vertex is a hole.
Status pack_heights(const int32_t* units, const uint8_t* hole, int stride, int step_log2, NodeRecord& record,
                    std::array<uint16_t, kHeightCount>& r16);

}  // namespace terrain::cook
