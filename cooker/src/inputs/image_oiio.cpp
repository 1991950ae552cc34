// The OpenImageIO side of image_oiio.h.
#include "inputs/image_oiio.h"

#include <OpenImageIO/imageio.h>

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

namespace {
void set_error(char* error, size_t size, const std::string& text) {
  if (error && size) std::snprintf(error, size, "%s", text.c_str());
}
}  // namespace

struct TerrainImage {
  std::unique_ptr<OIIO::ImageInput> in;
};

extern "C" {

__attribute__((visibility("default"))) TerrainImage* terrain_image_open(const char* path, TerrainImageSpec* spec,
                                                                        char* error, size_t error_size) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    set_error(error, error_size, OIIO::geterror());
    return nullptr;
  }
  const OIIO::ImageSpec& s = in->spec();
  *spec = TerrainImageSpec{};
  spec->width = s.width;
  spec->height = s.height;
  spec->nchannels = s.nchannels;
  spec->depth = s.depth;
  std::snprintf(spec->format_name, sizeof spec->format_name, "%s", in->format_name());
  std::snprintf(spec->type_name, sizeof spec->type_name, "%s", s.format.c_str());
  return new TerrainImage{std::move(in)};
}

__attribute__((visibility("default"))) int terrain_image_read_channel0(TerrainImage* image, float* out, char* error,
                                                                       size_t error_size) {
  OIIO::ImageInput& in = *image->in;
  const OIIO::ImageSpec& spec = in.spec();
  const size_t n = size_t(spec.width) * size_t(spec.height);
  // Channel 0, read in its native integer type (no normalisation to 0..1) or as float.
  auto read_as = [&]<typename T>(OIIO::TypeDesc type, T) -> bool {
    std::vector<T> raw(n);
    if (!in.read_image(0, 0, 0, 1, type, raw.data())) return false;
    for (size_t i = 0; i < n; ++i) out[i] = float(raw[i]);
    return true;
  };
  bool ok = false;
  switch (spec.format.basetype) {
    case OIIO::TypeDesc::UINT8: ok = read_as(OIIO::TypeDesc::UINT8, uint8_t{}); break;
    case OIIO::TypeDesc::UINT16: ok = read_as(OIIO::TypeDesc::UINT16, uint16_t{}); break;
    case OIIO::TypeDesc::INT16: ok = read_as(OIIO::TypeDesc::INT16, int16_t{}); break;
    default: ok = read_as(OIIO::TypeDesc::FLOAT, float{}); break;
  }
  if (!ok) set_error(error, error_size, in.geterror());
  return ok ? 1 : 0;
}

__attribute__((visibility("default"))) void terrain_image_close(TerrainImage* image) {
  if (!image) return;
  image->in->close();
  delete image;
}

}  // extern "C"
