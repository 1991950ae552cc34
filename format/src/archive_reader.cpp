// Reader over a ByteSource (terrain/byte_source.h). open() copies header, metadata and directory into
// memory and checks them before anything else is believed; payloads are read (pread for a file) into
// a buffer on every decode and checked there (CRC-32, then the section table). Nothing is mapped, so
// a file that shrinks after open() fails the reads that reach past its end (truncated), never faults.
#include "terrain/archive_reader.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cstring>
#include <mutex>
#include <thread>

#include "terrain/detail/bytes.h"
#include "layout.h"
#include "payload.h"
#include "terrain/archive_writer.h"
#include "terrain/bc_decode.h"

namespace terrain {

struct ArchiveReader::Impl {
  std::unique_ptr<ByteSource> source;
  uint64_t size = 0;
  detail::Header header;
  WorldInfo world;
  std::vector<NodeRecord> nodes;
  std::array<uint32_t, kMaxLevels> per_level{};
  std::array<size_t, kMaxLevels + 1> level_begin{};
  // Opened by_page (SPEC 20): `nodes` is empty; pages are read on first use and kept until close.
  bool by_page = false;
  std::vector<detail::PageRecord> table;
  std::unique_ptr<std::atomic<const NodeRecord*>[]> page_at;  // per page, null until read
  mutable std::mutex page_mutex;
  mutable std::vector<std::unique_ptr<NodeRecord[]>> page_owner;
  mutable std::atomic<uint64_t> pages_read{0};

  Status read_section(uint64_t offset, uint64_t bytes, std::vector<uint8_t>& out) const {
    out.resize(size_t(bytes));  // inside the source's size: decode_header checked the layout
    return source->read(offset, out);
  }

  Status check_metadata(std::span<const uint8_t> metadata) {
    if (detail::crc32_of(metadata) != header.metadata_crc32)
      return Status::failure(Error::metadata_checksum, "metadata CRC-32 mismatch (section at offset " +
                                                           std::to_string(header.metadata_offset) + ")");
    return detail::decode_metadata(metadata, header.format_version, world);
  }

  // By_page: the page table and the metadata end the file back to back: one read.
  Status parse_page_table() {
    std::vector<uint8_t> tail;
    const uint64_t at = header.page_table_offset();
    TERRAIN_TRY(read_section(at, size - at, tail));
    const auto table_bytes = std::span<const uint8_t>(tail).first(size_t(header.metadata_offset - at));
    TERRAIN_TRY(check_metadata(std::span<const uint8_t>(tail).subspan(table_bytes.size())));
    if (detail::crc32_of(table_bytes) != header.directory_crc32)
      return Status::failure(Error::directory_checksum, "page table CRC-32 mismatch (at offset " + std::to_string(at) + ")");
    TERRAIN_TRY(detail::decode_page_table(table_bytes, world, header, table));
    page_at = std::make_unique<std::atomic<const NodeRecord*>[]>(table.size());
    for (size_t p = 0; p < table.size(); ++p) page_at[p].store(nullptr);
    by_page = true;
    return Status::success();
  }

  // The entry of node `index`; by_page, reads and checks its page first.
  Status entry(size_t index, const NodeRecord*& out) const {
    if (index >= header.node_count)
      return Status::failure(Error::node_not_found, "node index " + std::to_string(index) + " out of range (" +
                                                        std::to_string(header.node_count) + " nodes)");
    if (!by_page) {
      out = &nodes[index];
      return Status::success();
    }
    const uint64_t p = index / header.page_entries;
    const NodeRecord* page = page_at[p].load(std::memory_order_acquire);
    if (!page) TERRAIN_TRY(read_page(p, page));
    out = page + index % header.page_entries;
    return Status::success();
  }

  Status read_page(uint64_t p, const NodeRecord*& out) const {
    const uint64_t first = p * header.page_entries;
    const uint64_t count = std::min<uint64_t>(header.page_entries, header.node_count - first);
    std::vector<uint8_t> bytes(size_t(count) * layout::kEntrySize);
    if (Status s = source->read(header.directory_offset + first * layout::kEntrySize, bytes); !s.ok()) {
      s.message = "directory page " + std::to_string(p) + ": " + s.message;
      return s;
    }
    auto records = std::make_unique<NodeRecord[]>(size_t(count));
    TERRAIN_TRY(detail::decode_page(bytes, p, table, world, header, records.get()));
    std::lock_guard lock(page_mutex);
    if (const NodeRecord* other = page_at[p].load(std::memory_order_acquire)) {  // another thread was first
      out = other;
      return Status::success();
    }
    out = records.get();
    page_at[p].store(out, std::memory_order_release);
    page_owner.push_back(std::move(records));
    pages_read.fetch_add(1, std::memory_order_relaxed);
    return Status::success();
  }

  // By_page: the page that holds `key` if any page does (from the page table alone), or -1.
  int64_t page_of(const NodeKey& key) const {
    const auto after = std::upper_bound(table.begin(), table.end(), key,
                                        [](const NodeKey& k, const detail::PageRecord& r) { return directory_less(k, r.first); });
    return after == table.begin() ? -1 : int64_t(after - table.begin()) - 1;
  }

  // By_page: the index of `key`, or -1.
  Status lookup(const NodeKey& key, int64_t& index) const {
    index = -1;
    const int64_t page_index = page_of(key);
    if (page_index < 0) return Status::success();
    const auto p = uint64_t(page_index);
    const NodeRecord* page = page_at[p].load(std::memory_order_acquire);
    if (!page) TERRAIN_TRY(read_page(p, page));
    const size_t count = size_t(std::min<uint64_t>(header.page_entries, header.node_count - p * header.page_entries));
    const NodeRecord* it = std::lower_bound(page, page + count, key,
                                            [](const NodeRecord& r, const NodeKey& k) { return directory_less(r.key, k); });
    if (it != page + count && it->key == key) index = int64_t(p * header.page_entries) + (it - page);
    return Status::success();
  }

  void count_levels() {
    per_level.fill(0);
    for (const NodeRecord& r : nodes) ++per_level[r.key.level];
    level_begin[0] = 0;
    for (int l = 0; l < kMaxLevels; ++l) level_begin[size_t(l) + 1] = level_begin[size_t(l)] + per_level[size_t(l)];
  }

  Status parse(DirectoryLoad load) {
    std::vector<uint8_t> head(size_t(std::min<uint64_t>(size, layout::kHeaderSize)));
    TERRAIN_TRY(source->read(0, head));
    TERRAIN_TRY(detail::decode_header(head, size, header));
    if (load == DirectoryLoad::by_page && header.page_entries != 0) return parse_page_table();
    // The directory and the metadata end the file back to back (decode_header checked it): one read,
    // so that a remote source opens in two round trips, this and the header's.
    std::vector<uint8_t> tail;
    TERRAIN_TRY(read_section(header.directory_offset, header.directory_size + header.metadata_size, tail));
    const auto directory = std::span<const uint8_t>(tail).first(size_t(header.directory_size));
    TERRAIN_TRY(check_metadata(std::span<const uint8_t>(tail).subspan(size_t(header.directory_size))));
    TERRAIN_TRY(detail::decode_directory(directory, world, header, nodes));
    count_levels();
    return Status::success();
  }

  std::string where(const NodeRecord& r) const {
    return "node " + node_name(r.key) + " at offset " + std::to_string(r.payload_offset) + ": ";
  }

  // Decodes stored bytes whose CRC-32 was checked. Errors name the node.
  Status decode_checked(const NodeRecord& r, std::span<const uint8_t> bytes, unsigned sections, NodeData& out) const {
    // Normals codec 4 is legal only in archives that declare it (SPEC 6.5, 16.7).
    constexpr size_t kNormalsCodecByte = 4 + size_t(layout::SectionId::normals) * layout::kPayloadTableEntrySize + 1;
    if (!world.derived_normals && bytes.size() > kNormalsCodecByte &&
        bytes[kNormalsCodecByte] == uint8_t(layout::Codec::normals_derived))
      return Status::failure(Error::payload_invalid,
                             where(r) + "normals section uses codec 4 (derived) but the archive has no derived_normals record");
    if (Status s = decode_node_payload(bytes, sections, out); !s.ok()) {
      s.message = where(r) + s.message;
      return s;
    }
    return Status::success();
  }

  // The stored bytes of nodes[index] into out, CRC-32 checked unless `check_crc` is false. Errors
  // name the node.
  Status read_payload(size_t index, std::vector<uint8_t>& out, bool check_crc = true) const {
    const NodeRecord* entry_of = nullptr;
    TERRAIN_TRY(entry(index, entry_of));
    const NodeRecord& r = *entry_of;
    out.resize(r.payload_size);
    if (Status s = source->read(r.payload_offset, out); !s.ok()) {
      s.message = where(r) + s.message;
      return s;
    }
    if (check_crc && detail::crc32_of(out) != r.payload_crc32) return Status::failure(Error::payload_checksum, where(r) + "payload CRC-32 mismatch");
    return Status::success();
  }
};

ArchiveReader::ArchiveReader() = default;
ArchiveReader::~ArchiveReader() = default;
ArchiveReader::ArchiveReader(ArchiveReader&&) noexcept = default;
ArchiveReader& ArchiveReader::operator=(ArchiveReader&&) noexcept = default;

Status ArchiveReader::open(std::unique_ptr<ByteSource> source, DirectoryLoad load) {
  impl_.reset();
  if (!source) return Status::failure(Error::invalid_argument, "no byte source");
  auto impl = std::make_unique<Impl>();
  impl->size = source->size();
  impl->source = std::move(source);
  if (impl->size == 0) return Status::failure(Error::truncated, impl->source->name() + ": archive is empty");
  if (Status s = impl->parse(load); !s.ok()) {
    // A file source names its path in read errors already; decode errors get it here.
    const std::string& name = impl->source->name();
    if (s.message.compare(0, name.size() + 2, name + ": ") != 0) s.message = name + ": " + s.message;
    return s;
  }
  impl_ = std::move(impl);
  return Status::success();
}

Status ArchiveReader::open(const std::string& path, DirectoryLoad load) {
  impl_.reset();
  std::unique_ptr<ByteSource> source;
  TERRAIN_TRY(open_file_source(path, source));
  return open(std::move(source), load);
}

Status ArchiveReader::open_memory(std::span<const uint8_t> bytes) {
  impl_.reset();
  if (bytes.empty()) return Status::failure(Error::truncated, "archive is empty");
  Status s = open(make_memory_source(std::vector<uint8_t>(bytes.begin(), bytes.end())));
  // Messages of an archive in memory do not start with "memory: " (as before sources existed).
  if (!s.ok() && s.message.rfind("memory: ", 0) == 0) s.message.erase(0, 8);
  return s;
}

bool ArchiveReader::is_open() const { return impl_ != nullptr; }

const WorldInfo& ArchiveReader::world() const {
  static const WorldInfo empty;
  return impl_ ? impl_->world : empty;
}
uint32_t ArchiveReader::format_version() const { return impl_ ? impl_->header.format_version : 0; }
uint64_t ArchiveReader::file_size() const { return impl_ ? impl_->size : 0; }
const ByteSource* ArchiveReader::source() const { return impl_ ? impl_->source.get() : nullptr; }

std::span<const NodeRecord> ArchiveReader::nodes() const {
  if (!impl_) return {};
  return impl_->nodes;
}

uint64_t ArchiveReader::node_count() const { return impl_ ? impl_->header.node_count : 0; }
uint64_t ArchiveReader::directory_pages() const { return impl_ ? impl_->header.page_count() : 0; }
uint64_t ArchiveReader::directory_pages_read() const { return impl_ ? impl_->pages_read.load() : 0; }

Status ArchiveReader::lookup(const NodeKey& key, int64_t& index) const {
  index = -1;
  if (!impl_) return Status::failure(Error::invalid_argument, "archive is not open");
  if (key.level >= uint32_t(terrain::level_count(impl_->world))) return Status::success();
  if (impl_->by_page) return impl_->lookup(key, index);
  index = find(key);
  return Status::success();
}

Status ArchiveReader::record(size_t index, NodeRecord& out) const {
  if (!impl_) return Status::failure(Error::invalid_argument, "archive is not open");
  const NodeRecord* r = nullptr;
  TERRAIN_TRY(impl_->entry(index, r));
  out = *r;
  return Status::success();
}

Status ArchiveReader::prefetch(std::span<const NodeKey> keys) const {
  if (!impl_) return Status::failure(Error::invalid_argument, "archive is not open");
  const Impl& m = *impl_;
  if (!m.by_page) return Status::success();
  std::vector<uint64_t> pages;
  for (const NodeKey& k : keys) {
    if (k.level >= uint32_t(terrain::level_count(m.world))) continue;
    const int64_t p = m.page_of(k);
    if (p >= 0 && !m.page_at[size_t(p)].load(std::memory_order_acquire)) pages.push_back(uint64_t(p));
  }
  std::sort(pages.begin(), pages.end());
  pages.erase(std::unique(pages.begin(), pages.end()), pages.end());
  constexpr size_t kInFlight = 16;
  std::vector<Status> results(pages.size());
  for (size_t begin = 0; begin < pages.size(); begin += kInFlight) {
    const size_t end = std::min(pages.size(), begin + kInFlight);
    std::vector<std::thread> readers;
    for (size_t i = begin + 1; i < end; ++i)
      readers.emplace_back([&m, &pages, &results, i] {
        const NodeRecord* page = nullptr;
        results[i] = m.read_page(pages[i], page);
      });
    const NodeRecord* page = nullptr;
    results[begin] = m.read_page(pages[begin], page);  // one on this thread
    for (std::thread& t : readers) t.join();
  }
  for (const Status& s : results)
    if (!s.ok()) return s;
  return Status::success();
}

Status ArchiveReader::load_directory() {
  if (!impl_) return Status::failure(Error::invalid_argument, "archive is not open");
  Impl& m = *impl_;
  if (!m.by_page) return Status::success();
  std::vector<uint8_t> directory;
  TERRAIN_TRY(m.read_section(m.header.directory_offset, m.header.directory_size, directory));
  TERRAIN_TRY(detail::decode_directory(directory, m.world, m.header, m.nodes));
  m.count_levels();
  m.by_page = false;  // pages read before stay owned (callers may hold their entries) but unused
  return Status::success();
}

int64_t ArchiveReader::find(const NodeKey& key) const {
  if (!impl_ || key.level >= uint32_t(terrain::level_count(impl_->world))) return -1;
  if (impl_->by_page) {
    int64_t index = -1;
    return impl_->lookup(key, index).ok() ? index : -1;
  }
  const auto begin = impl_->nodes.begin() + std::ptrdiff_t(impl_->level_begin[key.level]);
  const auto end = impl_->nodes.begin() + std::ptrdiff_t(impl_->level_begin[key.level + 1]);
  const auto it = std::lower_bound(begin, end, key, [](const NodeRecord& r, const NodeKey& k) { return directory_less(r.key, k); });
  if (it == end || !(it->key == key)) return -1;
  return it - impl_->nodes.begin();
}

std::vector<uint32_t> ArchiveReader::nodes_per_level() const {
  if (!impl_) return {};
  return {impl_->per_level.begin(), impl_->per_level.begin() + terrain::level_count(impl_->world)};
}
int ArchiveReader::level_count() const { return impl_ ? terrain::level_count(impl_->world) : 0; }
int ArchiveReader::top_level() const { return impl_ ? terrain::top_level(impl_->world) : -1; }
std::span<const NodeRecord> ArchiveReader::level_nodes(int level) const {
  if (!impl_ || level < 0 || level >= level_count()) return {};
  return std::span<const NodeRecord>(impl_->nodes).subspan(impl_->level_begin[size_t(level)], impl_->per_level[size_t(level)]);
}

Status ArchiveReader::read_payload(size_t index, std::vector<uint8_t>& out) const {
  if (!impl_) return Status::failure(Error::invalid_argument, "archive is not open");
  return impl_->read_payload(index, out);
}

Status ArchiveReader::decode_node(size_t index, NodeData& out, unsigned sections) const {
  // One payload buffer per thread, reused: the largest payload is 1 MiB (SPEC 12).
  thread_local std::vector<uint8_t> bytes;
  TERRAIN_TRY(read_payload(index, bytes));
  const NodeRecord* r = nullptr;
  TERRAIN_TRY(impl_->entry(index, r));
  return impl_->decode_checked(*r, bytes, sections, out);
}

Status ArchiveReader::read_payload_run(std::span<const uint32_t> run, std::vector<uint8_t>& out,
                                       const std::atomic<bool>* cancel) const {
  if (!impl_) return Status::failure(Error::invalid_argument, "archive is not open");
  if (run.empty()) return Status::failure(Error::invalid_argument, "empty payload run");
  std::vector<const NodeRecord*> entries(run.size());
  uint64_t bytes = 0;
  for (size_t i = 0; i < run.size(); ++i) {
    TERRAIN_TRY(impl_->entry(run[i], entries[i]));
    if (i > 0 && entries[i]->payload_offset != entries[i - 1]->payload_offset + entries[i - 1]->payload_size)
      return Status::failure(Error::invalid_argument, "payload run: node " + node_name(entries[i]->key) +
                                                          " does not follow node " + node_name(entries[i - 1]->key));
    bytes += entries[i]->payload_size;
  }
  out.resize(size_t(bytes));
  const uint64_t at = entries[0]->payload_offset;
  if (Status s = cancel ? impl_->source->read_cancellable(at, out, *cancel) : impl_->source->read(at, out); !s.ok()) {
    const std::string more = run.size() > 1 ? "(and the " + std::to_string(run.size() - 1) + " nodes after it, " +
                                                  std::to_string(bytes) + " bytes) "
                                            : "";
    s.message = impl_->where(*entries[0]) + more + s.message;
    return s;
  }
  return Status::success();
}

Status ArchiveReader::decode_payload(size_t index, std::span<const uint8_t> stored, NodeData& out,
                                     unsigned sections) const {
  if (!impl_) return Status::failure(Error::invalid_argument, "archive is not open");
  const NodeRecord* entry = nullptr;
  TERRAIN_TRY(impl_->entry(index, entry));
  const NodeRecord& r = *entry;
  if (stored.size() != r.payload_size)
    return Status::failure(Error::invalid_argument, impl_->where(r) + std::to_string(stored.size()) +
                                                        " stored bytes given, the directory says " +
                                                        std::to_string(r.payload_size));
  if (detail::crc32_of(stored) != r.payload_crc32)
    return Status::failure(Error::payload_checksum, impl_->where(r) + "payload CRC-32 mismatch");
  return impl_->decode_checked(r, stored, sections, out);
}

bool ArchiveReader::payloads_adjacent(size_t a, size_t b) const {
  const NodeRecord *ra = nullptr, *rb = nullptr;
  if (!impl_ || !impl_->entry(a, ra).ok() || !impl_->entry(b, rb).ok()) return false;
  return rb->payload_offset == ra->payload_offset + ra->payload_size;
}

Status ArchiveReader::section_bytes(SectionBytes& out) const {
  out = {};
  if (!impl_) return Status::failure(Error::invalid_argument, "archive is not open");
  if (impl_->by_page) return Status::failure(Error::invalid_argument, "the directory is read by page: load_directory() first");
  std::array<uint8_t, layout::kPayloadHeaderSize> head;
  for (size_t i = 0; i < impl_->nodes.size(); ++i) {
    const NodeRecord& r = impl_->nodes[i];
    detail::PayloadTable table;
    // The section table only: the first 64 bytes of each payload (a shorter payload fails the parse).
    const auto want = std::span<uint8_t>(head).first(std::min<size_t>(head.size(), r.payload_size));
    if (Status s = impl_->source->read(r.payload_offset, want); !s.ok()) {
      s.message = impl_->where(r) + s.message;
      return s;
    }
    if (Status s = detail::parse_payload_table(want, r.payload_size, table); !s.ok()) {
      s.message = "node " + node_name(impl_->nodes[i].key) + ": " + s.message;
      return s;
    }
    for (size_t s = 0; s < layout::kSectionCount; ++s) {
      out.stored[s] += table[s].stored_size;
      out.raw[s] += table[s].raw_size;
      out.stored_by_level[impl_->nodes[i].key.level][s] += table[s].stored_size;  // level checked at open
    }
    ++out.nodes_by_level[impl_->nodes[i].key.level];
  }
  return Status::success();
}

Status ArchiveReader::verify(void (*progress)(double fraction, void* user), void* user) const {
  if (!impl_) return Status::failure(Error::invalid_argument, "archive is not open");
  if (impl_->by_page) return Status::failure(Error::invalid_argument, "the directory is read by page: load_directory() first");
  const auto& nodes = impl_->nodes;
  const WorldInfo& world = impl_->world;
  // Decoded heights (units) and hole masks of one node; neighbours are decoded on demand.
  struct Grid {
    std::vector<int32_t> units = std::vector<int32_t>(size_t(kHeightCount));
    std::vector<uint8_t> holes = std::vector<uint8_t>(size_t(kHeightCount));
  };
  auto node_data = std::make_unique<NodeData>();
  auto load = [&](size_t index, Grid& g, unsigned sections) -> Status {
    NodeData& d = *node_data;
    TERRAIN_TRY(decode_node(index, d, sections));
    const NodeRecord& r = nodes[index];
    const int step = level_step_log2(world, int(r.key.level));
    for (size_t k = 0; k < size_t(kHeightCount); ++k) g.units[k] = vertex_units(r.height_offset, d.heights[k], step);
    decode_hole_mask(d, g.holes.data());
    return Status::success();
  };
  Grid self, other;
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (progress) progress(double(i) / double(nodes.size()), user);
    const NodeRecord& r = nodes[i];
    const std::string where = "node " + node_name(r.key) + ": ";
    TERRAIN_TRY(load(i, self, kSectionAll));
    // Section contents the directory promises.
    int holes = 0;
    for (size_t k = 0; k < size_t(kHeightCount); ++k) {
      if (self.holes[k]) {
        ++holes;
        continue;
      }
      if (self.units[k] < r.min_height || self.units[k] > r.max_height)
        return Status::failure(Error::payload_invalid, where + "vertex (" + std::to_string(k % kHeightSamples) + ", " +
                                                           std::to_string(k / kHeightSamples) + ") = " + std::to_string(self.units[k]) +
                                                           " units is outside [min_height, max_height] = [" +
                                                           std::to_string(r.min_height) + ", " + std::to_string(r.max_height) + "]");
    }
    if ((holes > 0) != bool(r.flags & kNodeFlagHasHoles))
      return Status::failure(Error::payload_invalid, where + "has_holes flag is " + ((r.flags & kNodeFlagHasHoles) ? "set" : "clear") +
                                                         " but the albedo alpha has " + std::to_string(holes) + " hole vertices");
    if (!world.palette.empty())
      for (size_t k = 0; k < node_data->splat.size(); ++k)
        if (node_data->splat[k] >= world.palette.size())
          return Status::failure(Error::payload_invalid, where + "splat sample " + std::to_string(k) + " uses material " +
                                                             std::to_string(node_data->splat[k]) + " but the palette has " +
                                                             std::to_string(world.palette.size()));
    // Shared vertices must carry one canonical value (format.h): west and south neighbours, parent.
    auto compare = [&](const NodeKey& key, auto&& map_vertex, const char* what) -> Status {
      const int64_t j = find(key);
      if (j < 0) return Status::success();
      TERRAIN_TRY(load(size_t(j), other, kSectionHeights | kSectionAlbedo));
      for (int v = 0; v < kHeightSamples; ++v)
        for (int u = 0; u < kHeightSamples; ++u) {
          int ou = 0, ov = 0;
          if (!map_vertex(u, v, ou, ov)) continue;
          const size_t a = size_t(v * kHeightSamples + u), b = size_t(ov * kHeightSamples + ou);
          if (self.holes[a] || other.holes[b]) continue;
          if (self.units[a] != other.units[b])
            return Status::failure(Error::payload_invalid, where + "vertex (" + std::to_string(u) + ", " + std::to_string(v) + ") = " +
                                                               std::to_string(self.units[a]) + " units but " + what + " " +
                                                               node_name(key) + " stores " + std::to_string(other.units[b]) +
                                                               " at the same point");
        }
      return Status::success();
    };
    if (r.key.x > 0)
      TERRAIN_TRY(compare({r.key.level, r.key.x - 1, r.key.y},
                          [](int u, int v, int& ou, int& ov) { ou = kQuadsPerSide; ov = v; return u == 0; }, "west neighbour"));
    if (r.key.y > 0)
      TERRAIN_TRY(compare({r.key.level, r.key.x, r.key.y - 1},
                          [](int u, int v, int& ou, int& ov) { ou = u; ov = kQuadsPerSide; return v == 0; }, "south neighbour"));
    if (r.key.level < uint32_t(terrain::top_level(world))) {  // overview levels too (SPEC 19)
      const int cx = int(r.key.x & 1) * 64, cy = int(r.key.y & 1) * 64;
      TERRAIN_TRY(compare(parent_of(r.key),
                          [cx, cy](int u, int v, int& ou, int& ov) {
                            ou = cx + u / 2;
                            ov = cy + v / 2;
                            return (u % 2) == 0 && (v % 2) == 0;
                          },
                          "parent"));
    }
  }
  if (progress) progress(1.0, user);
  return Status::success();
}

}  // namespace terrain
