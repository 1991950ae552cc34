#include "terrain/status.h"

#include <zlib.h>
#include <zstd.h>

#include <climits>

#include "terrain/detail/bytes.h"
#include "terrain/zstd_context.h"

namespace terrain {

const char* error_name(Error code) {
  switch (code) {
    case Error::ok: return "ok";
    case Error::io_open: return "io_open";
    case Error::io_read: return "io_read";
    case Error::io_write: return "io_write";
    case Error::io_rename: return "io_rename";
    case Error::io_changed: return "io_changed";
    case Error::bad_magic: return "bad_magic";
    case Error::unsupported_version: return "unsupported_version";
    case Error::truncated: return "truncated";
    case Error::header_checksum: return "header_checksum";
    case Error::header_invalid: return "header_invalid";
    case Error::section_out_of_bounds: return "section_out_of_bounds";
    case Error::metadata_checksum: return "metadata_checksum";
    case Error::metadata_invalid: return "metadata_invalid";
    case Error::directory_checksum: return "directory_checksum";
    case Error::directory_invalid: return "directory_invalid";
    case Error::node_not_found: return "node_not_found";
    case Error::payload_out_of_bounds: return "payload_out_of_bounds";
    case Error::payload_checksum: return "payload_checksum";
    case Error::payload_invalid: return "payload_invalid";
    case Error::decompress_failed: return "decompress_failed";
    case Error::invalid_argument: return "invalid_argument";
    case Error::unsupported_input: return "unsupported_input";
    case Error::no_data: return "no_data";
    case Error::cancelled: return "cancelled";
    case Error::internal: return "internal";
  }
  return "unknown_error";
}

std::string Status::to_string() const {
  if (ok()) return "ok";
  std::string s = error_name(code);
  if (!message.empty()) {
    s += ": ";
    s += message;
  }
  return s;
}

namespace detail {

uint32_t crc32_of(std::span<const uint8_t> bytes) { return crc32_update(0, bytes); }

uint32_t crc32_update(uint32_t crc, std::span<const uint8_t> bytes) {
  uLong c = crc;
  const uint8_t* p = bytes.data();
  size_t left = bytes.size();
  while (left > 0) {  // zlib takes uInt lengths
    const uInt n = left > UINT_MAX ? UINT_MAX : uInt(left);
    c = ::crc32(c, p, n);
    p += n;
    left -= n;
  }
  return uint32_t(c);
}

uint32_t crc32_combine(uint32_t crc_a, uint32_t crc_b, uint64_t length_b) {
  return uint32_t(::crc32_combine(crc_a, crc_b, z_off_t(length_b)));
}

namespace {
struct ThreadContexts {
  ZSTD_CCtx* cctx = nullptr;
  ZSTD_DCtx* dctx = nullptr;
  ~ThreadContexts() {
    ZSTD_freeCCtx(cctx);
    ZSTD_freeDCtx(dctx);
  }
};
thread_local ThreadContexts t_contexts;
}  // namespace

ZSTD_CCtx* thread_cctx() {
  if (!t_contexts.cctx) t_contexts.cctx = ZSTD_createCCtx();
  return t_contexts.cctx;
}
ZSTD_DCtx* thread_dctx() {
  if (!t_contexts.dctx) t_contexts.dctx = ZSTD_createDCtx();
  return t_contexts.dctx;
}

}  // namespace detail
}  // namespace terrain
