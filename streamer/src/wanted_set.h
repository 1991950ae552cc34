// The wanted set: which nodes should be resident for a set of views (see streamer.h, "The wanted
// set"). Pure computation over the archive directory; no I/O, no threads.
#pragma once
#include <cstdint>
#include <span>
#include <vector>

#include "terrain/archive_reader.h"
#include "terrain/streamer.h"

namespace terrain::detail {

// Directory in a form the per-frame computation can walk quickly. Built once at open.
struct NodeTree {
  struct Node {
    int32_t parent = -1;
    std::array<int32_t, 4> children{-1, -1, -1, -1};  // directory indices, -1 = no child
    uint32_t level = 0;
    double x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // footprint, frame metres
    double z0 = 0, z1 = 0;                  // min/max height, metres
    double error_m = 0;
  };
  std::vector<Node> nodes;     // by directory index
  std::vector<uint32_t> roots; // directory indices of the level-kRootLevel nodes, ascending
};

NodeTree build_node_tree(const ArchiveReader& reader);

struct WantedParams {
  uint32_t budget_nodes = 0;
  double error_target_px = 0;
  double prefetch_ratio = 1;
  uint32_t required_budget = 0;  // nodes of the required set (streamer.h: prefetch_reserve)
  double default_pixels_per_radian = 0;
  double outside_frustum_error_scale = 0;
};

// The parameters of a resolved streamer config (`roots`: the archive's root count).
WantedParams make_wanted_params(const StreamerConfig& config, uint32_t roots);

// Projected error of node `n` in pixels, max over views (streamer.h formula).
double projected_error_px(const NodeTree::Node& n, std::span<const View> views, const WantedParams& p);

struct WantedNode {
  uint32_t index = 0;     // directory index
  bool required = false;  // in the required set (error target itself, required_budget)
};

// Fills `out` with the wanted set in split order (roots first in directory order, then the
// children of each split in child order): this is also the request priority order.
// `failed[i]` != 0 excludes node i (and so its subtree).
void compute_wanted_set(const NodeTree& tree, std::span<const uint8_t> failed, std::span<const View> views,
                        const WantedParams& params, std::vector<WantedNode>& out);

}  // namespace terrain::detail
