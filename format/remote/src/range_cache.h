// A local cache of byte ranges of remote files (HttpOptions::cache_dir), kept across runs.
//
// One folder per file version under the cache folder, named by the FNV-1a 64 hash of the URL, the
// size and the server's validator (ETag, else Last-Modified), so a file changed on the server is a
// new version and never mixes with the old one's bytes. In it: `key` (those three, checked against
// a hash collision), `data` (a sparse file of the remote file's size: cached bytes at their own
// offsets) and `ranges`, a journal of 24-byte records (offset u64, size u32, CRC-32 of the bytes
// u32, CRC-32 of the record's first 16 bytes u32, zero u32), appended after the bytes are written.
// A record is trusted only when its own CRC holds and, the first time this process uses it, the
// bytes' CRC too: a journal cut short by a crash ends at its last whole record, and bytes that
// never reached the disk or were changed are a miss, fetched again, never served.
//
// The folder's size limit counts the disk blocks of every version's data: a range that would pass
// it first evicts other versions, least recently opened first; when only this one is left the
// range is not kept (the cache stays as it is). One process uses a version at a time (an
// exclusive lock on its journal); another process opening it reads without the cache.
#pragma once
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>

#include "terrain/status.h"

namespace terrain::detail {

class RangeCache {
 public:
  struct Stats {
    uint64_t hits = 0;          // reads answered from the cache
    uint64_t hit_bytes = 0;
    uint64_t stored = 0;        // ranges written
    uint64_t stored_bytes = 0;
    uint64_t refused = 0;       // ranges not kept: the limit, or a failed write
    uint64_t bad = 0;           // records whose bytes failed their CRC (then fetched again)
    uint64_t evicted = 0;       // other versions removed for room
  };

  // Opens (creating) the cache of one version of `url` under `dir`. Errors (io_open, naming the
  // folder): the folder cannot be made or written. `busy` is set, with no error and a null `out`,
  // when another process holds this version.
  static Status open(const std::string& dir, uint64_t limit_bytes, const std::string& url, uint64_t size,
                     const std::string& validator, std::unique_ptr<RangeCache>& out, bool& busy);
  ~RangeCache();
  RangeCache(const RangeCache&) = delete;
  RangeCache& operator=(const RangeCache&) = delete;

  // Copies [offset, offset + dst.size()) into dst when every byte of it is cached and intact.
  bool read(uint64_t offset, std::span<uint8_t> dst);
  // Keeps the bytes fetched for [offset, offset + bytes.size()) when the limit allows.
  void write(uint64_t offset, std::span<const uint8_t> bytes);
  Stats stats() const;
  // Bytes of disk the cache folder's data files take (every version).
  uint64_t disk_bytes() const;

 private:
  RangeCache() = default;
  struct Record {
    uint32_t size = 0;
    uint32_t crc = 0;
    bool verified = false;
  };
  bool make_room(uint64_t bytes);  // under mutex_
  // The disk the other versions take: a scan of the folder, at most once a second (other processes
  // may grow theirs), and always before anything is evicted. Under mutex_.
  uint64_t others_bytes(bool fresh);

  std::string root_, folder_;
  uint64_t limit_ = 0, size_ = 0;
  int data_fd_ = -1, journal_fd_ = -1;
  mutable std::mutex mutex_;
  std::map<uint64_t, Record> records_;  // by offset; ranges may overlap
  uint32_t largest_ = 0;                // the largest record's size
  uint64_t others_bytes_ = 0;           // other versions' disk at the last scan
  std::chrono::steady_clock::time_point others_scanned_{};  // when; default: never
  Stats stats_;
};

}  // namespace terrain::detail
