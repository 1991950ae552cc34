// Errors as values: every fallible call in format/ (and the components built on it) returns a Status.
// Codes are pinned and grouped by area (documented in format/SPEC.md, section "Error codes").
#pragma once
#include <cstdint>
#include <string>

namespace terrain {

enum class Error : uint16_t {
  ok = 0,
  // 1xx: files and I/O
  io_open = 100,
  io_read = 101,
  io_write = 102,
  io_rename = 103,
  io_changed = 104,  // the source changed since it was opened (a file replaced on a server)
  // 2xx: header
  bad_magic = 200,
  unsupported_version = 201,
  truncated = 202,
  header_checksum = 203,
  header_invalid = 204,
  // 3xx: metadata and directory sections
  section_out_of_bounds = 300,
  metadata_checksum = 301,
  metadata_invalid = 302,
  directory_checksum = 303,
  directory_invalid = 304,
  // 4xx: node payloads
  node_not_found = 400,
  payload_out_of_bounds = 401,
  payload_checksum = 402,
  payload_invalid = 403,
  decompress_failed = 404,
  // 5xx: caller mistakes and input data
  invalid_argument = 500,
  unsupported_input = 501,
  no_data = 502,
  cancelled = 503,
  internal = 504,
};

// Stable lower_snake name of a code, e.g. "payload_checksum".
const char* error_name(Error code);

// [[nodiscard]]: a call whose Status is dropped does not compile cleanly. A call that may fail and
// whose failure changes nothing says so: `(void)call();  // why`.
struct [[nodiscard]] Status {
  Error code = Error::ok;
  std::string message;  // says what is wrong and where (file, offset, node L/X/Y); empty when ok

  bool ok() const { return code == Error::ok; }
  static Status success() { return {}; }
  static Status failure(Error c, std::string msg) { return {c, std::move(msg)}; }
  // "payload_checksum: node 3/12/7: ..." for printing.
  std::string to_string() const;
};

}  // namespace terrain

// TERRAIN_TRY(expr): evaluates the Status expression `expr` once; when it is not ok, returns it
// unchanged from the enclosing function, otherwise goes on. For functions that return Status:
// in a function returning void, bool or a number it does not compile (Status converts to none of
// them); a return type constructible from Status would get the error through that constructor, so
// do not use it there. A caller that adds context to the message before returning writes that
// by hand: `if (Status s = f(); !s.ok()) { s.message = "where: " + s.message; return s; }`.
#define TERRAIN_TRY(expr)                                                          \
  do {                                                                             \
    if (::terrain::Status terrain_try_status_ = (expr); !terrain_try_status_.ok()) \
      return terrain_try_status_;                                                  \
  } while (0)
