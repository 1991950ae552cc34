// Test helpers for the streamer: cached synthetic archives, an independent reference of the
// wanted set, and a checker that mirrors the GPU state from FrameUpdates and checks every
// invariant of streamer.h after each update(), the residency index against a brute-force
// recomputation from node_state() and the archive's directory.
#pragma once
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "synthetic_archive.h"
#include "terrain/archive_reader.h"
#include "terrain/streamer.h"

namespace terrain::test {

using Key = std::tuple<uint32_t, uint32_t, uint32_t>;  // level, x, y
inline Key key_of(const NodeKey& k) { return {k.level, k.x, k.y}; }
inline NodeKey node_key(const Key& k) { return {std::get<0>(k), std::get<1>(k), std::get<2>(k)}; }
std::string key_name(const Key& k);

// The main test archive: 5x5 root cells, 80 % filled, every child present with p = 0.75 down to
// level 0 (~7000 nodes), errors of about 2.5 vertex spacings, so a 512-node budget binds.
inline synthetic::Spec deep_sparse_spec() {
  synthetic::Spec s;
  s.roots_x = 5;
  s.roots_y = 5;
  s.root_fill = 0.8;
  s.child_probability = 0.75;
  s.min_level = 0;
  s.error_scale = 2.5;
  s.seed = 3;
  return s;
}

// A default configuration but for the worker count, which tests pin (the default, 0, picks it
// from the machine).
inline StreamerConfig with_workers(uint32_t worker_threads) {
  StreamerConfig c;
  c.worker_threads = worker_threads;
  return c;
}

// Path of a synthetic archive with this spec, written once per build tree and reused.
std::string synthetic_archive(const synthetic::Spec& spec);

// Copies `src` to `dst`.
void copy_file(const std::string& src, const std::string& dst);

// The wanted set by the definition in streamer.h, written independently of streamer/src: a
// plain scan over the set for the best split each round. `failed` nodes (and their subtrees) are
// left out. `required` (optional) receives the required subset.
std::set<Key> reference_wanted(const ArchiveReader& reader, const StreamerConfig& config, std::span<const View> views,
                               const std::set<Key>& failed, std::set<Key>* required = nullptr);

// A camera just above the synthetic surface (or any height) with the default projection.
View view_at(double x, double y, double z);

class StreamChecker {
 public:
  // `check_markers`: delivered data carries the synthetic key marker (splat section).
  StreamChecker(const Streamer& streamer, bool check_markers);

  // Applies `u` to the mirrored GPU state and checks every invariant. Returns "" when all hold,
  // else the first problem (frame, node, what).
  std::string check(const FrameUpdate& u);

  const std::map<Key, int>& failures() const { return failure_count_; }
  // Every NodeFailure seen, in the order reported.
  const std::vector<NodeFailure>& failure_statuses() const { return failure_statuses_; }
  std::set<Key> failed_set() const;
  std::set<Key> resident_set() const;
  uint64_t deliveries() const { return deliveries_; }
  uint64_t evictions() const { return evictions_; }
  uint64_t slot_reuses() const { return slot_reuses_; }

 private:
  std::string check_index(const FrameUpdate& u);  // "" or the problem

  const Streamer& streamer_;
  const ArchiveReader& reader_;
  bool check_markers_;
  uint64_t last_frame_ = 0;
  std::vector<uint16_t> roots_mirror_;  // the residency index as a GPU holds it, from the dirty lists
  std::vector<uint32_t> tree_mirror_;
  std::vector<uint16_t> root_cells_;  // kIndexNotResident where the archive has a root, else kIndexNoNode
  std::vector<SlotDescriptor> slots_;
  std::vector<uint64_t> slot_evicted_frame_;
  std::vector<int> slot_busy_;
  std::map<Key, uint16_t> resident_;
  std::map<Key, const NodeData*> data_;
  std::map<Key, int> failure_count_;
  std::vector<NodeFailure> failure_statuses_;
  std::vector<Key> roots_;  // the top nodes (roots without overview levels): always resident
  uint32_t top_ = kRootLevel;
  uint64_t deliveries_ = 0, evictions_ = 0, slot_reuses_ = 0;
};

// Runs update() with `views` until the wanted set is resident (or `timeout_s` passes), checking
// every frame. Returns "" on success, else the problem.
std::string settle(Streamer& streamer, StreamChecker& checker, std::span<const View> views, double timeout_s = 30.0,
                   int* frames = nullptr);

// Settles, then compares resident == streamer's wanted == reference wanted (and required subset).
std::string settle_and_compare(Streamer& streamer, StreamChecker& checker, std::span<const View> views);

}  // namespace terrain::test
