// Archive reader. open() copies header, metadata and directory out of a ByteSource (a file read with
// pread, bytes in memory, ...) and validates them (checksums, bounds, ordering) before anything is
// trusted; payloads are read into buffers and checked when decoded. A version-3 archive (SPEC 20)
// may instead be opened DirectoryLoad::by_page: the open reads the header, the page table and the
// metadata only, and each directory page is read and checked the first time a node in it is used. Nothing is memory-mapped: when
// the file shrinks or fails after open(), the reads that reach past its end return `truncated` (or
// `io_read`) naming the node, and the caller decides (the streamer marks the node failed).
// All const methods are safe to call concurrently from many threads.
#pragma once
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "terrain/byte_source.h"
#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain {

struct SectionBytes {  // stored (compressed) and raw bytes per section, summed over nodes
  uint64_t stored[5] = {};
  uint64_t raw[5] = {};
  uint64_t stored_by_level[kMaxLevels][5] = {};  // the same stored bytes, split by the nodes' level
  uint64_t nodes_by_level[kMaxLevels] = {};
};

// How open() reads the directory. `whole`: every page at open, with every rule of SPEC 8 and 11
// checked (versions 1 and 2 always open so). `by_page` (version 3): the header, then the page table
// with the metadata in one read; pages as lookup() and the node methods need them. In a reader
// opened by_page, nodes(), level_nodes() and nodes_per_level() are empty and verify() and
// section_bytes() refuse until load_directory().
enum class DirectoryLoad { whole, by_page };

class ArchiveReader {
 public:
  ArchiveReader();
  ~ArchiveReader();
  ArchiveReader(ArchiveReader&&) noexcept;
  ArchiveReader& operator=(ArchiveReader&&) noexcept;

  // Opens a file (open_file_source(): regular files only, read with pread).
  Status open(const std::string& path, DirectoryLoad load = DirectoryLoad::whole);
  // Opens an archive from any byte source; the reader owns it from here on. Same checks as open().
  Status open(std::unique_ptr<ByteSource> source, DirectoryLoad load = DirectoryLoad::whole);
  // Opens an archive held in memory (the bytes are copied; used by the fuzzer and tests).
  // Same checks as open().
  Status open_memory(std::span<const uint8_t> bytes);
  bool is_open() const;

  const WorldInfo& world() const;
  uint32_t format_version() const;
  // The source's size at open() (equal to the header's file_size).
  uint64_t file_size() const;
  // The byte source (null when not open), e.g. to read raw ranges for a copy.
  const ByteSource* source() const;

  // Directory, sorted by directory_less (SPEC 20) for every format version. Empty until open()
  // succeeded, and in a reader opened by_page until load_directory().
  std::span<const NodeRecord> nodes() const;
  // Entries in the directory (also in a reader opened by_page).
  uint64_t node_count() const;
  // Index into the directory, or -1 when no node (level, x, y) exists. O(log n), reads no payload.
  // In a reader opened by_page it reads the node's page when needed, and a page that cannot be read
  // or fails its checks is -1 too: lookup() tells them apart.
  int64_t find(const NodeKey& key) const;
  // find() that reports why a page could not be used (io_read, truncated, directory_checksum,
  // directory_invalid, naming the page). `index` is -1 when the node does not exist.
  Status lookup(const NodeKey& key, int64_t& index) const;
  // The directory entry of node `index` (reads its page in a reader opened by_page).
  Status record(size_t index, NodeRecord& out) const;
  // By_page: reads the pages that hold `keys` or would hold them (the page table alone names a
  // key's page) and are not read yet, all at once (one read each, up to 16 in flight), and checks
  // them; later lookups of those keys read nothing. A runtime descending from the top to a camera
  // pays one round trip for every level's page this way instead of one per level. Returns the
  // first page's failure; the other pages are kept. Nothing to do in a reader opened whole.
  Status prefetch(std::span<const NodeKey> keys) const;
  // By_page: reads the whole directory section in one read (pages read before included) and checks it as a whole
  // open does; afterwards the reader is one opened whole. Not concurrent with other calls.
  Status load_directory();
  // Directory pages (0 for versions 1 and 2), and how many have been read since open().
  uint64_t directory_pages() const;
  uint64_t directory_pages_read() const;
  // Number of nodes per level, level_count() entries (levels 0 .. top_level()).
  std::vector<uint32_t> nodes_per_level() const;
  // Levels of the tree: 6, or 6 + K with K overview levels (SPEC 19); 0 when not open.
  int level_count() const;
  // The coarsest level: 5 (the roots) without overview levels, else 5 + K; -1 when not open.
  int top_level() const;
  // The directory entries of one level (a contiguous run of nodes()); empty for other levels.
  std::span<const NodeRecord> level_nodes(int level) const;

  // Reads the stored payload bytes of node `index` into `out` (resized to its payload_size) and
  // verifies their CRC-32. Errors name the node: "truncated: node 2/40/17 at offset 123456: <path>:
  // short read ...", "payload_checksum: node 2/40/17 at offset 123456: payload CRC-32 mismatch".
  Status read_payload(size_t index, std::vector<uint8_t>& out) const;
  // read_payload() into a buffer of the calling thread, then decodes the requested sections into
  // `out`. Errors name the node as above. On failure `out` holds unspecified data.
  Status decode_node(size_t index, NodeData& out, unsigned sections = kSectionAll) const;
  // The two halves of decode_node() for a caller that reads payloads itself, e.g. several nodes in
  // one range request. read_payload_run() reads the stored bytes of `run` (node indices whose
  // payloads lie back to back in the file, in file order: payloads_adjacent()) with one source read
  // into `out`, checking nothing; errors name the run's first node, its length and the range.
  // decode_payload() checks one node's stored bytes (size, CRC-32) and decodes `sections` into `out`;
  // errors name the node as above.
  // With `cancel`, the read gives up (`cancelled`) once it is set (ByteSource::read_cancellable).
  Status read_payload_run(std::span<const uint32_t> run, std::vector<uint8_t>& out,
                          const std::atomic<bool>* cancel = nullptr) const;
  Status decode_payload(size_t index, std::span<const uint8_t> stored, NodeData& out,
                        unsigned sections = kSectionAll) const;
  // True when node b's payload starts where node a's ends.
  bool payloads_adjacent(size_t a, size_t b) const;

  // Reads and checks everything: every payload checksum and decode, child masks against the
  // directory, heights inside [min, max], parent presence. Returns the first problem.
  // `progress` (may be null) gets a fraction 0..1.
  Status verify(void (*progress)(double fraction, void* user) = nullptr, void* user = nullptr) const;

  // Per-section byte totals (reads the 64-byte section table of every payload and parses it; no
  // checksum, no decompression).
  Status section_bytes(SectionBytes& out) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace terrain
