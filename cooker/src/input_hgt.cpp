// SRTM HGT: big-endian Int16, rows north to south, the name gives the south-west corner, samples on
// whole-degree edges (1201 or 3601 per side, edges shared with the neighbouring tiles), -32768 voids.
#include <cmath>
#include <filesystem>
#include <fmt/format.h>

#include "crs.h"
#include "inputs.h"

namespace terrain::cook {
namespace {

constexpr uint64_t kBytes3 = uint64_t(1201) * 1201 * 2, kBytes1 = uint64_t(3601) * 3601 * 2;

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

std::string tile_name(int lat, int lon) {
  return fmt::format("{}{:02}{}{:03}", lat < 0 ? 'S' : 'N', std::abs(lat), lon < 0 ? 'W' : 'E', std::abs(lon));
}

// A zip or gzip names the tile twice: in its own file name and in the name stored inside. Where
// the stored one is a tile name too they must agree, else the tile would be placed elsewhere.
Status check_stored_name(const std::string& path, const std::string& stored, int lat, int lon, const char* ext) {
  int slat = 0, slon = 0;
  if (stored.empty() || !parse_hgt_name(stored, slat, slon) || (slat == lat && slon == lon)) return Status::success();
  return Status::failure(Error::unsupported_input,
                         fmt::format("{}: holds {}, the tile {}, but its file name says {}; the position comes from "
                                     "the name, so rename the file after its content ({}{}) or re-pack it",
                                     path, stored, tile_name(slat, slon), tile_name(lat, lon), tile_name(slat, slon), ext));
}

}  // namespace

Status read_hgt(const std::string& path, const ReadOptions& options, Raster& out) {
  int lat = 0, lon = 0;
  if (!parse_hgt_name(path, lat, lon))
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: an HGT file name must start with its south-west corner, e.g. N22W160.hgt", path));
  std::vector<uint8_t> bytes;
  std::string container = "plain";
  uint64_t plain_size = 0;
  Status st;
  // No more than the larger tile is ever read: a bigger entry, stream or file is refused unread.
  if (ends_with(path, ".zip")) {
    std::string entry;
    st = read_zip_entry(path, ".hgt", bytes, entry, kBytes1);
    if (st.ok()) st = check_stored_name(path, entry, lat, lon, ".hgt.zip");
    container = "zip";
  } else if (ends_with(path, ".gz")) {
    st = check_stored_name(path, gzip_stored_name(path), lat, lon, ".hgt.gz");
    if (st.ok()) st = gunzip_file(path, bytes, kBytes1);
    container = "gzip";
  } else {
    std::error_code ec;
    plain_size = uint64_t(std::filesystem::file_size(path, ec));
    if (ec || plain_size == kBytes3 || plain_size == kBytes1) st = read_file_bytes(path, bytes);
    else bytes.clear();  // refused below by its size, unread
  }
  if (!st.ok()) return st;
  int n = 0;
  if (bytes.size() == kBytes3) n = 1201;
  else if (bytes.size() == kBytes1) n = 3601;
  else
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: {} bytes of HGT data; expected 1201x1201 (3\") or 3601x3601 (1\") Int16 "
                                       "samples ({} or {} bytes)", path,
                                       container == "plain" ? plain_size : uint64_t(bytes.size()),
                                       kBytes3, kBytes1));
  if (Status mst = check_raster_memory(path, uint64_t(n), uint64_t(n), "Int16", options); !mst.ok()) return mst;
  const double nodata = options.nodata_value.value_or(-32768.0);
  out = Raster{};
  out.path = path;
  out.width = out.height = n;
  out.nodata_declared = true;  // -32768, or --nodata-value
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
