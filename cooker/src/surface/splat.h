// Splat material ids and the baked far-distance albedo.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "materials.h"
#include "surface_layers.h"

namespace terrain::cook {

// Splat lattice extended by one sample on each side: element (k, l) is node vertex
// (2k - 2, 2l - 2), k, l = 0..66; the node's 65x65 splat map is k, l = 1..65. The extra ring
// (taken from the window, i.e. the neighbours' data) lets the albedo apron blend real materials.
inline constexpr int kSplatLattice = kSplatSamples + 2;  // 67

struct SplatLattice {
  std::array<uint8_t, kSplatLattice * kSplatLattice> ids{};
};

// Attributes of node vertex (i, j) measured from the window (format/SPEC.md section 16.4).
// Returns false when the vertex has no data.
bool measure_sample(const SurfaceInput& in, int i, int j, SurfaceSample& out);

// Attributes a rule reads (the others are not measured: their values would never be looked at).
inline constexpr unsigned kNeedAspect = 1, kNeedCurvature = 2, kNeedAll = 3;
// The same from a window-shaped field h (raw or filtered heights), only the attributes in `needs`
// besides height and slope. False when the vertex has no data.
bool measure_field(const SurfaceInput& in, const float* h, int i, int j, SurfaceSample& out, unsigned needs);
// measure_field at the kLatticeRow vertices (2k - 6, j), k = 0 .. kLatticeRow - 1, of one row of
// the splat lattice with its two extra rings, in loops that vectorise: the same values (out[k],
// ok[k] = 1 where measure_field returns true; elements without data hold their position only).
inline constexpr int kLatticeRow = kSplatLattice + 4;  // 71
void measure_lattice_row(const SurfaceInput& in, const float* h, int j, unsigned needs, SurfaceSample* out,
                         uint8_t* ok);

// Gaussian-filtered heights of the window (sigma scale_m, radius 2 sigma capped by the margin) at
// the vertices the splat lattice measures (-8 .. 136; the rest of `out` is NaN): a normalized
// convolution in a fixed summation order (splat.cpp). False (out untouched) when sigma is under
// half a spacing: the lattice then reads the raw heights.
bool filter_heights(const float* h, double scale_m, double spacing_m, std::vector<float>& out);

// fields_seconds (optional): CPU seconds spent on the filtered height fields (the report's split).
void compute_splat_lattice(const SurfaceInput& in, const MaterialRules& rules, SplatLattice& out,
                           double* fields_seconds = nullptr);
// The despeckle passes of compute_splat_lattice (format/SPEC.md 16.4) on a kLatticeRow^2 lattice
// of ids with a data flag (0 or 1) per element, into the kSplatLattice^2 lattice ids (its inner
// part). _per_sample is the same passes without the neighbour counts that skip most samples:
// the definition the tests hold the fast form to.
void despeckle_lattice(const uint8_t* wide, const uint8_t* has, uint8_t* ids);
void despeckle_lattice_per_sample(const uint8_t* wide, const uint8_t* has, uint8_t* ids);
void copy_node_splat(const SplatLattice& lattice, std::array<uint8_t, kSplatCount>& splat);

// 132x132 RGBA8 (sRGB colour, alpha 0 = hole at the texel's south-west vertex): the bilinear blend
// (in linear light) of the palette colours of the 4 surrounding splat samples, each with a gentle
// world-space variation (amplitude = material detail_strength), or the orthophoto colour.
void bake_albedo(const SurfaceInput& in, const MaterialRules& rules, const SplatLattice& lattice, uint8_t* rgba);

}  // namespace terrain::cook
