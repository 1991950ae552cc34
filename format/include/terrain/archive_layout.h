// Archive format v1/v2: byte offsets and limits of every fixed structure (format/SPEC.md tables).
// Names follow the SPEC's field names. Exposed so tests and independent tools can address fields
// directly (e.g. to corrupt one on purpose); normal users go through ArchiveReader/ArchiveWriter.
#pragma once
#include <array>
#include <cstdint>

namespace terrain::layout {

// ---- File header (SPEC "Header"): 128 bytes at offset 0 -----------------------------------------
inline constexpr std::array<uint8_t, 8> kMagic = {'T', 'E', 'R', 'R', 'A', 'I', 'N', 0x1A};
inline constexpr uint32_t kFormatVersion = 1;        // the first version; readers open 1, 2 and 3
inline constexpr uint32_t kFormatVersionV2 = 2;      // extension records (SPEC 6.5)
inline constexpr uint32_t kFormatVersionV3 = 3;      // the paged directory (SPEC 20): what writers write
inline constexpr uint32_t kMaxFormatVersion = kFormatVersionV3;
inline constexpr uint32_t kHeaderSize = 128;
namespace header {
inline constexpr uint32_t magic = 0;             // 8 bytes
inline constexpr uint32_t format_version = 8;    // u32
inline constexpr uint32_t header_size = 12;      // u32
inline constexpr uint32_t header_flags = 16;     // u32, reserved (0)
inline constexpr uint32_t node_count = 20;       // u32
inline constexpr uint32_t file_size = 24;        // u64
inline constexpr uint32_t payload_offset = 32;   // u64
inline constexpr uint32_t payload_size = 40;     // u64
inline constexpr uint32_t directory_offset = 48; // u64
inline constexpr uint32_t directory_size = 56;   // u64
inline constexpr uint32_t metadata_offset = 64;  // u64
inline constexpr uint32_t metadata_size = 72;    // u64
inline constexpr uint32_t directory_crc32 = 80;  // u32
inline constexpr uint32_t metadata_crc32 = 84;   // u32
inline constexpr uint32_t reserved = 88;         // 36 bytes, reserved (0)
inline constexpr uint32_t page_entries = 88;     // v3: u32, entries per directory page (SPEC 20)
inline constexpr uint32_t reserved_v3 = 92;      // v3: 32 bytes, reserved (0)
inline constexpr uint32_t header_crc32 = 124;    // u32, CRC-32 of bytes 0..123
}  // namespace header

// ---- Directory entry (SPEC "Directory"): 48 bytes per node -------------------------------------
inline constexpr uint32_t kEntrySize = 48;
namespace entry {
inline constexpr uint32_t level = 0;              // u8
inline constexpr uint32_t child_mask = 1;         // u8
inline constexpr uint32_t flags = 2;              // u8
inline constexpr uint32_t reserved0 = 3;          // u8, reserved (0)
inline constexpr uint32_t x = 4;                  // u32
inline constexpr uint32_t y = 8;                  // u32
inline constexpr uint32_t height_offset = 12;     // i32
inline constexpr uint32_t min_height = 16;        // i32
inline constexpr uint32_t max_height = 20;        // i32
inline constexpr uint32_t geometric_error_m = 24; // f32
inline constexpr uint32_t payload_crc32 = 28;     // u32
inline constexpr uint32_t payload_offset = 32;    // u64
inline constexpr uint32_t payload_size = 40;      // u32
inline constexpr uint32_t reserved1 = 44;         // u32, reserved (0)
}  // namespace entry

// ---- Directory pages (SPEC 20, format v3) --------------------------------------------------------
// The directory's node_count entries are cut into pages of page_entries entries (the last may be
// shorter); a page table of one 16-byte record per page follows the last page.
inline constexpr uint32_t kPageRecordSize = 16;
namespace page_record {
inline constexpr uint32_t level = 0;      // u8: the page's first key
inline constexpr uint32_t reserved = 1;   // u8[3], reserved (0)
inline constexpr uint32_t x = 4;          // u32
inline constexpr uint32_t y = 8;          // u32
inline constexpr uint32_t page_crc32 = 12;  // u32, CRC-32 of the page's entries
}  // namespace page_record
inline constexpr uint32_t kMinPageEntries = 1024;
inline constexpr uint32_t kMaxPageEntries = 1u << 20;
// Writers keep the page table within this many records (512 KiB).
inline constexpr uint32_t kMaxPageTableRecords = 1u << 15;
// The page size a writer chooses (SPEC 20): the smallest power of two >= 1024 entries whose page
// table holds at most kMaxPageTableRecords records.
inline constexpr uint32_t page_entries_for(uint64_t node_count) {
  uint32_t e = kMinPageEntries;
  while (e < kMaxPageEntries && (node_count + e - 1) / e > kMaxPageTableRecords) e *= 2;
  return e;
}

// ---- Metadata (SPEC "Metadata"): 168-byte fixed part, then variable data ------------------------
inline constexpr uint32_t kMetadataFixedSize = 168;
inline constexpr uint32_t kMaterialRecordSize = 52;
inline constexpr uint32_t kMaterialNameBytes = 32;  // NUL-padded, at most 31 bytes of name
namespace metadata {
inline constexpr uint32_t level_count = 0;          // u32 (6)
inline constexpr uint32_t height_samples = 4;       // u32 (129)
inline constexpr uint32_t level0_node_size_m = 8;   // f64 (64.0)
inline constexpr uint32_t height_unit_log2 = 16;    // i32 (-10)
inline constexpr uint32_t roots_x = 20;             // u32
inline constexpr uint32_t roots_y = 24;             // u32
inline constexpr uint32_t step_log2 = 28;           // u8[6]
inline constexpr uint32_t reserved0 = 34;           // u16, reserved (0)
inline constexpr uint32_t reserved1 = 36;           // u32, reserved (0)
inline constexpr uint32_t origin_x_m = 40;          // f64
inline constexpr uint32_t origin_y_m = 48;          // f64
inline constexpr uint32_t extent_min_x_m = 56;      // f64
inline constexpr uint32_t extent_min_y_m = 64;      // f64
inline constexpr uint32_t extent_max_x_m = 72;      // f64
inline constexpr uint32_t extent_max_y_m = 80;      // f64
inline constexpr uint32_t projection_kind = 88;     // u8
inline constexpr uint32_t reserved2 = 89;           // u8[3], reserved (0)
inline constexpr uint32_t epsg = 92;                // i32
inline constexpr uint32_t semi_major_m = 96;        // f64
inline constexpr uint32_t inverse_flattening = 104; // f64
inline constexpr uint32_t lat0_deg = 112;           // f64
inline constexpr uint32_t lon0_deg = 120;           // f64
inline constexpr uint32_t scale_k0 = 128;           // f64
inline constexpr uint32_t false_easting_m = 136;    // f64
inline constexpr uint32_t false_northing_m = 144;   // f64
inline constexpr uint32_t crs_name_size = 152;      // u32
inline constexpr uint32_t palette_count = 156;      // u32
inline constexpr uint32_t cook_info_size = 160;     // u32
inline constexpr uint32_t reserved3 = 164;          // u32: v1 reserved (0); v2 extension_size
inline constexpr uint32_t extension_size = 164;     // v2: bytes of extension records after cook_info
}  // namespace metadata

// ---- Metadata extension records (SPEC 6.5, format v2): after cook_info ------------------------
// Each record: u32 tag, u32 size, size bytes, zero padding to a multiple of 4. Tags ascend, each at
// most once. A tag with kExtensionOptional set may be skipped by a reader that does not know it;
// any other unknown tag makes the file unreadable (metadata_invalid).
inline constexpr uint32_t kExtensionHeaderSize = 8;
inline constexpr uint32_t kExtensionOptional = 0x80000000u;
inline constexpr uint32_t kExtensionFrameDefinition = 1;  // UTF-8 PROJ WKT2:2019 of a projection_kind 2 frame
inline constexpr uint32_t kExtensionOverviewLevels = 2;  // SPEC 19: u8 K, then u8 step_log2 of levels 6 .. 5+K
inline constexpr uint32_t kExtensionDerivedNormals = 3;  // SPEC 16.7: no data; payloads may use normals codec 4
inline constexpr uint32_t kMaxFrameDefinitionSize = 64 * 1024;
inline constexpr uint32_t kMaxExtensionSize = 16u << 20;

// ---- Node payload (SPEC "Payload"): section table, then section data ---------------------------
inline constexpr uint32_t kSectionCount = 5;
inline constexpr uint32_t kPayloadTableEntrySize = 12;
inline constexpr uint32_t kPayloadHeaderSize = 4 + kSectionCount * kPayloadTableEntrySize;  // 64
enum class SectionId : uint8_t { heights = 0, normals = 1, albedo = 2, splat = 3, cones = 4 };
enum class Codec : uint8_t {
  stored = 0,             // raw bytes
  zstd = 1,               // one zstd frame of the raw bytes
  height_predictor = 2,   // one zstd frame of the height residual planes (heights only)
  height_constant = 3,    // 2 bytes: the one value of every height sample (heights only)
  normals_derived = 4,    // one zstd frame of the apron and AO; the rest from the heights (normals only, SPEC 16.7)
};
// Raw (decoded) size of each section, indexed by SectionId.
inline constexpr std::array<uint32_t, kSectionCount> kSectionRawSize = {
    2 * 129 * 129, 33 * 33 * 16, 33 * 33 * 8, 65 * 65, 2 * 2 * 16};
inline constexpr std::array<const char*, kSectionCount> kSectionName = {"heights", "normals", "albedo",
                                                                        "splat", "cones"};

// ---- Reader limits (SPEC "Limits") --------------------------------------------------------------
inline constexpr uint32_t kMaxPayloadSize = 1u << 20;      // bytes per node payload
inline constexpr uint32_t kMaxNodeCount = 1u << 24;         // versions 1 and 2
inline constexpr uint32_t kMaxNodeCountV3 = 1u << 31;       // version 3 (node indices fit an int32 + 1)
inline constexpr uint32_t kMaxRoots = 1u << 16;            // per axis
inline constexpr uint32_t kMaxCrsNameSize = 1024;
inline constexpr uint32_t kMaxPaletteCount = 256;
inline constexpr uint32_t kMaxCookInfoSize = 16u << 20;
inline constexpr uint32_t kMaxStepLog2 = 14;

}  // namespace terrain::layout
