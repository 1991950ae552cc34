// The residency state a GPU renderer needs: the slot table and the streamer's residency index
// (terrain/residency_index.h, layout in terrain/surface_contract.h), with what changed since the
// renderer last uploaded it. Whoever feeds the viewer (the streamer adapter, a load-everything
// source, a test) writes here; the renderer and the CPU reference read it.
#pragma once
#include <cstdint>
#include <span>
#include <vector>

#include "gpu_types.h"
#include "terrain/format.h"
#include "terrain/residency_index.h"

namespace terrain::view {

using Rect = DirtyRect;  // half-open [x0, x1) x [y0, y1); empty when x0 >= x1

// A node payload to copy into atlas slot `slot` (the state's descriptor for the slot must already be
// set: it gives the quantization). `data` must stay valid until the renderer's upload() returns.
struct NodeUpload {
  uint32_t slot = 0;
  const NodeData* data = nullptr;
};

class TerrainState {
 public:
  // Every root TV_SLOT_INVALID (no such node), nothing resident, every slot free; all of it dirty.
  void init(const WorldInfo& world, uint32_t slot_count);

  const WorldInfo& world() const { return index_.world(); }
  uint32_t roots_x() const { return world().roots_x; }
  uint32_t roots_y() const { return world().roots_y; }
  uint32_t slot_count() const { return uint32_t(slots_.size()); }

  // Records node `key` as resident in `value` (< TV_SLOT_INVALID; set the slot's descriptor first:
  // its child mask says which children exist), as existing but not resident (TV_SLOT_EMPTY) or as
  // absent (TV_SLOT_INVALID). ResidencyIndex::set_node says the rest.
  void set_node(const NodeKey& key, uint16_t value);
  uint16_t slot_of(const NodeKey& key) const { return index_.slot_of(key); }
  uint16_t root(int64_t x, int64_t y) const { return index_.root(x, y); }

  // The top level: kRootLevel, or the overview levels' top (format/SPEC.md section 19).
  int top_level() const { return top_level(world()); }
  static int top_level(const WorldInfo& w) { return terrain::top_level(w); }
  // Where the GPU traversal starts: the top level's resident nodes, in key order.
  std::vector<uint32_t> start_slots() const;
  // Child c of the resident node in `slot` (TV_SLOT_EMPTY exists but not resident, TV_SLOT_INVALID
  // no such node).
  uint16_t child(uint32_t slot, int c) const { return index_.child(slot, c); }
  const ResidencyIndex& index() const { return index_; }

  const SlotDescriptor& descriptor(uint32_t s) const { return slots_[s]; }
  const std::vector<SlotDescriptor>& descriptors() const { return slots_; }
  // The descriptor of slot s; when a node is resident there, its children follow the new child mask.
  void set_slot(uint32_t s, const SlotDescriptor& desc);

  // Changes since the last take_dirty(): the index's and the slots' descriptors.
  struct Dirty {
    ResidencyChanges index;
    std::vector<uint32_t> slots;  // descriptors; sorted, unique
  };
  Dirty take_dirty();

 private:
  ResidencyIndex index_;
  std::vector<SlotDescriptor> slots_;
  std::vector<uint32_t> dirty_slots_;
};

}  // namespace terrain::view
