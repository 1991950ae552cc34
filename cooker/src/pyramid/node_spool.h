// Node payloads of a block-wise cook, held until the archive can take them in its canonical order.
//
// Blocks finish in block order, but the archive's payloads go level by level (5 first), then by
// row and column, whatever the block size or order: that order is what makes the bytes independent
// of both. Each block's payloads are appended to a spool file next to the archive as they are
// cooked; drain() then copies them into the writer in canonical order, punching copied space out of
// the spool as it goes. Cost: every payload byte is written twice and read once more; memory holds
// one record (56 bytes) per node and 4 bytes per MiB of spool, not the payloads.
#pragma once
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "terrain/archive_writer.h"
#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::cook {

class NodeSpool {
 public:
  NodeSpool() = default;
  ~NodeSpool();  // removes the spool file
  NodeSpool(const NodeSpool&) = delete;
  NodeSpool& operator=(const NodeSpool&) = delete;

  // Creates the spool file `path` (replaced if it exists; removed by the destructor).
  Status open(const std::string& path);
  Status add(const NodeRecord& record, std::span<const uint8_t> payload);
  // Hands every node to `writer` in canonical order (level 5 first, towards 0, then overview
  // levels from 6 upward; in a level by y, then x).
  Status drain(ArchiveWriter& writer);
  uint64_t bytes() const { return bytes_; }
  // Bytes of spool space drain() has given back to the file system so far (whole 1 MiB chunks).
  uint64_t punched_bytes() const { return punched_; }
  // Node count per level and payload bytes: what an ordered writer is told (archive_writer.h).
  ArchiveShape shape() const;
  size_t nodes() const { return entries_.size(); }

  struct Entry {
    NodeRecord record;
    uint64_t offset = 0;
    uint32_t size = 0;
  };
  // The entries in canonical order, and one entry's payload (for writers of other files: units).
  std::vector<Entry> sorted_entries() const;
  Status read(const Entry& e, std::vector<uint8_t>& out) const;

 private:
  std::string path_;
  int fd_ = -1;
  uint64_t bytes_ = 0, punched_ = 0;
  std::vector<Entry> entries_;
};

// True when `a` comes before `b` in the archive's payload order (format.h: payload_order_rank).
inline bool payload_order_less(const NodeKey& a, const NodeKey& b) {
  if (a.level != b.level) return payload_order_rank(a.level) < payload_order_rank(b.level);
  if (a.y != b.y) return a.y < b.y;
  return a.x < b.x;
}

}  // namespace terrain::cook
