// The image (PNG/EXR) writer of terrain-inspect --export. OpenImageIO would cost every run of the
// tool ~0.35 s of CPU to start (tool_module.h), so terrain-inspect loads it only when it writes an
// image: image_write_oiio.cpp is built both into terrain_image_write_linked (library users, tests,
// terrain-export) and as the module terrain-image-write-oiio.so, which image_write_dlopen.cpp
// opens on first use. No OIIO type crosses it.
#pragma once
#include <cstddef>

#include "terrain/status.h"

extern "C" {

enum TerrainPixelType { terrain_pixel_u8 = 0, terrain_pixel_u16 = 1, terrain_pixel_f32 = 2 };
// Writes `width` x `height` pixels of `nchannels` channels to `path` (the format from its
// extension), image row 0 from `first_row`, each next row `row_stride` bytes after it (negative:
// rows stored bottom up). Colour is straight (unassociated) alpha. 0 on failure with the reason in
// `error`.
int terrain_image_write(const char* path, int width, int height, int nchannels, int pixel_type, const void* first_row,
                        ptrdiff_t row_stride, char* error, size_t error_size);
}

namespace terrain::inspect {

using ImageWriteFn = decltype(&terrain_image_write);
// The writer: linked in (image_write_static.cpp) or loaded on first use (image_write_dlopen.cpp).
Status image_writer(ImageWriteFn& write);

}  // namespace terrain::inspect
