// File helpers for the readers: whole files, gzip (zlib) and zip entries (libzip).
#include <zip.h>
#include <zlib.h>

#include <algorithm>
#include <cctype>
#include <fmt/format.h>
#include <fstream>
#include <memory>

#include "inputs/inputs.h"

namespace terrain::cook {

bool ends_with(const std::string& s, const std::string& suffix) {
  if (suffix.size() > s.size()) return false;
  return std::equal(suffix.rbegin(), suffix.rend(), s.rbegin(), [](char a, char b) {
    return std::tolower(static_cast<unsigned char>(a)) == std::tolower(static_cast<unsigned char>(b));
  });
}

Status read_file_bytes(const std::string& path, std::vector<uint8_t>& out) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return Status::failure(Error::io_open, fmt::format("{}: cannot open", path));
  const std::streamoff size = in.tellg();
  if (size < 0) return Status::failure(Error::io_read, fmt::format("{}: cannot read its size", path));
  out.resize(size_t(size));
  in.seekg(0);
  if (size > 0 && !in.read(reinterpret_cast<char*>(out.data()), size))
    return Status::failure(Error::io_read, fmt::format("{}: read failed", path));
  return Status::success();
}

Status gunzip_file(const std::string& path, std::vector<uint8_t>& out, uint64_t max_bytes) {
  std::unique_ptr<gzFile_s, int (*)(gzFile)> gz(gzopen(path.c_str(), "rb"), gzclose);
  if (!gz) return Status::failure(Error::io_open, fmt::format("{}: cannot open", path));
  gzbuffer(gz.get(), 1 << 17);
  out.clear();
  std::vector<uint8_t> chunk(1 << 20);
  for (;;) {
    const int got = gzread(gz.get(), chunk.data(), unsigned(chunk.size()));
    if (got < 0) {
      int err = 0;
      const char* msg = gzerror(gz.get(), &err);
      return Status::failure(Error::io_read, fmt::format("{}: gzip data is corrupt ({})", path, msg ? msg : "?"));
    }
    if (got == 0) break;
    if (uint64_t(out.size()) + uint64_t(got) > max_bytes)
      return Status::failure(Error::unsupported_input,
                             fmt::format("{}: decompresses to more than {} bytes, more than this input can hold", path,
                                         max_bytes));
    out.insert(out.end(), chunk.begin(), chunk.begin() + got);
  }
  return Status::success();
}

Status read_zip_entry(const std::string& path, const std::string& suffix, std::vector<uint8_t>& out,
                      std::string& entry, uint64_t max_bytes) {
  int err = 0;
  std::unique_ptr<zip_t, void (*)(zip_t*)> archive(zip_open(path.c_str(), ZIP_RDONLY, &err), zip_discard);
  if (!archive) {
    zip_error_t ze;
    zip_error_init_with_code(&ze, err);
    std::string msg = zip_error_strerror(&ze);
    zip_error_fini(&ze);
    return Status::failure(Error::io_open, fmt::format("{}: cannot open as zip ({})", path, msg));
  }
  const zip_int64_t n = zip_get_num_entries(archive.get(), 0);
  for (zip_int64_t i = 0; i < n; ++i) {
    zip_stat_t st;
    if (zip_stat_index(archive.get(), zip_uint64_t(i), 0, &st) != 0 || !(st.valid & ZIP_STAT_NAME) ||
        !(st.valid & ZIP_STAT_SIZE))
      continue;
    if (!ends_with(st.name, suffix)) continue;
    if (st.size > max_bytes)
      return Status::failure(Error::unsupported_input,
                             fmt::format("{}: entry {} is {} bytes, more than the {} this input can hold", path, st.name,
                                         uint64_t(st.size), max_bytes));
    std::unique_ptr<zip_file_t, int (*)(zip_file_t*)> file(zip_fopen_index(archive.get(), zip_uint64_t(i), 0),
                                                          zip_fclose);
    if (!file) return Status::failure(Error::io_read, fmt::format("{}: cannot open entry {}", path, st.name));
    // Grow with the bytes that really decompress: the header's size is the input's word, and a
    // forged one (4 GB for a 100-byte entry) must not become an allocation.
    out.clear();
    constexpr uint64_t kChunk = uint64_t(1) << 20;
    for (uint64_t done = 0; done < uint64_t(st.size);) {
      const uint64_t want = std::min<uint64_t>(kChunk, uint64_t(st.size) - done);
      out.resize(size_t(done + want));
      const zip_int64_t got = zip_fread(file.get(), out.data() + done, want);
      if (got <= 0)
        return Status::failure(Error::io_read, fmt::format("{}: entry {} is corrupt or truncated", path, st.name));
      done += uint64_t(got);
      out.resize(size_t(done));
    }
    entry = st.name;
    return Status::success();
  }
  return Status::failure(Error::unsupported_input, fmt::format("{}: the zip holds no *{} entry", path, suffix));
}

std::string gzip_stored_name(const std::string& path) {
  // RFC 1952: magic 1f 8b, method, flags, mtime (4), xfl, os; FEXTRA (bit 2): 2-byte length and
  // data; FNAME (bit 3): the original name, zero-terminated (ISO 8859-1).
  std::ifstream in(path, std::ios::binary);
  uint8_t h[10] = {};
  if (!in.read(reinterpret_cast<char*>(h), 10) || h[0] != 0x1f || h[1] != 0x8b || !(h[3] & 0x08)) return "";
  if (h[3] & 0x04) {
    uint8_t len[2] = {};
    if (!in.read(reinterpret_cast<char*>(len), 2)) return "";
    in.ignore(std::streamsize(len[0] | len[1] << 8));
  }
  std::string name;
  for (char c; name.size() < 4096 && in.get(c) && c != '\0';) name += c;
  return name;
}

}  // namespace terrain::cook
