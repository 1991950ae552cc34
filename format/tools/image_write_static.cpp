// image_writer() with the writer linked in (terrain_image_write_linked: tests, terrain-export).
#include "image_write.h"

namespace terrain::inspect {

Status image_writer(ImageWriteFn& write) {
  write = &terrain_image_write;
  return Status::success();
}

}  // namespace terrain::inspect
