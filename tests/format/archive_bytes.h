// Byte-level access to an archive file for tests that damage or edit one on purpose: little-endian
// fields (format/SPEC.md section 1) and a re-seal of the sizes and CRCs, so the reader gets past
// the checksums to the rule under test.
#pragma once
#include <zlib.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include "terrain/archive_layout.h"

namespace terrain::test {

inline std::vector<uint8_t> slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}
inline uint64_t get_u64(const std::vector<uint8_t>& b, size_t at) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | b[at + size_t(i)];
  return v;
}
inline uint32_t get_u32(const std::vector<uint8_t>& b, size_t at) {
  return uint32_t(b[at]) | uint32_t(b[at + 1]) << 8 | uint32_t(b[at + 2]) << 16 | uint32_t(b[at + 3]) << 24;
}
inline void put_u32(std::vector<uint8_t>& b, size_t at, uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + size_t(i)] = uint8_t(v >> (8 * i));
}
inline void put_u64(std::vector<uint8_t>& b, size_t at, uint64_t v) {
  for (int i = 0; i < 8; ++i) b[at + size_t(i)] = uint8_t(v >> (8 * i));
}
inline uint32_t crc(const uint8_t* p, size_t n) { return uint32_t(crc32(crc32(0L, Z_NULL, 0), p, uInt(n))); }

// Re-seals a file after a deliberate change: metadata size, file size and the directory,
// metadata and header CRCs (an unchanged directory keeps its CRC).
inline void reseal(std::vector<uint8_t>& b) {
  namespace h = layout::header;
  const size_t dir = size_t(get_u64(b, h::directory_offset)), meta = size_t(get_u64(b, h::metadata_offset));
  put_u64(b, h::metadata_size, b.size() - meta);
  put_u64(b, h::file_size, b.size());
  put_u32(b, h::directory_crc32, crc(b.data() + dir, meta - dir));
  put_u32(b, h::metadata_crc32, crc(b.data() + meta, b.size() - meta));
  put_u32(b, h::header_crc32, crc(b.data(), h::header_crc32));
}

}  // namespace terrain::test
