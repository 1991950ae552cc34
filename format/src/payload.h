// Node payload section table (SPEC "Payload"), parsed without decompressing anything.
#pragma once
#include <array>
#include <cstdint>
#include <span>

#include "terrain/archive_layout.h"
#include "terrain/status.h"

namespace terrain::detail {

struct PayloadSection {
  layout::Codec codec = layout::Codec::stored;
  uint32_t stored_size = 0;
  uint32_t raw_size = 0;
  uint32_t data_offset = 0;  // from the start of the payload
  int height_shift = 0;      // heights with the height predictor only
};
using PayloadTable = std::array<PayloadSection, layout::kSectionCount>;

// Checks the table (ids, codecs, reserved bytes, raw sizes, stored sizes add up to the payload).
Status parse_payload_table(std::span<const uint8_t> payload, PayloadTable& out);
// The same checks from the first 64 bytes of a payload of `payload_size` bytes (`table` may be
// longer; bytes past 64 are not read): what a reader that fetches only the table can check.
Status parse_payload_table(std::span<const uint8_t> table, uint64_t payload_size, PayloadTable& out);

}  // namespace terrain::detail
