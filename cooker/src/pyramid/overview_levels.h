// Overview levels above the roots (format/SPEC.md section 19), built from the cooked roots, not
// from the source, in one place that the one-process cook (from its node spool) and the work-unit
// merge (from the unit files) share, so both give the same bytes at any thread count.
//
// What it does, given the roots' records and a way to read their payloads:
//  - heights: the level-6 lattice is the roots' even vertices (their values are final: the cook
//    rounded them to the overview step already, compute_window, SPEC 19 rule 7); a vertex is a
//    hole when no root holds it as a non-hole vertex. Level L's vertex (i, j) of node (X, Y) is
//    lattice vertex ((128 X + i) << (L - 6), (128 Y + j) << (L - 6)).
//  - surface layers: recomputed from the overview heights at the level's spacing with the cook's
//    surface code (normals, splat from the material rules, albedo baked from the splat, cones), on
//    the same 165 x 165 window as any node, so aprons agree across overview node edges. Not
//    downsampled from the children: an orthophoto (--albedo) or class raster (--landcover) does
//    not reach the overview levels (the merge has no inputs open).
//  - geometric_error_m (rule 8): max over children c of (error_c + deviation_c), deviation_c the
//    largest |overview surface - child surface| at the child's vertices in its quadrant (both are
//    triangulated along the same SW-NE diagonals, so an overview triangle is a union of its
//    children's triangles and the largest difference is at a child vertex).
//  - directory: every level-6 node with a root below it, every level-(L+1) node with a level-L
//    node below it; child masks name them.
// Memory: the level-6 lattice (4 bytes per vertex, 16 KB per root cell) goes to a scratch file,
// written by rows of roots and read back by bands of rows: 65 lattice rows while writing, at most
// 329 rows of (roots_x * 64 + 1) vertices while building (26 MB at 317 x 317 roots), plus 9 bytes
// per root cell (existence, error bound) and a node's working set per thread.
#pragma once
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "surface/surface_layers.h"
#include "terrain/archive_writer.h"
#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::cook {

// The cooked roots: their records (key, error, heights' offset) and their payloads by index.
// read() is called from one thread at a time.
struct RootSource {
  std::vector<NodeRecord> roots;
  std::function<Status(size_t index, std::vector<uint8_t>& payload)> read;
};

struct OverviewSettings {
  WorldInfo world;  // origin, roots_x/y, step_log2[5] and overview_step_log2 (K = its size, > 0)
  const MaterialRules* rules = nullptr;
  BcQuality bc_quality = BcQuality::balanced;
  float bc_rdo = 0;  // CookOptions::bc_rdo
  bool check_all_errors = false;  // CookOptions::error_checks == all
  PayloadOptions payload;
  bool heights_only = false;
  int threads = 1;
  std::string scratch_path;  // the level-6 lattice's scratch file (created, unlinked at once)
};

// Where the built nodes go: an archive writer's add_node, or a spool.
using NodeOut = std::function<Status(const NodeRecord& record, std::span<const uint8_t> payload)>;

// What write_overview_levels built: its nodes, and the largest geometric_error_m of one of them.
struct OverviewStats {
  uint64_t nodes = 0;
  double error_max_m = 0;
};

// Builds the K overview levels and hands their nodes to `out` (level 6 first, then by y, x).
// `stats`: what it built (the report's overview_nodes and overview_error_max_m).
Status write_overview_levels(const OverviewSettings& settings, const RootSource& roots, const NodeOut& out,
                             OverviewStats& stats);

}  // namespace terrain::cook
