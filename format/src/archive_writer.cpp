// Streaming atomic writer: payloads go straight to `path`.tmp-<pid> as they arrive; only the
// 48-byte directory entries stay in memory. finish() appends directory and metadata, writes the
// header into the 128 bytes reserved at the start, fsyncs and renames over the final path.
#include "terrain/archive_writer.h"
#include "terrain/output_paths.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <unordered_set>

#include "bytes.h"
#include "layout.h"
#include "payload.h"

namespace terrain {
namespace {

struct KeyHash {
  size_t operator()(const NodeKey& k) const {
    uint64_t h = (uint64_t(k.level) << 58) ^ (uint64_t(k.x) << 29) ^ uint64_t(k.y) ^ (uint64_t(k.x) >> 35);
    h ^= h >> 33;
    h *= 0xff51afd7ed558ccdULL;
    h ^= h >> 33;
    return size_t(h);
  }
};

std::string errno_text() { return std::strerror(errno); }

Status write_all(int fd, const uint8_t* data, size_t size, uint64_t offset, const std::string& path) {
  while (size > 0) {
    const ssize_t n = ::pwrite(fd, data, size, off_t(offset));
    if (n < 0) {
      if (errno == EINTR) continue;
      return Status::failure(Error::io_write, path + ": write failed at offset " + std::to_string(offset) + ": " + errno_text());
    }
    data += n;
    size -= size_t(n);
    offset += uint64_t(n);
  }
  return Status::success();
}

}  // namespace

Status validate_world(const WorldInfo& world) { return detail::validate_world(world); }

struct ArchiveWriter::Impl {
  std::string path, temp_path;
  int fd = -1;
  uint64_t offset = 0;  // end of the payloads written so far
  std::vector<NodeRecord> records;
  std::unordered_set<NodeKey, KeyHash> keys;
  Status failed;  // sticky first error

  void close_and_remove() {
    if (fd >= 0) ::close(fd);
    fd = -1;
    if (!temp_path.empty()) ::unlink(temp_path.c_str());
    temp_path.clear();
    records.clear();
    keys.clear();
  }
  Status fail(Status s) {
    close_and_remove();
    failed = s;
    return s;
  }
};

ArchiveWriter::ArchiveWriter() : impl_(std::make_unique<Impl>()) {}
ArchiveWriter::~ArchiveWriter() { abort(); }

Status ArchiveWriter::open(const std::string& path) {
  abort();
  impl_->failed = {};
  if (path.empty()) return Status::failure(Error::invalid_argument, "empty archive path");
  // The rename at finish() replaces whatever `path` names: as root that would turn /dev/null or a
  // FIFO into a regular file, and a directory cannot be replaced at all. Refuse before any work.
  if (struct stat st {}; ::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
    return Status::failure(Error::invalid_argument,
                           path + ": is a " + file_kind_name(st.st_mode) + ", not a regular file; refusing to replace it");
  impl_->path = path;
  impl_->temp_path = path + ".tmp-" + std::to_string(::getpid());
  impl_->fd = ::open(impl_->temp_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (impl_->fd < 0) {
    const std::string msg = impl_->temp_path + ": cannot create: " + errno_text();
    impl_->temp_path.clear();
    return Status::failure(Error::io_open, msg);
  }
  const uint8_t zeros[layout::kHeaderSize] = {};
  if (Status s = write_all(impl_->fd, zeros, sizeof(zeros), 0, impl_->temp_path); !s.ok()) return impl_->fail(s);
  impl_->offset = layout::kHeaderSize;
  return Status::success();
}

Status ArchiveWriter::add_node(const NodeRecord& record, std::span<const uint8_t> payload) {
  Impl& w = *impl_;
  if (!w.failed.ok()) return w.failed;
  if (w.fd < 0) return Status::failure(Error::invalid_argument, "add_node before open() or after finish()");
  NodeRecord r = record;
  r.payload_offset = w.offset;
  r.payload_size = payload.size() > layout::kMaxPayloadSize ? layout::kMaxPayloadSize + 1 : uint32_t(payload.size());
  if (Status s = detail::validate_record(r, nullptr); !s.ok()) {
    s.code = Error::invalid_argument;
    return s;  // a caller mistake: the archive so far stays usable
  }
  detail::PayloadTable table;
  if (Status s = detail::parse_payload_table(payload, table); !s.ok())
    return Status::failure(Error::invalid_argument, "node " + node_name(r.key) + ": payload: " + s.to_string());
  if (!w.keys.insert(r.key).second)
    return Status::failure(Error::invalid_argument, "node " + node_name(r.key) + " was added twice");
  r.payload_crc32 = detail::crc32_of(payload);
  if (Status s = write_all(w.fd, payload.data(), payload.size(), w.offset, w.temp_path); !s.ok()) return w.fail(s);
  w.offset += payload.size();
  w.records.push_back(r);
  return Status::success();
}

Status ArchiveWriter::finish(const WorldInfo& world) {
  Impl& w = *impl_;
  if (!w.failed.ok()) return w.failed;
  if (w.fd < 0) return Status::failure(Error::invalid_argument, "finish before open() or after finish()");
  if (Status s = detail::validate_world(world); !s.ok()) return w.fail(s);
  if (w.records.size() > layout::kMaxNodeCount) return w.fail(Status::failure(Error::invalid_argument, "too many nodes"));
  std::sort(w.records.begin(), w.records.end(), [](const NodeRecord& a, const NodeRecord& b) { return key_less(a.key, b.key); });
  for (const NodeRecord& r : w.records)
    if (Status s = detail::validate_record(r, &world); !s.ok()) return w.fail(s);
  const uint64_t payload_size = w.offset - layout::kHeaderSize;
  if (Status s = detail::validate_directory(w.records, layout::kHeaderSize, payload_size, top_level(world)); !s.ok()) return w.fail(s);

  std::vector<uint8_t> directory(w.records.size() * layout::kEntrySize);
  for (size_t i = 0; i < w.records.size(); ++i) detail::encode_entry(w.records[i], directory.data() + i * layout::kEntrySize);
  std::vector<uint8_t> metadata;
  detail::encode_metadata(world, metadata);

  detail::Header h;
  h.format_version = detail::required_format_version(world);
  h.node_count = uint32_t(w.records.size());
  h.payload_offset = layout::kHeaderSize;
  h.payload_size = payload_size;
  h.directory_offset = w.offset;
  h.directory_size = directory.size();
  h.metadata_offset = h.directory_offset + h.directory_size;
  h.metadata_size = metadata.size();
  h.file_size = h.metadata_offset + h.metadata_size;
  h.directory_crc32 = detail::crc32_of(directory);
  h.metadata_crc32 = detail::crc32_of(metadata);
  uint8_t header[layout::kHeaderSize];
  detail::encode_header(h, header);

  if (Status s = write_all(w.fd, directory.data(), directory.size(), h.directory_offset, w.temp_path); !s.ok()) return w.fail(s);
  if (Status s = write_all(w.fd, metadata.data(), metadata.size(), h.metadata_offset, w.temp_path); !s.ok()) return w.fail(s);
  if (::ftruncate(w.fd, off_t(h.file_size)) != 0)  // drop leftovers of an earlier failed attempt (none expected)
    return w.fail(Status::failure(Error::io_write, w.temp_path + ": truncate failed: " + errno_text()));
  // Header last: a file with a valid header is complete.
  if (Status s = write_all(w.fd, header, sizeof(header), 0, w.temp_path); !s.ok()) return w.fail(s);
  if (::fsync(w.fd) != 0) return w.fail(Status::failure(Error::io_write, w.temp_path + ": fsync failed: " + errno_text()));
  if (::close(w.fd) != 0) {
    w.fd = -1;
    return w.fail(Status::failure(Error::io_write, w.temp_path + ": close failed: " + errno_text()));
  }
  w.fd = -1;
  if (::rename(w.temp_path.c_str(), w.path.c_str()) != 0)
    return w.fail(Status::failure(Error::io_rename, "cannot rename " + w.temp_path + " to " + w.path + ": " + errno_text()));
  w.temp_path.clear();
  // Make the rename durable.
  std::string dir = std::filesystem::path(w.path).parent_path().string();
  if (dir.empty()) dir = ".";
  if (int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
  w.records.clear();
  w.keys.clear();
  return Status::success();
}

void ArchiveWriter::abort() {
  if (impl_) impl_->close_and_remove();
}

uint64_t ArchiveWriter::bytes_written() const { return impl_->offset; }

}  // namespace terrain
