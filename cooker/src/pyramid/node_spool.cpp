#include "pyramid/node_spool.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fmt/format.h>

namespace terrain::cook {

NodeSpool::~NodeSpool() {
  if (fd_ >= 0) ::close(fd_);
  if (!path_.empty()) ::unlink(path_.c_str());
}

Status NodeSpool::open(const std::string& path) {
  fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd_ < 0)
    return Status::failure(Error::io_write, fmt::format("{}: cannot create the node spool: {}", path, std::strerror(errno)));
  path_ = path;
  return Status::success();
}

Status NodeSpool::add(const NodeRecord& record, std::span<const uint8_t> payload) {
  size_t done = 0;
  while (done < payload.size()) {
    const ssize_t n = ::pwrite(fd_, payload.data() + done, payload.size() - done, off_t(bytes_ + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      return Status::failure(Error::io_write, fmt::format("{}: writing the node spool: {}", path_,
                                                          n < 0 ? std::strerror(errno) : "no space written"));
    done += size_t(n);
  }
  entries_.push_back({record, bytes_, uint32_t(payload.size())});
  bytes_ += payload.size();
  return Status::success();
}

std::vector<NodeSpool::Entry> NodeSpool::sorted_entries() const {
  std::vector<Entry> out = entries_;
  std::sort(out.begin(), out.end(),
            [](const Entry& a, const Entry& b) { return payload_order_less(a.record.key, b.record.key); });
  return out;
}

ArchiveShape NodeSpool::shape() const {
  ArchiveShape s;
  for (const Entry& e : entries_) ++s.level_nodes[e.record.key.level];
  s.payload_bytes = bytes_;
  return s;
}

Status NodeSpool::read(const Entry& e, std::vector<uint8_t>& out) const {
  out.resize(e.size);
  size_t done = 0;
  while (done < e.size) {
    const ssize_t n = ::pread(fd_, out.data() + done, e.size - done, off_t(e.offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      return Status::failure(Error::io_read, fmt::format("{}: reading the node spool: {}", path_,
                                                         n < 0 ? std::strerror(errno) : "unexpected end"));
    done += size_t(n);
  }
  return Status::success();
}

namespace {
constexpr int kChunkShift = 20;  // spool space goes back in 1 MiB chunks

// Calls f(chunk, bytes) for each chunk the entry's payload overlaps.
template <class F>
void for_each_chunk(const NodeSpool::Entry& e, F&& f) {
  for (uint64_t a = e.offset, end = e.offset + e.size; a < end;) {
    const uint64_t c = a >> kChunkShift, next = std::min(end, (c + 1) << kChunkShift);
    f(size_t(c), uint32_t(next - a));
    a = next;
  }
}
}  // namespace

Status NodeSpool::drain(ArchiveWriter& writer) {
  const std::vector<Entry> sorted = sorted_entries();
  entries_.clear();
  entries_.shrink_to_fit();
  // The spool is in block order, the drain in canonical order: a chunk whose every payload byte has
  // been copied is punched out of the file, so the disk holds the archive plus what is left to copy
  // (not both in full). Best effort: where the file system cannot punch holes the space stays until
  // the spool is removed, as before.
  std::vector<uint32_t> left(size_t((bytes_ + (uint64_t(1) << kChunkShift) - 1) >> kChunkShift), 0);
  for (const Entry& e : sorted) for_each_chunk(e, [&](size_t c, uint32_t n) { left[c] += n; });
  std::vector<uint8_t> buf;
  for (const Entry& e : sorted) {
    TERRAIN_TRY(read(e, buf));
    TERRAIN_TRY(writer.add_node(e.record, buf));
    for_each_chunk(e, [&](size_t c, uint32_t n) {
      left[c] -= n;
      if (left[c] == 0 && ::fallocate(fd_, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, off_t(c) << kChunkShift,
                                      off_t(1) << kChunkShift) == 0)
        punched_ += uint64_t(1) << kChunkShift;
    });
  }
  return Status::success();
}

}  // namespace terrain::cook
