// Byte-level access to an archive file for tests that damage or edit one on purpose: little-endian
// fields (format/SPEC.md section 1) and a re-seal of the sizes and CRCs, so the reader gets past
// the checksums to the rule under test.
#pragma once
#include <zlib.h>

#include <algorithm>
#include <array>
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
// metadata and header CRCs (an unchanged directory keeps its CRC). Version 3 (SPEC 20): each
// page's CRC-32 and first key in the page table, then the table's CRC-32.
inline void reseal(std::vector<uint8_t>& b) {
  namespace h = layout::header;
  const size_t dir = size_t(get_u64(b, h::directory_offset)), meta = size_t(get_u64(b, h::metadata_offset));
  put_u64(b, h::metadata_size, b.size() - meta);
  put_u64(b, h::file_size, b.size());
  if (get_u32(b, h::format_version) >= layout::kFormatVersionV3) {
    namespace r = layout::page_record;
    const size_t nodes = get_u32(b, h::node_count), per_page = get_u32(b, h::page_entries);
    const size_t table = dir + nodes * layout::kEntrySize;
    for (size_t p = 0; table + (p + 1) * layout::kPageRecordSize <= meta && p * per_page < nodes; ++p) {
      const size_t first = dir + p * per_page * layout::kEntrySize;
      const size_t count = std::min(per_page, nodes - p * per_page);
      uint8_t* rec = b.data() + table + p * layout::kPageRecordSize;
      rec[r::level] = b[first + layout::entry::level];
      std::copy_n(b.data() + first + layout::entry::x, 4, rec + r::x);
      std::copy_n(b.data() + first + layout::entry::y, 4, rec + r::y);
      put_u32(b, table + p * layout::kPageRecordSize + r::page_crc32, crc(b.data() + first, count * layout::kEntrySize));
    }
    put_u32(b, h::directory_crc32, crc(b.data() + table, meta - table));
  } else {
    put_u32(b, h::directory_crc32, crc(b.data() + dir, meta - dir));
  }
  put_u32(b, h::metadata_crc32, crc(b.data() + meta, b.size() - meta));
  put_u32(b, h::header_crc32, crc(b.data(), h::header_crc32));
}

// The bytes a version-1 or version-2 writer made of the same archive (SPEC 5, 8): the version-3
// file `v3` without its page table, its directory in row order (level, y, x), page_entries zero.
// Readers open every version; tests of the older ones start here.
inline std::vector<uint8_t> legacy_bytes(const std::vector<uint8_t>& v3, uint32_t version) {
  namespace h = layout::header;
  namespace e = layout::entry;
  const size_t dir = size_t(get_u64(v3, h::directory_offset)), meta = size_t(get_u64(v3, h::metadata_offset));
  const size_t nodes = get_u32(v3, h::node_count);
  std::vector<std::vector<uint8_t>> entries(nodes);
  for (size_t i = 0; i < nodes; ++i)
    entries[i].assign(v3.begin() + std::ptrdiff_t(dir + i * layout::kEntrySize),
                      v3.begin() + std::ptrdiff_t(dir + (i + 1) * layout::kEntrySize));
  std::sort(entries.begin(), entries.end(), [](const std::vector<uint8_t>& a, const std::vector<uint8_t>& b) {
    auto key = [](const std::vector<uint8_t>& x) {
      return std::array<uint32_t, 3>{x[e::level], get_u32(x, e::y), get_u32(x, e::x)};
    };
    return key(a) < key(b);
  });
  std::vector<uint8_t> out(v3.begin(), v3.begin() + std::ptrdiff_t(dir));
  for (const auto& x : entries) out.insert(out.end(), x.begin(), x.end());
  const size_t new_meta = out.size();
  out.insert(out.end(), v3.begin() + std::ptrdiff_t(meta), v3.end());
  put_u32(out, h::format_version, version);
  put_u32(out, h::page_entries, 0);
  put_u64(out, h::directory_size, nodes * layout::kEntrySize);
  put_u64(out, h::metadata_offset, new_meta);
  reseal(out);
  return out;
}

}  // namespace terrain::test
