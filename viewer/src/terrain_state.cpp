#include "terrain_state.h"

#include <algorithm>

namespace terrain::view {

void Rect::add(uint32_t x, uint32_t y) {
  if (empty()) {
    *this = {x, y, x + 1, y + 1};
    return;
  }
  x0 = std::min(x0, x);
  y0 = std::min(y0, y);
  x1 = std::max(x1, x + 1);
  y1 = std::max(y1, y + 1);
}

void TerrainState::init(const WorldInfo& world, uint32_t slot_count) {
  world_ = world;
  for (int level = 0; level < kLevelCount; ++level) {
    grids_[level].assign(size_t(grid_width(level)) * grid_height(level), uint16_t(TV_SLOT_INVALID));
    dirty_index_[level] = {0, 0, grid_width(level), grid_height(level)};
  }
  slots_.assign(slot_count, SlotDescriptor{});
  dirty_slots_.clear();
  for (uint32_t s = 0; s < slot_count; ++s) dirty_slots_.push_back(s);
}

uint16_t TerrainState::index(int level, uint32_t x, uint32_t y) const {
  return grids_[level][size_t(y) * grid_width(level) + x];
}

uint16_t TerrainState::index_or_invalid(int level, int64_t x, int64_t y) const {
  if (level < 0 || level >= kLevelCount || x < 0 || y < 0 || x >= grid_width(level) || y >= grid_height(level))
    return uint16_t(TV_SLOT_INVALID);
  return index(level, uint32_t(x), uint32_t(y));
}

void TerrainState::set_index(int level, uint32_t x, uint32_t y, uint16_t value) {
  auto& cell = grids_[level][size_t(y) * grid_width(level) + x];
  if (cell == value) return;
  cell = value;
  dirty_index_[level].add(x, y);
}

void TerrainState::set_slot(uint32_t s, const SlotDescriptor& desc) {
  slots_[s] = desc;
  dirty_slots_.push_back(s);
}

TerrainState::Dirty TerrainState::take_dirty() {
  Dirty out;
  out.index = dirty_index_;
  for (auto& r : dirty_index_) r = {};
  std::sort(dirty_slots_.begin(), dirty_slots_.end());
  dirty_slots_.erase(std::unique(dirty_slots_.begin(), dirty_slots_.end()), dirty_slots_.end());
  out.slots.swap(dirty_slots_);
  return out;
}

}  // namespace terrain::view
