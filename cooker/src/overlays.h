// The overlay rasters of a cook (--albedo orthophoto, --holes mask, --landcover classes): read,
// mapped from their own CRS to the frame and sampled at the node window vertices.
#pragma once
#include <memory>
#include <vector>

#include "surface/surface_layers.h"
#include "terrain/cook.h"
#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::cook {

// Reads the overlays `o` names (none: `out` stays null) and maps each to `frame` over the frame
// rectangle [x0, x1] x [y0, y1] (metres: the root grid with its window margin). Fails on a raster
// that does not overlap that rectangle, on a bad --landcover-table and with --heights-only.
Status load_overlays(const CookOptions& o, const FrameCrs& frame, const std::vector<Material>& palette, double x0,
                     double y0, double x1, double y1, int threads, std::unique_ptr<SurfaceOverlays>& out);

}  // namespace terrain::cook
