// Encoding and validation of the fixed archive structures (header, metadata, directory), shared by
// the writer and the reader so the writer can never produce a file the reader rejects.
#pragma once
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "terrain/archive_layout.h"
#include "terrain/format.h"
#include "terrain/surface_contract.h"
#include "terrain/status.h"

namespace terrain::detail {

struct Header {
  uint32_t format_version = layout::kFormatVersion;
  uint32_t node_count = 0;
  uint64_t file_size = 0;
  uint64_t payload_offset = layout::kHeaderSize, payload_size = 0;
  uint64_t directory_offset = 0, directory_size = 0;
  uint64_t metadata_offset = 0, metadata_size = 0;
  uint32_t directory_crc32 = 0, metadata_crc32 = 0;
  uint32_t page_entries = 0;  // version 3 (SPEC 20); 0 in versions 1 and 2
  // Version 3: the number of directory pages, and where the page table starts.
  uint64_t page_count() const { return page_entries ? (uint64_t(node_count) + page_entries - 1) / page_entries : 0; }
  uint64_t page_table_offset() const { return directory_offset + uint64_t(node_count) * layout::kEntrySize; }
};

// One record of a version-3 page table (SPEC 20).
struct PageRecord {
  NodeKey first;
  uint32_t crc32 = 0;
};

void encode_header(const Header& h, uint8_t out[layout::kHeaderSize]);
// Checks magic, version, CRC, reserved fields and the section layout against `file_size` (the
// archive's actual size). `head` holds the file's first min(file_size, 128) bytes.
Status decode_header(std::span<const uint8_t> head, uint64_t file_size, Header& out);

Status validate_world(const WorldInfo& world);
void encode_metadata(const WorldInfo& world, std::vector<uint8_t>& out);
Status decode_metadata(std::span<const uint8_t> bytes, uint32_t format_version, WorldInfo& out);

void encode_entry(const NodeRecord& r, uint8_t out[layout::kEntrySize]);
// Decodes the whole directory section (`bytes`: header.directory_size bytes) and checks it: each
// entry on its own (ranges, reserved bits, grid bounds, payload bounds), then the cross-node rules
// (validate_directory). Version 3: the page table's CRC-32 (directory_checksum), then each page
// (decode_page). Versions 1 and 2: the row order of their directory (key_less). `out` is in
// directory order (directory_less) for every version: older directories are sorted into it.
Status decode_directory(std::span<const uint8_t> bytes, const WorldInfo& world, const Header& header,
                        std::vector<NodeRecord>& out);
// Version 3: decodes the page table (header.page_count() records, CRC-32 checked by the caller):
// reserved bytes zero, each first key inside its level's grid, first keys strictly ascending.
Status decode_page_table(std::span<const uint8_t> bytes, const WorldInfo& world, const Header& header,
                         std::vector<PageRecord>& out);
// Version 3: decodes page `page` (its entries' bytes) and checks what one page can tell: its CRC-32
// (directory_checksum), each entry on its own, its first key against the page table, strict
// directory order inside the page and before the next page's first key.
Status decode_page(std::span<const uint8_t> bytes, uint64_t page, std::span<const PageRecord> table,
                   const WorldInfo& world, const Header& header, NodeRecord* out);
// Version 3: the page table of a directory in directory order (first keys, CRC-32 of each page's
// encoded entries in `entries`).
void encode_page_table(std::span<const uint8_t> entries, std::span<const NodeRecord> nodes, uint32_t page_entries,
                       std::vector<uint8_t>& out);
// Checks one record's own fields (no cross-node checks). `where` prefixes messages.
Status validate_record(const NodeRecord& r, const WorldInfo* world);
// Cross-node checks of a directory in directory order (directory_less): strict order, payloads tile
// the payload region, child masks match the directory, every node below `top` (the archive's
// top_level()) has its parent, and with overview levels the top level holds at most kMaxTopNodes
// nodes.
Status validate_directory(std::span<const NodeRecord> nodes, uint64_t payload_offset, uint64_t payload_size, int top);


}  // namespace terrain::detail
