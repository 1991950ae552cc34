#include "terrain/streamer.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <queue>
#include <thread>
#include <unordered_map>

#include "load_queue.h"
#include "resident_surface.h"
#include "terrain/queries.h"
#include "terrain/remote_source.h"
#include "wanted_set.h"

namespace terrain {

double pixels_per_radian(double viewport_px, double fov_rad) { return 0.5 * viewport_px / std::tan(0.5 * fov_rad); }

namespace {

// Life of a node on the owner's thread.
enum class Phase : uint8_t {
  idle,       // not resident, no request outstanding
  requested,  // in the published request list or taken by a worker
  decoded,    // decoded, waiting for delivery (holds a buffer, counts as in flight)
  resident,
  failed,
};

uint64_t raw_section_bytes(unsigned sections) {
  uint64_t bytes = 0;
  if (sections & kSectionHeights) bytes += sizeof(NodeData::heights);
  if (sections & kSectionNormals) bytes += sizeof(NodeData::normals_bc3);
  if (sections & kSectionAlbedo) bytes += sizeof(NodeData::albedo_bc1);
  if (sections & kSectionSplat) bytes += sizeof(NodeData::splat);
  if (sections & kSectionCones) bytes += sizeof(NodeData::cones_bc3);
  return bytes;
}

}  // namespace

namespace detail {
WantedParams make_wanted_params(const StreamerConfig& c, uint32_t tops) {
  WantedParams p;
  p.budget_nodes = c.budget_nodes;
  p.error_target_px = c.error_target_px;
  p.prefetch_ratio = c.prefetch_ratio;
  p.required_budget = std::max(tops, uint32_t(std::floor(double(c.budget_nodes) * (1.0 - c.prefetch_reserve))));
  p.default_pixels_per_radian = c.default_pixels_per_radian;
  p.outside_frustum_error_scale = c.outside_frustum_error_scale;
  return p;
}
}  // namespace detail

struct Streamer::Impl {
  ArchiveReader reader;
  StreamerConfig config;
  detail::WantedParams wanted_params;
  detail::NodeTree tree;
  std::span<const NodeRecord> records;
  std::unique_ptr<detail::LoadQueue> loader;

  // Per node (directory index), owner's thread only.
  std::vector<Phase> phase;
  std::vector<uint16_t> slot_of;
  std::vector<NodeData*> data;
  std::vector<uint8_t> in_set;           // kWanted | kRequired: in the current wanted / required set
  std::vector<uint32_t> order;           // position in the current wanted set (priority rank)
  std::vector<uint8_t> failed;
  static constexpr uint8_t kWanted = 1, kRequired = 2;

  // GPU-side state.
  ResidencyIndex index;
  ResidencyChanges index_changes;  // the last update()'s, behind FrameUpdate::dirty_children
  std::vector<SlotDescriptor> slot_table;
  std::vector<int32_t> slot_owner;  // node index or -1
  std::priority_queue<uint16_t, std::vector<uint16_t>, std::greater<>> free_slots;  // lowest first
  struct Fenced {
    uint16_t slot;
    uint64_t free_at_frame;
  };
  std::vector<Fenced> fenced;  // in eviction order, so free_at_frame ascending

  // Work lists.
  std::vector<detail::WantedNode> wanted;
  std::vector<uint32_t> resident;  // directory indices
  std::vector<uint32_t> decoded;   // nodes in Phase::decoded
  uint32_t top_count = 0;  // nodes of the archive's top level: always resident
  detail::SurfacePublisher surfaces;  // terrain/queries.h: snapshots of the resident surface

  // Per-frame output.
  uint64_t frame = 0;
  std::vector<NodeDelivery> deliveries;
  std::vector<NodeEviction> evictions;
  std::vector<NodeFailure> failures;
  std::vector<uint16_t> dirty_slots;
  FrameUpdate update;
  std::vector<View> last_views;
  bool have_views = false;
  // Results consumed this update; their in-flight room is given back only after the new request
  // list is published, so workers never take a stale request in between.
  uint32_t to_release = 0;
  // Query surfaces the workers made for decoded nodes not yet delivered (at most the loads in
  // flight): linked into the snapshot at delivery, dropped with the node's data.
  std::unordered_map<uint32_t, std::shared_ptr<const detail::NodeSurface>> decoded_surfaces;
  std::vector<NodeData*> to_free;  // buffers to give back, in one lock at the end of update()

  // Counters.
  StreamerStats stats;
  uint64_t loads_delivered = 0, loads_discarded = 0, requests_dropped = 0, bytes_decoded = 0;
  uint64_t failed_count = 0;

  ~Impl() {
    loader.reset();  // joins workers before buffers and the reader go away
  }

  Status validate_config(uint32_t tops, int top, bool remote) {
    StreamerConfig& c = config;
    auto bad = [](const std::string& what) { return Status::failure(Error::invalid_argument, "streamer config: " + what); };
    if (c.budget_nodes < 1 || c.budget_nodes > kMaxSlots)
      return bad("budget_nodes " + std::to_string(c.budget_nodes) + " is outside 1.." + std::to_string(kMaxSlots));
    if (c.budget_nodes < tops)
      return bad("budget_nodes " + std::to_string(c.budget_nodes) + " is smaller than the archive's " + std::to_string(tops) +
                 (top == kRootLevel ? " roots (level 5 nodes, no overview levels above them: format/SPEC.md section 19)"
                                    : " top-level nodes (level " + std::to_string(top) + ")") +
                 ", which are always resident; raise budget_nodes to at least " + std::to_string(tops));
    if (c.fence_frames < 1) return bad("fence_frames must be at least 1");
    if (c.max_deliveries_per_frame < 1) return bad("max_deliveries_per_frame must be at least 1");
    if (!(c.error_target_px > 0) || !std::isfinite(c.error_target_px))
      return bad("error_target_px must be a positive number of pixels");
    if (!(c.prefetch_ratio > 0 && c.prefetch_ratio <= 1)) return bad("prefetch_ratio must be in (0, 1]");
    if (!(c.prefetch_reserve >= 0 && c.prefetch_reserve < 1)) return bad("prefetch_reserve must be in [0, 1)");
    if (!(c.default_pixels_per_radian > 0) || !std::isfinite(c.default_pixels_per_radian))
      return bad("default_pixels_per_radian must be positive");
    if (!(c.outside_frustum_error_scale >= 0 && c.outside_frustum_error_scale <= 1))
      return bad("outside_frustum_error_scale must be in [0, 1]");
    if (c.sections == 0 || (c.sections & ~unsigned(kSectionAll)) != 0)
      return bad("sections must be a non-empty set of terrain::Section bits");
    if (c.worker_threads == 0) c.worker_threads = std::max(1u, std::thread::hardware_concurrency());
    if (c.worker_threads > 256) return bad("worker_threads above 256");
    if (c.slot_count == 0) {
      const uint64_t automatic = uint64_t(c.budget_nodes) + uint64_t(c.fence_frames) * c.max_deliveries_per_frame;
      c.slot_count = uint32_t(std::min<uint64_t>(automatic, kMaxSlots));
    }
    if (c.slot_count < c.budget_nodes || c.slot_count > kMaxSlots)
      return bad("slot_count " + std::to_string(c.slot_count) + " must be in budget_nodes.." + std::to_string(kMaxSlots));
    if (c.max_in_flight == 0) c.max_in_flight = std::max(2 * c.worker_threads, c.budget_nodes / 32);
    if (c.max_fetches == 0) c.max_fetches = remote ? kRemoteFetches : c.worker_threads;
    if (c.max_fetches > 256) return bad("max_fetches above 256");
    return Status::success();
  }

  Status open(ArchiveReader&& opened, const StreamerConfig& cfg) {
    config = cfg;
    reader = std::move(opened);
    if (!reader.is_open()) return Status::failure(Error::invalid_argument, "streamer: the archive reader is not open");
    const std::string path = reader.source()->name();
    HttpStats http;
    const bool remote = http_stats(*reader.source(), http);
    records = reader.nodes();
    const WorldInfo& world = reader.world();
    if (world.roots_x == 0 || world.roots_y == 0 || world.roots_x > kStreamerMaxRootsPerSide ||
        world.roots_y > kStreamerMaxRootsPerSide)
      return Status::failure(Error::unsupported_input,
                             "streamer: " + path + ": root grid " + std::to_string(world.roots_x) + "x" +
                                 std::to_string(world.roots_y) + " is outside the streamer's 1.." +
                                 std::to_string(kStreamerMaxRootsPerSide) +
                                 " roots per side (format/SPEC.md section 12)");
    tree = detail::build_node_tree(reader);
    top_count = uint32_t(tree.tops.size());
    if (top_count == 0) return Status::failure(Error::no_data, "streamer: " + path + " has no root nodes");
    TERRAIN_TRY(validate_config(top_count, reader.top_level(), remote));
    wanted_params = detail::make_wanted_params(config, top_count);

    const size_t n = records.size();
    phase.assign(n, Phase::idle);
    slot_of.assign(n, 0);
    data.assign(n, nullptr);
    in_set.assign(n, 0);
    order.assign(n, 0);
    failed.assign(n, 0);

    index.init(world, config.slot_count);
    for (const NodeRecord& r : records)
      if (r.key.level == uint32_t(kRootLevel)) index.set_node(r.key, kIndexNotResident);
    slot_table.assign(config.slot_count, SlotDescriptor{});
    slot_owner.assign(config.slot_count, -1);
    for (uint32_t s = 0; s < config.slot_count; ++s) free_slots.push(uint16_t(s));

    // Top nodes (roots without overview levels): loaded by the workers while this thread waits
    // (it never decodes).
    loader = std::make_unique<detail::LoadQueue>(reader, config.sections, config.max_fetches, config.worker_threads,
                                                 config.budget_nodes + config.max_in_flight);
    std::vector<uint32_t> dropped;
    loader->publish(tree.tops, dropped);
    for (uint32_t r : tree.tops) phase[r] = Phase::requested;
    std::vector<detail::LoadQueue::Result> results;
    uint32_t done = 0;
    std::optional<Status> first_error;
    while (done < top_count) {
      results.clear();
      loader->collect(results, /*wait=*/true);
      for (auto& r : results) {
        ++done;
        if (!r.status.ok()) {
          loader->free_buffers({&r.data, 1});
          loader->release(1);
          if (!first_error)
            first_error = Status::failure(r.status.code, std::string("streamer: ") +
                                                             (reader.top_level() == kRootLevel ? "root node " : "top node ") +
                                                             node_name(records[r.node].key) +
                                                             " cannot be loaded (top nodes are always resident): " +
                                                             r.status.to_string());
          continue;
        }
        phase[r.node] = Phase::decoded;
        data[r.node] = r.data;
        if (r.surface) decoded_surfaces[r.node] = std::move(r.surface);
        decoded.push_back(r.node);
        bytes_decoded += raw_section_bytes(config.sections);
      }
    }
    if (first_error) return *first_error;
    fill_stats();  // stats() after open() counts the top nodes' loads
    return Status::success();
  }

  void release_fenced() {
    size_t i = 0;
    while (i < fenced.size() && fenced[i].free_at_frame <= frame) free_slots.push(fenced[i++].slot);
    fenced.erase(fenced.begin(), fenced.begin() + ptrdiff_t(i));
  }

  void collect_results() {
    std::vector<detail::LoadQueue::Result> results;
    loader->collect(results, /*wait=*/false);
    for (auto& r : results) {
      if (r.status.code == Error::cancelled) {  // no longer wanted when its read was stopped: not a failure
        ++to_release;
        phase[r.node] = Phase::idle;
        continue;
      }
      if (!r.status.ok()) {
        to_free.push_back(r.data);
        ++to_release;
        phase[r.node] = Phase::failed;
        failed[r.node] = 1;
        ++failed_count;
        index.set_node(records[r.node].key, kIndexNoNode);
        failures.push_back({records[r.node].key, std::move(r.status)});
        continue;
      }
      phase[r.node] = Phase::decoded;
      data[r.node] = r.data;
      if (r.surface) decoded_surfaces[r.node] = std::move(r.surface);
      decoded.push_back(r.node);
      bytes_decoded += raw_section_bytes(config.sections);
    }
  }

  void compute_wanted(std::span<const View> views) {
    if (!views.empty()) {
      last_views.assign(views.begin(), views.end());
      have_views = true;
    }
    for (const detail::WantedNode& w : wanted) in_set[w.index] = 0;  // the previous set: O(wanted), not O(nodes)
    detail::compute_wanted_set(tree, failed, have_views ? std::span<const View>(last_views) : std::span<const View>(),
                               wanted_params, wanted);
    for (uint32_t i = 0; i < wanted.size(); ++i) {
      const uint32_t node = wanted[i].index;
      in_set[node] = uint8_t(kWanted | (wanted[i].required ? kRequired : 0));
      order[node] = i;
    }
  }

  bool is_wanted(uint32_t node) const { return in_set[node] & kWanted; }

  // The wanted nodes of `nodes`, in order; `drop(node)` is called for each of the others.
  template <class Drop>
  std::vector<uint32_t> keep_wanted(const std::vector<uint32_t>& nodes, Drop&& drop) const {
    std::vector<uint32_t> kept;
    kept.reserve(nodes.size());
    for (uint32_t node : nodes) {
      if (is_wanted(node))
        kept.push_back(node);
      else
        drop(node);
    }
    return kept;
  }

  // Gives a node's decoded data back (at the end of update()); the node becomes idle.
  void release_data(uint32_t node) {
    to_free.push_back(data[node]);
    data[node] = nullptr;
    phase[node] = Phase::idle;
    decoded_surfaces.erase(node);
  }

  void evict_unwanted() {
    // Directory order is level ascending, so children go before their parents.
    std::sort(resident.begin(), resident.end());
    resident = keep_wanted(resident, [&](uint32_t node) {
      const uint16_t slot = slot_of[node];
      index.set_node(records[node].key, kIndexNotResident);
      slot_owner[slot] = -1;
      fenced.push_back({slot, frame + config.fence_frames});
      release_data(node);
      surfaces.remove(node);
      evictions.push_back({records[node].key, slot});
    });
  }

  void deliver() {
    // Discard what is no longer wanted, then deliver in priority order (parents first).
    std::vector<uint32_t> waiting = keep_wanted(decoded, [&](uint32_t node) {
      release_data(node);
      ++loads_discarded;
      ++to_release;
    });
    std::sort(waiting.begin(), waiting.end(), [&](uint32_t a, uint32_t b) { return order[a] < order[b]; });
    const uint32_t cap = frame == 1 ? std::max(config.max_deliveries_per_frame, top_count)
                                    : config.max_deliveries_per_frame;
    decoded.clear();
    for (uint32_t node : waiting) {
      const int32_t parent = tree.nodes[node].parent;
      const bool parent_ok = parent < 0 || phase[size_t(parent)] == Phase::resident;
      if (deliveries.size() >= cap || !parent_ok || free_slots.empty() || resident.size() >= config.budget_nodes) {
        decoded.push_back(node);
        continue;
      }
      const uint16_t slot = free_slots.top();
      free_slots.pop();
      const NodeRecord& r = records[node];
      slot_table[slot] = slot_descriptor_of(r, reader.world());
      slot_owner[slot] = int32_t(node);
      slot_of[node] = slot;
      phase[node] = Phase::resident;
      resident.push_back(node);
      index.set_node(r.key, slot, r.child_mask);
      dirty_slots.push_back(slot);
      deliveries.push_back({r.key, slot, &records[node], data[node]});
      if (config.sections & kSectionHeights) {
        const auto it = decoded_surfaces.find(node);
        if (it != decoded_surfaces.end()) {
          surfaces.add(node, std::move(it->second));
          decoded_surfaces.erase(it);
        } else {
          surfaces.add(node, detail::make_node_surface(reader, node, *data[node], (config.sections & kSectionAlbedo) != 0));
        }
      }
      ++loads_delivered;
      ++to_release;
    }
    std::sort(dirty_slots.begin(), dirty_slots.end());
  }

  void request() {
    std::vector<uint32_t> requests;
    for (const detail::WantedNode& w : wanted) {
      const Phase p = phase[w.index];
      if (p == Phase::idle || p == Phase::requested) requests.push_back(w.index);
    }
    std::vector<uint32_t> dropped;
    loader->publish(requests, dropped);
    for (uint32_t node : requests)
      if (phase[node] == Phase::idle) phase[node] = Phase::requested;
    for (uint32_t node : dropped) phase[node] = Phase::idle;
    requests_dropped += dropped.size();
  }

  void fill_stats() {
    StreamerStats s;
    s.frame = frame;
    s.resident = uint32_t(resident.size());
    s.wanted = uint32_t(wanted.size());
    for (const detail::WantedNode& w : wanted) {
      const bool missing = phase[w.index] != Phase::resident;
      s.wanted_missing += missing;
      if (w.required) {
        ++s.required;
        s.required_missing += missing;
      }
    }
    s.pending = s.wanted_missing;
    s.failed = uint32_t(failed_count);
    s.fenced_slots = uint32_t(fenced.size());
    s.free_slots = uint32_t(free_slots.size());
    const detail::LoadQueue::Counters c = loader->counters();
    s.in_flight = c.in_flight;
    s.loads_started = c.loads_started;
    s.loads_delivered = loads_delivered;
    s.loads_discarded = loads_discarded;
    s.requests_dropped = requests_dropped;
    s.fetches = c.fetches;
    s.reads_cancelled = c.reads_cancelled;
    s.fetch_seconds = c.fetch_seconds;
    s.bytes_read = c.bytes_read;
    s.bytes_decoded = bytes_decoded;
    s.decode_seconds = c.decode_seconds;
    s.decode_cpu_seconds = c.decode_cpu_seconds;
    s.buffer_bytes = c.buffers_allocated * sizeof(NodeData);
    stats = s;
  }

  const FrameUpdate& run_update(std::span<const View> views) {
    ++frame;
    deliveries.clear();
    evictions.clear();
    failures.clear();
    dirty_slots.clear();
    update = FrameUpdate{};
    update.frame = frame;

    release_fenced();
    collect_results();
    compute_wanted(views);
    request();  // before anything frees in-flight room: see to_release
    evict_unwanted();
    deliver();
    // Decode buffers: resident + in flight <= budget + max_in_flight. Wanted nodes never exceed the
    // budget, so within that bound workers may decode far ahead of the per-frame delivery cap.
    // Buffers go back to the pool before the room opens, so no worker allocates in between.
    loader->free_buffers(to_free);
    to_free.clear();
    loader->set_capacity(config.budget_nodes + config.max_in_flight - uint32_t(resident.size()));
    loader->release(to_release);
    to_release = 0;
    fill_stats();
    surfaces.publish(frame, reader);

    update.delivered = deliveries;
    update.evicted = evictions;
    update.failed = failures;
    update.dirty_slots = dirty_slots;
    // The index's changes since the previous update(): on the first, all of it (init()).
    index.take_changes(index_changes);
    update.dirty_roots = index_changes.roots;
    update.dirty_starts = index_changes.starts;
    update.dirty_children = index_changes.children;
    return update;
  }
};

Streamer::Streamer() = default;
Streamer::~Streamer() = default;

Status Streamer::open(const std::string& archive_path, const StreamerConfig& config) {
  close();
  ArchiveReader reader;
  TERRAIN_TRY(open_archive(reader, archive_path));
  return open(std::move(reader), config);
}

Status Streamer::open(ArchiveReader&& reader, const StreamerConfig& config) {
  close();
  auto impl = std::make_unique<Impl>();
  TERRAIN_TRY(impl->open(std::move(reader), config));
  impl_ = std::move(impl);
  return Status::success();
}

void Streamer::close() { impl_.reset(); }
bool Streamer::is_open() const { return impl_ != nullptr; }

// A closed streamer answers with empty state instead of crashing.
namespace {
const FrameUpdate kNoUpdate{};
const ArchiveReader kNoArchive{};
const WorldInfo kNoWorld{};
const StreamerConfig kNoConfig{};
const ResidencyIndex kNoIndex{};
}  // namespace

const FrameUpdate& Streamer::update(std::span<const View> views) { return impl_ ? impl_->run_update(views) : kNoUpdate; }

const ArchiveReader& Streamer::archive() const { return impl_ ? impl_->reader : kNoArchive; }
const WorldInfo& Streamer::world() const { return impl_ ? impl_->reader.world() : kNoWorld; }
const StreamerConfig& Streamer::config() const { return impl_ ? impl_->config : kNoConfig; }
uint32_t Streamer::slot_count() const { return impl_ ? impl_->config.slot_count : 0; }

const ResidencyIndex& Streamer::residency() const { return impl_ ? impl_->index : kNoIndex; }

std::span<const SlotDescriptor> Streamer::slots() const {
  if (!impl_) return {};
  return impl_->slot_table;
}
StreamerStats Streamer::stats() const { return impl_ ? impl_->stats : StreamerStats{}; }
ResidentSurface Streamer::resident_surface() const {
  return impl_ ? ResidentSurface(impl_->surfaces.latest()) : ResidentSurface{};
}

NodeState Streamer::node_state(const NodeKey& key) const {
  if (!impl_) return NodeState::absent;
  const int64_t index = impl_->reader.find(key);
  if (index < 0) return NodeState::absent;
  switch (impl_->phase[size_t(index)]) {
    case Phase::resident: return NodeState::resident;
    case Phase::failed: return NodeState::failed;
    case Phase::requested:
    case Phase::decoded: return impl_->is_wanted(uint32_t(index)) ? NodeState::pending : NodeState::idle;
    case Phase::idle: break;
  }
  return impl_->is_wanted(uint32_t(index)) ? NodeState::pending : NodeState::idle;
}

int32_t Streamer::slot_of(const NodeKey& key) const {
  if (!impl_) return -1;
  const int64_t index = impl_->reader.find(key);
  if (index < 0 || impl_->phase[size_t(index)] != Phase::resident) return -1;
  return impl_->slot_of[size_t(index)];
}

const NodeData* Streamer::resident_data(const NodeKey& key) const {
  if (!impl_) return nullptr;
  const int64_t index = impl_->reader.find(key);
  if (index < 0 || impl_->phase[size_t(index)] != Phase::resident) return nullptr;
  return impl_->data[size_t(index)];
}

namespace {
std::vector<NodeKey> keys_where(std::span<const NodeRecord> records, const std::function<bool(uint32_t)>& pred) {
  std::vector<NodeKey> keys;
  for (uint32_t i = 0; i < records.size(); ++i)
    if (pred(i)) keys.push_back(records[i].key);
  return keys;
}
}  // namespace

std::vector<NodeKey> Streamer::resident_nodes() const {
  if (!impl_) return {};
  return keys_where(impl_->records, [&](uint32_t i) { return impl_->phase[i] == Phase::resident; });
}
std::vector<NodeKey> Streamer::wanted_nodes() const {
  if (!impl_) return {};
  return keys_where(impl_->records, [&](uint32_t i) { return impl_->is_wanted(i); });
}
std::vector<NodeKey> Streamer::required_nodes() const {
  if (!impl_) return {};
  return keys_where(impl_->records, [&](uint32_t i) { return (impl_->in_set[i] & Impl::kRequired) != 0; });
}

}  // namespace terrain
