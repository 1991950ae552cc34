// Residency without the streamer: every node of a world is known up front (an archive read
// entirely, or a synthetic world) and a predicate chooses the resident set. Used by tests (exact
// control over the streaming frontier), by the full-detail reference render of the benchmark and
// by `terrain-view --load-all`.
#pragma once
#include <functional>
#include <map>
#include <vector>

#include "terrain/status.h"
#include "terrain_state.h"

namespace terrain::view {

struct MemoryNode {
  NodeRecord record;
  const NodeData* data = nullptr;  // owned by the caller, must outlive the residency
};

class StaticResidency {
 public:
  // Grids: TV_SLOT_EMPTY where a node exists, TV_SLOT_INVALID elsewhere; nothing resident yet.
  void init(const WorldInfo& world, std::vector<MemoryNode> nodes, uint32_t slot_count, TerrainState& state);

  // Makes exactly the nodes with resident(key) resident (a node whose parent is not resident is
  // skipped, so the streamer's invariant holds), evicting the others; appends uploads for nodes
  // that became resident. Error when the slots run out.
  Status apply(const std::function<bool(const NodeKey&)>& resident, TerrainState& state, std::vector<NodeUpload>& uploads);

  size_t node_count() const { return nodes_.size(); }
  const std::vector<MemoryNode>& nodes() const { return nodes_; }
  uint32_t resident_count() const { return uint32_t(slot_of_.size()); }

 private:
  WorldInfo world_;
  std::vector<MemoryNode> nodes_;  // level descending (parents first)
  std::map<std::tuple<uint32_t, uint32_t, uint32_t>, uint32_t> slot_of_;  // (level, x, y) -> slot
  std::vector<uint32_t> free_slots_;
};

}  // namespace terrain::view
