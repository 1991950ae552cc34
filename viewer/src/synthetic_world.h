// A synthetic, fully specified terrain world for tests and demos that must not depend on the
// cooker: an analytic height field quantized exactly as format.h requires (one canonical unit value
// per vertex position, shared by every level), normals, albedo with a hole disc, splat ids and
// conservative patch cones, BC-encoded by small exact encoders.
#pragma once
#include <functional>
#include <string>
#include <vector>

#include "terrain/format.h"
#include "terrain/status.h"

namespace terrain::view {

struct SyntheticOptions {
  uint32_t roots_x = 2, roots_y = 2;
  double origin_x_m = 500000.0, origin_y_m = 4200000.0;  // UTM-sized on purpose
  // A node exists when its parent exists and this returns true (default: every node down to level 2).
  std::function<bool(const NodeKey&)> keep = [](const NodeKey& k) { return k.level >= 2; };
  double hole_x_m = -1, hole_y_m = -1, hole_radius_m = 0;  // frame coordinates; radius 0 = no holes
  double relief_m = 350.0;  // peak-to-valley scale of the hills
  double detail = 1.0;      // weight of the short-wavelength terms (0: smooth slopes, narrow cones)
  double flat_from_x_m = 1e30;  // local x (m from the origin) from where the terrain is flat (fades over 300 m)
  // Tests: the geometric error is at least error_floor_m * 4^level (times the relief weight at the
  // node), so views refine deep where the smooth field alone would not ask for it. 0 = measured only.
  double error_floor_m = 0;
  bool cones = true;        // false: every patch "never cull"
};

struct SyntheticNode {
  NodeRecord record;
  NodeData data;
};

struct SyntheticWorld {
  WorldInfo world;
  std::vector<SyntheticNode> nodes;  // parents before children (level descending)
};

SyntheticWorld make_synthetic_world(const SyntheticOptions& options);

// Writes the world as an archive (terrain::ArchiveWriter).
Status write_synthetic_archive(const SyntheticWorld& world, const std::string& path);

}  // namespace terrain::view
