#include "image_io.h"

#include <OpenImageIO/imageio.h>

namespace terrain::view {

Status write_png(const std::string& path, const std::vector<uint8_t>& rgba, uint32_t width, uint32_t height) {
  std::vector<uint8_t> rgb(size_t(width) * height * 3);
  for (size_t i = 0, n = size_t(width) * height; i < n; ++i)
    for (int k = 0; k < 3; ++k) rgb[i * 3 + size_t(k)] = rgba[i * 4 + size_t(k)];
  auto out = OIIO::ImageOutput::create(path);
  if (!out) return Status::failure(Error::io_open, "cannot write " + path + ": " + OIIO::geterror());
  OIIO::ImageSpec spec(int(width), int(height), 3, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "sRGB");
  if (!out->open(path, spec)) return Status::failure(Error::io_open, "cannot write " + path + ": " + out->geterror());
  const bool ok = out->write_image(OIIO::TypeDesc::UINT8, rgb.data());
  const bool closed = out->close();
  if (!ok || !closed) return Status::failure(Error::io_write, "cannot write " + path + ": " + out->geterror());
  return Status::success();
}

}  // namespace terrain::view
