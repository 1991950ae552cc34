// The wanted set: which nodes should be resident for a set of views (see streamer.h, "The wanted
// set"). Pure computation over the archive directory; no I/O, no threads.
#pragma once
#include <cstdint>
#include <span>
#include <vector>

#include "terrain/archive_reader.h"
#include "terrain/streamer.h"

namespace terrain::detail {

// Directory in a form the per-frame computation can walk quickly. Built once at open. Per archive
// node it holds only the links (20 bytes); footprint, heights and error are read from the
// reader's directory record when a node is considered.
struct NodeTree {
  struct Node {
    int32_t parent = -1;
    std::array<int32_t, 4> children{-1, -1, -1, -1};  // directory indices, -1 = no child
  };
  std::vector<Node> nodes;      // by directory index
  std::vector<uint32_t> tops;   // directory indices of the top level's nodes, ascending: the roots,
                                // or the top overview level's nodes (format/SPEC.md section 19)
  std::span<const NodeRecord> records;  // the reader's directory
  double origin_x = 0, origin_y = 0;
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

// The parameters of a resolved streamer config (`tops`: the archive's top-level node count).
WantedParams make_wanted_params(const StreamerConfig& config, uint32_t tops);

// Projected error of node `index` in pixels, max over views (streamer.h formula).
double projected_error_px(const NodeTree& tree, uint32_t index, std::span<const View> views, const WantedParams& p);

struct WantedNode {
  uint32_t index = 0;     // directory index
  bool required = false;  // in the required set (error target itself, required_budget)
};

// Fills `out` with the wanted set in split order (top nodes first in directory order, then the
// children of each split in child order): this is also the request priority order.
// `failed[i]` != 0 excludes node i (and so its subtree).
void compute_wanted_set(const NodeTree& tree, std::span<const uint8_t> failed, std::span<const View> views,
                        const WantedParams& params, std::vector<WantedNode>& out);

}  // namespace terrain::detail
