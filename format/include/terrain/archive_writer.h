// Streaming, deterministic, atomic archive writer.
// Payloads are appended as they come (never the whole archive in memory); the directory and
// metadata follow at finish(), then the header is written and the temp file renamed over `path`.
// A writer destroyed or failed before finish() removes its temp file: any earlier archive at
// `path` stays untouched.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "terrain/archive_reader.h"
#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain {

struct NormalsDerivation;  // terrain/derived_normals.h

struct PayloadOptions {
  // zstd level of the heights (and of every section unless surface_zstd_level is set). 3 is the
  // quick general default; levels 10-18 switch the height residuals to tuned optimal parsing
  // (payload.cpp), and level 9, which terrain-cook uses, parses a second time (lazy2, 16
  // attempts) only where a quick pass finds the residuals compressible.
  int zstd_level = 3;
  bool height_predictor = true;  // predictor + zstd (or plain zstd where smaller); false: plain zstd only (benchmarks)
  // zstd level of the normals, albedo, splat and cones sections (BC blocks and material ids);
  // unset: zstd_level. Those sections gain little from high levels (see CookOptions).
  std::optional<int> surface_zstd_level;
};

// Encodes one node's payload (section table + zstd sections) into `out` (replaced).
// Thread-safe; deterministic for the same inputs and options.
// timing (optional): the calling thread's CPU clock (CLOCK_THREAD_CPUTIME_ID, seconds) read after
// each section is encoded, in section order (heights, normals, albedo, splat, cones).
struct PayloadTiming {
  std::array<double, 5> section_end_s{};
};
// derived_normals (optional): the normals section is written with codec 4 (SPEC 16.7) from it, and
// data.normals_bc3 is not read; the archive must then declare the derived_normals extension.
Status encode_node_payload(const NodeData& data, const PayloadOptions& options, std::vector<uint8_t>& out,
                           PayloadTiming* timing = nullptr, const NormalsDerivation* derived_normals = nullptr);

// Decodes `bytes` (one node's stored payload, checksum already verified or not) into `out`.
// Only the sections in `sections` are written. Safe on any bytes: bounds-checked, never trusts sizes.
Status decode_node_payload(std::span<const uint8_t> bytes, unsigned sections, NodeData& out);

// Checks a WorldInfo against the SPEC's metadata rules (the same checks finish() and the reader
// apply), so a cooker can fail early with a clear message.
Status validate_world(const WorldInfo& world);

// What an ordered writer is told before its first node: the node count of each level (overview
// levels included) and the payload bytes of all of them, so the directory's place in the file is
// known from the start.
struct ArchiveShape {
  std::array<uint64_t, kMaxLevels> level_nodes{};
  uint64_t payload_bytes = 0;
};

class ArchiveWriter {
 public:
  ArchiveWriter();
  ~ArchiveWriter();  // aborts (removes the temp file) unless finish() succeeded
  ArchiveWriter(const ArchiveWriter&) = delete;
  ArchiveWriter& operator=(const ArchiveWriter&) = delete;

  // Creates `path`.tmp-<host>-<pid> next to `path` (output_paths.h), first removing what a killed
  // writer of `path` on this host left there.
  Status open(const std::string& path);
  // Streaming (ordered) mode, for a merge of sorted parts: nodes must come in the canonical payload
  // order (SPEC 18: level 5 first, then towards 0; within a level by y, then x; then the overview
  // levels of SPEC 19, level 6 first, upward), exactly `shape.level_nodes` of each level and
  // `shape.payload_bytes` in all. Each directory entry is written in place as its node comes, so
  // memory does not grow with the node count (a write buffer and one read buffer). Every check of
  // finish() is still made: order and counts as the nodes come, child masks of levels 0..4 against
  // the level above as they come, and those of the overview levels (written after their
  // children) at finish(), each read back from the file. The bytes are the same as the default
  // mode's for the same calls.
  Status open_ordered(const std::string& path, const ArchiveShape& shape);
  // Appends one node. `record` payload fields are ignored and filled in. Nodes may come in any
  // order (the payload order is the call order: call in a deterministic order for identical
  // bytes); the directory is sorted by key at finish(). Duplicate keys are an error.
  // `payload_crc` (optional) receives the payload's CRC-32 (a caller checking its own CRC over
  // the same bytes combines it instead of computing it again).
  Status add_node(const NodeRecord& record, std::span<const uint8_t> payload, uint32_t* payload_crc = nullptr);
  // Writes directory, metadata and header, flushes, fsyncs and renames over the final path.
  Status finish(const WorldInfo& world);
  // Removes the temp file; the final path is left as it was.
  void abort();

  // The header and payloads written so far; after a successful finish(), the whole file's size.
  uint64_t bytes_written() const;
  // Stored and raw bytes per section of the nodes added so far (as ArchiveReader::section_bytes).
  SectionBytes section_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace terrain
