// terrain_image_write() through OpenImageIO (image_write.h): linked into terrain_image_write_linked
// and built as the module terrain-image-write-oiio.so.
#include <OpenImageIO/imageio.h>

#include <cstdio>
#include <string>

#include "image_write.h"

namespace {

int fail(char* error, size_t error_size, const std::string& what) {
  if (error && error_size) std::snprintf(error, error_size, "%s", what.c_str());
  return 0;
}

}  // namespace

extern "C" __attribute__((visibility("default"))) int terrain_image_write(const char* path, int width, int height,
                                                                          int nchannels, int pixel_type,
                                                                          const void* first_row, ptrdiff_t row_stride,
                                                                          char* error, size_t error_size) {
  OIIO::TypeDesc type = OIIO::TypeDesc::UINT8;
  if (pixel_type == terrain_pixel_u16) type = OIIO::TypeDesc::UINT16;
  else if (pixel_type == terrain_pixel_f32) type = OIIO::TypeDesc::FLOAT;
  else if (pixel_type != terrain_pixel_u8) return fail(error, error_size, "unknown pixel type");
  auto o = OIIO::ImageOutput::create(path);
  if (!o) return fail(error, error_size, "no image writer for this extension");
  OIIO::ImageSpec spec(width, height, nchannels, type);
  // The bytes are straight (unassociated) colour: without this, OIIO divides RGB by alpha.
  spec.attribute("oiio:UnassociatedAlpha", 1);
  if (!o->open(path, spec)) return fail(error, error_size, o->geterror());
  if (!o->write_image(type, first_row, OIIO::AutoStride, OIIO::stride_t(row_stride)) || !o->close())
    return fail(error, error_size, o->geterror());
  return 1;
}
