#include "terrain_state.h"

#include <algorithm>

namespace terrain::view {

void TerrainState::init(const WorldInfo& world, uint32_t slot_count) {
  index_.init(world, slot_count);
  slots_.assign(slot_count, SlotDescriptor{});
  dirty_slots_.clear();
  for (uint32_t s = 0; s < slot_count; ++s) dirty_slots_.push_back(s);
}

void TerrainState::set_node(const NodeKey& key, uint16_t value) {
  index_.set_node(key, value, value < slots_.size() ? slots_[value].child_mask : uint8_t(0));
}

void TerrainState::set_slot(uint32_t s, const SlotDescriptor& desc) {
  slots_[s] = desc;
  dirty_slots_.push_back(s);
  index_.set_child_mask(s, desc.child_mask);  // when the slot's node is resident: its children follow
}

std::vector<uint32_t> TerrainState::start_slots() const {
  const std::span<const uint32_t> starts = index_.start_slots();
  return {starts.begin(), starts.end()};
}

TerrainState::Dirty TerrainState::take_dirty() {
  Dirty out;
  index_.take_changes(out.index);
  std::sort(dirty_slots_.begin(), dirty_slots_.end());
  dirty_slots_.erase(std::unique(dirty_slots_.begin(), dirty_slots_.end()), dirty_slots_.end());
  out.slots.swap(dirty_slots_);
  return out;
}

}  // namespace terrain::view
