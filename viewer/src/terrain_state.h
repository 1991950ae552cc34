// The viewer's copy of the residency state a GPU renderer needs (FC5 section 4.1): per-level index
// grids of uint16 (slot, TV_SLOT_EMPTY, TV_SLOT_INVALID) and the slot table, with the regions that
// changed since the renderer last uploaded them. Whoever feeds the viewer (the streamer adapter, a
// load-everything source, a test) writes here; the renderer and the CPU reference read it.
#pragma once
#include <array>
#include <cstdint>
#include <unordered_map>
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
  // Grids start as TV_SLOT_INVALID everywhere; every slot free.
  void init(const WorldInfo& world, uint32_t slot_count);

  const WorldInfo& world() const { return world_; }
  uint32_t roots_x() const { return world_.roots_x; }
  uint32_t roots_y() const { return world_.roots_y; }
  uint32_t grid_width(int level) const { return level_grid_width(world_.roots_x, level); }
  uint32_t grid_height(int level) const { return level_grid_width(world_.roots_y, level); }
  uint32_t slot_count() const { return uint32_t(slots_.size()); }

  uint16_t index(int level, uint32_t x, uint32_t y) const;
  // Outside the grid reads as TV_SLOT_INVALID.
  uint16_t index_or_invalid(int level, int64_t x, int64_t y) const;
  void set_index(int level, uint32_t x, uint32_t y, uint16_t value);
  const std::vector<uint16_t>& grid(int level) const { return grids_[level]; }

  // Overview levels (format/SPEC.md section 19): levels 6 .. top_level() have no index grids;
  // the state keeps their resident nodes in a small map (at most the resident set).
  int top_level() const { return top_level(world_); }
  static int top_level(const WorldInfo& w) { return terrain::top_level(w); }
  // Records node `key` (level >= 6) as resident in `slot`, or removes it (slot >= TV_SLOT_INVALID).
  void set_overview(const NodeKey& key, uint16_t slot);
  // Slot of an overview node, TV_SLOT_EMPTY when it is not resident.
  uint16_t overview_slot(const NodeKey& key) const;
  // Where the GPU traversal starts: the top level's resident nodes (the roots without overview
  // levels), in key order.
  std::vector<uint32_t> start_slots() const;
  // Child c of the resident node in `slot` (TV_SLOT_EMPTY exists but not resident, TV_SLOT_INVALID
  // no such node), from the child mask and the index grid or the overview map.
  uint16_t child(uint32_t slot, int c) const;
  // The tree buffer of config.h ("Tree buffer"): start list and the child words of overview slots.
  std::vector<uint32_t> tree_buffer() const;

  const SlotDescriptor& descriptor(uint32_t s) const { return slots_[s]; }
  const std::vector<SlotDescriptor>& descriptors() const { return slots_; }
  void set_slot(uint32_t s, const SlotDescriptor& desc);

  // Changes since the last take_dirty(): index rectangles per level and slots.
  struct Dirty {
    std::array<Rect, kLevelCount> index;
    std::vector<uint32_t> slots;  // sorted, unique
  };
  Dirty take_dirty();

 private:
  WorldInfo world_;
  std::array<std::vector<uint16_t>, kLevelCount> grids_;
  std::vector<SlotDescriptor> slots_;
  std::unordered_map<uint64_t, uint16_t> overview_;  // (level, x, y) -> slot of resident overview nodes
  std::array<Rect, kLevelCount> dirty_index_;
  std::vector<uint32_t> dirty_slots_;
};

}  // namespace terrain::view
