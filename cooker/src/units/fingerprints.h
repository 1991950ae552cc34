// Fingerprints of the work units (format/SPEC.md section 18): 64-bit FNV-1a hashes, written as 16
// hex digits. An input file's is of its absolute path (resolved at plan time, so `unit` and `merge`
// run from any working directory), size, modification time, inode number and status change time
// (a file rewritten or replaced gets a new ctime even where `cp -p`, `rsync -t` or `tar` keep its
// size and mtime; no tool can set ctime back; contents are never hashed: national inputs are
// terabytes). A unit's (plan_file.h) is of the plan's global decisions, its roots, its source
// window and the fingerprints of the input files whose footprint meets that window.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>

#include "base/sample_window.h"

namespace terrain::cook {

inline constexpr uint64_t kFnv1aBasis = 1469598103934665603ull;  // terrain/detail/bytes.h's
// FNV-1a of `s`, continuing `h` (terrain/detail/bytes.h's fnv1a).
uint64_t fnv1a(std::string_view s, uint64_t h = kFnv1aBasis);
std::string hex64(uint64_t v);  // 16 lower-case hex digits
// FNV-1a of a file's bytes, read in chunks; false when it cannot be read.
bool file_fnv1a(const std::string& path, uint64_t& h);

struct InputFile {
  std::string path, fingerprint;  // path: absolute, resolved at plan time
  uint64_t size = 0;
  int64_t mtime_ns = 0;
  uint64_t inode = 0;    // st_ino
  int64_t ctime_ns = 0;  // st_ctim: changes with every write, rename onto, chmod or new hard link
  SampleRect footprint;  // mosaic samples it may contribute to (the whole mosaic when unknown)
};

// Size, mtime, inode and ctime of `f.path` into `f`; false (errno set) when it cannot be stat'ed.
bool stat_file(InputFile& f);
// The fingerprint of `f`'s path and stat.
std::string file_fingerprint(const InputFile& f);
// What differs between two stats of one file, for messages: "size 10 -> 12, ctime 5 -> 9".
std::string file_change(const InputFile& was, const InputFile& now);

}  // namespace terrain::cook
