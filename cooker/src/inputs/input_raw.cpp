// Raw heightmaps (Unreal/World Machine style .r16/.raw, float .r32/.f32): no header, so the size and
// sample type come from --raw-size / --raw-type; rows north to south.
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>

#include "inputs/inputs.h"

namespace terrain::cook {

Status read_raw(const std::string& path, const ReadOptions& options, Raster& out) {
  std::string type = options.raw_type;
  if (type.empty()) type = ends_with(path, ".r32") || ends_with(path, ".f32") ? "f32" : "u16";
  int bytes = 0;
  if (type == "u16" || type == "i16") bytes = 2;
  else if (type == "f32") bytes = 4;
  else
    return Status::failure(Error::invalid_argument, fmt::format("--raw-type {}: expected u16, i16 or f32", type));
  const int w = options.raw_size[0], h = options.raw_size[1];
  if (w <= 0 || h <= 0)
    return Status::failure(Error::invalid_argument,
                           fmt::format("{}: raw heightmaps need --raw-size WIDTHxHEIGHT (e.g. --raw-size 1025x1025)", path));
  // The size is known from the flags: compare it with the file's before reading a byte.
  const uint64_t expected = uint64_t(w) * uint64_t(h) * uint64_t(bytes);
  std::error_code ec;
  const uint64_t size = uint64_t(std::filesystem::file_size(path, ec));
  if (ec) return Status::failure(Error::io_open, fmt::format("{}: cannot read its size ({})", path, ec.message()));
  if (size != expected)
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: {} bytes, but {}x{} {} samples need {} bytes (check --raw-size / --raw-type)",
                                       path, size, w, h, type, expected));
  TERRAIN_TRY(check_raster_memory(path, uint64_t(w), uint64_t(h), type, options, expected));
  std::vector<uint8_t> data;
  TERRAIN_TRY(read_file_bytes(path, data));
  if (data.size() != expected)
    return Status::failure(Error::io_read, fmt::format("{}: changed size while being read", path));
  out = Raster{};
  out.path = path;
  out.nodata_declared = options.nodata_value.has_value();
  out.width = w;
  out.height = h;
  out.values.resize(size_t(w) * size_t(h));
  const bool swap = options.raw_big_endian;
  for (size_t i = 0; i < out.values.size(); ++i) {
    uint8_t b[4];
    std::memcpy(b, &data[i * size_t(bytes)], size_t(bytes));
    if (swap) std::reverse(b, b + bytes);
    double v = 0;
    if (type == "u16") { uint16_t x; std::memcpy(&x, b, 2); v = x; }
    else if (type == "i16") { int16_t x; std::memcpy(&x, b, 2); v = x; }
    else { float x; std::memcpy(&x, b, 4); v = x; }
    const bool missing = !std::isfinite(v) || (options.nodata_value && v == *options.nodata_value);
    out.values[i] = missing ? NAN : float(v);
  }
  out.description = fmt::format("raw {} {}x{} {}-endian", type, w, h, swap ? "big" : "little");
  return Status::success();
}

}  // namespace terrain::cook
