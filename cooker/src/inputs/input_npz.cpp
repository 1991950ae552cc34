// NumPy .npz (a zip of .npy arrays), e.g. matplotlib's jacksboro_fault_dem.npz: a 2-D `elevation`
// array plus optional scalars xmin, xmax, ymin, ymax (extent edges) and dx, dy (sample spacing).
//
// Orientation: rows run north to south (image order) and the extent scalars are the OUTER EDGES of
// the samples, whichever of ymin/ymax holds the larger number. jacksboro_fault_dem.npz stores
// ymin = 36.7329 > ymax = 36.4463: those are the northern and southern edges (the file was evidently
// written from a north-up raster's geotransform, origin_y then origin_y - rows * dy), and
// (xmax - xmin) / dx = 403 = columns, (ymin - ymax) / dy = 344 = rows, so the scalars are edges, not
// sample centres. The relief confirms north-up: the 900-1000 m ridge of the Tennessee Cumberland
// Mountains lies in the southern rows and the 450-550 m Kentucky plateau in the northern rows.
#include <charconv>
#include <cmath>
#include <cstring>
#include <fmt/format.h>
#include <map>

#include "inputs/inputs.h"

namespace terrain::cook {
namespace {

struct NpyArray {
  char kind = 0;        // 'i', 'u', 'f'
  int item_bytes = 0;
  bool big_endian = false;
  std::vector<int64_t> shape;
  const uint8_t* data = nullptr;
  size_t count = 0;
  double at(size_t i) const {
    uint8_t b[8];
    std::memcpy(b, data + i * size_t(item_bytes), size_t(item_bytes));
    if (big_endian) std::reverse(b, b + item_bytes);
    switch (kind * 16 + item_bytes) {
      case 'i' * 16 + 1: return int8_t(b[0]);
      case 'u' * 16 + 1: return b[0];
      case 'i' * 16 + 2: { int16_t v; std::memcpy(&v, b, 2); return v; }
      case 'u' * 16 + 2: { uint16_t v; std::memcpy(&v, b, 2); return v; }
      case 'i' * 16 + 4: { int32_t v; std::memcpy(&v, b, 4); return v; }
      case 'u' * 16 + 4: { uint32_t v; std::memcpy(&v, b, 4); return v; }
      case 'i' * 16 + 8: { int64_t v; std::memcpy(&v, b, 8); return double(v); }
      case 'f' * 16 + 4: { float v; std::memcpy(&v, b, 4); return v; }
      case 'f' * 16 + 8: { double v; std::memcpy(&v, b, 8); return v; }
      default: return NAN;
    }
  }
};

// Parses the .npy header: {'descr': '<i2', 'fortran_order': False, 'shape': (344, 403), }
// Error::unsupported_input says what is wrong with the array (the caller names the file).
Status parse_npy(const std::vector<uint8_t>& bytes, NpyArray& out) {
  auto refuse = [](std::string why) { return Status::failure(Error::unsupported_input, std::move(why)); };
  if (bytes.size() < 10 || std::memcmp(bytes.data(), "\x93NUMPY", 6) != 0) return refuse("not an .npy array");
  const int major = bytes[6];
  size_t header_len = 0, header_at = 0;
  if (major == 1) { header_len = size_t(bytes[8]) | size_t(bytes[9]) << 8; header_at = 10; }
  else if (major >= 2 && bytes.size() >= 12) {
    header_len = size_t(bytes[8]) | size_t(bytes[9]) << 8 | size_t(bytes[10]) << 16 | size_t(bytes[11]) << 24;
    header_at = 12;
  } else return refuse("unknown .npy version");
  if (header_at + header_len > bytes.size()) return refuse("truncated .npy header");
  const std::string h(reinterpret_cast<const char*>(bytes.data() + header_at), header_len);
  const size_t d = h.find("'descr'");
  const size_t q1 = d == std::string::npos ? d : h.find('\'', d + 7);
  const size_t q2 = q1 == std::string::npos ? q1 : h.find('\'', q1 + 1);
  if (q2 == std::string::npos || q2 - q1 < 3) return refuse("no dtype in .npy header");
  const std::string descr = h.substr(q1 + 1, q2 - q1 - 1);
  out.big_endian = descr[0] == '>';
  out.kind = descr[1];
  out.item_bytes = std::atoi(descr.c_str() + 2);
  if (std::strchr("iuf", out.kind) == nullptr || (out.item_bytes != 1 && out.item_bytes != 2 && out.item_bytes != 4 && out.item_bytes != 8))
    return refuse("dtype " + descr + " not supported");
  if (h.find("'fortran_order': True") != std::string::npos) return refuse("Fortran-ordered arrays are not supported");
  const size_t s = h.find("'shape'");
  const size_t p1 = s == std::string::npos ? s : h.find('(', s);
  const size_t p2 = p1 == std::string::npos ? p1 : h.find(')', p1);
  if (p2 == std::string::npos) return refuse("no shape in .npy header");
  out.shape.clear();
  out.count = 1;
  for (size_t i = p1 + 1; i < p2;) {
    while (i < p2 && !std::isdigit(static_cast<unsigned char>(h[i]))) ++i;
    if (i >= p2) break;
    int64_t v = 0;
    auto [e, ec] = std::from_chars(h.data() + i, h.data() + p2, v);
    // Each side below 2^31 and the product at most 2^32 (checked before multiplying: no wrap).
    if (ec != std::errc() || v < 0 || v >= (int64_t(1) << 31) || (v > 0 && out.count > (size_t(1) << 32) / size_t(v)))
      return refuse("bad shape");
    out.shape.push_back(v);
    out.count *= size_t(v);
    i = size_t(e - h.data());
  }
  const size_t data_at = header_at + header_len;
  if (out.count > (size_t(1) << 32) || bytes.size() - data_at < out.count * size_t(out.item_bytes))
    return refuse("array data truncated");
  out.data = bytes.data() + data_at;
  return Status::success();
}

}  // namespace

Status read_npz(const std::string& path, const ReadOptions& options, Raster& out) {
  std::map<std::string, std::vector<uint8_t>> entries;
  for (const char* name : {"elevation", "xmin", "xmax", "ymin", "ymax", "dx", "dy"}) {
    std::vector<uint8_t> bytes;
    std::string entry;
    const std::string file = std::string(name) + ".npy";
    // The scalars are a few hundred bytes; the array may take the budget, no more.
    const bool array = std::string(name) == "elevation";
    const uint64_t max_bytes = array ? options.memory_limit_bytes : uint64_t(1) << 16;
    if (Status st = read_zip_entry(path, file, bytes, entry, max_bytes); array && !st.ok() &&
                                                                          st.message.find("more than") != std::string::npos)
      return Status::failure(st.code, st.message + " (--memory-limit)");
    else if (st.ok() && (entry == file || ends_with(entry, "/" + file)))
      entries[name] = std::move(bytes);
  }
  if (!entries.count("elevation")) {
    std::vector<uint8_t> bytes;
    std::string entry;
    // Says whether the zip itself is readable; an entry too large to read here still proves it is.
    Status st = read_zip_entry(path, ".npy", bytes, entry, uint64_t(1) << 16);
    return st.ok() || st.message.find("more than") != std::string::npos
               ? Status::failure(Error::unsupported_input, fmt::format("{}: no 'elevation' array in the .npz", path))
                   : st;
  }
  NpyArray elev;
  if (Status st = parse_npy(entries["elevation"], elev); !st.ok())
    return Status::failure(st.code, fmt::format("{}: elevation.npy: {}", path, st.message));
  if (elev.shape.size() != 2 || elev.shape[0] < 2 || elev.shape[1] < 2)
    return Status::failure(Error::unsupported_input, fmt::format("{}: elevation must be a 2-D array", path));
  if (Status st = check_raster_memory(path, uint64_t(elev.shape[1]), uint64_t(elev.shape[0]),
                                      fmt::format("{}{}", elev.kind, elev.item_bytes * 8), options,
                                      entries["elevation"].size());
      !st.ok())
    return st;
  out = Raster{};
  out.path = path;
  out.nodata_declared = options.nodata_value.has_value();
  out.height = int(elev.shape[0]);
  out.width = int(elev.shape[1]);
  out.values.resize(elev.count);
  for (size_t i = 0; i < elev.count; ++i) {
    const double v = elev.at(i);
    out.values[i] = !std::isfinite(v) || (options.nodata_value && v == *options.nodata_value) ? NAN : float(v);
  }
  std::map<std::string, double> scalar;
  for (const char* name : {"xmin", "xmax", "ymin", "ymax", "dx", "dy"}) {
    NpyArray a;
    // A scalar that does not parse is left out, as a missing one (the extent then stays unknown).
    if (entries.count(name) && parse_npy(entries[name], a).ok() && a.count == 1) scalar[name] = a.at(0);
  }
  if (scalar.count("xmin") && scalar.count("xmax") && scalar.count("ymin") && scalar.count("ymax")) {
    const double west = std::min(scalar["xmin"], scalar["xmax"]), east = std::max(scalar["xmin"], scalar["xmax"]);
    const double north = std::max(scalar["ymin"], scalar["ymax"]), south = std::min(scalar["ymin"], scalar["ymax"]);
    // Edges unless dx says the extent spans (n - 1) samples (sample centres).
    double dx = (east - west) / out.width, dy = (north - south) / out.height;
    bool centres = false;
    if (scalar.count("dx") && std::fabs((east - west) / scalar["dx"] - (out.width - 1)) < 1e-3) centres = true;
    if (centres) {
      dx = (east - west) / (out.width - 1);
      dy = (north - south) / (out.height - 1);
    }
    out.geo.c[0] = centres ? west : west + 0.5 * dx;
    out.geo.c[1] = dx;
    out.geo.c[2] = 0;
    out.geo.c[3] = centres ? north : north - 0.5 * dy;
    out.geo.c[4] = 0;
    out.geo.c[5] = -dy;
    out.geo.valid = dx > 0 && dy > 0;
    out.geo.point_samples = centres;
  }
  out.description = fmt::format("NumPy .npz elevation {}{} {}x{}{}", elev.kind, elev.item_bytes * 8, out.width,
                                out.height, out.geo.valid ? ", extent from xmin/xmax/ymin/ymax (rows north to south)" : "");
  return Status::success();
}

}  // namespace terrain::cook
