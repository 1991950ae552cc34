// POSIX file I/O of the work units' files: whole writes, reads at an offset, and text files written
// under a staged name (output_paths.h) and renamed into place.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "terrain/status.h"

namespace terrain::cook {

// All `n` bytes to `fd`, retrying short writes and EINTR; io_write naming `path` otherwise.
Status write_all(int fd, const uint8_t* p, size_t n, const std::string& path);
// `n` bytes of `fd` at `off` into `p`; truncated naming `path` when the file ends early.
Status read_at(int fd, uint8_t* p, size_t n, uint64_t off, const std::string& path);

// A file written piece by piece (through a 64 KB buffer) under a staged name, then renamed into
// place by commit(); with `durable`, fsynced first (else the caller syncs the folder's filesystem
// before anything names the file). Uncommitted, the staged file is removed.
class StagedText {
 public:
  explicit StagedText(const std::string& stage_for);
  ~StagedText();
  StagedText(const StagedText&) = delete;
  StagedText& operator=(const StagedText&) = delete;
  void put(std::string_view text);
  Status commit(const std::string& path, bool durable);

 private:
  static constexpr size_t kBuffer = size_t(1) << 16;
  void flush();
  std::string temp_, buf_;
  int fd_ = -1;
  Status st_;
  bool committed_ = false;
};

// `text` under `path` through a staged name renamed into place (StagedText).
Status write_text_file(const std::string& path, const std::string& text, bool durable);

}  // namespace terrain::cook
