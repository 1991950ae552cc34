// The residency index: the GPU-side quadtree state of the resident nodes (FC5 section 4.1, made
// sparse). Its layout (the root grid and the tree words) is terrain/surface_contract.h's
// "Residency index: GPU layout"; format/SPEC.md section 12 says what a renderer may rely on.
//
// The Streamer keeps one (Streamer::residency()) and lists what each update() changed in its
// FrameUpdate; a renderer fed by other means (everything in memory, a test) fills its own with
// set_node(). Memory follows the resident set and the root count, never the world's area: 2
// bytes per root cell and 12 per slot, plus a hash entry per resident or failed node.
#pragma once
#include <cstdint>
#include <map>
#include <span>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "terrain/format.h"
#include "terrain/surface_contract.h"

namespace terrain {

// Half-open rectangle of root-grid cells [x0, x1) x [y0, y1); empty when x0 >= x1.
struct DirtyRect {
  uint32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  bool empty() const { return x0 >= x1 || y0 >= y1; }
  void add(uint32_t x, uint32_t y);  // grows the rectangle to hold cell (x, y)
};

// What changed in the index since the last take_changes().
struct ResidencyChanges {
  DirtyRect roots;                 // root-grid cells
  bool starts = false;             // tree words [0, kIndexTreeStart + slot count): header and start list
  std::vector<uint16_t> children;  // slots whose two child words changed; ascending, unique
};

class ResidencyIndex {
 public:
  // Every root cell kIndexNoNode, nothing resident, every child word kIndexNoChildren; all of it
  // marked changed (the first upload is the whole index). slot_count <= kMaxSlots.
  void init(const WorldInfo& world, uint32_t slot_count);

  // Records node `key` as resident in slot `value` (< slot_count), as existing but not resident
  // (kIndexNotResident) or as absent (kIndexNoNode: its payload failed, or a root the archive does
  // not have). `child_mask` (bit c: child_of(key, c) exists in the archive) matters only for a
  // resident node; a level-0 node has no children. Below the roots existence comes from the
  // parent's child mask, so only failed nodes need kIndexNoNode there. A slot holds one node at a
  // time: give the old node up (kIndexNotResident) before another takes its slot. Root cells
  // outside the world and slots >= slot_count are ignored.
  void set_node(const NodeKey& key, uint16_t value, uint8_t child_mask = 0);
  // A new child mask for the node resident in `slot` (none: nothing happens); its child words follow.
  void set_child_mask(uint32_t slot, uint8_t child_mask);

  const WorldInfo& world() const { return world_; }
  uint32_t slot_count() const { return slot_count_; }
  int top_level() const { return top_level_; }

  // Slot of `key` when resident; otherwise kIndexNotResident, or kIndexNoNode for a root cell
  // without a root, a failed node or a root cell outside the world.
  uint16_t slot_of(const NodeKey& key) const;
  // Root cell (x, y): its slot, kIndexNotResident or kIndexNoNode (also outside the world).
  uint16_t root(int64_t x, int64_t y) const;
  // Child c of the node in `slot`, as its tree word says (kIndexNoNode for a slot holding no node).
  uint16_t child(uint32_t slot, int c) const;
  // The start list: slots of the top level's resident nodes, in key order.
  std::span<const uint32_t> start_slots() const;

  // The two arrays of the GPU layout, to upload as they are.
  std::span<const uint16_t> root_grid() const { return roots_; }  // roots_x * roots_y, row 0 = south
  std::span<const uint32_t> tree() const { return tree_; }        // index_tree_words(slot_count)

  // Moves the changes since the last call into `out` (its buffers are reused) and forgets them.
  void take_changes(ResidencyChanges& out);

 private:
  void write_child(uint16_t slot, int c, uint16_t value);
  void fill_children(uint16_t slot, const NodeKey& key, uint8_t mask);
  void clear_children(uint16_t slot);
  void rebuild_starts();

  WorldInfo world_;
  uint32_t slot_count_ = 0;
  int top_level_ = kRootLevel;
  std::vector<uint16_t> roots_;
  std::vector<uint32_t> tree_;
  std::vector<uint8_t> masks_;                       // per slot: child mask of its node
  std::vector<uint64_t> slot_keys_;                  // per slot: packed key of its node, kNoKey if none
  std::unordered_map<uint64_t, uint16_t> resident_;  // packed key -> slot, every resident node
  std::unordered_set<uint64_t> absent_;              // failed nodes other than roots
  std::map<uint64_t, uint16_t> tops_;                // resident top-level nodes, key order
  ResidencyChanges changes_;
};

}  // namespace terrain
