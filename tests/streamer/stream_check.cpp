#include "stream_check.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <sstream>
#include <thread>

#include "test_data.h"

namespace terrain::test {

std::string key_name(const Key& k) {
  return std::to_string(std::get<0>(k)) + "/" + std::to_string(std::get<1>(k)) + "/" + std::to_string(std::get<2>(k));
}

std::string synthetic_archive(const synthetic::Spec& spec) {
  std::ostringstream name;
  name << "synthetic-v4-" << spec.roots_x << "x" << spec.roots_y << "-f" << spec.root_fill << "-p" << spec.child_probability
       << "-m" << spec.min_level << "-e" << spec.error_scale << "-s" << spec.seed << (spec.realistic_payload ? "-real" : "")
       << "-z" << spec.zstd_level << (spec.overview_levels ? "-o" + std::to_string(spec.overview_levels) : std::string())
       << ".terrain";
  const std::filesystem::path dir = bin_dir().parent_path() / "streamer-test-archives";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / name.str()).string();
  {
    ArchiveReader probe;
    if (std::filesystem::exists(path) && probe.open(path).ok()) return path;
  }
  // The writer is atomic (temp file + rename), so concurrent test processes may both write.
  if (Status s = synthetic::write_archive(path, spec); !s.ok()) throw std::runtime_error("synthetic archive: " + s.to_string());
  return path;
}

void copy_file(const std::string& src, const std::string& dst) {
  std::filesystem::copy_file(src, dst, std::filesystem::copy_options::overwrite_existing);
}

View view_at(double x, double y, double z) {
  View v;
  v.x = x;
  v.y = y;
  v.z = z;
  return v;
}

// ---- Reference wanted set --------------------------------------------------------------------

namespace {

struct Box {
  double x0, y0, z0, x1, y1, z1;
};

Box box_of(const WorldInfo& w, const NodeRecord& r) {
  const double size = node_size_m(int(r.key.level));
  Box b;
  b.x0 = w.origin_x_m + double(r.key.x) * size;
  b.y0 = w.origin_y_m + double(r.key.y) * size;
  b.x1 = b.x0 + size;
  b.y1 = b.y0 + size;
  b.z0 = double(r.min_height) * kHeightUnitM;
  b.z1 = double(r.max_height) * kHeightUnitM;
  return b;
}

double reference_error(const WorldInfo& w, const NodeRecord& r, const StreamerConfig& c, std::span<const View> views) {
  const Box b = box_of(w, r);
  double best = 0;
  for (const View& v : views) {
    const double cx = std::clamp(v.x, b.x0, b.x1), cy = std::clamp(v.y, b.y0, b.y1), cz = std::clamp(v.z, b.z0, b.z1);
    const double d = std::sqrt((v.x - cx) * (v.x - cx) + (v.y - cy) * (v.y - cy) + (v.z - cz) * (v.z - cz));
    const double ppr = v.pixels_per_radian > 0 ? v.pixels_per_radian : c.default_pixels_per_radian;
    double e = double(r.geometric_error_m) * ppr / std::max(d, 1e-3);
    if (v.has_frustum) {
      bool outside = false;
      for (const FrustumPlane& p : v.frustum) {
        bool all_out = true;
        for (int corner = 0; corner < 8 && all_out; ++corner) {
          const double qx = (corner & 1 ? b.x1 : b.x0) - v.x, qy = (corner & 2 ? b.y1 : b.y0) - v.y,
                       qz = (corner & 4 ? b.z1 : b.z0) - v.z;
          all_out = p.nx * qx + p.ny * qy + p.nz * qz + p.d < 0;
        }
        outside = outside || all_out;
      }
      if (outside) e *= c.outside_frustum_error_scale;
    }
    best = std::max(best, e);
  }
  return best;
}

}  // namespace

std::set<Key> reference_wanted(const ArchiveReader& reader, const StreamerConfig& config, std::span<const View> views,
                               const std::set<Key>& failed, std::set<Key>* required) {
  const WorldInfo& w = reader.world();
  auto record = [&](const Key& k) -> const NodeRecord* {
    const int64_t i = reader.find(node_key(k));
    return i < 0 ? nullptr : &reader.nodes()[size_t(i)];
  };
  std::map<Key, double> error;
  auto err = [&](const Key& k) {
    auto it = error.find(k);
    if (it != error.end()) return it->second;
    return error[k] = reference_error(w, *record(k), config, views);
  };
  const auto top = uint32_t(reader.top_level());  // the roots, or the top overview level
  auto priority = [&](const Key& k) {  // min of the errors along the path from the top
    double p = err(k);
    NodeKey n = node_key(k);
    while (n.level < top) {
      n = parent_of(n);
      p = std::min(p, err(key_of(n)));
    }
    return p;
  };
  auto live_children = [&](const Key& k) {
    std::vector<Key> out;
    if (std::get<0>(k) == 0) return out;
    for (int c = 0; c < 4; ++c) {
      const Key ck = key_of(child_of(node_key(k), c));
      if (record(ck) && !failed.count(ck)) out.push_back(ck);
    }
    return out;
  };

  // One greedy run: the best split each round, stopping at the first that does not fit.
  auto run = [&](double threshold, uint64_t budget) {
    std::vector<Key> set;
    std::set<Key> split;
    for (const NodeRecord& r : reader.nodes())
      if (r.key.level == top && !failed.count(key_of(r.key))) set.push_back(key_of(r.key));
    while (!views.empty()) {
      std::optional<Key> best;
      double best_p = 0;
      for (const Key& k : set) {
        if (split.count(k) || !(err(k) > threshold) || live_children(k).empty()) continue;
        const double p = priority(k);
        bool better = !best;
        if (best) {
          if (p != best_p) better = p > best_p;
          else if (std::get<0>(k) != std::get<0>(*best)) better = std::get<0>(k) > std::get<0>(*best);
          else better = key_less(node_key(k), node_key(*best));
        }
        if (better) {
          best = k;
          best_p = p;
        }
      }
      if (!best) break;
      const std::vector<Key> children = live_children(*best);
      if (set.size() + children.size() > budget) break;
      split.insert(*best);
      set.insert(set.end(), children.begin(), children.end());
    }
    return std::set<Key>(set.begin(), set.end());
  };
  uint64_t roots = 0;  // top nodes
  for (const NodeRecord& r : reader.nodes()) roots += r.key.level == top;
  if (required)
    *required = run(config.error_target_px,
                    std::max<uint64_t>(roots, uint64_t(std::floor(config.budget_nodes * (1.0 - config.prefetch_reserve)))));
  return run(config.error_target_px * config.prefetch_ratio, config.budget_nodes);
}

// ---- Checker ---------------------------------------------------------------------------------

StreamChecker::StreamChecker(const Streamer& streamer, bool check_markers)
    : streamer_(streamer), reader_(streamer.archive()), check_markers_(check_markers) {
  // Garbage until the first upload.
  roots_mirror_.assign(size_t(streamer.world().roots_x) * streamer.world().roots_y, 0x1234);
  tree_mirror_.assign(index_tree_words(streamer.slot_count()), 0xDEADBEEF);
  top_ = uint32_t(reader_.top_level());
  root_cells_.assign(roots_mirror_.size(), kIndexNoNode);
  for (const NodeRecord& r : reader_.nodes()) {
    if (r.key.level == top_) roots_.push_back(key_of(r.key));
    if (r.key.level == uint32_t(kRootLevel))
      root_cells_[size_t(r.key.y) * streamer.world().roots_x + r.key.x] = kIndexNotResident;
  }
  slots_.assign(streamer.slot_count(), SlotDescriptor{});
  slot_evicted_frame_.assign(streamer.slot_count(), 0);
  slot_busy_.assign(streamer.slot_count(), 0);
}

std::set<Key> StreamChecker::failed_set() const {
  std::set<Key> out;
  for (const auto& [k, n] : failure_count_) out.insert(k);
  return out;
}

std::set<Key> StreamChecker::resident_set() const {
  std::set<Key> out;
  for (const auto& [k, s] : resident_) out.insert(k);
  return out;
}

std::string StreamChecker::check_index(const FrameUpdate& u) {
  // Apply the dirty lists as a GPU upload would.
  const ResidencyIndex& index = streamer_.residency();
  const WorldInfo& w = streamer_.world();
  const uint32_t cap = streamer_.slot_count();
  const DirtyRect& r = u.dirty_roots;
  if (!r.empty()) {
    if (r.x1 > w.roots_x || r.y1 > w.roots_y) return "dirty root rectangle outside the root grid";
    for (uint32_t y = r.y0; y < r.y1; ++y)
      for (uint32_t x = r.x0; x < r.x1; ++x)
        roots_mirror_[size_t(y) * w.roots_x + x] = index.root_grid()[size_t(y) * w.roots_x + x];
  }
  const std::span<const uint32_t> tree = index.tree();
  if (tree.size() != tree_mirror_.size()) return "index tree of " + std::to_string(tree.size()) + " words";
  if (u.dirty_starts) std::copy(tree.begin(), tree.begin() + kIndexTreeStart + cap, tree_mirror_.begin());
  for (size_t i = 0; i < u.dirty_children.size(); ++i) {
    const uint16_t s = u.dirty_children[i];
    if (i > 0 && s <= u.dirty_children[i - 1]) return "dirty child slots not ascending";
    if (s >= cap) return "dirty child slot " + std::to_string(s) + " out of range";
    for (size_t k = 0; k < 2; ++k) tree_mirror_[index_child_word(cap, s) + k] = tree[index_child_word(cap, s) + k];
  }
  // After the first update the lists name only what the events touched: a node's own slot and its
  // parent's per event, the roots' cells only for root events, the start list never (top nodes stay).
  if (u.frame > 1) {
    const size_t events = u.delivered.size() + u.evicted.size() + u.failed.size();
    if (u.dirty_children.size() > 2 * events)
      return std::to_string(u.dirty_children.size()) + " dirty child slots for " + std::to_string(events) + " events";
    if (u.dirty_starts) return "start list marked dirty after the first update";
    bool root_event = false;
    for (const NodeDelivery& d : u.delivered) root_event |= d.key.level == uint32_t(kRootLevel);
    for (const NodeEviction& e : u.evicted) root_event |= e.key.level == uint32_t(kRootLevel);
    for (const NodeFailure& f : u.failed) root_event |= f.key.level == uint32_t(kRootLevel);
    if (!root_event && !u.dirty_roots.empty()) return "root cells marked dirty without a root event";
  }

  // The index recomputed by brute force from node_state() and the directory (surface_contract.h):
  // the roots' cells, then the start list and child words of every resident node.
  auto value_of = [&](const NodeKey& k) -> uint16_t {
    switch (streamer_.node_state(k)) {
      case NodeState::resident: return uint16_t(streamer_.slot_of(k));
      case NodeState::absent:
      case NodeState::failed: return kIndexNoNode;
      default: return kIndexNotResident;
    }
  };
  std::vector<uint16_t> roots = root_cells_;  // kIndexNotResident where a root exists
  for (const Key& k : failed_set())
    if (std::get<0>(k) == uint32_t(kRootLevel)) roots[size_t(std::get<2>(k)) * w.roots_x + std::get<1>(k)] = value_of(node_key(k));
  std::vector<uint32_t> want(tree.size(), kIndexNoChildren);
  want[0] = 0;
  want[1] = cap;
  want[2] = want[3] = 0;
  std::fill(want.begin() + kIndexTreeStart, want.begin() + kIndexTreeStart + cap, 0u);
  for (const NodeKey& key : streamer_.resident_nodes()) {  // directory order: key order within a level
    const NodeRecord& rec = reader_.nodes()[size_t(reader_.find(key))];
    const uint16_t v = value_of(rec.key);
    if (v >= kIndexNoNode) return "resident node " + key_name(key_of(key)) + " has no slot";
    if (rec.key.level == uint32_t(kRootLevel)) roots[size_t(rec.key.y) * w.roots_x + rec.key.x] = v;
    if (rec.key.level == top_) want[kIndexTreeStart + want[0]++] = v;
    uint16_t child[4];
    for (int c = 0; c < 4; ++c)
      child[c] = rec.key.level > 0 && (rec.child_mask & (1 << c)) ? value_of(child_of(rec.key, c)) : kIndexNoNode;
    want[index_child_word(cap, v)] = uint32_t(child[0]) | uint32_t(child[1]) << 16;
    want[index_child_word(cap, v) + 1] = uint32_t(child[2]) | uint32_t(child[3]) << 16;
  }
  for (size_t i = 0; i < roots.size(); ++i) {
    if (index.root_grid()[i] != roots[i])
      return "root cell " + std::to_string(i) + " is " + std::to_string(index.root_grid()[i]) + ", expected " +
             std::to_string(roots[i]);
    if (roots_mirror_[i] != roots[i])
      return "root cell " + std::to_string(i) + " changed without a dirty rectangle covering it";
  }
  for (size_t i = 0; i < want.size(); ++i) {
    if (tree[i] != want[i])
      return "index tree word " + std::to_string(i) + " is " + std::to_string(tree[i]) + ", expected " + std::to_string(want[i]);
    if (tree_mirror_[i] != want[i]) return "index tree word " + std::to_string(i) + " changed without being listed dirty";
  }
  return "";
}

std::string StreamChecker::check(const FrameUpdate& u) {
  const StreamerConfig& cfg = streamer_.config();
  std::ostringstream err;
  auto fail = [&](const std::string& what) {
    err << "frame " << u.frame << ": " << what;
    return err.str();
  };
  if (u.frame != last_frame_ + 1) return fail("frame number " + std::to_string(u.frame) + " after " + std::to_string(last_frame_));
  last_frame_ = u.frame;

  // Evictions: of resident nodes, children before parents, slots fenced from now on.
  for (const NodeEviction& e : u.evicted) {
    const Key k = key_of(e.key);
    auto it = resident_.find(k);
    if (it == resident_.end()) return fail("evicted node " + key_name(k) + " was not resident");
    if (it->second != e.slot) return fail("eviction of " + key_name(k) + " names slot " + std::to_string(e.slot));
    if (e.key.level == top_) return fail("top node " + key_name(k) + " evicted");
    resident_.erase(it);
    data_.erase(k);
    for (int c = 0; c < 4 && e.key.level > 0; ++c)
      if (resident_.count(key_of(child_of(e.key, c))))
        return fail("node " + key_name(k) + " evicted while its child " + key_name(key_of(child_of(e.key, c))) + " stays resident");
    slot_evicted_frame_[e.slot] = u.frame;
    slot_busy_[e.slot] = 0;
    ++evictions_;
  }

  // Deliveries: bounded, parents first, into free slots whose fence has passed, right data.
  if (u.frame > 1 && u.delivered.size() > cfg.max_deliveries_per_frame)
    return fail(std::to_string(u.delivered.size()) + " deliveries above the cap " + std::to_string(cfg.max_deliveries_per_frame));
  for (const NodeDelivery& d : u.delivered) {
    const Key k = key_of(d.key);
    if (resident_.count(k)) return fail("delivered node " + key_name(k) + " was already resident");
    if (d.slot >= slots_.size()) return fail("slot " + std::to_string(d.slot) + " out of range");
    if (slot_busy_[d.slot]) return fail("node " + key_name(k) + " delivered into occupied slot " + std::to_string(d.slot));
    if (slot_evicted_frame_[d.slot] != 0) {
      if (u.frame < slot_evicted_frame_[d.slot] + cfg.fence_frames)
        return fail("slot " + std::to_string(d.slot) + " evicted in frame " + std::to_string(slot_evicted_frame_[d.slot]) +
                    " reused before its fence (" + std::to_string(cfg.fence_frames) + " frames)");
      ++slot_reuses_;
    }
    if (d.key.level < top_ && !resident_.count(key_of(parent_of(d.key))))
      return fail("node " + key_name(k) + " delivered before its parent");
    if (!d.record || !(d.record->key == d.key)) return fail("delivery of " + key_name(k) + " carries the wrong record");
    if (!d.data) return fail("delivery of " + key_name(k) + " has no data");
    if (check_markers_ && !synthetic::key_marker_matches(*d.data, d.key))
      return fail("delivered data of " + key_name(k) + " belongs to another node");
    if (failure_count_.count(k)) return fail("failed node " + key_name(k) + " delivered");
    resident_[k] = d.slot;
    data_[k] = d.data;
    slot_busy_[d.slot] = 1;
    ++deliveries_;
  }

  for (const NodeFailure& f : u.failed) {
    const Key k = key_of(f.key);
    if (++failure_count_[k] > 1) return fail("failure of " + key_name(k) + " reported twice");
    failure_statuses_.push_back(f);
    if (f.status.ok()) return fail("failure of " + key_name(k) + " carries an ok status");
    if (resident_.count(k)) return fail("failed node " + key_name(k) + " is resident");
  }

  for (size_t i = 0; i < u.dirty_slots.size(); ++i) {
    if (i > 0 && u.dirty_slots[i] <= u.dirty_slots[i - 1]) return fail("dirty slots not ascending");
    slots_[u.dirty_slots[i]] = streamer_.slots()[u.dirty_slots[i]];
  }
  for (const NodeDelivery& d : u.delivered)
    if (!std::binary_search(u.dirty_slots.begin(), u.dirty_slots.end(), d.slot))
      return fail("slot " + std::to_string(d.slot) + " delivered but not marked dirty");
  if (std::string problem = check_index(u); !problem.empty()) return fail(problem);

  // Resident set, roots, parents, budget, descriptors, data lifetime.
  const std::vector<NodeKey> listed = streamer_.resident_nodes();
  if (listed.size() != resident_.size())
    return fail("resident_nodes() lists " + std::to_string(listed.size()) + " nodes, deliveries minus evictions give " +
                std::to_string(resident_.size()));
  for (const NodeKey& k : listed)
    if (!resident_.count(key_of(k))) return fail("resident_nodes() lists " + key_name(key_of(k)) + " which was never delivered");
  if (resident_.size() > cfg.budget_nodes) return fail(std::to_string(resident_.size()) + " resident nodes exceed the budget");
  for (const Key& r : roots_)
    if (!resident_.count(r)) return fail("top node " + key_name(r) + " is not resident");
  const StreamerStats st = streamer_.stats();
  if (st.resident != resident_.size()) return fail("stats().resident disagrees");
  for (const auto& [k, slot] : resident_) {
    const NodeKey nk = node_key(k);
    if (nk.level < top_ && !resident_.count(key_of(parent_of(nk))))
      return fail("node " + key_name(k) + " is resident without its parent");
    if (streamer_.slot_of(nk) != slot) return fail("slot_of(" + key_name(k) + ") disagrees");
    const NodeRecord& r = reader_.nodes()[size_t(reader_.find(nk))];
    const SlotDescriptor& d = slots_[slot];
    if (d.min_height != r.min_height || d.max_height != r.max_height || d.height_offset != r.height_offset ||
        d.geometric_error_m != r.geometric_error_m || d.x != nk.x || d.y != nk.y || d.level != nk.level ||
        d.step_log2 != level_step_log2(reader_.world(), int(nk.level)) || d.flags != r.flags || d.child_mask != r.child_mask)
      return fail("slot " + std::to_string(slot) + " descriptor does not describe " + key_name(k));
    const NodeData* data = streamer_.resident_data(nk);
    if (data != data_[k]) return fail("resident_data(" + key_name(k) + ") moved while resident");
    if (check_markers_ && !synthetic::key_marker_matches(*data, nk))
      return fail("data of resident node " + key_name(k) + " was overwritten while resident");
  }
  return "";
}

std::string settle(Streamer& streamer, StreamChecker& checker, std::span<const View> views, double timeout_s, int* frames) {
  const auto start = std::chrono::steady_clock::now();
  for (int frame = 0;; ++frame) {
    const FrameUpdate& u = streamer.update(views);
    if (std::string e = checker.check(u); !e.empty()) return e;
    if (streamer.stats().wanted_missing == 0) {
      if (frames) *frames = frame + 1;
      return "";
    }
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() > timeout_s)
      return "not settled after " + std::to_string(timeout_s) + " s: " + std::to_string(streamer.stats().wanted_missing) +
             " wanted nodes missing";
    std::this_thread::sleep_for(std::chrono::microseconds(300));
  }
}

std::string settle_and_compare(Streamer& streamer, StreamChecker& checker, std::span<const View> views) {
  if (std::string e = settle(streamer, checker, views); !e.empty()) return e;
  std::set<Key> required;
  const std::set<Key> reference = reference_wanted(streamer.archive(), streamer.config(), views, checker.failed_set(), &required);
  std::set<Key> wanted;
  for (const NodeKey& k : streamer.wanted_nodes()) wanted.insert(key_of(k));
  std::set<Key> req_streamer;
  for (const NodeKey& k : streamer.required_nodes()) req_streamer.insert(key_of(k));
  const std::set<Key> resident = checker.resident_set();
  auto diff = [](const std::set<Key>& a, const std::set<Key>& b) {
    std::string s;
    int n = 0;
    for (const Key& k : a)
      if (!b.count(k) && n++ < 5) {
        s += ' ';
        s += key_name(k);
      }
    return s;
  };
  if (resident != reference)
    return "settled resident set (" + std::to_string(resident.size()) + ") != reference wanted set (" +
           std::to_string(reference.size()) + "); resident only:" + diff(resident, reference) +
           "; reference only:" + diff(reference, resident);
  if (wanted != reference) return "streamer's wanted_nodes() != reference";
  if (req_streamer != required) return "streamer's required_nodes() != reference required set";
  return "";
}

}  // namespace terrain::test
