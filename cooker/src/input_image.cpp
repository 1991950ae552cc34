// Heightmap images from game tools (PNG 8/16-bit grey, EXR float) through OpenImageIO. They carry
// no georeferencing: --origin, --spacing and --crs give it (inputs.cpp).
#include <OpenImageIO/imageio.h>

#include <cmath>
#include <fmt/format.h>

#include "inputs.h"

namespace terrain::cook {

Status read_image(const std::string& path, const ReadOptions& options, Raster& out) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) return Status::failure(Error::io_open, fmt::format("{}: cannot open as an image ({})", path, OIIO::geterror()));
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels < 1 || spec.depth != 1)
    return Status::failure(Error::unsupported_input, fmt::format("{}: unsupported image layout", path));
  if (int64_t(spec.width) * spec.height > (int64_t(1) << 32))
    return Status::failure(Error::unsupported_input, fmt::format("{}: image too large", path));
  const OIIO::TypeDesc fmt_in = spec.format;
  // The raster and the native-type copy read_as makes.
  if (Status st = check_raster_memory(path, uint64_t(spec.width), uint64_t(spec.height), fmt_in.c_str(), options,
                                      uint64_t(spec.width) * uint64_t(spec.height) * 4);
      !st.ok())
    return st;
  out = Raster{};
  out.nodata_declared = options.nodata_value.has_value();
  out.path = path;
  out.width = spec.width;
  out.height = spec.height;
  out.values.resize(size_t(spec.width) * size_t(spec.height));
  // Channel 0, read in its native integer type (no normalisation to 0..1) or as float.
  auto read_as = [&]<typename T>(OIIO::TypeDesc type, T) -> bool {
    std::vector<T> raw(out.values.size());
    if (!in->read_image(0, 0, 0, 1, type, raw.data())) return false;
    for (size_t i = 0; i < raw.size(); ++i) out.values[i] = float(raw[i]);
    return true;
  };
  bool ok = false;
  switch (fmt_in.basetype) {
    case OIIO::TypeDesc::UINT8: ok = read_as(OIIO::TypeDesc::UINT8, uint8_t{}); break;
    case OIIO::TypeDesc::UINT16: ok = read_as(OIIO::TypeDesc::UINT16, uint16_t{}); break;
    case OIIO::TypeDesc::INT16: ok = read_as(OIIO::TypeDesc::INT16, int16_t{}); break;
    default: ok = read_as(OIIO::TypeDesc::FLOAT, float{}); break;
  }
  if (!ok) return Status::failure(Error::io_read, fmt::format("{}: {}", path, in->geterror()));
  if (options.nodata_value) {
    const float nd = float(*options.nodata_value);
    for (float& v : out.values)
      if (v == nd) v = NAN;
  }
  for (float& v : out.values)
    if (!std::isfinite(v)) v = NAN;
  out.description = fmt::format("{} image {} {}x{} ({} channel{})", in->format_name(), fmt_in.c_str(), spec.width,
                                spec.height, spec.nchannels, spec.nchannels > 1 ? "s, first used" : "");
  in->close();
  return Status::success();
}

}  // namespace terrain::cook
