// Streaming atomic writer: payloads go to `path`.tmp-<host>-<pid> as they arrive (through a write buffer:
// one write per few MB, not one per node). Default mode: only the 48-byte directory entries stay
// in memory; finish() appends the sorted directory. Ordered mode (open_ordered): the directory's
// place is known from the start, each entry is written there as its node comes and nothing grows
// with the node count. finish() then writes metadata and the header into the 128 bytes reserved
// at the start, fsyncs and renames over the final path.
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


#include "terrain/detail/bytes.h"
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

Status read_all(int fd, uint8_t* data, size_t size, uint64_t offset, const std::string& path) {
  while (size > 0) {
    const ssize_t n = ::pread(fd, data, size, off_t(offset));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      return Status::failure(Error::io_read, path + ": cannot read its directory back at offset " + std::to_string(offset) +
                                                 (n < 0 ? ": " + errno_text() : ": short read"));
    data += n;
    size -= size_t(n);
    offset += uint64_t(n);
  }
  return Status::success();
}

// An ordered writer's level directory, written in row order (key_less), put into directory order
// (directory_less) in place: both orders keep each band of 32 rows contiguous, so one band at a
// time is read, sorted and written back. Memory: one band of the level.
Status reorder_level(int fd, uint64_t begin, uint64_t count, const std::string& path) {
  namespace f = layout::entry;
  constexpr size_t kChunk = 4096;  // entries per read while finding a band's end
  std::vector<uint8_t> band;
  std::vector<uint8_t> chunk;
  uint64_t band_first = 0;  // index of band[0]
  uint64_t next = 0;        // entries read so far
  auto band_of = [](const uint8_t* e) { return detail::load_u32(e + f::y) >> kDirectoryTileLog2; };
  auto flush = [&]() -> Status {
    const size_t n = band.size() / layout::kEntrySize;
    std::vector<uint32_t> order(n);
    for (uint32_t i = 0; i < n; ++i) order[i] = i;
    auto key = [&](uint32_t i) {
      const uint8_t* e = band.data() + size_t(i) * layout::kEntrySize;
      return NodeKey{0, detail::load_u32(e + f::x), detail::load_u32(e + f::y)};
    };
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return directory_less(key(a), key(b)); });
    std::vector<uint8_t> sorted(band.size());
    for (size_t i = 0; i < n; ++i)
      std::memcpy(sorted.data() + i * layout::kEntrySize, band.data() + size_t(order[i]) * layout::kEntrySize, layout::kEntrySize);
    TERRAIN_TRY(write_all(fd, sorted.data(), sorted.size(), begin + band_first * layout::kEntrySize, path));
    band_first += n;
    band.clear();
    return Status::success();
  };
  while (next < count) {
    const size_t n = size_t(std::min<uint64_t>(kChunk, count - next));
    chunk.resize(n * layout::kEntrySize);
    TERRAIN_TRY(read_all(fd, chunk.data(), chunk.size(), begin + next * layout::kEntrySize, path));
    for (size_t i = 0; i < n; ++i) {
      const uint8_t* e = chunk.data() + i * layout::kEntrySize;
      if (!band.empty() && band_of(e) != band_of(band.data())) TERRAIN_TRY(flush());
      band.insert(band.end(), e, e + layout::kEntrySize);
    }
    next += n;
  }
  if (!band.empty()) TERRAIN_TRY(flush());
  return Status::success();
}

// The page table (SPEC 20) of the `count` entries at `begin`, read back page by page.
Status page_table_of(int fd, uint64_t begin, uint64_t count, uint32_t page_entries, const std::string& path,
                     std::vector<uint8_t>& out) {
  namespace f = layout::page_record;
  const uint64_t pages = (count + page_entries - 1) / page_entries;
  out.assign(size_t(pages) * layout::kPageRecordSize, 0);
  std::vector<uint8_t> page;
  for (uint64_t p = 0; p < pages; ++p) {
    const uint64_t first = p * page_entries, n = std::min<uint64_t>(page_entries, count - first);
    page.resize(size_t(n) * layout::kEntrySize);
    TERRAIN_TRY(read_all(fd, page.data(), page.size(), begin + first * layout::kEntrySize, path));
    uint8_t* e = out.data() + size_t(p) * layout::kPageRecordSize;
    e[f::level] = page[layout::entry::level];
    std::memcpy(e + f::x, page.data() + layout::entry::x, 4);
    std::memcpy(e + f::y, page.data() + layout::entry::y, 4);
    detail::store_u32(e + f::page_crc32, detail::crc32_of(page));
  }
  return Status::success();
}

}  // namespace

Status validate_world(const WorldInfo& world) { return detail::validate_world(world); }

// The children level L+1's child masks announce, in the directory order of level L (y, then x):
// for each row of parents, the children of its southern half (bits 0, 1) left to right, then of
// its northern half (bits 2, 3). The ordered writer checks level L's nodes against this sequence,
// reading level L+1's entries back from the file (each row twice).
struct ChildStream {
  int fd = -1;
  uint64_t begin = 0, count = 0;  // file offset and entry count of level L+1's directory
  uint32_t level = 0;             // L+1
  uint64_t row_begin = 0, row_end = 0, i = 0;
  int half = 0, c = 0;
  std::vector<uint8_t> buf;
  uint64_t buf_first = 0, buf_count = 0;

  void reset(int file, uint64_t offset, uint64_t n, uint32_t parent_level) {
    fd = file;
    begin = offset;
    count = n;
    level = parent_level;
    row_begin = row_end = i = 0;
    half = c = 0;
    buf_first = buf_count = 0;
  }
  // Entry i of level L+1; nullptr when unreadable.
  const uint8_t* entry(uint64_t k) {
    if (k < buf_first || k >= buf_first + buf_count) {
      constexpr uint64_t kChunk = 1024;
      buf_first = k;
      buf_count = std::min(kChunk, count - k);
      buf.resize(size_t(buf_count) * layout::kEntrySize);
      size_t got = 0;
      while (got < buf.size()) {
        const ssize_t n = ::pread(fd, buf.data() + got, buf.size() - got, off_t(begin + k * layout::kEntrySize + got));
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
          buf_count = 0;
          return nullptr;
        }
        got += size_t(n);
      }
    }
    return buf.data() + size_t(k - buf_first) * layout::kEntrySize;
  }
  // The next announced child; false when there is none. `error` when the file is unreadable.
  bool next(NodeKey& out, bool& error) {
    namespace f = layout::entry;
    for (;;) {
      if (row_begin == row_end) {  // the next row of parents
        if (row_end >= count) return false;
        row_begin = row_end;
        const uint8_t* e = entry(row_begin);
        if (!e) return error = true, false;
        const uint32_t py = detail::load_u32(e + f::y);
        for (row_end = row_begin + 1; row_end < count; ++row_end) {
          const uint8_t* n = entry(row_end);
          if (!n) return error = true, false;
          if (detail::load_u32(n + f::y) != py) break;
        }
        half = c = 0;
        i = row_begin;
      }
      if (i == row_end) {
        if (half == 0) {
          half = 1;
          c = 0;
          i = row_begin;
        } else {
          row_begin = row_end;
        }
        continue;
      }
      const uint8_t* e = entry(i);
      if (!e) return error = true, false;
      const NodeKey parent{level, detail::load_u32(e + f::x), detail::load_u32(e + f::y)};
      const uint8_t mask = e[f::child_mask];
      while (c < 2) {
        const int bit = half * 2 + c++;
        if (mask & (1u << bit)) {
          out = child_of(parent, bit);
          return true;
        }
      }
      ++i;
      c = 0;
    }
  }
};

struct ArchiveWriter::Impl {
  std::string path, temp_path;
  int fd = -1;
  uint64_t offset = 0;  // end of the payloads added so far (some may still be in `out`)
  uint64_t file_size = 0;  // set by a successful finish()
  std::vector<NodeRecord> records;
  std::unordered_set<NodeKey, KeyHash> keys;
  Status failed;  // sticky first error
  SectionBytes sections;
  // Write buffer of the payloads: bytes [out_offset, out_offset + out.size()) of the file.
  std::vector<uint8_t> out;
  uint64_t out_offset = 0;
  // 256 KB: larger buffers cost more in page faults (fresh pages of each merge) than they save in writes.
  static constexpr size_t kOutBuffer = size_t(256) << 10;

  // Ordered mode.
  bool ordered = false;
  ArchiveShape shape;
  std::array<uint64_t, kMaxLevels> dir_start{};  // file offset of each level's directory
  std::array<uint64_t, kMaxLevels> added{};      // nodes of each level added so far
  std::array<uint32_t, kMaxLevels> max_x{}, max_y{};
  int level = -1;  // the level being added
  NodeKey last{};
  std::vector<uint8_t> dir;  // entries of `level` not yet written
  uint64_t dir_offset = 0;   // file offset of dir[0]
  ChildStream children;

  Status flush_out() {
    if (out.empty()) return Status::success();
    Status s = write_all(fd, out.data(), out.size(), out_offset, temp_path);
    out_offset += out.size();
    out.clear();
    return s;
  }
  Status flush_dir() {
    if (dir.empty()) return Status::success();
    Status s = write_all(fd, dir.data(), dir.size(), dir_offset, temp_path);
    dir_offset += dir.size();
    dir.clear();
    return s;
  }
  Status append_payload(std::span<const uint8_t> payload) {
    if (out.size() + payload.size() > kOutBuffer)
      TERRAIN_TRY(flush_out());
    if (payload.size() >= kOutBuffer) {  // never with payloads of at most 1 MiB; kept general
      Status s = write_all(fd, payload.data(), payload.size(), out_offset, temp_path);
      out_offset += payload.size();
      return s;
    }
    out.insert(out.end(), payload.begin(), payload.end());
    return Status::success();
  }
  // Ordered mode: the children level `level` should have and did not get.
  Status check_level_complete() {
    if (level < 0) return Status::success();
    const auto l = size_t(level);
    if (added[l] != shape.level_nodes[l])
      return Status::failure(Error::invalid_argument, "level " + std::to_string(level) + " got " + std::to_string(added[l]) +
                                                          " nodes, the shape says " + std::to_string(shape.level_nodes[l]));
    if (level < kRootLevel) {
      NodeKey missing;
      bool error = false;
      if (children.next(missing, error))
        return Status::failure(Error::directory_invalid, "node " + node_name(parent_of(missing)) + ": child_mask bit " +
                                                             std::to_string((missing.x & 1) | ((missing.y & 1) << 1)) +
                                                             " is set but child " + node_name(missing) + " is absent");
      if (error) return Status::failure(Error::io_read, temp_path + ": cannot read its directory back");
    }
    return Status::success();
  }
  // Ordered mode: level `lvl`'s nodes announce no children (the level below is empty).
  Status check_no_children(int lvl) {
    if (lvl <= 0) return Status::success();  // level 0 has no child masks (validate_record)
    TERRAIN_TRY(flush_dir());
    ChildStream stream;
    stream.reset(fd, dir_start[size_t(lvl)], shape.level_nodes[size_t(lvl)], uint32_t(lvl));
    NodeKey missing;
    bool error = false;
    if (stream.next(missing, error))
      return Status::failure(Error::directory_invalid, "node " + node_name(parent_of(missing)) + ": child_mask bit " +
                                                           std::to_string((missing.x & 1) | ((missing.y & 1) << 1)) +
                                                           " is set but child " + node_name(missing) + " is absent");
    if (error) return Status::failure(Error::io_read, temp_path + ": cannot read its directory back");
    return Status::success();
  }
  // Ordered mode: a level's place in the payload order: 5, 4, .., 0, then 6, 7, .. (SPEC 18, 19).
  static int rank(int l) { return payload_order_rank(uint32_t(l)); }
  static int level_of_rank(int k) { return k <= kRootLevel ? kRootLevel - k : k; }  // its inverse
  Status shape_says_empty(int from_rank, int to_rank) const {  // the levels of ranks [from, to)
    for (int k = std::max(from_rank, 0); k < to_rank; ++k)
      if (shape.level_nodes[size_t(level_of_rank(k))] != 0)
        return Status::failure(Error::invalid_argument, "level " + std::to_string(level_of_rank(k)) +
                                                            " got no nodes, the shape says " +
                                                            std::to_string(shape.level_nodes[size_t(level_of_rank(k))]));
    return Status::success();
  }
  // Ordered mode: the checks of `r` against the order, the shape and the level above.
  Status check_ordered(const NodeRecord& r, uint64_t payload_size) {
    const auto l = size_t(r.key.level);
    if (r.key.level >= uint32_t(kMaxLevels))
      return Status::failure(Error::invalid_argument, "node " + node_name(r.key) + ": level out of range");
    if (int(r.key.level) != level) {
      if (level >= 0 && rank(int(r.key.level)) < rank(level))
        return Status::failure(Error::invalid_argument, "node " + node_name(r.key) + " comes after level " + std::to_string(level) +
                                                            " (an ordered writer takes level 5 first, then towards 0, then "
                                                            "the overview levels from 6 upward)");
      TERRAIN_TRY(check_level_complete());
      if (level > 0 && level <= kRootLevel && int(r.key.level) != level - 1)
        TERRAIN_TRY(check_no_children(level));
      TERRAIN_TRY(shape_says_empty(level < 0 ? 0 : rank(level) + 1, rank(int(r.key.level))));
      TERRAIN_TRY(flush_dir());  // the level above is read back from the file
      level = int(r.key.level);
      dir_offset = dir_start[l];
      if (level < kRootLevel) children.reset(fd, dir_start[l + 1], shape.level_nodes[l + 1], r.key.level + 1);
    } else if (!key_less(last, r.key)) {
      return Status::failure(Error::invalid_argument, "node " + node_name(r.key) + " is not after node " + node_name(last) +
                                                          " (an ordered writer takes each level by y, then x, once each)");
    }
    if (added[l] == shape.level_nodes[l])
      return Status::failure(Error::invalid_argument, "level " + std::to_string(level) + " has more nodes than the shape's " +
                                                          std::to_string(shape.level_nodes[l]));
    if (offset - layout::kHeaderSize + payload_size > shape.payload_bytes)
      return Status::failure(Error::invalid_argument, "the payloads exceed the shape's " + std::to_string(shape.payload_bytes) + " bytes");
    if (level < kRootLevel) {
      NodeKey expected;
      bool error = false;
      const bool has = children.next(expected, error);
      if (error) return Status::failure(Error::io_read, temp_path + ": cannot read its directory back");
      if (!has || key_less(r.key, expected))
        return Status::failure(Error::directory_invalid, "node " + node_name(r.key) + ": parent " + node_name(parent_of(r.key)) +
                                                             " is absent or its child_mask bit " +
                                                             std::to_string((r.key.x & 1) | ((r.key.y & 1) << 1)) + " is clear");
      if (!(expected == r.key))
        return Status::failure(Error::directory_invalid, "node " + node_name(parent_of(expected)) + ": child_mask bit " +
                                                             std::to_string((expected.x & 1) | ((expected.y & 1) << 1)) +
                                                             " is set but child " + node_name(expected) + " is absent");
    }
    return Status::success();
  }
  // Ordered mode, at finish(): overview level `parent_level` (written after its children) announces
  // exactly the nodes of the level below, in their directory order: every child's bit is set and
  // every set bit has its child (SPEC 19 rule 5: roots and overview nodes are closed upward).
  Status check_children_of(int parent_level) {
    const auto p = size_t(parent_level), c = p - 1;
    ChildStream announced, below;
    announced.reset(fd, dir_start[p], shape.level_nodes[p], uint32_t(parent_level));
    below.reset(fd, dir_start[c], shape.level_nodes[c], uint32_t(parent_level - 1));
    for (uint64_t k = 0; k < shape.level_nodes[c]; ++k) {
      const uint8_t* e = below.entry(k);
      if (!e) return Status::failure(Error::io_read, temp_path + ": cannot read its directory back");
      const NodeKey key{uint32_t(parent_level - 1), detail::load_u32(e + layout::entry::x), detail::load_u32(e + layout::entry::y)};
      NodeKey expected;
      bool error = false;
      const bool has = announced.next(expected, error);
      if (error) return Status::failure(Error::io_read, temp_path + ": cannot read its directory back");
      if (!has || key_less(key, expected))
        return Status::failure(Error::directory_invalid, "node " + node_name(key) + ": parent " + node_name(parent_of(key)) +
                                                             " is absent or its child_mask bit " +
                                                             std::to_string((key.x & 1) | ((key.y & 1) << 1)) +
                                                             " is clear (overview levels are closed upward, SPEC 19)");
      if (!(expected == key))
        return Status::failure(Error::directory_invalid, "node " + node_name(parent_of(expected)) + ": child_mask bit " +
                                                             std::to_string((expected.x & 1) | ((expected.y & 1) << 1)) +
                                                             " is set but child " + node_name(expected) + " is absent");
    }
    NodeKey extra;
    bool error = false;
    if (announced.next(extra, error))
      return Status::failure(Error::directory_invalid, "node " + node_name(parent_of(extra)) + ": child_mask bit " +
                                                           std::to_string((extra.x & 1) | ((extra.y & 1) << 1)) +
                                                           " is set but child " + node_name(extra) + " is absent");
    if (error) return Status::failure(Error::io_read, temp_path + ": cannot read its directory back");
    return Status::success();
  }

  // Directory and node count of an ordered writer at finish(): every check default mode makes on
  // the whole directory was made as the nodes came, but the grid bounds, which need the world.
  Status finish_ordered(const WorldInfo& world, std::vector<uint8_t>& page_table, uint64_t& node_count) {
    Impl& w = *this;
    const int top = top_level(world);
    for (int l = top + 1; l < kMaxLevels; ++l)
      if (w.shape.level_nodes[size_t(l)] != 0)
        return Status::failure(Error::invalid_argument, "the shape has nodes at level " + std::to_string(l) +
                                                            ", above the world's top level " + std::to_string(top));
    TERRAIN_TRY(w.check_level_complete());
    if (w.level <= kRootLevel)
      TERRAIN_TRY(w.check_no_children(w.level));
    TERRAIN_TRY(w.shape_says_empty(w.level < 0 ? 0 : rank(w.level) + 1, rank(top) + 1));
    if (w.offset - layout::kHeaderSize != w.shape.payload_bytes)
      return Status::failure(Error::invalid_argument, "the payloads are " + std::to_string(w.offset - layout::kHeaderSize) +
                                                          " bytes, the shape says " + std::to_string(w.shape.payload_bytes));
    TERRAIN_TRY(w.flush_dir());
    for (int l = kRootLevel + 1; l <= top; ++l)
      TERRAIN_TRY(w.check_children_of(l));
    if (top > kRootLevel && w.shape.level_nodes[size_t(top)] > kMaxTopNodes)
      return Status::failure(Error::directory_invalid, "the top level " + std::to_string(top) + " has " +
                                                           std::to_string(w.shape.level_nodes[size_t(top)]) + " nodes, more than " +
                                                           std::to_string(kMaxTopNodes) + " (SPEC 19)");
    node_count = 0;
    for (size_t l = 0; l <= size_t(top); ++l) {
      const uint64_t n = w.shape.level_nodes[l];
      if (n && (w.max_x[l] >= level_grid_cells(world.roots_x, int(l)) || w.max_y[l] >= level_grid_cells(world.roots_y, int(l))))
        return Status::failure(Error::directory_invalid, "level " + std::to_string(l) + " has a node outside its node grid");
      TERRAIN_TRY(reorder_level(w.fd, w.dir_start[l], n, w.temp_path));
      node_count += n;
    }
    return page_table_of(w.fd, w.dir_start[0], node_count, layout::page_entries_for(node_count), w.temp_path, page_table);
  }

  void close_and_remove() {
    if (fd >= 0) ::close(fd);
    fd = -1;
    if (!temp_path.empty()) ::unlink(temp_path.c_str());
    temp_path.clear();
    records.clear();
    keys.clear();
    out.clear();
    dir.clear();
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
  *impl_ = Impl{};
  if (path.empty()) return Status::failure(Error::invalid_argument, "empty archive path");
  // The rename at finish() replaces whatever `path` names: as root that would turn /dev/null or a
  // FIFO into a regular file, and a directory cannot be replaced at all. Refuse before any work.
  if (struct stat st {}; ::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
    return Status::failure(Error::invalid_argument,
                           path + ": is a " + file_kind_name(st.st_mode) + ", not a regular file; refusing to replace it");
  impl_->path = path;
  // A killed earlier writer of this archive left its staged file: clear it before staging ours.
  remove_stale_staging(path);
  impl_->temp_path = staging_path(path);
  impl_->fd = ::open(impl_->temp_path.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (impl_->fd < 0) {
    const std::string msg = impl_->temp_path + ": cannot create: " + errno_text();
    impl_->temp_path.clear();
    return Status::failure(Error::io_open, msg);
  }
  const uint8_t zeros[layout::kHeaderSize] = {};
  if (Status s = write_all(impl_->fd, zeros, sizeof(zeros), 0, impl_->temp_path); !s.ok()) return impl_->fail(s);
  impl_->offset = impl_->out_offset = layout::kHeaderSize;
  impl_->file_size = 0;
  impl_->out.reserve(Impl::kOutBuffer);
  return Status::success();
}

Status ArchiveWriter::open_ordered(const std::string& path, const ArchiveShape& shape) {
  uint64_t nodes = 0;
  for (uint64_t n : shape.level_nodes) nodes += n;
  if (nodes > layout::kMaxNodeCountV3) return Status::failure(Error::invalid_argument, "too many nodes");
  TERRAIN_TRY(open(path));
  Impl& w = *impl_;
  w.ordered = true;
  w.shape = shape;
  // Directory: level 0 first (key order), right after the payloads.
  uint64_t at = layout::kHeaderSize + shape.payload_bytes;
  for (size_t l = 0; l < size_t(kMaxLevels); ++l) {
    w.dir_start[l] = at;
    at += shape.level_nodes[l] * layout::kEntrySize;
  }
  w.dir.reserve(size_t(64) << 10);
  return Status::success();
}

Status ArchiveWriter::add_node(const NodeRecord& record, std::span<const uint8_t> payload, uint32_t* payload_crc) {
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
  if (w.ordered) {
    // A broken order, shape or tree fails the writer: its directory is partly written.
    if (Status s = w.check_ordered(r, payload.size()); !s.ok()) return w.fail(s);
  } else if (!w.keys.insert(r.key).second) {
    return Status::failure(Error::invalid_argument, "node " + node_name(r.key) + " was added twice");
  }
  r.payload_crc32 = detail::crc32_of(payload);
  if (payload_crc) *payload_crc = r.payload_crc32;
  if (Status s = w.append_payload(payload); !s.ok()) return w.fail(s);
  w.offset += payload.size();
  for (size_t k = 0; k < layout::kSectionCount; ++k) {
    w.sections.stored[k] += table[k].stored_size;
    w.sections.raw[k] += table[k].raw_size;
    w.sections.stored_by_level[r.key.level][k] += table[k].stored_size;  // level checked by validate_record
  }
  ++w.sections.nodes_by_level[r.key.level];
  if (w.ordered) {
    const auto l = size_t(r.key.level);
    uint8_t entry[layout::kEntrySize];
    detail::encode_entry(r, entry);
    w.dir.insert(w.dir.end(), entry, entry + layout::kEntrySize);
    if (w.dir.size() >= (size_t(64) << 10))
      if (Status s = w.flush_dir(); !s.ok()) return w.fail(s);
    w.max_x[l] = std::max(w.max_x[l], r.key.x);
    w.max_y[l] = std::max(w.max_y[l], r.key.y);
    ++w.added[l];
    w.last = r.key;
  } else {
    w.records.push_back(r);
  }
  return Status::success();
}

Status ArchiveWriter::finish(const WorldInfo& world) {
  Impl& w = *impl_;
  if (!w.failed.ok()) return w.failed;
  if (w.fd < 0) return Status::failure(Error::invalid_argument, "finish before open() or after finish()");
  if (Status s = detail::validate_world(world); !s.ok()) return w.fail(s);
  if (Status s = w.flush_out(); !s.ok()) return w.fail(s);
  const uint64_t payload_size = w.offset - layout::kHeaderSize;
  std::vector<uint8_t> directory;   // the entries (default mode; an ordered writer wrote them)
  std::vector<uint8_t> page_table;  // SPEC 20
  uint64_t node_count = 0;
  if (w.ordered) {
    if (Status s = w.finish_ordered(world, page_table, node_count); !s.ok()) return w.fail(s);
  } else {
    if (w.records.size() > layout::kMaxNodeCountV3) return w.fail(Status::failure(Error::invalid_argument, "too many nodes"));
    std::sort(w.records.begin(), w.records.end(), [](const NodeRecord& a, const NodeRecord& b) { return directory_less(a.key, b.key); });
    for (const NodeRecord& r : w.records)
      if (Status s = detail::validate_record(r, &world); !s.ok()) return w.fail(s);
    if (Status s = detail::validate_directory(w.records, layout::kHeaderSize, payload_size, top_level(world)); !s.ok()) return w.fail(s);
    directory.resize(w.records.size() * layout::kEntrySize);
    for (size_t i = 0; i < w.records.size(); ++i) detail::encode_entry(w.records[i], directory.data() + i * layout::kEntrySize);
    node_count = w.records.size();
    detail::encode_page_table(directory, w.records, layout::page_entries_for(node_count), page_table);
  }
  std::vector<uint8_t> metadata;
  detail::encode_metadata(world, metadata);

  detail::Header h;
  h.format_version = layout::kFormatVersionV3;
  h.page_entries = layout::page_entries_for(node_count);
  h.node_count = uint32_t(node_count);
  h.payload_offset = layout::kHeaderSize;
  h.payload_size = payload_size;
  h.directory_offset = w.offset;
  h.directory_size = node_count * layout::kEntrySize + page_table.size();
  h.metadata_offset = h.directory_offset + h.directory_size;
  h.metadata_size = metadata.size();
  h.file_size = h.metadata_offset + h.metadata_size;
  h.directory_crc32 = detail::crc32_of(page_table);
  h.metadata_crc32 = detail::crc32_of(metadata);
  uint8_t header[layout::kHeaderSize];
  detail::encode_header(h, header);

  if (!w.ordered)
    if (Status s = write_all(w.fd, directory.data(), directory.size(), h.directory_offset, w.temp_path); !s.ok()) return w.fail(s);
  if (Status s = write_all(w.fd, page_table.data(), page_table.size(), h.page_table_offset(), w.temp_path); !s.ok()) return w.fail(s);
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
  w.file_size = h.file_size;
  return Status::success();
}

void ArchiveWriter::abort() {
  if (impl_) impl_->close_and_remove();
}

uint64_t ArchiveWriter::bytes_written() const { return impl_->file_size ? impl_->file_size : impl_->offset; }

SectionBytes ArchiveWriter::section_bytes() const { return impl_->sections; }

}  // namespace terrain
