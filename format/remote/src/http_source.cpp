// HTTP range requests through libcurl (terrain/remote_source.h).
#include <curl/curl.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cstring>
#include <mutex>
#include <thread>
#include <vector>

#include "range_cache.h"
#include "terrain/archive_layout.h"
#include "terrain/remote_source.h"

namespace terrain {
namespace {

std::string range_text(uint64_t offset, size_t size) {
  return "bytes [" + std::to_string(offset) + ", " + std::to_string(offset + size) + ")";
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = char(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

bool parse_u64(std::string_view s, uint64_t& v) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

// One response: its status, the headers we read, and the body written straight into `dst`.
struct Response {
  long status = 0;
  std::string etag, last_modified;
  bool has_range = false;  // Content-Range: bytes first-last/total
  uint64_t first = 0, last = 0, total = 0;
  bool total_known = false;
  std::span<uint8_t> dst;
  size_t received = 0;
  bool overflow = false;  // the body was longer than dst (the transfer is aborted)
};

size_t on_header(char* data, size_t size, size_t n, void* user) {
  Response& r = *static_cast<Response*>(user);
  const std::string_view line = trim(std::string_view(data, size * n));
  if (line.starts_with("HTTP/")) {
    // A new status line (after a redirect or 100 Continue): the headers start again.
    const Response keep = r;
    r = Response{};
    r.dst = keep.dst;
    const size_t sp = line.find(' ');
    uint64_t code = 0;
    if (sp != std::string_view::npos && parse_u64(line.substr(sp + 1, 3), code)) r.status = long(code);
    return size * n;
  }
  const size_t colon = line.find(':');
  if (colon == std::string_view::npos) return size * n;
  const std::string name = lower(trim(line.substr(0, colon)));
  const std::string_view value = trim(line.substr(colon + 1));
  if (name == "etag") {
    r.etag = std::string(value);
  } else if (name == "last-modified") {
    r.last_modified = std::string(value);
  } else if (name == "content-range" && value.starts_with("bytes ")) {
    const std::string_view spec = value.substr(6);
    const size_t slash = spec.find('/'), dash = spec.find('-');
    if (slash != std::string_view::npos) {
      r.total_known = parse_u64(spec.substr(slash + 1), r.total);
      if (dash != std::string_view::npos && dash < slash)
        r.has_range = parse_u64(spec.substr(0, dash), r.first) && parse_u64(spec.substr(dash + 1, slash - dash - 1), r.last);
    }
  }
  return size * n;
}

size_t on_body(char* data, size_t size, size_t n, void* user) {
  Response& r = *static_cast<Response*>(user);
  const size_t len = size * n;
  if (r.status < 200 || r.status >= 300) return len;  // an error page: not the archive's bytes
  if (len > r.dst.size() - r.received) {
    r.overflow = true;
    return 0;  // aborts the transfer (CURLE_WRITE_ERROR)
  }
  std::memcpy(r.dst.data() + r.received, data, len);
  r.received += len;
  return len;
}

// libcurl's progress callback: a non-zero answer stops the transfer.
int on_progress(void* cancel, curl_off_t, curl_off_t, curl_off_t, curl_off_t) {
  return cancel && static_cast<const std::atomic<bool>*>(cancel)->load() ? 1 : 0;
}

bool transient_curl(CURLcode c) {
  switch (c) {
    case CURLE_OPERATION_TIMEDOUT:
    case CURLE_COULDNT_CONNECT:
    case CURLE_RECV_ERROR:
    case CURLE_SEND_ERROR:
    case CURLE_GOT_NOTHING:
    case CURLE_PARTIAL_FILE:
    case CURLE_HTTP2:
    case CURLE_HTTP2_STREAM:
      return true;
    default:
      return false;
  }
}

bool transient_status(long s) { return s == 408 || s == 429 || (s >= 500 && s < 600); }

struct Outcome {
  Status status;
  bool transient = false;
};

class HttpSource final : public ByteSource {
 public:
  HttpSource(std::string url, HttpOptions options) : url_(std::move(url)), options_(std::move(options)) {}
  ~HttpSource() override {
    for (CURL* h : idle_) curl_easy_cleanup(h);
  }
  HttpSource(const HttpSource&) = delete;
  HttpSource& operator=(const HttpSource&) = delete;

  uint64_t size() const override { return size_; }
  const std::string& name() const override { return url_; }

  Status read(uint64_t offset, std::span<uint8_t> dst) const override { return read_until(offset, dst, nullptr); }
  Status read_cancellable(uint64_t offset, std::span<uint8_t> dst, const std::atomic<bool>& cancel) const override {
    return read_until(offset, dst, &cancel);
  }

  // The size and validator, from a request for the file's first bytes (retried as reads are):
  // as many as an archive header holds (format/SPEC.md section 5), which an ArchiveReader reads
  // first and so gets without another round trip.
  Status open() {
    head_.assign(layout::kHeaderSize, 0);
    for (uint32_t attempt = 0;; ++attempt) {
      Outcome o = fetch(0, head_, false);
      if (o.status.ok()) {
        head_.resize(size_t(std::min<uint64_t>(head_received_, size_)));
        return open_cache();
      }
      if (o.transient && attempt < options_.retries) {
        retries_.fetch_add(1, std::memory_order_relaxed);
        std::this_thread::sleep_for(std::chrono::milliseconds(uint64_t(options_.backoff_ms) << std::min(attempt, 16u)));
        continue;
      }
      return Status::failure(Error::io_open, o.status.message);
    }
  }

  // The cache of this version, when options_.cache_dir names one and the server tells versions apart.
  Status open_cache() {
    if (options_.cache_dir.empty() || (etag_.empty() && last_modified_.empty())) return Status::success();
    bool busy = false;
    return detail::RangeCache::open(options_.cache_dir, options_.cache_limit_bytes, url_, size_,
                                    etag_.empty() ? "Last-Modified " + last_modified_ : "ETag " + etag_, cache_, busy);
  }

  HttpStats stats() const {
    HttpStats s{.requests = requests_.load(), .bytes = bytes_.load(), .retries = retries_.load(),
                .failures = failures_.load(), .cancelled = cancelled_.load()};
    if (cache_) {
      const detail::RangeCache::Stats c = cache_->stats();
      s.cached = true;
      s.cache_hits = c.hits;
      s.cache_bytes = c.hit_bytes;
      s.cache_refused = c.refused;
    }
    return s;
  }

 private:
  // read(), giving up once `cancel` (when given) is set: before a request, or while its bytes come.
  Status read_until(uint64_t offset, std::span<uint8_t> dst, const std::atomic<bool>* cancel) const {
    if (dst.empty()) return Status::success();
    if (offset > size_ || dst.size() > size_ - offset)
      return Status::failure(Error::truncated, url_ + ": " + range_text(offset, dst.size()) + " lies beyond its " +
                                                   std::to_string(size_) + " bytes");
    if (offset + dst.size() <= head_.size()) {  // the bytes open() fetched: no request
      std::memcpy(dst.data(), head_.data() + offset, dst.size());
      return Status::success();
    }
    if (cache_ && cache_->read(offset, dst)) return Status::success();
    for (uint32_t attempt = 0;; ++attempt) {
      if (cancel && cancel->load()) {
        cancelled_.fetch_add(1, std::memory_order_relaxed);
        return Status::failure(Error::cancelled, url_ + ": " + range_text(offset, dst.size()) + ": no longer wanted");
      }
      Outcome o = fetch(offset, dst, true, cancel);
      if (o.status.ok()) {
        if (cache_) cache_->write(offset, dst);
        return o.status;
      }
      if (o.transient && attempt < options_.retries) {
        retries_.fetch_add(1, std::memory_order_relaxed);
        std::this_thread::sleep_for(std::chrono::milliseconds(uint64_t(options_.backoff_ms) << std::min(attempt, 16u)));
        continue;
      }
      (o.status.code == Error::cancelled ? cancelled_ : failures_).fetch_add(1, std::memory_order_relaxed);
      if (o.transient)
        o.status.message += " (after " + std::to_string(attempt) + (attempt == 1 ? " retry)" : " retries)");
      return o.status;
    }
  }

  CURL* acquire() const {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!idle_.empty()) {
        CURL* h = idle_.back();
        idle_.pop_back();
        return h;
      }
    }
    return curl_easy_init();
  }
  void release(CURL* h) const {
    std::lock_guard<std::mutex> lock(mutex_);
    idle_.push_back(h);
  }

  // One request for [offset, offset + dst.size()). `validate`: send the validator and check the
  // answer against what open() learnt; false (open() itself): learn the size and the validator.
  // With `cancel`, the transfer stops (cancelled) once it is set.
  Outcome fetch(uint64_t offset, std::span<uint8_t> dst, bool validate, const std::atomic<bool>* cancel = nullptr) const {
    const std::string what = url_ + ": " + range_text(offset, dst.size());
    CURL* h = acquire();
    if (!h) return {Status::failure(Error::io_read, what + ": cannot start a request (curl_easy_init)"), false};
    Response r;
    r.dst = dst;
    char error[CURL_ERROR_SIZE] = {};
    const std::string range = std::to_string(offset) + "-" + std::to_string(offset + dst.size() - 1);
    curl_slist* headers = nullptr;
    if (validate && !if_match_.empty()) headers = curl_slist_append(headers, ("If-Match: " + if_match_).c_str());
    if (validate && if_match_.empty() && !last_modified_.empty())
      headers = curl_slist_append(headers, ("If-Unmodified-Since: " + last_modified_).c_str());
    curl_easy_setopt(h, CURLOPT_URL, url_.c_str());
    curl_easy_setopt(h, CURLOPT_RANGE, range.c_str());
    curl_easy_setopt(h, CURLOPT_HTTPHEADER, headers);
    curl_easy_setopt(h, CURLOPT_HEADERFUNCTION, on_header);
    curl_easy_setopt(h, CURLOPT_HEADERDATA, &r);
    curl_easy_setopt(h, CURLOPT_WRITEFUNCTION, on_body);
    curl_easy_setopt(h, CURLOPT_WRITEDATA, &r);
    curl_easy_setopt(h, CURLOPT_ERRORBUFFER, error);
    curl_easy_setopt(h, CURLOPT_NOSIGNAL, 1L);
    curl_easy_setopt(h, CURLOPT_FOLLOWLOCATION, 1L);
    curl_easy_setopt(h, CURLOPT_MAXREDIRS, 5L);
    curl_easy_setopt(h, CURLOPT_TIMEOUT_MS, long(options_.timeout_ms));
    curl_easy_setopt(h, CURLOPT_CONNECTTIMEOUT_MS, long(options_.connect_timeout_ms));
    curl_easy_setopt(h, CURLOPT_ACCEPT_ENCODING, nullptr);  // the bytes as stored, never re-encoded
    if (!options_.ca_file.empty()) curl_easy_setopt(h, CURLOPT_CAINFO, options_.ca_file.c_str());
    curl_easy_setopt(h, CURLOPT_NOPROGRESS, cancel ? 0L : 1L);
    curl_easy_setopt(h, CURLOPT_XFERINFOFUNCTION, on_progress);
    curl_easy_setopt(h, CURLOPT_XFERINFODATA, const_cast<std::atomic<bool>*>(cancel));
    requests_.fetch_add(1, std::memory_order_relaxed);
    const CURLcode code = curl_easy_perform(h);
    curl_easy_setopt(h, CURLOPT_HTTPHEADER, nullptr);
    curl_easy_setopt(h, CURLOPT_ERRORBUFFER, nullptr);
    curl_slist_free_all(headers);
    bytes_.fetch_add(r.received, std::memory_order_relaxed);
    if (code != CURLE_OK) {
      // A connection in an unknown state is not reused.
      curl_easy_cleanup(h);
      if (code == CURLE_ABORTED_BY_CALLBACK)
        return {Status::failure(Error::cancelled, what + ": no longer wanted (stopped after " +
                                                      std::to_string(r.received) + " bytes)"), false};
      if (r.overflow)
        return {Status::failure(Error::io_read, what + (r.status == 200 ? ": the server ignored the range (HTTP 200): it "
                                                                          "does not answer range requests"
                                                                        : ": the server sent more bytes than asked")),
                false};
      return {Status::failure(Error::io_read, what + ": " + (error[0] ? std::string(error) : curl_easy_strerror(code))),
              transient_curl(code)};
    }
    release(h);
    const std::string http = "HTTP " + std::to_string(r.status);
    if (r.status == 412)
      return {Status::failure(Error::io_changed, what + ": changed on the server since it was opened (" + http +
                                                     ", precondition failed)"), false};
    if (r.status == 416)
      return {Status::failure(Error::truncated, what + ": beyond the end of the file on the server (" + http +
                                                    "): it is smaller than the " + std::to_string(size_) +
                                                    " bytes it had when opened"), false};
    if (r.status == 404 || r.status == 410) return {Status::failure(Error::io_read, what + ": not found (" + http + ")"), false};
    if (transient_status(r.status)) return {Status::failure(Error::io_read, what + ": " + http), true};
    if (r.status != 206 && r.status != 200)
      return {Status::failure(Error::io_read, what + ": the server answered " + http), false};
    if (!validate) {
      // Opening: the total size from the Content-Range, the validator from the headers.
      if (r.status != 206 || !r.total_known)
        return {Status::failure(Error::io_read, url_ + ": the server does not answer range requests (" + http +
                                                    " without a Content-Range total)"), false};
      if (r.total == 0) return {Status::failure(Error::truncated, url_ + ": the file is empty"), false};
      if (r.first != 0 || r.received != std::min<uint64_t>(dst.size(), r.total))
        return {Status::failure(Error::io_read, what + ": short answer of " + std::to_string(r.received) + " bytes"), true};
      size_ = r.total;
      head_received_ = r.received;
      etag_ = r.etag;
      if_match_ = r.etag.starts_with("W/") ? std::string() : r.etag;  // If-Match compares strong tags only
      last_modified_ = r.last_modified;
      return {Status::success(), false};
    }
    if (r.status == 200 && !(offset == 0 && dst.size() == size_))
      return {Status::failure(Error::io_read, what + ": the server ignored the range (" + http + ")"), false};
    if (r.status == 206 && (!r.has_range || r.first != offset || r.last != offset + dst.size() - 1))
      return {Status::failure(Error::io_read, what + ": the server answered another range (" + http + ")"), false};
    if ((r.total_known && r.total != size_) || (!etag_.empty() && !r.etag.empty() && r.etag != etag_))
      return {Status::failure(Error::io_changed, what + ": changed on the server since it was opened (size " +
                                                     (r.total_known ? std::to_string(r.total) : std::string("?")) +
                                                     ", ETag " + r.etag + "; at open " + std::to_string(size_) +
                                                     ", " + etag_ + ")"), false};
    if (r.received != dst.size())
      return {Status::failure(Error::io_read, what + ": short answer of " + std::to_string(r.received) + " bytes"), true};
    return {Status::success(), false};
  }

  std::string url_;
  HttpOptions options_;
  mutable uint64_t size_ = 0;  // set by open(), then constant
  std::vector<uint8_t> head_;  // the file's first bytes, fetched by open(), then constant
  std::unique_ptr<detail::RangeCache> cache_;  // set by open() (or null), then constant
  mutable size_t head_received_ = 0;
  mutable std::string etag_, if_match_, last_modified_;
  mutable std::mutex mutex_;
  mutable std::vector<CURL*> idle_;
  mutable std::atomic<uint64_t> requests_{0}, bytes_{0}, retries_{0}, failures_{0}, cancelled_{0};
};

}  // namespace

bool http_supported() { return true; }

Status open_http_source(const std::string& url, const HttpOptions& options, std::unique_ptr<ByteSource>& out) {
  out.reset();
  static std::once_flag once;
  static CURLcode global = CURLE_OK;
  std::call_once(once, [] { global = curl_global_init(CURL_GLOBAL_DEFAULT); });
  if (global != CURLE_OK)
    return Status::failure(Error::io_open, url + ": cannot start libcurl: " + curl_easy_strerror(global));
  auto source = std::make_unique<HttpSource>(url, options);
  TERRAIN_TRY(source->open());
  out = std::move(source);
  return Status::success();
}

bool http_stats(const ByteSource& source, HttpStats& out) {
  const auto* http = dynamic_cast<const HttpSource*>(&source);
  if (!http) return false;
  out = http->stats();
  return true;
}

}  // namespace terrain
