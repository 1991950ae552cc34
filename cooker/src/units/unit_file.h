// The unit file (format/SPEC.md section 18, "Unit file"): W/units/unit-<i>.tcu, one per work unit,
// written atomically (temp file, fsync, rename). A 64-byte header (magic, version, index, the plan's
// and the unit's fingerprints, counts), a table of 48-byte node records in canonical order, the
// unit's statistics (JSON), the node payloads back to back in table order, and a trailer: the
// CRC-32 of every byte before it and "TCUE". A unit file is valid for a plan when its unit
// fingerprint is the plan's for that unit.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "pyramid/pyramid.h"
#include "terrain/cook.h"
#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::cook {

struct CookSession;
struct PlanFile;

inline constexpr size_t kUnitHeader = 64, kUnitRecord = 48;

// Statistics a unit adds to the cook's report, stored in its file for the merge.
struct UnitStats {
  PyramidTotals totals;
  CookReport part;  // the fields cook_block and the window reads fill (report_blocks of `totals`)
};

// Cooks unit `index` of the session into its unit file (atomically: temp file, fsync, rename).
Status write_unit(CookSession& s, const PlanFile& plan, uint32_t index, const std::string& work_dir);

// Checks unit `index`'s file against the plan: present, complete, checksum, fingerprints. Its
// message says what is wrong.
Status check_unit_file(const std::string& work_dir, const PlanFile& plan, uint32_t index);
// The same without the payloads' CRC (reads the header, table, stats and trailer only): for a plan
// deciding which units of an earlier plan to keep. A unit damaged inside its payloads passes; the
// unit command (check_unit_file) redoes it and the merge names it.
Status check_unit_file_head(const std::string& work_dir, const PlanFile& plan, uint32_t index);

// ---- reading a unit file (the merge, merge.h) ----

// A unit file's parts, checked: header, node table, stats and the payloads' extent.
struct UnitContents {
  std::string plan_fp, unit_fp;
  std::vector<std::pair<NodeRecord, uint64_t>> nodes;  // record (payload_offset relative), file offset
  std::string stats;  // JSON (read_unit checked that it parses)
  uint64_t payload_start = 0, size = 0;
  uint32_t head_crc = 0;    // CRC-32 of the bytes before the payloads
  uint32_t stored_crc = 0;  // the trailer's, of every byte before it
};

// How much of a unit file read_unit checks. `full`: every byte against the CRC (a unit deciding
// whether it is done: a damaged file must be redone). `head`: everything but the payloads' CRC,
// which the caller computes from the bytes it reads anyway (the merge, while it copies them) or
// leaves to the unit and the merge (plan, keeping the units of an earlier plan).
enum class UnitCheck { head, full };

// Reads and checks a unit file: header, size, trailer, node table (in canonical order, payloads
// back to back), stats, fingerprint; with UnitCheck::full also the CRC of every byte. Whatever
// the mode, a file failing any check is reported as "checksum mismatch" when its CRC does not
// match (a damaged file is named as such, not by the field the damage hit). The failure's message
// says what is wrong ("missing", "truncated (N bytes)", ...).
Status read_unit(const std::string& path, uint32_t index, const std::string& expected_unit_fp, UnitCheck check,
                 UnitContents& out);
// The message of a unit whose CRC does not match.
inline constexpr const char* kUnitDamaged = "checksum mismatch (damaged or half-written)";

// A table entry (SPEC 18) at `p`: the node's record; payload offset and size are the caller's.
NodeRecord unit_record(const uint8_t* p);
// The payload size of the table entry at `p`.
uint32_t unit_record_payload_size(const uint8_t* p);
// Continues `crc` over bytes [from, to) of `fd`, streamed; false when unreadable.
bool crc_range(int fd, uint64_t from, uint64_t to, uint32_t& crc, const std::string& path);
// Adds the stats of unit `index` (`c.stats`) to the cook's (the sums cook_block makes, in unit
// order); invalid_argument "unit I: bad stats (...)" when they are malformed.
Status add_unit_stats(const UnitContents& c, uint32_t index, PyramidTotals& totals, CookReport& report);

}  // namespace terrain::cook
