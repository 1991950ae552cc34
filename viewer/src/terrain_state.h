// The viewer's copy of the residency state a GPU renderer needs (FC5 section 4.1, made sparse):
// the slot table, the resident nodes' children and a uint16 per root cell (slot, TV_SLOT_EMPTY,
// TV_SLOT_INVALID), with what changed since the renderer last uploaded it. Whoever feeds the
// viewer (the streamer adapter, a load-everything source, a test) writes here; the renderer and
// the CPU reference read it.
#pragma once
#include <array>
#include <cstdint>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "gpu_types.h"
#include "terrain/format.h"

namespace terrain::view {

struct Rect {  // half-open [x0, x1) x [y0, y1); empty when x0 >= x1
  uint32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  bool empty() const { return x0 >= x1 || y0 >= y1; }
  void add(uint32_t x, uint32_t y);
};

// A node payload to copy into atlas slot `slot` (the state's descriptor for the slot must already be
// set: it gives the quantization). `data` must stay valid until the renderer's upload() returns.
struct NodeUpload {
  uint32_t slot = 0;
  const NodeData* data = nullptr;
};

class TerrainState {
 public:
  // Every root TV_SLOT_INVALID (no such node), nothing resident, every slot free.
  void init(const WorldInfo& world, uint32_t slot_count);

  const WorldInfo& world() const { return world_; }
  uint32_t roots_x() const { return world_.roots_x; }
  uint32_t roots_y() const { return world_.roots_y; }
  uint32_t slot_count() const { return uint32_t(slots_.size()); }

  // What the GPU reads (config.h "Tree buffer", "Root grid"): a sparse index, so memory follows
  // the resident set and the root count, never the world's area at level 0. Per slot, the slots
  // of its four children (12 bytes per slot with the start list); per root cell, its slot
  // (2 bytes per root: 200 KB at 10^5 roots, where the dense per-level grids of FC5 cost 2730).
  //
  // Records node `key` as resident in `value` (< TV_SLOT_INVALID), as existing but not resident
  // (TV_SLOT_EMPTY) or as absent (TV_SLOT_INVALID: a node whose payload failed, or a root the
  // archive does not have). Below the roots, existence comes from the parent's child mask; only
  // failed nodes need TV_SLOT_INVALID.
  void set_node(const NodeKey& key, uint16_t value);
  // Slot of `key` when resident; otherwise TV_SLOT_EMPTY, or TV_SLOT_INVALID for a root cell
  // without a root, a failed node or a place outside the world.
  uint16_t slot_of(const NodeKey& key) const;
  // Root cell (x, y): its slot, TV_SLOT_EMPTY or TV_SLOT_INVALID (also outside the world).
  uint16_t root(int64_t x, int64_t y) const;
  const std::vector<uint16_t>& root_grid() const { return roots_; }

  // The top level: kRootLevel, or the overview levels' top (format/SPEC.md section 19).
  int top_level() const { return top_level(world_); }
  static int top_level(const WorldInfo& w) { return terrain::top_level(w); }
  // Where the GPU traversal starts: the top level's resident nodes, in key order.
  std::vector<uint32_t> start_slots() const;
  // Child c of the resident node in `slot` (TV_SLOT_EMPTY exists but not resident, TV_SLOT_INVALID
  // no such node), from the child mask and the resident set.
  uint16_t child(uint32_t slot, int c) const;
  // The tree buffer of config.h ("Tree buffer"): start list and every resident slot's child words.
  std::vector<uint32_t> tree_buffer() const;

  const SlotDescriptor& descriptor(uint32_t s) const { return slots_[s]; }
  const std::vector<SlotDescriptor>& descriptors() const { return slots_; }
  void set_slot(uint32_t s, const SlotDescriptor& desc);

  // Changes since the last take_dirty(): the root cells and the slots.
  struct Dirty {
    Rect roots;
    std::vector<uint32_t> slots;  // sorted, unique
  };
  Dirty take_dirty();

 private:
  WorldInfo world_;
  std::vector<uint16_t> roots_;                        // roots_x * roots_y, row 0 = south
  std::vector<SlotDescriptor> slots_;
  std::unordered_map<uint64_t, uint16_t> resident_;    // (level, x, y) -> slot of every resident node
  std::unordered_set<uint64_t> absent_;                // failed nodes below or above the roots
  Rect dirty_roots_;
  std::vector<uint32_t> dirty_slots_;
};

}  // namespace terrain::view
