#include "fuzz_archive_reader_body.h"

#include <cstdio>
#include <algorithm>
#include <cstdlib>
#include <memory>
#include <vector>

#include <zlib.h>

#include "terrain/archive_layout.h"

#include "terrain/archive_reader.h"
#include "terrain/bc_decode.h"
#include "terrain/sample.h"

namespace terrain::fuzz {
namespace {

void require(bool ok, const char* what) {
  if (!ok) {
    std::fprintf(stderr, "fuzz_archive_reader: invariant broken: %s\n", what);
    std::abort();
  }
}

}  // namespace

namespace {

uint64_t u64_at(const std::vector<uint8_t>& b, size_t at) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | b[at + size_t(i)];
  return v;
}
void put_crc(std::vector<uint8_t>& b, size_t field, size_t begin, size_t size) {
  const uint32_t crc = uint32_t(::crc32(0L, b.data() + begin, uInt(size)));
  for (int i = 0; i < 4; ++i) b[field + size_t(i)] = uint8_t(crc >> (8 * i));
}

// Recomputes every checksum of a damaged archive (where its offsets are in bounds), so the fuzzer
// also reaches the parsers behind the CRCs: metadata fields, directory rules, payload tables, zstd.
bool repair_checksums(std::vector<uint8_t>& b) {
  if (b.size() < layout::kHeaderSize) return false;
  const uint64_t dir_off = u64_at(b, layout::header::directory_offset), dir_size = u64_at(b, layout::header::directory_size);
  const uint64_t meta_off = u64_at(b, layout::header::metadata_offset), meta_size = u64_at(b, layout::header::metadata_size);
  auto inside = [&](uint64_t off, uint64_t size) { return off <= b.size() && size <= b.size() - off; };
  if (inside(dir_off, dir_size)) {
    for (uint64_t e = dir_off; e + layout::kEntrySize <= dir_off + dir_size; e += layout::kEntrySize) {
      const uint64_t p_off = u64_at(b, size_t(e + layout::entry::payload_offset));
      uint32_t p_size = 0;
      for (int i = 3; i >= 0; --i) p_size = (p_size << 8) | b[size_t(e + layout::entry::payload_size) + size_t(i)];
      if (inside(p_off, p_size)) put_crc(b, size_t(e + layout::entry::payload_crc32), size_t(p_off), p_size);
    }
    uint32_t version = 0, nodes = 0, per_page = 0;
    for (int i = 3; i >= 0; --i) {
      version = (version << 8) | b[layout::header::format_version + size_t(i)];
      nodes = (nodes << 8) | b[layout::header::node_count + size_t(i)];
      per_page = (per_page << 8) | b[layout::header::page_entries + size_t(i)];
    }
    const uint64_t table = dir_off + uint64_t(nodes) * layout::kEntrySize;
    if (version >= layout::kFormatVersionV3 && per_page > 0 && table <= dir_off + dir_size) {  // SPEC 20: pages, then the table
      for (uint64_t p = 0; p * per_page < nodes && table + (p + 1) * layout::kPageRecordSize <= dir_off + dir_size; ++p) {
        const uint64_t first = dir_off + p * per_page * layout::kEntrySize;
        const uint64_t count = std::min<uint64_t>(per_page, nodes - p * per_page);
        put_crc(b, size_t(table + p * layout::kPageRecordSize + layout::page_record::page_crc32), size_t(first),
                size_t(count * layout::kEntrySize));
      }
      put_crc(b, layout::header::directory_crc32, size_t(table), size_t(dir_off + dir_size - table));
    } else {
      put_crc(b, layout::header::directory_crc32, size_t(dir_off), size_t(dir_size));
    }
  }
  if (inside(meta_off, meta_size)) put_crc(b, layout::header::metadata_crc32, size_t(meta_off), size_t(meta_size));
  put_crc(b, layout::header::header_crc32, 0, layout::header::header_crc32);
  return true;
}

int one_input(const uint8_t* data, size_t size);
void one_input_by_page(const uint8_t* data, size_t size);

}  // namespace

int archive_reader_one_input(const uint8_t* data, size_t size) {
  const int opened = one_input(data, size);
  one_input_by_page(data, size);
  std::vector<uint8_t> repaired(data, data + size);
  if (repair_checksums(repaired)) {
    one_input(repaired.data(), repaired.size());
    one_input_by_page(repaired.data(), repaired.size());
  }
  return opened;
}

namespace {

int one_input(const uint8_t* data, size_t size) {
  ArchiveReader reader;
  const Status st = reader.open_memory({data, size});
  if (!st.ok()) {
    require(!st.message.empty(), "an error without a message");
    require(!reader.is_open(), "reader open after a failed open");
    return 0;
  }
  const auto nodes = reader.nodes();
  uint64_t per_level_sum = 0;
  for (uint32_t n : reader.nodes_per_level()) per_level_sum += n;
  require(per_level_sum == nodes.size(), "nodes_per_level does not add up");
  for (size_t i = 0; i < nodes.size(); ++i) {
    require(reader.find(nodes[i].key) == int64_t(i), "find() misses a directory key");
    if (nodes[i].key.level == 0) continue;
    for (int c = 0; c < 4; ++c) {
      const int64_t child = reader.find(child_of(nodes[i].key, c));
      const bool bit = ((nodes[i].child_mask >> c) & 1) != 0;
      // (written as != -1: GCC 12 -O2 folded "child >= 0" to false here; see the format report)
      require((child != -1) == bit, "child_mask lies");
    }
  }
  require(reader.find({9, 0, 0}) == -1, "find() of an impossible level");
  SectionBytes bytes;
  (void)reader.section_bytes(bytes);
  auto out = std::make_unique<NodeData>();
  std::vector<uint8_t> holes(static_cast<size_t>(kHeightCount));
  const size_t decode_limit = 64;  // keeps one input fast; the directory checks above cover all
  for (size_t i = 0; i < nodes.size() && i < decode_limit; ++i) {
    if (reader.decode_node(i, *out).ok()) decode_hole_mask(*out, holes.data());
    (void)reader.decode_node(i, *out, kSectionHeights);
  }
  (void)reader.decode_node(nodes.size(), *out);  // out of range: an error, not a crash
  if (nodes.size() <= 8) (void)reader.verify();
  SurfaceSampler sampler(reader);
  const WorldInfo& w = reader.world();
  std::optional<SurfaceSample> got;
  for (double f : {0.0, 0.37, 0.5, 1.0})
    (void)sampler.sample(w.origin_x_m + f * w.roots_x * node_size_m(kRootLevel), w.origin_y_m + f * w.roots_y * node_size_m(kRootLevel), got);
  return 1;
}

// The same bytes opened by page (SPEC 20): a page that fails its checks fails its own nodes, and a
// directory whose cross-page rules are broken (child masks, parents) is never a crash.
void one_input_by_page(const uint8_t* data, size_t size) {
  if (size == 0) return;
  ArchiveReader reader;
  if (!reader.open(make_memory_source(std::vector<uint8_t>(data, data + size)), DirectoryLoad::by_page).ok()) return;
  auto out = std::make_unique<NodeData>();
  const uint64_t limit = std::min<uint64_t>(reader.node_count(), 64);
  for (uint64_t i = 0; i < limit; ++i) {
    NodeRecord r;
    if (!reader.record(size_t(i), r).ok()) continue;
    int64_t index = -1;
    require(reader.lookup(r.key, index).ok() && index == int64_t(i), "lookup() misses a key its checked page holds");
    for (int c = 0; c < 4 && r.key.level > 0; ++c) (void)reader.lookup(child_of(r.key, c), index);
    (void)reader.decode_node(size_t(i), *out);
  }
  NodeRecord none;
  require(!reader.record(size_t(reader.node_count()), none).ok(), "record() past the directory");
  int64_t index = 0;
  (void)reader.lookup({9, 0, 0}, index);
  SurfaceSampler sampler(reader);
  const WorldInfo& w = reader.world();
  std::optional<SurfaceSample> got;
  for (double f : {0.0, 0.37, 1.0})
    (void)sampler.sample(w.origin_x_m + f * w.roots_x * node_size_m(kRootLevel), w.origin_y_m + f * w.roots_y * node_size_m(kRootLevel), got);
  if (reader.load_directory().ok()) require(reader.nodes().size() == reader.node_count(), "load_directory() lost nodes");
}

}  // namespace
}  // namespace terrain::fuzz
