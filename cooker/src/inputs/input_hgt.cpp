// SRTM HGT: big-endian Int16, rows north to south, the name gives the south-west corner, samples on
// whole-degree edges (1201 or 3601 per side, edges shared with the neighbouring tiles), -32768 voids.
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>

#include "frame/crs.h"
#include "inputs/inputs.h"
#include "inputs/source_raster.h"

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

// The tile's samples as stored (big-endian Int16, n x n), read by rows with pread: the file itself
// for a plain .hgt, else an unlinked temporary file the zip or gzip was inflated into once (so a
// mosaic of thousands of tiles holds none of them in memory; the file goes when the cook ends,
// killed or not).
class HgtSource final : public SourceRaster {
 public:
  HgtSource(int fd, int n, double nodata) : fd_(fd), n_(n), nodata_(nodata) {}
  ~HgtSource() override {
    if (fd_ >= 0) ::close(fd_);
  }
  SourceInfo& info() { return info_; }
  uint64_t scratch_bytes(int w, int) const override { return uint64_t(w) * 2; }
  Status read_window(int x0, int y0, int w, int h, float* out) override {
    if (x0 < 0 || y0 < 0 || w <= 0 || h <= 0 || x0 + w > n_ || y0 + h > n_)
      return Status::failure(Error::invalid_argument, fmt::format("{}: window {}x{} at ({}, {}) outside the {}x{} tile",
                                                                  info_.path, w, h, x0, y0, n_, n_));
    row_.resize(size_t(w) * 2);
    for (int r = 0; r < h; ++r) {
      const off_t at = (off_t(y0 + r) * n_ + x0) * 2;
      size_t done = 0;
      while (done < row_.size()) {
        const ssize_t got = ::pread(fd_, row_.data() + done, row_.size() - done, at + off_t(done));
        if (got < 0 && errno == EINTR) continue;
        if (got <= 0)
          return Status::failure(Error::io_read, fmt::format("{}: cannot read row {}: {}", info_.path, y0 + r,
                                                             got < 0 ? std::strerror(errno) : "file shortened"));
        done += size_t(got);
      }
      float* o = out + size_t(r) * size_t(w);
      for (int i = 0; i < w; ++i) {
        const int16_t v = int16_t(uint16_t(row_[2 * size_t(i)]) << 8 | row_[2 * size_t(i) + 1]);
        o[i] = double(v) == nodata_ ? NAN : float(v);
      }
    }
    info_.bytes_read += uint64_t(w) * uint64_t(h) * 2;
    return Status::success();
  }

 private:
  int fd_;
  int n_;
  double nodata_;
  std::vector<uint8_t> row_;
};

// An unlinked temporary file in $TMPDIR (else /tmp) holding `bytes`; -1 and `error` on failure.
int unlinked_temp_file(const std::vector<uint8_t>& bytes, std::string& error) {
  const char* dir = std::getenv("TMPDIR");
  std::string templ = std::string(dir && *dir ? dir : "/tmp") + "/terrain-hgt-XXXXXX";
  const int fd = ::mkstemp(templ.data());
  if (fd < 0) {
    error = fmt::format("cannot create a temporary file in {}: {}", dir && *dir ? dir : "/tmp", std::strerror(errno));
    return -1;
  }
  ::unlink(templ.c_str());
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t put = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (put < 0 && errno == EINTR) continue;
    if (put <= 0) {
      error = fmt::format("cannot write a temporary file in {}: {}", dir && *dir ? dir : "/tmp", std::strerror(errno));
      ::close(fd);
      return -1;
    }
    done += size_t(put);
  }
  return fd;
}

// The checks and georeferencing both readers share: name, container, size. `bytes` holds the
// samples of a zip or gzip (inflated), stays empty for a plain file (whose size was checked).
Status open_hgt(const std::string& path, int& n, std::vector<uint8_t>& bytes, std::string& container, Raster& head) {
  int lat = 0, lon = 0;
  if (!parse_hgt_name(path, lat, lon))
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: an HGT file name must start with its south-west corner, e.g. N22W160.hgt", path));
  bytes.clear();
  container = "plain";
  uint64_t size = 0;
  Status st;
  // No more than the larger tile is ever read: a bigger entry, stream or file is refused unread.
  if (ends_with(path, ".zip")) {
    std::string entry;
    st = read_zip_entry(path, ".hgt", bytes, entry, kBytes1);
    if (st.ok()) st = check_stored_name(path, entry, lat, lon, ".hgt.zip");
    container = "zip";
    size = bytes.size();
  } else if (ends_with(path, ".gz")) {
    st = check_stored_name(path, gzip_stored_name(path), lat, lon, ".hgt.gz");
    if (st.ok()) st = gunzip_file(path, bytes, kBytes1);
    container = "gzip";
    size = bytes.size();
  } else {
    std::error_code ec;
    size = uint64_t(std::filesystem::file_size(path, ec));
    if (ec) return Status::failure(Error::io_read, fmt::format("{}: {}", path, ec.message()));
  }
  if (!st.ok()) return st;
  if (size == kBytes3) n = 1201;
  else if (size == kBytes1) n = 3601;
  else
    return Status::failure(Error::unsupported_input,
                           fmt::format("{}: {} bytes of HGT data; expected 1201x1201 (3\") or 3601x3601 (1\") Int16 "
                                       "samples ({} or {} bytes)", path, size, kBytes3, kBytes1));
  head = Raster{};
  head.path = path;
  head.width = head.height = n;
  head.nodata_declared = true;  // -32768, or --nodata-value
  const double step = 1.0 / (n - 1);
  head.geo.c[0] = lon;
  head.geo.c[1] = step;
  head.geo.c[2] = 0;
  head.geo.c[3] = lat + 1;
  head.geo.c[4] = 0;
  head.geo.c[5] = -step;
  head.geo.valid = true;
  head.geo.point_samples = true;  // samples on whole-degree edges, shared with the neighbours
  head.crs = wgs84_geographic();
  return Status::success();
}

}  // namespace

Status open_hgt_source(const std::string& path, const ReadOptions& options, std::unique_ptr<SourceRaster>& out) {
  int n = 0;
  std::vector<uint8_t> bytes;
  std::string container;
  Raster head;
  TERRAIN_TRY(open_hgt(path, n, bytes, container, head));
  int fd = -1;
  if (container == "plain") {
    fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return Status::failure(Error::io_read, fmt::format("{}: {}", path, std::strerror(errno)));
  } else {
    std::string error;
    fd = unlinked_temp_file(bytes, error);
    if (fd < 0) return Status::failure(Error::io_write, fmt::format("{}: inflating the tile: {}", path, error));
  }
  const double nodata = options.nodata_value.value_or(-32768.0);
  auto src = std::make_unique<HgtSource>(fd, n, nodata);
  SourceInfo& info = src->info();
  info.path = path;
  info.width = info.height = n;
  info.geo = head.geo;
  info.crs = head.crs;
  info.nodata = nodata;
  info.sample_type = "Int16";
  info.description = fmt::format("SRTM HGT {}\" {}x{} ({}), voids {}", n == 1201 ? 3 : 1, n, n, container, nodata);
  out = std::move(src);
  return Status::success();
}

Status read_hgt(const std::string& path, const ReadOptions& options, Raster& out) {
  std::unique_ptr<SourceRaster> src;
  TERRAIN_TRY(open_hgt_source(path, options, src));
  const SourceInfo& info = src->info();
  if (Status mst = check_raster_memory(path, uint64_t(info.width), uint64_t(info.height), "Int16", options); !mst.ok())
    return mst;
  out = Raster{};
  out.path = path;
  out.width = info.width;
  out.height = info.height;
  out.nodata_declared = true;
  out.geo = info.geo;
  out.crs = info.crs;
  out.description = info.description;
  out.values.resize(size_t(info.width) * size_t(info.height));
  return src->read_window(0, 0, info.width, info.height, out.values.data());
}

}  // namespace terrain::cook
