// Memory-mapped archive reader. open() validates header, metadata and directory (checksums,
// bounds, ordering) before anything is trusted; payloads are checked when decoded.
// All const methods are safe to call concurrently from many threads.
#pragma once
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain {

struct SectionBytes {  // stored (compressed) and raw bytes per section, summed over nodes
  uint64_t stored[5] = {};
  uint64_t raw[5] = {};
  uint64_t stored_by_level[kMaxLevels][5] = {};  // the same stored bytes, split by the nodes' level
  uint64_t nodes_by_level[kMaxLevels] = {};
};

class ArchiveReader {
 public:
  ArchiveReader();
  ~ArchiveReader();
  ArchiveReader(ArchiveReader&&) noexcept;
  ArchiveReader& operator=(ArchiveReader&&) noexcept;

  Status open(const std::string& path);
  // Opens an archive held in memory (the bytes are copied; used by the fuzzer and tests).
  // Same checks as open().
  Status open_memory(std::span<const uint8_t> bytes);
  bool is_open() const;

  const WorldInfo& world() const;
  uint32_t format_version() const;
  uint64_t file_size() const;

  // Directory, sorted by key_less. Empty until open() succeeded.
  std::span<const NodeRecord> nodes() const;
  // Index into nodes(), or -1 when no node (level, x, y) exists. O(log n), reads no payload.
  int64_t find(const NodeKey& key) const;
  // Number of nodes per level, level_count() entries (levels 0 .. top_level()).
  std::vector<uint32_t> nodes_per_level() const;
  // Levels of the tree: 6, or 6 + K with K overview levels (SPEC 19); 0 when not open.
  int level_count() const;
  // The coarsest level: 5 (the roots) without overview levels, else 5 + K; -1 when not open.
  int top_level() const;
  // The directory entries of one level (a contiguous run of nodes()); empty for other levels.
  std::span<const NodeRecord> level_nodes(int level) const;

  // Stored payload bytes of node `index` (bounds already validated at open()).
  std::span<const uint8_t> payload(size_t index) const;
  // Verifies the payload checksum, then decodes the requested sections into `out`.
  // Errors name the node: "payload_checksum: node 2/40/17 at offset 123456: ...".
  Status decode_node(size_t index, NodeData& out, unsigned sections = kSectionAll) const;

  // Reads and checks everything: every payload checksum and decode, child masks against the
  // directory, heights inside [min, max], parent presence. Returns the first problem.
  // `progress` (may be null) gets a fraction 0..1.
  Status verify(void (*progress)(double fraction, void* user) = nullptr, void* user = nullptr) const;

  // Per-section byte totals (parses each payload's section table; no decompression).
  Status section_bytes(SectionBytes& out) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace terrain
