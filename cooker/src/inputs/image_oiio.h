// The image (PNG/EXR) reader's C interface. OpenImageIO drags some 150 shared libraries into a
// process (ffmpeg, OpenCV, OpenVDB, ...), whose dynamic linking costs more than a small work unit
// cooks (cooker/README.md, "Figures behind the code"). terrain-cook therefore loads it only when an
// image input is given, so a process without image inputs never maps OpenImageIO: image_oiio.cpp
// is built both into terrain_cooker (linked) and as the module terrain-image-oiio.so, which
// image_api_dlopen.cpp opens on first use. No OIIO type crosses it.
#pragma once
#include <cstddef>

#include "terrain/status.h"

extern "C" {

struct TerrainImage;  // an open image
struct TerrainImageSpec {
  int width = 0, height = 0, nchannels = 0, depth = 0;
  char format_name[64] = {};  // "png", "openexr"
  char type_name[32] = {};    // "uint16", "float"
};
// Opens `path`; null on failure with the reason in `error`.
TerrainImage* terrain_image_open(const char* path, TerrainImageSpec* spec, char* error, size_t error_size);
// Channel 0 into `out` (width * height floats): integer types as their values (no normalisation
// to 0..1), others as float. 0 on failure with the reason in `error`.
int terrain_image_read_channel0(TerrainImage* image, float* out, char* error, size_t error_size);
void terrain_image_close(TerrainImage* image);
}

namespace terrain::cook {

struct ImageApi {
  decltype(&terrain_image_open) open = nullptr;
  decltype(&terrain_image_read_channel0) read_channel0 = nullptr;
  decltype(&terrain_image_close) close = nullptr;
};
// The reader: linked in (image_api_static.cpp) or loaded on first use (image_api_dlopen.cpp).
Status image_api(const ImageApi*& api);

}  // namespace terrain::cook
