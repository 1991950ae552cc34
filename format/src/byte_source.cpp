// File (pread) and memory byte sources (terrain/byte_source.h).
#include "terrain/byte_source.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "terrain/output_paths.h"

namespace terrain {
namespace {

std::string range_text(uint64_t offset, size_t size) {
  return "bytes [" + std::to_string(offset) + ", " + std::to_string(offset + size) + ")";
}

class FileSource final : public ByteSource {
 public:
  FileSource(int fd, uint64_t size, std::string path) : fd_(fd), size_(size), path_(std::move(path)) {}
  ~FileSource() override { ::close(fd_); }
  FileSource(const FileSource&) = delete;
  FileSource& operator=(const FileSource&) = delete;

  uint64_t size() const override { return size_; }
  const std::string& name() const override { return path_; }

  Status read(uint64_t offset, std::span<uint8_t> dst) const override {
    size_t done = 0;
    while (done < dst.size()) {
      const ssize_t n = ::pread(fd_, dst.data() + done, dst.size() - done, off_t(offset + done));
      if (n < 0) {
        if (errno == EINTR) continue;
        return Status::failure(Error::io_read, path_ + ": cannot read " + range_text(offset, dst.size()) + ": " +
                                                   std::strerror(errno));
      }
      if (n == 0) {
        struct stat st {};
        const std::string now = ::fstat(fd_, &st) == 0 ? std::to_string(st.st_size) : std::string("unknown");
        return Status::failure(Error::truncated, path_ + ": short read of " + range_text(offset, dst.size()) +
                                                     ": the file ends at " + now + " bytes, it had " +
                                                     std::to_string(size_) + " when opened (truncated or replaced since)");
      }
      done += size_t(n);
    }
    return Status::success();
  }

 private:
  int fd_;
  uint64_t size_;
  std::string path_;
};

class MemorySource final : public ByteSource {
 public:
  explicit MemorySource(std::vector<uint8_t> bytes) : bytes_(std::move(bytes)) {}
  uint64_t size() const override { return bytes_.size(); }
  const std::string& name() const override { return name_; }
  Status read(uint64_t offset, std::span<uint8_t> dst) const override {
    if (offset > bytes_.size() || dst.size() > bytes_.size() - offset)
      return Status::failure(Error::truncated, name_ + ": " + range_text(offset, dst.size()) + " lies beyond its " +
                                                   std::to_string(bytes_.size()) + " bytes");
    std::copy_n(bytes_.begin() + std::ptrdiff_t(offset), dst.size(), dst.begin());
    return Status::success();
  }

 private:
  std::vector<uint8_t> bytes_;
  std::string name_ = "memory";
};

}  // namespace

Status open_file_source(const std::string& path, std::unique_ptr<ByteSource>& out) {
  out.reset();
  // O_NONBLOCK: opening a FIFO must not wait for a writer; the file-type check below refuses it.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return Status::failure(Error::io_open, path + ": cannot open: " + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    return Status::failure(Error::io_read, path + ": cannot stat: " + std::strerror(e));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    return Status::failure(Error::io_open, path + ": not a regular file (" + file_kind_name(st.st_mode) + ")");
  }
  if (st.st_size == 0) {
    ::close(fd);
    return Status::failure(Error::truncated, path + ": file is empty");
  }
  out = std::make_unique<FileSource>(fd, uint64_t(st.st_size), path);
  return Status::success();
}

std::unique_ptr<ByteSource> make_memory_source(std::vector<uint8_t> bytes) {
  return std::make_unique<MemorySource>(std::move(bytes));
}

}  // namespace terrain
