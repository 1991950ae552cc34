// Synthetic archives for the streamer's tests and benchmark: many roots, deep sparse quadtrees,
// geometric errors that shrink with the level like cooked terrain. Every node's heights carry
// its own key in samples 0..3 (see key_marker_matches) so a consumer can check that delivered
// data belongs to the node it was delivered for.
#pragma once
#include <cstdint>
#include <string>

#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::synthetic {

struct Spec {
  uint32_t roots_x = 6, roots_y = 6;
  double root_fill = 0.8;          // fraction of root cells holding a root
  double child_probability = 0.7;  // each child of a node exists with this probability ...
  uint32_t min_level = 0;          // ... down to this level
  double error_scale = 1.0;        // geometric error ~ error_scale * vertex spacing
  double origin_x_m = 500000.0, origin_y_m = 4000000.0;  // UTM-sized on purpose
  uint64_t seed = 1;
  bool realistic_payload = false;  // fractal heights and noisy BC blocks (decode cost like real data)
  int zstd_level = 1;
};

struct Summary {
  uint64_t nodes = 0;
  uint64_t roots = 0;
  uint64_t payload_bytes = 0;
};

// Writes the archive to `path` (atomically, through terrain::ArchiveWriter).
Status write_archive(const std::string& path, const Spec& spec, Summary* summary = nullptr);

// Height units of the synthetic surface at frame point (x, y): lets tests put cameras just above it.
double surface_height_m(const Spec& spec, double x, double y);

// True when `data`'s heights carry the marker of `key`.
bool key_marker_matches(const NodeData& data, const NodeKey& key);

}  // namespace terrain::synthetic
