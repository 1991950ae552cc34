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
  overview_.clear();
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

namespace {
uint64_t overview_key(const NodeKey& k) { return uint64_t(k.level) << 56 | uint64_t(k.y) << 28 | k.x; }
}  // namespace

void TerrainState::set_overview(const NodeKey& key, uint16_t slot) {
  if (slot >= TV_SLOT_INVALID)
    overview_.erase(overview_key(key));
  else
    overview_[overview_key(key)] = slot;
}

uint16_t TerrainState::overview_slot(const NodeKey& key) const {
  auto it = overview_.find(overview_key(key));
  return it == overview_.end() ? uint16_t(TV_SLOT_EMPTY) : it->second;
}

std::vector<uint32_t> TerrainState::start_slots() const {
  std::vector<uint32_t> out;
  const int top = top_level();
  if (top == kRootLevel) {
    for (uint16_t s : grids_[kRootLevel])
      if (s < TV_SLOT_INVALID) out.push_back(s);
    return out;
  }
  std::vector<std::pair<uint64_t, uint16_t>> tops;
  for (const auto& [k, s] : overview_)
    if (int(k >> 56) == top) tops.push_back({k, s});
  std::sort(tops.begin(), tops.end());
  for (const auto& t : tops) out.push_back(t.second);
  return out;
}

uint16_t TerrainState::child(uint32_t slot, int c) const {
  const SlotDescriptor& d = slots_[slot];
  if (!(d.child_mask & (1u << c)) || d.level == 0) return uint16_t(TV_SLOT_INVALID);
  const NodeKey k = child_of(NodeKey{d.level, d.x, d.y}, c);
  if (k.level <= uint32_t(kRootLevel)) return index_or_invalid(int(k.level), k.x, k.y);
  return overview_slot(k);
}

std::vector<uint32_t> TerrainState::tree_buffer() const {
  const uint32_t cap = slot_count();
  const std::vector<uint32_t> starts = start_slots();
  std::vector<uint32_t> out(TV_TREE_START + cap + 2 * size_t(cap), (uint32_t(TV_SLOT_INVALID) << 16) | TV_SLOT_INVALID);
  out[0] = uint32_t(starts.size());
  out[1] = cap;
  out[2] = out[3] = 0;
  std::copy(starts.begin(), starts.end(), out.begin() + TV_TREE_START);
  for (const auto& [k, s] : overview_) {
    uint32_t* w = &out[TV_TREE_START + cap + 2 * size_t(s)];
    w[0] = uint32_t(child(s, 0)) | uint32_t(child(s, 1)) << 16;
    w[1] = uint32_t(child(s, 2)) | uint32_t(child(s, 3)) << 16;
  }
  return out;
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
