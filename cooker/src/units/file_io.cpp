#include "units/file_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fmt/format.h>

#include "terrain/output_paths.h"

namespace terrain::cook {

Status write_all(int fd, const uint8_t* p, size_t n, const std::string& path) {
  while (n > 0) {
    const ssize_t k = ::write(fd, p, n);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0)
      return Status::failure(Error::io_write, fmt::format("{}: {}", path, k < 0 ? std::strerror(errno) : "short write"));
    p += k;
    n -= size_t(k);
  }
  return Status::success();
}

Status read_at(int fd, uint8_t* p, size_t n, uint64_t off, const std::string& path) {
  while (n > 0) {
    const ssize_t k = ::pread(fd, p, n, off_t(off));
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0)
      return Status::failure(Error::truncated, fmt::format("{}: {}", path, k < 0 ? std::strerror(errno) : "ends early"));
    p += k;
    n -= size_t(k);
    off += uint64_t(k);
  }
  return Status::success();
}

StagedText::StagedText(const std::string& stage_for) : temp_(staging_path(stage_for)) {
  fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) st_ = Status::failure(Error::io_write, fmt::format("{}: {}", temp_, std::strerror(errno)));
  buf_.reserve(kBuffer);
}

StagedText::~StagedText() {
  if (fd_ >= 0) ::close(fd_);
  if (!committed_) ::unlink(temp_.c_str());
}

void StagedText::put(std::string_view text) {
  buf_.append(text);
  if (buf_.size() >= kBuffer) flush();
}

Status StagedText::commit(const std::string& path, bool durable) {
  flush();
  if (st_.ok() && durable && ::fsync(fd_) != 0)
    st_ = Status::failure(Error::io_write, fmt::format("{}: fsync: {}", temp_, std::strerror(errno)));
  if (fd_ >= 0 && ::close(fd_) != 0 && st_.ok())
    st_ = Status::failure(Error::io_write, fmt::format("{}: {}", temp_, std::strerror(errno)));
  fd_ = -1;
  if (st_.ok() && ::rename(temp_.c_str(), path.c_str()) != 0)
    st_ = Status::failure(Error::io_rename, fmt::format("{}: {}", path, std::strerror(errno)));
  committed_ = st_.ok();
  return st_;
}

void StagedText::flush() {
  if (st_.ok() && !buf_.empty()) st_ = write_all(fd_, reinterpret_cast<const uint8_t*>(buf_.data()), buf_.size(), temp_);
  buf_.clear();
}

Status write_text_file(const std::string& path, const std::string& text, bool durable) {
  StagedText f(path);
  f.put(text);
  return f.commit(path, durable);
}

}  // namespace terrain::cook
