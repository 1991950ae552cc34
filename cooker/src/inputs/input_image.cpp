// Heightmap images from game tools (PNG 8/16-bit grey, EXR float) through OpenImageIO, behind the
// C interface of image_oiio.h. They carry no georeferencing: --origin, --spacing and --crs give it
// (inputs.cpp).
#include <cmath>
#include <fmt/format.h>

#include "inputs/image_oiio.h"
#include "inputs/inputs.h"

namespace terrain::cook {

Status read_image(const std::string& path, const ReadOptions& options, Raster& out) {
  const ImageApi* api = nullptr;
  if (Status st = image_api(api); !st.ok())
    return Status::failure(st.code, fmt::format("{}: cannot read images: {}", path, st.message));
  char error[512] = {};
  TerrainImageSpec spec;
  TerrainImage* image = api->open(path.c_str(), &spec, error, sizeof error);
  if (!image) return Status::failure(Error::io_open, fmt::format("{}: cannot open as an image ({})", path, error));
  struct Closer {
    const ImageApi* api;
    TerrainImage* image;
    ~Closer() { api->close(image); }
  } closer{api, image};
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels < 1 || spec.depth != 1)
    return Status::failure(Error::unsupported_input, fmt::format("{}: unsupported image layout", path));
  if (int64_t(spec.width) * spec.height > (int64_t(1) << 32))
    return Status::failure(Error::unsupported_input, fmt::format("{}: image too large", path));
  // The raster and the native-type copy the reader makes.
  if (Status st = check_raster_memory(path, uint64_t(spec.width), uint64_t(spec.height), spec.type_name, options,
                                      uint64_t(spec.width) * uint64_t(spec.height) * 4);
      !st.ok())
    return st;
  out = Raster{};
  out.nodata_declared = options.nodata_value.has_value();
  out.path = path;
  out.width = spec.width;
  out.height = spec.height;
  out.values.resize(size_t(spec.width) * size_t(spec.height));
  if (!api->read_channel0(image, out.values.data(), error, sizeof error))
    return Status::failure(Error::io_read, fmt::format("{}: {}", path, error));
  if (options.nodata_value) {
    const float nd = float(*options.nodata_value);
    for (float& v : out.values)
      if (v == nd) v = NAN;
  }
  for (float& v : out.values)
    if (!std::isfinite(v)) v = NAN;
  out.description = fmt::format("{} image {} {}x{} ({} channel{})", spec.format_name, spec.type_name, spec.width,
                                spec.height, spec.nchannels, spec.nchannels > 1 ? "s, first used" : "");
  return Status::success();
}

}  // namespace terrain::cook
