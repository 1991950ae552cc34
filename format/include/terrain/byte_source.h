// Where an archive's bytes come from. ArchiveReader copies every range it needs out of a ByteSource
// and keeps no pointer into it, so a source that changes or fails after open() (a file truncated or
// replaced in place, a download still running, a server going away) makes reads fail with a Status,
// never a signal. Implementations: a local file read with pread(2), bytes held in memory; a remote
// source (HTTP range requests) implements the same three calls.
#pragma once
#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "terrain/status.h"

namespace terrain {

class ByteSource {
 public:
  virtual ~ByteSource() = default;
  // The size in bytes when the source was opened. The reader checks the archive against it and
  // never asks for a range beyond it; it does not change when the underlying file does.
  virtual uint64_t size() const = 0;
  // Copies the bytes [offset, offset + dst.size()) into dst: all of them, or a failure. Safe to call
  // from many threads at once (no shared position). Errors name the source and the range:
  // `truncated` when the data ends before the range does (the file shrank after open, a short
  // read), `io_read` for any other failure. On failure dst holds unspecified bytes.
  virtual Status read(uint64_t offset, std::span<uint8_t> dst) const = 0;
  // read() that may give up early, with `cancelled`, once `cancel` is set: a remote source stops
  // the transfer. This default, for sources whose reads are quick (a file, memory), reads all.
  virtual Status read_cancellable(uint64_t offset, std::span<uint8_t> dst, const std::atomic<bool>& cancel) const {
    (void)cancel;
    return read(offset, dst);
  }
  // What messages call the source: the path it was opened with, or "memory".
  virtual const std::string& name() const = 0;
};

// Opens a regular file for pread (the descriptor stays open until the source is destroyed). Refuses
// FIFOs, devices and directories without blocking (io_open), and an empty file (truncated).
Status open_file_source(const std::string& path, std::unique_ptr<ByteSource>& out);
// A source over a private copy of `bytes`.
std::unique_ptr<ByteSource> make_memory_source(std::vector<uint8_t> bytes);

}  // namespace terrain
