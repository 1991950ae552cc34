// Which input wins where inputs overlap (CookOptions::overlap): the order in which the mosaic
// (mosaic_source.h) lets inputs take precedence, and so whose grid and CRS it reads them on.
#pragma once
#include <cstddef>
#include <span>
#include <vector>

#include "inputs/raster.h"

namespace terrain::cook {

// The sample spacing of `r` in ground metres at its centre: the geometric mean of its two axes'
// spacings (so the finer of two inputs is the one with more samples per square metre). Geographic
// rasters: on a sphere of the mean Earth radius (6371008.8 m), the east axis scaled by the cosine of
// the centre's latitude; projected and local rasters: their CRS metres.
double ground_spacing_m(const Raster& r);
// Its two axes' spacings (east, north) in ground metres, as ground_spacing_m takes them.
void ground_spacing_axes_m(const Raster& r, double& sx, double& sy);

// The order of precedence of `rasters` (indices into it) under the rule "finer wins": by
// ground_spacing_m, finest first. Rasters on one grid family (same CRS and spacing in CRS units,
// needs_resampling() false: tiles of one dataset) share the key of the finest of them, so they keep
// list order among themselves at any latitude; equal keys keep list order. The keys are a function
// of the set of rasters, so the same inputs in any order give the same precedence up to equal keys.
std::vector<size_t> finer_first_order(std::span<const Raster* const> rasters);

}  // namespace terrain::cook
