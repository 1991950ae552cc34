#include "sources.h"

#include <algorithm>
#include <climits>
#include <cstdio>
#include <map>

#include "terrain/archive_reader.h"
#include "terrain/remote_source.h"

namespace terrain::view {
namespace {

class StreamSource final : public NodeSource {
 public:
  Status open(const std::string& path, const StreamSourceOptions& o) {
    StreamerConfig config;
    config.budget_nodes = o.budget_nodes;
    config.error_target_px = o.error_target_px;
    config.worker_threads = o.worker_threads;
    config.max_deliveries_per_frame = std::max(o.max_deliveries_per_frame, 1u);
    ArchiveReader reader;  // opened once: the streamer takes it over
    TERRAIN_TRY(open_archive(reader, path, o.http));
    {
      // The streamer keeps the top level resident: at most 16 overview nodes (format/SPEC.md
      // section 19), or every root of an archive without overview levels. Budget 0 (the default)
      // = 512, raised for such an archive to its roots + 512 so that it opens too.
      const uint64_t roots = uint64_t(reader.world().roots_x) * reader.world().roots_y;
      const bool overview = reader.top_level() > kRootLevel;
      if (o.budget_nodes == 0)
        config.budget_nodes = overview ? 512u : uint32_t(std::min<uint64_t>(std::max<uint64_t>(512, roots + 512), kMaxSlots));
      else if (!overview && o.budget_nodes < roots)
        return Status::failure(Error::invalid_argument,
                               "--budget " + std::to_string(o.budget_nodes) + " is smaller than the archive's " +
                                   std::to_string(roots) + " roots, which stay resident (it has no overview levels, "
                                   "format/SPEC.md section 19): use --budget " + std::to_string(roots) + " or more, or 0");
    }
    return streamer_.open(std::move(reader), config);
  }
  const WorldInfo& world() const override { return streamer_.world(); }
  uint32_t slot_count() const override { return streamer_.slot_count(); }
  void height_range(int32_t& lo, int32_t& hi) const override {
    lo = INT32_MAX;
    hi = INT32_MIN;
    for (const NodeRecord& r : streamer_.archive().nodes())
      if (r.key.level == uint32_t(kRootLevel)) {
        lo = std::min(lo, r.min_height);
        hi = std::max(hi, r.max_height);
      }
    if (lo > hi) lo = hi = 0;
  }
  Status update(const Camera& camera, const FrameUniforms& u, TerrainState& state,
                std::vector<NodeUpload>& uploads) override {
    if (!initialised_) {
      state.init(streamer_.world(), streamer_.slot_count());
      for (const NodeRecord& r : streamer_.archive().nodes())
        if (r.key.level == uint32_t(kRootLevel)) state.set_node(r.key, uint16_t(TV_SLOT_EMPTY));
      initialised_ = true;
    }
    View v;
    v.x = camera.position[0];
    v.y = camera.position[1];
    v.z = camera.position[2];
    v.pixels_per_radian = double(u.cam_frac[3]);
    v.has_frustum = true;
    for (int p = 0; p < 6; ++p)
      v.frustum[size_t(p)] = {double(u.planes[p][0]), double(u.planes[p][1]), double(u.planes[p][2]), double(u.planes[p][3])};
    const FrameUpdate& fu = streamer_.update({&v, 1});
    last_ = {};
    for (const NodeFailure& f : fu.failed)
      std::fprintf(stderr, "terrain-view: node %u/%u/%u failed to load: %s\n", f.key.level, f.key.x, f.key.y,
                   f.status.message.c_str());
    // Descriptors first (the upload computes patch bounds with the slot's quantization).
    for (uint16_t s : fu.dirty_slots) state.set_slot(s, streamer_.slots()[s]);
    for (const NodeDelivery& d : fu.delivered) uploads.push_back({d.slot, d.data});
    // The residency index: the streamer's class, filled here from the same events as the streamer's
    // own (the state also serves the load-everything source and the tests, which have no streamer):
    // children out before parents, parents in before children.
    for (const NodeEviction& e : fu.evicted) state.set_node(e.key, uint16_t(TV_SLOT_EMPTY));
    for (const NodeFailure& f : fu.failed) state.set_node(f.key, uint16_t(TV_SLOT_INVALID));
    for (const NodeDelivery& d : fu.delivered) state.set_node(d.key, d.slot);
    const StreamerStats st = streamer_.stats();
    last_.resident = st.resident;
    last_.delivered = uint32_t(fu.delivered.size());
    last_.evicted = uint32_t(fu.evicted.size());
    last_.failed = st.failed;
    last_.pending = st.pending;
    last_.required_missing = st.required_missing;
    return Status::success();
  }
  bool settled() const override { return last_.pending == 0 && last_.required_missing == 0; }
  SourceStats stats() const override { return last_; }
  const NodeData* slot_data(uint32_t slot) const override {
    if (slot >= streamer_.slot_count()) return nullptr;
    const SlotDescriptor& d = streamer_.slots()[slot];
    const NodeData* data = streamer_.resident_data(NodeKey{d.level, d.x, d.y});
    return streamer_.slot_of(NodeKey{d.level, d.x, d.y}) == int32_t(slot) ? data : nullptr;
  }

 private:
  Streamer streamer_;
  bool initialised_ = false;
  SourceStats last_;
};

class LoadAllSource final : public NodeSource {
 public:
  Status open(const std::string& path, uint32_t max_nodes) {
    TERRAIN_TRY(open_archive(reader_, path));
    const auto nodes = reader_.nodes();
    if (nodes.size() > max_nodes)
      return Status::failure(Error::invalid_argument,
                             path + " has " + std::to_string(nodes.size()) + " nodes; --load-all keeps at most " +
                                 std::to_string(max_nodes) + " (use the streamer instead)");
    data_.resize(nodes.size());
    std::vector<MemoryNode> memory;
    for (size_t i = 0; i < nodes.size(); ++i) {
      TERRAIN_TRY(reader_.decode_node(i, data_[i]));
      memory.push_back({nodes[i], &data_[i]});
    }
    memory_ = std::move(memory);
    return Status::success();
  }
  const WorldInfo& world() const override { return reader_.world(); }
  uint32_t slot_count() const override { return uint32_t(std::max<size_t>(data_.size(), 1)); }
  void height_range(int32_t& lo, int32_t& hi) const override {
    lo = INT32_MAX;
    hi = INT32_MIN;
    for (const NodeRecord& r : reader_.nodes())
      if (r.key.level == uint32_t(kRootLevel)) {
        lo = std::min(lo, r.min_height);
        hi = std::max(hi, r.max_height);
      }
    if (lo > hi) lo = hi = 0;
  }
  Status update(const Camera&, const FrameUniforms&, TerrainState& state, std::vector<NodeUpload>& uploads) override {
    if (initialised_) return Status::success();
    initialised_ = true;
    residency_.init(reader_.world(), memory_, slot_count(), state);
    Status s = residency_.apply([](const NodeKey&) { return true; }, state, uploads);
    for (const NodeUpload& u : uploads) slot_node_[u.slot] = u.data;
    return s;
  }
  bool settled() const override { return initialised_; }
  SourceStats stats() const override {
    SourceStats s;
    s.resident = residency_.resident_count();
    return s;
  }
  const NodeData* slot_data(uint32_t slot) const override {
    auto it = slot_node_.find(slot);
    return it == slot_node_.end() ? nullptr : it->second;
  }

 private:
  ArchiveReader reader_;
  std::vector<NodeData> data_;
  std::vector<MemoryNode> memory_;
  StaticResidency residency_;
  std::map<uint32_t, const NodeData*> slot_node_;
  bool initialised_ = false;
};

}  // namespace

Status open_stream_source(const std::string& archive, const StreamSourceOptions& options, std::unique_ptr<NodeSource>& out) {
  auto s = std::make_unique<StreamSource>();
  TERRAIN_TRY(s->open(archive, options));
  out = std::move(s);
  return Status::success();
}

Status open_load_all_source(const std::string& archive, uint32_t max_nodes, std::unique_ptr<NodeSource>& out) {
  auto s = std::make_unique<LoadAllSource>();
  TERRAIN_TRY(s->open(archive, max_nodes));
  out = std::move(s);
  return Status::success();
}

}  // namespace terrain::view
