// read_image() for builds of the cooker without OpenImageIO (terrain_cooker_noimage, used by the
// tests so their processes start without OIIO's ~260 shared libraries).
#include <fmt/format.h>

#include "inputs/inputs.h"

namespace terrain::cook {

Status read_image(const std::string& path, const ReadOptions&, Raster&) {
  return Status::failure(Error::unsupported_input,
                         fmt::format("{}: this build of the cooker has no image (PNG/EXR) input; use terrain-cook", path));
}

}  // namespace terrain::cook
