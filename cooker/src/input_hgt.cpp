// SRTM HGT: big-endian Int16, rows north to south, the name gives the south-west corner, samples on
// whole-degree edges (1201 or 3601 per side, edges shared with the neighbouring tiles), -32768 voids.
#include <cmath>
#include <fmt/format.h>

#include "crs.h"
#include "inputs.h"

namespace terrain::cook {
namespace {

// "N22W160" (any case) at the start of the file's base name.
bool parse_hgt_name(const std::string& path, int& lat, int& lon) {
  std::string base = path.substr(path.find_last_of('/') == std::string::npos ? 0 : path.find_last_of('/') + 1);
  if (base.size() < 7) return false;
  const char ns = char(std::toupper(static_cast<unsigned char>(base[0])));
  const char ew = char(std::toupper(static_cast<unsigned char>(base[3])));
  if ((ns != 'N' && ns != 'S') || (ew != 'E' && ew != 'W')) return false;
  for (int i : {1, 2, 4, 5, 6})
    if (!std::isdigit(static_cast<unsigned char>(base[size_t(i)]))) return false;
  lat = (base[1] - '0') * 10 + (base[2] - '0');
  lon = (base[4] - '0') * 100 + (base[5] - '0') * 10 + (base[6] - '0');
  if (ns == 'S') lat = -lat;
  if (ew == 'W') lon = -lon;
  return lat >= -90 && lat < 90 && lon >= -180 && lon < 180;
}

}  // namespace

Status read_hgt(const std::string& path, const ReadOptions& options, Raster& out) {
  int lat = 0, lon = 0;
  if (!parse_hgt_name(path, lat, lon))
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: an HGT file name must start with its south-west corner, e.g. N22W160.hgt", path));
  std::vector<uint8_t> bytes;
  std::string container = "plain";
  Status st;
  if (ends_with(path, ".zip")) {
    std::string entry;
    st = read_zip_entry(path, ".hgt", bytes, entry);
    container = "zip";
  } else if (ends_with(path, ".gz")) {
    st = gunzip_file(path, bytes);
    container = "gzip";
  } else {
    st = read_file_bytes(path, bytes);
  }
  if (!st.ok()) return st;
  int n = 0;
  if (bytes.size() == size_t(1201) * 1201 * 2) n = 1201;
  else if (bytes.size() == size_t(3601) * 3601 * 2) n = 3601;
  else
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: {} bytes of HGT data; expected 1201x1201 (3\") or 3601x3601 (1\") Int16 "
                                       "samples ({} or {} bytes)", path, bytes.size(), 1201 * 1201 * 2, 3601 * 3601 * 2));
  const double nodata = options.nodata_value.value_or(-32768.0);
  out = Raster{};
  out.path = path;
  out.width = out.height = n;
  out.values.resize(size_t(n) * n);
  for (size_t i = 0; i < out.values.size(); ++i) {
    const int16_t v = int16_t(uint16_t(bytes[2 * i]) << 8 | bytes[2 * i + 1]);
    out.values[i] = double(v) == nodata ? NAN : float(v);
  }
  const double step = 1.0 / (n - 1);
  out.geo.c[0] = lon;
  out.geo.c[1] = step;
  out.geo.c[2] = 0;
  out.geo.c[3] = lat + 1;
  out.geo.c[4] = 0;
  out.geo.c[5] = -step;
  out.geo.valid = true;
  out.geo.point_samples = true;  // samples on whole-degree edges, shared with the neighbours
  out.crs = wgs84_geographic();
  out.description = fmt::format("SRTM HGT {}\" {}x{} ({}), voids {}", n == 1201 ? 3 : 1, n, n, container, nodata);
  return Status::success();
}

}  // namespace terrain::cook
