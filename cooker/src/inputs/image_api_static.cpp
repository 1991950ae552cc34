// image_api() with the reader linked in (terrain_cooker: library users, the fuzzer).
#include "inputs/image_oiio.h"

namespace terrain::cook {

Status image_api(const ImageApi*& api) {
  static const ImageApi linked{&terrain_image_open, &terrain_image_read_channel0, &terrain_image_close};
  api = &linked;
  return Status::success();
}

}  // namespace terrain::cook
