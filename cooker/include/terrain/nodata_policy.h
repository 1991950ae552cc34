// What the cook does with nodata samples (CookOptions::nodata). A light header: stage headers
// include it without the whole of terrain/cook.h.
#pragma once
#include <cstdint>

namespace terrain::cook {

// What happens to nodata samples (GDAL_NODATA, HGT -32768 voids, NaN in float input).
enum class NodataPolicy : uint8_t {
  automatic,  // voids enclosed by data and no larger than fill_max_samples are filled; the rest are holes
  hole,       // every nodata sample is a hole
  fill,       // every nodata sample is filled (holes only outside the inputs' footprint)
};

}  // namespace terrain::cook
