#include "residency.h"

#include <algorithm>

namespace terrain::view {

void StaticResidency::init(const WorldInfo& world, std::vector<MemoryNode> nodes, uint32_t slot_count, TerrainState& state) {
  world_ = world;
  nodes_ = std::move(nodes);
  std::stable_sort(nodes_.begin(), nodes_.end(),
                   [](const MemoryNode& a, const MemoryNode& b) { return a.record.key.level > b.record.key.level; });
  slot_of_.clear();
  free_slots_.clear();
  for (uint32_t s = slot_count; s-- > 0;) free_slots_.push_back(s);
  state.init(world, slot_count);
  for (const MemoryNode& n : nodes_)
    if (n.record.key.level == uint32_t(kRootLevel)) state.set_node(n.record.key, uint16_t(TV_SLOT_EMPTY));
}

Status StaticResidency::apply(const std::function<bool(const NodeKey&)>& resident, TerrainState& state,
                              std::vector<NodeUpload>& uploads) {
  auto key_of = [](const NodeKey& k) { return std::make_tuple(k.level, k.x, k.y); };
  // Decide parents first (nodes_ is level descending): a node stays only if its parent stays.
  std::map<std::tuple<uint32_t, uint32_t, uint32_t>, bool> keep;
  for (const MemoryNode& n : nodes_) {
    const NodeKey& k = n.record.key;
    bool want = resident(k);
    if (want && int(k.level) < top_level(world_)) {
      auto p = keep.find(key_of(parent_of(k)));
      want = p != keep.end() && p->second;
    }
    keep[key_of(k)] = want;
  }
  // Evict, children first.
  for (size_t i = nodes_.size(); i-- > 0;) {
    const NodeKey& k = nodes_[i].record.key;
    auto it = slot_of_.find(key_of(k));
    if (it == slot_of_.end() || keep[key_of(k)]) continue;
    free_slots_.push_back(it->second);
    slot_of_.erase(it);
    state.set_node(k, uint16_t(TV_SLOT_EMPTY));
  }
  // Load, parents first.
  for (const MemoryNode& n : nodes_) {
    const NodeKey& k = n.record.key;
    if (!keep[key_of(k)] || slot_of_.count(key_of(k))) continue;
    if (free_slots_.empty())
      return Status::failure(Error::invalid_argument,
                             "residency: more nodes wanted than the " + std::to_string(state.slot_count()) + " atlas slots");
    const uint32_t slot = free_slots_.back();
    free_slots_.pop_back();
    slot_of_[key_of(k)] = slot;
    state.set_slot(slot, slot_descriptor_of(n.record, world_));
    state.set_node(k, uint16_t(slot));
    uploads.push_back({slot, n.data});
  }
  return Status::success();
}

}  // namespace terrain::view
