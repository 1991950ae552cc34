#include "wanted_set.h"

#include <algorithm>
#include <cmath>
#include <queue>

namespace terrain::detail {

NodeTree build_node_tree(const ArchiveReader& reader) {
  NodeTree tree;
  const WorldInfo& world = reader.world();
  std::span<const NodeRecord> records = reader.nodes();
  tree.records = records;
  tree.origin_x = world.origin_x_m;
  tree.origin_y = world.origin_y_m;
  tree.nodes.resize(records.size());
  const auto top = uint32_t(reader.top_level());
  for (size_t i = 0; i < records.size(); ++i) {
    const NodeRecord& r = records[i];
    NodeTree::Node& n = tree.nodes[i];
    if (r.key.level == top) tree.tops.push_back(uint32_t(i));
    if (r.key.level == 0) continue;
    for (int c = 0; c < 4; ++c) {
      // The child mask is a claim of the record; the directory decides what exists.
      const int64_t child = reader.find(child_of(r.key, c));
      if (child < 0) continue;
      n.children[size_t(c)] = int32_t(child);
      tree.nodes[size_t(child)].parent = int32_t(i);
    }
  }
  return tree;
}

namespace {

double squared(double v) { return v * v; }

struct Box {
  double x0, y0, x1, y1, z0, z1;
};
Box box_of(const NodeTree& tree, uint32_t index) {
  const NodeRecord& r = tree.records[index];
  const double size = node_size_m(int(r.key.level));
  const double x0 = tree.origin_x + double(r.key.x) * size, y0 = tree.origin_y + double(r.key.y) * size;
  return {x0, y0, x0 + size, y0 + size, units_to_metres(r.min_height), units_to_metres(r.max_height)};
}

// Distance from a point to an axis-aligned box (0 inside).
double box_distance(const Box& n, double px, double py, double pz) {
  const double dx = std::max({n.x0 - px, 0.0, px - n.x1});
  const double dy = std::max({n.y0 - py, 0.0, py - n.y1});
  const double dz = std::max({n.z0 - pz, 0.0, pz - n.z1});
  return std::sqrt(squared(dx) + squared(dy) + squared(dz));
}

// True when the box lies entirely on the outer side of some plane.
bool box_outside_frustum(const Box& n, const View& v) {
  for (const FrustumPlane& pl : v.frustum) {
    // The corner that maximises the plane function ("p-vertex"), relative to the eye.
    const double qx = (pl.nx >= 0 ? n.x1 : n.x0) - v.x;
    const double qy = (pl.ny >= 0 ? n.y1 : n.y0) - v.y;
    const double qz = (pl.nz >= 0 ? n.z1 : n.z0) - v.z;
    if (pl.nx * qx + pl.ny * qy + pl.nz * qz + pl.d < 0) return true;
  }
  return false;
}

}  // namespace

double projected_error_px(const NodeTree& tree, uint32_t index, std::span<const View> views, const WantedParams& p) {
  const Box n = box_of(tree, index);
  const double error_m = double(tree.records[index].geometric_error_m);
  double best = 0;
  for (const View& v : views) {
    const double ppr = v.pixels_per_radian > 0 ? v.pixels_per_radian : p.default_pixels_per_radian;
    const double distance = std::max(box_distance(n, v.x, v.y, v.z), 1e-3);
    double e = error_m * ppr / distance;
    if (v.has_frustum && box_outside_frustum(n, v)) e *= p.outside_frustum_error_scale;
    best = std::max(best, e);
  }
  return best;
}

void compute_wanted_set(const NodeTree& tree, std::span<const uint8_t> failed, std::span<const View> views,
                        const WantedParams& params, std::vector<WantedNode>& out) {
  out.clear();
  struct Candidate {
    double priority;
    uint32_t level;
    uint32_t index;
    size_t slot_in_out;  // position of the node in `out` (for its `required` flag)
    double error;
  };
  // Highest priority first; ties: coarser level, then lower directory index.
  auto lower = [](const Candidate& a, const Candidate& b) {
    if (a.priority != b.priority) return a.priority < b.priority;
    if (a.level != b.level) return a.level < b.level;
    return a.index > b.index;
  };
  std::priority_queue<Candidate, std::vector<Candidate>, decltype(lower)> queue(lower);
  const double split_threshold = params.error_target_px * params.prefetch_ratio;

  auto live_children = [&](uint32_t index) {
    uint32_t count = 0;
    for (int32_t c : tree.nodes[index].children)
      if (c >= 0 && !failed[size_t(c)]) ++count;
    return count;
  };
  auto consider = [&](uint32_t index, double parent_priority, size_t slot_in_out) {
    const uint32_t level = tree.records[index].key.level;
    if (level == 0 || live_children(index) == 0) return;
    const double e = projected_error_px(tree, index, views, params);
    if (!(e > split_threshold)) return;
    queue.push({std::min(e, parent_priority), level, index, slot_in_out, e});
  };

  for (uint32_t top : tree.tops) {
    if (failed[top]) continue;
    out.push_back({top, true});
  }
  if (views.empty()) return;
  for (size_t i = 0; i < out.size(); ++i) consider(out[i].index, INFINITY, i);

  // Required splits (e > target, reached through required splits) have priority > target and
  // every prefetch-only split has priority <= target, so the required ones pop first, in the
  // order a run at the target alone would pop them: the required set is that run's result.
  uint32_t required_count = uint32_t(out.size());
  bool required_stopped = false;
  while (!queue.empty()) {
    const Candidate top = queue.top();
    queue.pop();
    const uint32_t count = live_children(top.index);
    if (out.size() + count > params.budget_nodes) break;
    bool required = out[top.slot_in_out].required && top.error > params.error_target_px && !required_stopped;
    if (required && required_count + count > params.required_budget) {
      required = false;
      required_stopped = true;
    }
    if (required) required_count += count;
    for (int32_t c : tree.nodes[top.index].children) {
      if (c < 0 || failed[size_t(c)]) continue;
      out.push_back({uint32_t(c), required});
      consider(uint32_t(c), top.priority, out.size() - 1);
    }
  }
}

}  // namespace terrain::detail
