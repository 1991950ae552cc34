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
};

void encode_header(const Header& h, uint8_t out[layout::kHeaderSize]);
// Checks magic, version, CRC, reserved fields and the section layout against `file_size` (the
// archive's actual size). `head` holds the file's first min(file_size, 128) bytes.
Status decode_header(std::span<const uint8_t> head, uint64_t file_size, Header& out);

Status validate_world(const WorldInfo& world);
// 1, or 2 when `world` uses a version-2 feature (SPEC 6.5): today's archives stay version 1.
uint32_t required_format_version(const WorldInfo& world);
void encode_metadata(const WorldInfo& world, std::vector<uint8_t>& out);
Status decode_metadata(std::span<const uint8_t> bytes, uint32_t format_version, WorldInfo& out);

void encode_entry(const NodeRecord& r, uint8_t out[layout::kEntrySize]);
// Decodes and checks each entry on its own (ranges, reserved bits, grid bounds, payload bounds).
Status decode_directory(std::span<const uint8_t> bytes, uint32_t node_count, const WorldInfo& world,
                        const Header& header, std::vector<NodeRecord>& out);
// Checks one record's own fields (no cross-node checks). `where` prefixes messages.
Status validate_record(const NodeRecord& r, const WorldInfo* world);
// Cross-node checks of a key-sorted directory: strict order, payloads tile the payload region,
// child masks match the directory, every node below `top` (the archive's top_level()) has its
// parent, and with overview levels the top level holds at most kMaxTopNodes nodes.
Status validate_directory(std::span<const NodeRecord> nodes, uint64_t payload_offset, uint64_t payload_size, int top);


}  // namespace terrain::detail
