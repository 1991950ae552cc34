#include "terrain/residency_index.h"

#include <algorithm>

namespace terrain {

void DirtyRect::add(uint32_t x, uint32_t y) {
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
// Level, y, x: ascending packed keys are key order within a level (y, then x). Node coordinates
// are below 2^21 (65536 roots of 32 level-0 nodes), well inside the 28 bits each.
uint64_t pack(const NodeKey& k) { return uint64_t(k.level) << 56 | uint64_t(k.y) << 28 | k.x; }
NodeKey unpack(uint64_t k) { return {uint32_t(k >> 56), uint32_t(k >> 28) & 0xFFFFFFFu, uint32_t(k) & 0xFFFFFFFu}; }
constexpr uint64_t kNoKey = ~uint64_t(0);
static_assert((uint64_t(kStreamerMaxRootsPerSide) << kRootLevel) <= (uint64_t(1) << 28), "node coordinates fit 28 bits");
}  // namespace

void ResidencyIndex::init(const WorldInfo& world, uint32_t slot_count) {
  world_ = world;
  slot_count_ = std::min(slot_count, kMaxSlots);
  top_level_ = terrain::top_level(world);
  roots_.assign(size_t(world.roots_x) * world.roots_y, kIndexNoNode);
  tree_.assign(index_tree_words(slot_count_), kIndexNoChildren);
  masks_.assign(slot_count_, 0);
  slot_keys_.assign(slot_count_, kNoKey);
  tree_[0] = 0;
  tree_[1] = slot_count_;
  tree_[2] = tree_[3] = 0;
  std::fill(tree_.begin() + kIndexTreeStart, tree_.begin() + ptrdiff_t(kIndexTreeStart + slot_count_), 0u);
  resident_.clear();
  absent_.clear();
  tops_.clear();
  changes_.roots = roots_.empty() ? DirtyRect{} : DirtyRect{0, 0, world.roots_x, world.roots_y};
  changes_.starts = true;
  changes_.children.resize(slot_count_);
  for (uint32_t s = 0; s < slot_count_; ++s) changes_.children[s] = uint16_t(s);
}

uint16_t ResidencyIndex::root(int64_t x, int64_t y) const {
  if (x < 0 || y < 0 || x >= int64_t(world_.roots_x) || y >= int64_t(world_.roots_y)) return kIndexNoNode;
  return roots_[size_t(y) * world_.roots_x + size_t(x)];
}

uint16_t ResidencyIndex::slot_of(const NodeKey& key) const {
  if (key.level == uint32_t(kRootLevel)) return root(key.x, key.y);
  const uint64_t k = pack(key);
  if (auto it = resident_.find(k); it != resident_.end()) return it->second;
  return absent_.count(k) ? kIndexNoNode : kIndexNotResident;
}

uint16_t ResidencyIndex::child(uint32_t slot, int c) const {
  if (slot >= slot_count_ || c < 0 || c > 3) return kIndexNoNode;
  return uint16_t(tree_[index_child_word(slot_count_, slot) + size_t(c >> 1)] >> (16 * (c & 1)));
}

std::span<const uint32_t> ResidencyIndex::start_slots() const {
  if (tree_.empty()) return {};
  return std::span<const uint32_t>(tree_).subspan(kIndexTreeStart, tree_[0]);
}

void ResidencyIndex::write_child(uint16_t slot, int c, uint16_t value) {
  uint32_t& w = tree_[index_child_word(slot_count_, slot) + size_t(c >> 1)];
  const int shift = 16 * (c & 1);
  const uint32_t next = (w & ~(0xFFFFu << shift)) | uint32_t(value) << shift;
  if (next == w) return;
  w = next;
  changes_.children.push_back(slot);
}

void ResidencyIndex::fill_children(uint16_t slot, const NodeKey& key, uint8_t mask) {
  for (int c = 0; c < 4; ++c)
    write_child(slot, c, (mask & (1u << c)) ? slot_of(child_of(key, c)) : kIndexNoNode);
}

void ResidencyIndex::clear_children(uint16_t slot) {
  for (int c = 0; c < 4; ++c) write_child(slot, c, kIndexNoNode);
}

void ResidencyIndex::rebuild_starts() {
  uint32_t n = 0;
  for (const auto& [k, s] : tops_) tree_[kIndexTreeStart + n++] = s;
  std::fill(tree_.begin() + ptrdiff_t(kIndexTreeStart + n), tree_.begin() + ptrdiff_t(kIndexTreeStart + slot_count_), 0u);
  tree_[0] = n;
  changes_.starts = true;
}

void ResidencyIndex::set_node(const NodeKey& key, uint16_t value, uint8_t child_mask) {
  const bool root_level = key.level == uint32_t(kRootLevel);
  if (root_level && (key.x >= world_.roots_x || key.y >= world_.roots_y)) return;
  if (value < kIndexNoNode && value >= slot_count_) return;
  const uint64_t k = pack(key);
  const uint16_t old = slot_of(key);
  if (old < kIndexNoNode && old != value) {  // leaves its slot
    resident_.erase(k);
    if (slot_keys_[old] == k) {
      masks_[old] = 0;
      slot_keys_[old] = kNoKey;
      clear_children(old);
    }
  }
  if (root_level) {
    uint16_t& cell = roots_[size_t(key.y) * world_.roots_x + key.x];
    if (cell != value) changes_.roots.add(key.x, key.y);
    cell = value;
  } else if (value == kIndexNoNode) {
    absent_.insert(k);
  } else {
    absent_.erase(k);
  }
  if (value < kIndexNoNode) {
    resident_[k] = value;
    masks_[value] = key.level > 0 ? child_mask : 0;
    slot_keys_[value] = k;
    fill_children(value, key, masks_[value]);
  }
  // The parent's word for this child, when the parent is resident and has the child.
  if (key.level + 1 < uint32_t(kMaxLevels)) {
    const NodeKey parent{key.level + 1, key.x >> 1, key.y >> 1};
    const int c = int(key.x & 1) | int(key.y & 1) << 1;
    if (auto it = resident_.find(pack(parent)); it != resident_.end() && (masks_[it->second] & (1u << c)))
      write_child(it->second, c, value);
  }
  if (int(key.level) == top_level_) {
    const bool was = tops_.count(k) != 0;
    const bool is = value < kIndexNoNode;
    if (is && (!was || tops_[k] != value)) {
      tops_[k] = value;
      rebuild_starts();
    } else if (!is && was) {
      tops_.erase(k);
      rebuild_starts();
    }
  }
}

void ResidencyIndex::set_child_mask(uint32_t slot, uint8_t child_mask) {
  if (slot >= slot_count_ || slot_keys_[slot] == kNoKey) return;
  const NodeKey key = unpack(slot_keys_[slot]);
  masks_[slot] = key.level > 0 ? child_mask : 0;
  fill_children(uint16_t(slot), key, masks_[slot]);
}

void ResidencyIndex::take_changes(ResidencyChanges& out) {
  out.roots = changes_.roots;
  out.starts = changes_.starts;
  std::sort(changes_.children.begin(), changes_.children.end());
  changes_.children.erase(std::unique(changes_.children.begin(), changes_.children.end()), changes_.children.end());
  out.children.swap(changes_.children);
  changes_.roots = {};
  changes_.starts = false;
  changes_.children.clear();
}

}  // namespace terrain
