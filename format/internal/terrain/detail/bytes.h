// Little-endian loads and stores (the archive is little-endian everywhere, SPEC "Conventions") and
// CRC-32. Internal to the toolchain (format/internal: never installed, not the package's API): the
// archive's code and the cooker's own containers (the work units' files) share them.
#pragma once
#include <bit>
#include <cstdint>
#include <cstring>
#include <span>
#include <string_view>
#include <vector>

namespace terrain::detail {

inline uint16_t load_u16(const uint8_t* p) { return uint16_t(p[0] | (p[1] << 8)); }
inline uint32_t load_u32(const uint8_t* p) {
  return uint32_t(p[0]) | (uint32_t(p[1]) << 8) | (uint32_t(p[2]) << 16) | (uint32_t(p[3]) << 24);
}
inline uint64_t load_u64(const uint8_t* p) { return uint64_t(load_u32(p)) | (uint64_t(load_u32(p + 4)) << 32); }
inline int32_t load_i32(const uint8_t* p) { return int32_t(load_u32(p)); }
inline float load_f32(const uint8_t* p) { return std::bit_cast<float>(load_u32(p)); }
inline double load_f64(const uint8_t* p) { return std::bit_cast<double>(load_u64(p)); }

inline void store_u16(uint8_t* p, uint16_t v) {
  p[0] = uint8_t(v);
  p[1] = uint8_t(v >> 8);
}
inline void store_u32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = uint8_t(v >> (8 * i));
}
inline void store_u64(uint8_t* p, uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = uint8_t(v >> (8 * i));
}
inline void store_i32(uint8_t* p, int32_t v) { store_u32(p, uint32_t(v)); }
inline void store_f32(uint8_t* p, float v) { store_u32(p, std::bit_cast<uint32_t>(v)); }
inline void store_f64(uint8_t* p, double v) { store_u64(p, std::bit_cast<uint64_t>(v)); }

// FNV-1a (64-bit) of `s`, continuing `h`: the fingerprints of the cooker's work units and the
// names of the HTTP range cache's folders.
inline constexpr uint64_t kFnv1aBasis = 1469598103934665603ull;
inline uint64_t fnv1a(std::string_view s, uint64_t h = kFnv1aBasis) {
  for (unsigned char c : s) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

// CRC-32 (ISO-HDLC, zlib's crc32) of a byte range of any length.
uint32_t crc32_of(std::span<const uint8_t> bytes);
// `crc` (the CRC-32 of the bytes before, 0 for none) continued over `bytes`:
// crc32_update(crc32_of(a), b) == crc32_of(a followed by b).
uint32_t crc32_update(uint32_t crc, std::span<const uint8_t> bytes);
// The CRC-32 of a followed by b from crc32_of(a), crc32_of(b) and b's length (zlib's crc32_combine).
uint32_t crc32_combine(uint32_t crc_a, uint32_t crc_b, uint64_t length_b);

}  // namespace terrain::detail
