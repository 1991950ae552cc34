// Synthetic archives for the tests and benchmarks, so they need neither the cooker nor real data.
// One generator, two shapes:
//  - sparse_tree (the streamer's tests and terrain-stream-bench): many roots, deep sparse random
//    quadtrees, geometric errors that shrink with the level like cooked terrain. Every node's splat
//    carries its own key (see key_marker_matches) so a consumer can check that delivered data
//    belongs to the node it was delivered for.
//  - analytic_surface (the viewer's GPU-vs-reference tests): an analytic height field quantized
//    exactly as format.h requires (one canonical unit value per vertex position, shared by every
//    level), normals, albedo with a hole disc, splat ids and conservative patch cones, BC-encoded
//    by small exact encoders (bc_encode.h).
// Both share the world header (world_info) and the writer (write_archive).
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::synthetic {

enum class Shape { sparse_tree, analytic_surface };

// Defaults are the sparse tree's; analytic_surface() gives the analytic surface's.
struct Spec {
  Shape shape = Shape::sparse_tree;
  uint32_t roots_x = 6, roots_y = 6;
  double origin_x_m = 500000.0, origin_y_m = 4000000.0;  // UTM-sized on purpose
  int zstd_level = 1;

  // sparse_tree
  double root_fill = 0.8;          // fraction of root cells holding a root
  double child_probability = 0.7;  // each child of a node exists with this probability ...
  uint32_t min_level = 0;          // ... down to this level
  double error_scale = 1.0;        // geometric error ~ error_scale * vertex spacing
  uint64_t seed = 1;
  bool realistic_payload = false;  // fractal heights and noisy BC blocks (decode cost like real data)
  // Overview levels above the roots (format v2, SPEC 19): 0 = none (a version-1 file, as before),
  // -1 = overview_levels_needed(roots), K > 0 = K levels. Their step is the roots' step and their
  // heights are the even vertices of their children (holes where no root holds a vertex), so the
  // crack-free rule holds between roots and overview levels; their albedo is the fast constant one.
  int overview_levels = 0;

  // analytic_surface
  // A node exists when its parent exists and this returns true (default: every node down to level 2).
  std::function<bool(const NodeKey&)> keep = [](const NodeKey& k) { return k.level >= 2; };
  double hole_x_m = -1, hole_y_m = -1, hole_radius_m = 0;  // frame coordinates; radius 0 = no holes
  double relief_m = 350.0;  // peak-to-valley scale of the hills
  double detail = 1.0;      // weight of the short-wavelength terms (0: smooth slopes, narrow cones)
  double flat_from_x_m = 1e30;  // local x (m from the origin) from where the terrain is flat (fades over 300 m)
  double flat_until_x_m = -1e30;  // ... and up to where it is flat (fades over 300 m east of it)
  // The geometric error is at least error_floor_m * 4^level (times the relief weight at the node),
  // so views refine deep where the smooth field alone would not ask for it. 0 = measured only.
  double error_floor_m = 0;
  bool cones = true;  // false: every patch "never cull"
  // >= 0: a straight north-south material boundary at this local x (m from the origin): splat id 0
  // (sand) west of it, 1 (grass) east, and the albedo baked from that splat as the cook bakes it
  // without an orthophoto (format/SPEC.md 16.3, the cook's own variation noise). < 0: the default
  // height-band splat and albedo, byte for byte.
  double splat_boundary_x_m = -1;
};

// The analytic surface's defaults: 2 x 2 roots, every node down to level 2.
Spec analytic_surface();

struct Summary {
  uint64_t nodes = 0;
  uint64_t roots = 0;
  uint64_t payload_bytes = 0;
};

struct Node {
  NodeRecord record;
  NodeData data;
};

struct World {
  WorldInfo world;
  std::vector<Node> nodes;  // in the order write_archive() writes them
};

// The world header of `spec` (frame, extent, steps, palette, cook info).
WorldInfo world_info(const Spec& spec);

// The whole world in memory (small worlds: a node's data is ~64 KB).
World make_world(const Spec& spec);

// Writes the archive to `path` (atomically, through terrain::ArchiveWriter), one node at a time.
Status write_archive(const std::string& path, const Spec& spec, Summary* summary = nullptr);

// Sparse tree: height units of the synthetic surface at frame point (x, y), so tests can put
// cameras just above it.
double surface_height_m(const Spec& spec, double x, double y);

// Sparse tree: true when `data` carries the marker of `key`.
bool key_marker_matches(const NodeData& data, const NodeKey& key);

}  // namespace terrain::synthetic
