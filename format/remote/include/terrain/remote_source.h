// Archives by location: a local path, read with pread (open_file_source), or an http:// or
// https:// URL, read with HTTP range requests (libcurl; the TERRAIN_HTTP build option, on by
// default). Either is a ByteSource the reader and the streamer read as they read a file.
//
// An HTTP source learns the archive's size and the server's validator (ETag, else Last-Modified)
// with one request at open, for the file's first 128 bytes (an archive's header, kept: reading them
// again costs no request), and sends that validator with every later range (If-Match or
// If-Unmodified-Since): a file changed on the server since open fails its reads (io_changed),
// never mixes two archives' bytes; the payload CRC stays the final guard. Failures are Statuses
// naming the URL and the range, never crashes:
//   - not found (404, 410) and refused answers (other 4xx, a server that ignores ranges): io_open
//     at open, io_read after it;
//   - transient: a timeout, a reset or refused connection, 5xx, 408, 429: retried `retries` times,
//     the k-th after backoff_ms * 2^(k-1), then io_read;
//   - a short or overlong answer, or a Content-Range other than the one asked for: io_read;
//   - changed since open (412, another total size): io_changed; beyond its end (416): truncated;
//   - a read_cancellable() whose flag was set stops its transfer: cancelled, never retried.
// Reads may run on many threads at once; each takes an idle connection (kept alive) or opens one.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "terrain/archive_reader.h"
#include "terrain/byte_source.h"
#include "terrain/status.h"

namespace terrain {

struct HttpOptions {
  uint32_t timeout_ms = 10000;         // a request that takes longer fails (transient)
  uint32_t connect_timeout_ms = 5000;  // likewise for the connection alone
  uint32_t retries = 3;                // transient failures retried this many times per read
  uint32_t backoff_ms = 50;            // wait before the k-th retry: backoff_ms * 2^(k-1)
  std::string ca_file;                 // https: a CA bundle (PEM) to trust instead of the system's
  // A local folder that keeps the ranges read (made when absent), so that the next run reads them
  // from disk: one folder per file version (URL, size, ETag or Last-Modified), every range's bytes
  // CRC-checked before they are served, versions least recently opened evicted to stay within
  // cache_limit_bytes of disk. "" = none. A folder that cannot be made or written fails the open;
  // a version another process holds is read without the cache. Not for a server that gives
  // neither ETag nor Last-Modified (nothing would tell its versions apart): read without it.
  std::string cache_dir;
  uint64_t cache_limit_bytes = uint64_t(1) << 30;
};

// What an HTTP source has done since open (counters; any thread may read them).
struct HttpStats {
  uint64_t requests = 0;  // HTTP requests sent, retries included
  uint64_t bytes = 0;     // body bytes received
  uint64_t retries = 0;   // requests repeated after a transient failure
  uint64_t failures = 0;  // reads that failed after their retries
  uint64_t cancelled = 0;  // reads given up (ByteSource::read_cancellable) when the caller no longer wanted them
  bool cached = false;         // reads go through HttpOptions::cache_dir
  uint64_t cache_hits = 0;     // reads answered from it, without a request
  uint64_t cache_bytes = 0;    // ... their bytes
  uint64_t cache_refused = 0;  // ranges it did not keep (its limit, a failed write)
};

// True for "http://..." and "https://..." (case-insensitive scheme).
bool is_url(std::string_view location);
// Whether this build reads URLs (TERRAIN_HTTP).
bool http_supported();

// Opens `url` (http or https): one range request for the size and validator.
Status open_http_source(const std::string& url, const HttpOptions& options, std::unique_ptr<ByteSource>& out);
// A URL through open_http_source, anything else through open_file_source.
Status open_location(const std::string& location, std::unique_ptr<ByteSource>& out,
                     const HttpOptions& options = {});
// reader.open() of open_location(location): an archive by path or URL, its directory read as `load`
// says (DirectoryLoad::by_page: the header and one read of page table and metadata, SPEC 20).
Status open_archive(ArchiveReader& reader, const std::string& location, const HttpOptions& options = {},
                    DirectoryLoad load = DirectoryLoad::whole);
// The counters of an HTTP source; false (out untouched) for any other source.
bool http_stats(const ByteSource& source, HttpStats& out);

}  // namespace terrain
