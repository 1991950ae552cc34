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

namespace {
uint64_t key_bits(const NodeKey& k) { return uint64_t(k.level) << 56 | uint64_t(k.y) << 28 | k.x; }
}  // namespace

void TerrainState::init(const WorldInfo& world, uint32_t slot_count) {
  world_ = world;
  roots_.assign(size_t(world.roots_x) * world.roots_y, uint16_t(TV_SLOT_INVALID));
  dirty_roots_ = roots_.empty() ? Rect{} : Rect{0, 0, world.roots_x, world.roots_y};
  slots_.assign(slot_count, SlotDescriptor{});
  resident_.clear();
  absent_.clear();
  dirty_slots_.clear();
  for (uint32_t s = 0; s < slot_count; ++s) dirty_slots_.push_back(s);
}

uint16_t TerrainState::root(int64_t x, int64_t y) const {
  if (x < 0 || y < 0 || x >= int64_t(world_.roots_x) || y >= int64_t(world_.roots_y)) return uint16_t(TV_SLOT_INVALID);
  return roots_[size_t(y) * world_.roots_x + size_t(x)];
}

void TerrainState::set_node(const NodeKey& key, uint16_t value) {
  const uint64_t k = key_bits(key);
  if (key.level == uint32_t(kRootLevel)) {
    if (key.x >= world_.roots_x || key.y >= world_.roots_y) return;
    uint16_t& cell = roots_[size_t(key.y) * world_.roots_x + key.x];
    if (cell == value) return;
    cell = value;
    dirty_roots_.add(key.x, key.y);
    if (value < TV_SLOT_INVALID)
      resident_[k] = value;
    else
      resident_.erase(k);
    return;
  }
  if (value < TV_SLOT_INVALID)
    resident_[k] = value;
  else
    resident_.erase(k);
  if (value == TV_SLOT_INVALID)
    absent_.insert(k);
  else
    absent_.erase(k);
}

uint16_t TerrainState::slot_of(const NodeKey& key) const {
  if (key.level == uint32_t(kRootLevel)) return root(key.x, key.y);
  const uint64_t k = key_bits(key);
  if (auto it = resident_.find(k); it != resident_.end()) return it->second;
  return absent_.count(k) ? uint16_t(TV_SLOT_INVALID) : uint16_t(TV_SLOT_EMPTY);
}

void TerrainState::set_slot(uint32_t s, const SlotDescriptor& desc) {
  slots_[s] = desc;
  dirty_slots_.push_back(s);
}

std::vector<uint32_t> TerrainState::start_slots() const {
  std::vector<uint32_t> out;
  const int top = top_level();
  if (top == kRootLevel) {
    for (uint16_t s : roots_)
      if (s < TV_SLOT_INVALID) out.push_back(s);
    return out;
  }
  std::vector<std::pair<uint64_t, uint16_t>> tops;
  for (const auto& [k, s] : resident_)
    if (int(k >> 56) == top) tops.push_back({k, s});
  std::sort(tops.begin(), tops.end());
  for (const auto& t : tops) out.push_back(t.second);
  return out;
}

uint16_t TerrainState::child(uint32_t slot, int c) const {
  const SlotDescriptor& d = slots_[slot];
  if (!(d.child_mask & (1u << c)) || d.level == 0) return uint16_t(TV_SLOT_INVALID);
  return slot_of(child_of(NodeKey{d.level, d.x, d.y}, c));
}

std::vector<uint32_t> TerrainState::tree_buffer() const {
  const uint32_t cap = slot_count();
  const std::vector<uint32_t> starts = start_slots();
  std::vector<uint32_t> out(TV_TREE_START + cap + 2 * size_t(cap), (uint32_t(TV_SLOT_INVALID) << 16) | TV_SLOT_INVALID);
  out[0] = uint32_t(starts.size());
  out[1] = cap;
  out[2] = out[3] = 0;
  std::copy(starts.begin(), starts.end(), out.begin() + TV_TREE_START);
  auto children = [&](uint32_t s) {
    uint32_t* w = &out[TV_TREE_START + cap + 2 * size_t(s)];
    w[0] = uint32_t(child(s, 0)) | uint32_t(child(s, 1)) << 16;
    w[1] = uint32_t(child(s, 2)) | uint32_t(child(s, 3)) << 16;
  };
  for (const auto& [k, s] : resident_) children(s);
  return out;
}

TerrainState::Dirty TerrainState::take_dirty() {
  Dirty out;
  out.roots = dirty_roots_;
  dirty_roots_ = {};
  std::sort(dirty_slots_.begin(), dirty_slots_.end());
  dirty_slots_.erase(std::unique(dirty_slots_.begin(), dirty_slots_.end()), dirty_slots_.end());
  out.slots.swap(dirty_slots_);
  return out;
}

}  // namespace terrain::view
