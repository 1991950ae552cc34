// Byte ranges of remote files kept on local disk (range_cache.h).
#include "range_cache.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>
#include <vector>

#include "terrain/detail/bytes.h"

namespace terrain::detail {
namespace {

namespace fs = std::filesystem;

constexpr size_t kRecordSize = 24;

std::string hex16(uint64_t v) {
  static const char digits[] = "0123456789abcdef";
  std::string s(16, '0');
  for (int i = 15; i >= 0; --i, v >>= 4) s[size_t(i)] = digits[v & 15];
  return s;
}

bool pread_all(int fd, uint8_t* dst, size_t size, uint64_t offset) {
  while (size > 0) {
    const ssize_t n = ::pread(fd, dst, size, off_t(offset));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    dst += n;
    size -= size_t(n);
    offset += uint64_t(n);
  }
  return true;
}

bool pwrite_all(int fd, const uint8_t* src, size_t size, uint64_t offset) {
  while (size > 0) {
    const ssize_t n = ::pwrite(fd, src, size, off_t(offset));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    src += n;
    size -= size_t(n);
    offset += uint64_t(n);
  }
  return true;
}

uint64_t data_disk_bytes(const fs::path& data) {
  struct stat st {};
  if (::stat(data.c_str(), &st) != 0) return 0;
  return uint64_t(st.st_blocks) * 512;
}

std::string errno_text() { return std::strerror(errno); }

}  // namespace

Status RangeCache::open(const std::string& dir, uint64_t limit_bytes, const std::string& url, uint64_t size,
                        const std::string& validator, std::unique_ptr<RangeCache>& out, bool& busy) {
  out.reset();
  busy = false;
  const std::string key = url + "\n" + std::to_string(size) + "\n" + validator + "\n";
  const fs::path folder = fs::path(dir) / hex16(fnv1a(key));
  auto fail = [&](const std::string& what) {
    return Status::failure(Error::io_open, "cache folder " + dir + ": " + what);
  };
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec) return fail("cannot create " + folder.string() + ": " + ec.message());

  auto cache = std::unique_ptr<RangeCache>(new RangeCache());
  cache->root_ = dir;
  cache->folder_ = folder.string();
  cache->limit_ = limit_bytes;
  cache->size_ = size;
  cache->journal_fd_ = ::open((folder / "ranges").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (cache->journal_fd_ < 0) return fail("cannot open " + (folder / "ranges").string() + ": " + errno_text());
  if (::flock(cache->journal_fd_, LOCK_EX | LOCK_NB) != 0) {
    if (errno == EWOULDBLOCK) {
      busy = true;
      return Status::success();
    }
    return fail("cannot lock " + (folder / "ranges").string() + ": " + errno_text());
  }
  // The key: a folder of another file whose hash collides is emptied and taken over.
  {
    std::ifstream in(folder / "key", std::ios::binary);
    std::stringstream held;
    held << in.rdbuf();
    if (held.str() != key) {
      if (::ftruncate(cache->journal_fd_, 0) != 0) return fail("cannot reset " + (folder / "ranges").string());
      fs::remove(folder / "data", ec);
      std::ofstream k(folder / "key", std::ios::binary | std::ios::trunc);
      k << key;
      if (!k.flush()) return fail("cannot write " + (folder / "key").string());
    }
  }
  cache->data_fd_ = ::open((folder / "data").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (cache->data_fd_ < 0) return fail("cannot open " + (folder / "data").string() + ": " + errno_text());
  struct stat st {};
  if (::fstat(cache->data_fd_, &st) != 0 || (uint64_t(st.st_size) != size && ::ftruncate(cache->data_fd_, off_t(size)) != 0))
    return fail("cannot size " + (folder / "data").string() + " to " + std::to_string(size) + " bytes: " + errno_text());

  // The journal up to its last whole, intact record (a crash may have cut it).
  std::vector<uint8_t> journal;
  if (::fstat(cache->journal_fd_, &st) == 0 && st.st_size > 0) {
    journal.resize(size_t(st.st_size));
    if (!pread_all(cache->journal_fd_, journal.data(), journal.size(), 0)) journal.clear();
  }
  size_t good = 0;
  for (; good + kRecordSize <= journal.size(); good += kRecordSize) {
    const uint8_t* r = journal.data() + good;
    if (crc32_of({r, 16}) != load_u32(r + 16)) break;
    const uint64_t offset = load_u64(r);
    const uint32_t bytes = load_u32(r + 8);
    if (bytes == 0 || offset > size || bytes > size - offset) break;
    cache->records_[offset] = Record{bytes, load_u32(r + 12), false};
    cache->largest_ = std::max(cache->largest_, bytes);
  }
  if (good != journal.size() && ::ftruncate(cache->journal_fd_, off_t(good)) != 0)
    return fail("cannot repair " + (folder / "ranges").string() + ": " + errno_text());
  ::futimens(cache->journal_fd_, nullptr);  // opened now: the least recently opened version goes first
  out = std::move(cache);
  return Status::success();
}

RangeCache::~RangeCache() {
  if (data_fd_ >= 0) ::close(data_fd_);
  if (journal_fd_ >= 0) ::close(journal_fd_);  // releases the lock
}

bool RangeCache::read(uint64_t offset, std::span<uint8_t> dst) {
  std::lock_guard lock(mutex_);
  const uint64_t end = offset + dst.size();
  // Records covering [offset, end) one after the other, each reaching as far as possible.
  std::vector<std::map<uint64_t, Record>::iterator> used;
  for (uint64_t at = offset; at < end;) {
    auto best = records_.end();
    for (auto it = records_.lower_bound(at > largest_ ? at - largest_ : 0); it != records_.end() && it->first <= at; ++it)
      if (it->first + it->second.size > at && (best == records_.end() || it->first + it->second.size > best->first + best->second.size))
        best = it;
    if (best == records_.end()) return false;
    used.push_back(best);
    at = best->first + best->second.size;
  }
  for (auto it : used) {
    if (it->second.verified) continue;
    std::vector<uint8_t> bytes(it->second.size);
    if (!pread_all(data_fd_, bytes.data(), bytes.size(), it->first) || crc32_of(bytes) != it->second.crc) {
      records_.erase(it);  // fetched again (and kept again) by the caller
      ++stats_.bad;
      return false;
    }
    it->second.verified = true;
  }
  if (!pread_all(data_fd_, dst.data(), dst.size(), offset)) return false;
  ++stats_.hits;
  stats_.hit_bytes += dst.size();
  return true;
}

void RangeCache::write(uint64_t offset, std::span<const uint8_t> bytes) {
  if (bytes.empty() || offset > size_ || bytes.size() > size_ - offset || bytes.size() > UINT32_MAX) return;
  std::lock_guard lock(mutex_);
  if (!make_room(bytes.size()) || !pwrite_all(data_fd_, bytes.data(), bytes.size(), offset)) {
    ++stats_.refused;
    return;
  }
  uint8_t r[kRecordSize] = {};
  store_u64(r, offset);
  store_u32(r + 8, uint32_t(bytes.size()));
  store_u32(r + 12, crc32_of(bytes));
  store_u32(r + 16, crc32_of({r, 16}));
  struct stat st {};
  if (::fstat(journal_fd_, &st) != 0 || !pwrite_all(journal_fd_, r, kRecordSize, uint64_t(st.st_size))) {
    ++stats_.refused;
    return;
  }
  records_[offset] = Record{uint32_t(bytes.size()), load_u32(r + 12), true};
  largest_ = std::max(largest_, uint32_t(bytes.size()));
  ++stats_.stored;
  stats_.stored_bytes += bytes.size();
}

uint64_t RangeCache::others_bytes(bool fresh) {
  const auto now = std::chrono::steady_clock::now();
  if (fresh || others_scanned_ == std::chrono::steady_clock::time_point{} || now - others_scanned_ > std::chrono::seconds(1)) {
    others_bytes_ = 0;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(root_, ec))
      if (e.is_directory() && e.path() != fs::path(folder_)) others_bytes_ += data_disk_bytes(e.path() / "data");
    others_scanned_ = now;
  }
  return others_bytes_;
}

bool RangeCache::make_room(uint64_t bytes) {
  // This version's disk by one fstat; the others' from the last scan, unless that says no.
  struct stat st {};
  const uint64_t own = ::fstat(data_fd_, &st) == 0 ? uint64_t(st.st_blocks) * 512 : 0;
  if (own + others_bytes(false) + bytes <= limit_) return true;
  if (own + others_bytes(true) + bytes <= limit_) return true;
  // Other versions, least recently opened first; one another process holds stays.
  struct Version {
    fs::path folder;
    fs::file_time_type opened;
  };
  std::vector<Version> others;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(root_, ec)) {
    if (!e.is_directory() || e.path() == fs::path(folder_)) continue;
    const fs::file_time_type t = fs::last_write_time(e.path() / "ranges", ec);
    others.push_back({e.path(), ec ? fs::file_time_type::min() : t});
  }
  std::sort(others.begin(), others.end(), [](const Version& a, const Version& b) { return a.opened < b.opened; });
  for (const Version& v : others) {
    const int fd = ::open((v.folder / "ranges").c_str(), O_RDWR | O_CLOEXEC);
    if (fd >= 0 && ::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      ::close(fd);
      continue;
    }
    fs::remove_all(v.folder, ec);
    if (fd >= 0) ::close(fd);
    ++stats_.evicted;
    if (own + others_bytes(true) + bytes <= limit_) return true;
  }
  return false;
}

uint64_t RangeCache::disk_bytes() const {
  uint64_t total = 0;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(root_, ec))
    if (e.is_directory()) total += data_disk_bytes(e.path() / "data");
  return total;
}

RangeCache::Stats RangeCache::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

}  // namespace terrain::detail
