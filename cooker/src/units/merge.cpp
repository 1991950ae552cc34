#include "units/merge.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <map>
#include <memory>
#include <fmt/format.h>

#include "pyramid/node_spool.h"
#include "pyramid/overview_levels.h"
#include "session/cook_session.h"
#include "terrain/archive_writer.h"
#include "terrain/bc_decode.h"
#include "terrain/cpu_clock.h"
#include "terrain/detail/bytes.h"  // format/internal: CRC-32
#include "terrain/output_paths.h"
#include "terrain/surface_contract.h"
#include "units/file_io.h"
#include "units/plan_file.h"
#include "units/unit_file.h"
#include "units/work_dir.h"

namespace terrain::cook {
namespace {

// A unit's place in the merge, from its checked head: what the copy needs, not its node table.
struct MergeUnit {
  uint32_t crc = 0, stored_crc = 0;  // running CRC-32 of the bytes copied so far, the trailer's
  uint64_t nodes = 0, left = 0;      // nodes in the file, nodes not copied yet
  std::array<uint64_t, kLevelCount> level_begin{};    // table index of each level's first node
  std::array<uint64_t, kLevelCount> level_nodes{};    // and its node count
  std::array<uint64_t, kLevelCount> level_payload{};  // file offset of each level's first payload
  std::array<uint64_t, kLevelCount> level_bytes{};    // and its payload bytes
};

// A read buffer kept across the bands and levels of a merge (fresh megabytes per cursor cost page
// faults: more system time than the copy itself).
struct ReadBuffer {
  std::unique_ptr<uint8_t[]> data;  // uninitialised: zeroing it per refill would cost as much
  size_t capacity = 0;
};

// Reads one unit's nodes of one level in table order, table and payloads in large sequential reads.
class LevelCursor {
 public:
  LevelCursor(int fd, const std::string& path, const MergeUnit& u, int level, size_t chunk, ReadBuffer& buf)
      : fd_(fd), path_(path), buf_(buf), next_(u.level_begin[size_t(level)]),
        end_(u.level_begin[size_t(level)] + u.level_nodes[size_t(level)]),
        payload_at_(u.level_payload[size_t(level)]),
        payload_end_(u.level_payload[size_t(level)] + u.level_bytes[size_t(level)]), chunk_(chunk) {}
  bool done() const { return next_ == end_; }
  // The next node's record (its payload_offset: the file offset of its payload).
  Status peek(NodeRecord& r) {
    if (table_i_ == table_n_) {
      const uint64_t n = std::min<uint64_t>(end_ - next_, kTableChunk);
      table_.resize(size_t(n) * kUnitRecord);
      TERRAIN_TRY(read_at(fd_, table_.data(), table_.size(), kUnitHeader + next_ * kUnitRecord, path_));
      table_i_ = 0;
      table_n_ = n;
    }
    const uint8_t* p = &table_[size_t(table_i_) * kUnitRecord];
    r = unit_record(p);
    r.payload_size = unit_record_payload_size(p);
    r.payload_offset = payload_at_;
    return Status::success();
  }
  // The payload of the node peek() returned; then moves to the next node.
  Status take(uint32_t size, std::span<const uint8_t>& payload) {
    if (payload_at_ < buf_at_ || payload_at_ + size > buf_at_ + buf_size_) {
      // Refill from this payload on: `chunk_` bytes, never past the level's payloads.
      const size_t want = size_t(std::max<uint64_t>(size, std::min<uint64_t>(chunk_, payload_end_ - payload_at_)));
      if (want > buf_.capacity) {
        buf_.data.reset(new uint8_t[want]);
        buf_.capacity = want;
      }
      buf_at_ = payload_at_;
      buf_size_ = 0;
      while (buf_size_ < size) {  // at least this payload; what follows is a bonus
        const ssize_t k = ::pread(fd_, buf_.data.get() + buf_size_, want - buf_size_, off_t(buf_at_ + buf_size_));
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) return Status::failure(Error::truncated, fmt::format("{}: {}", path_, k < 0 ? std::strerror(errno) : "ends early"));
        buf_size_ += size_t(k);
      }
    }
    payload = {buf_.data.get() + size_t(payload_at_ - buf_at_), size};
    payload_at_ += size;
    ++next_;
    ++table_i_;
    return Status::success();
  }

 private:
  static constexpr uint64_t kTableChunk = 1024;
  int fd_;
  const std::string& path_;
  ReadBuffer& buf_;
  uint64_t next_, end_, payload_at_, payload_end_;
  size_t chunk_;
  std::vector<uint8_t> table_;
  uint64_t table_i_ = 0, table_n_ = 0;
  size_t buf_size_ = 0;
  uint64_t buf_at_ = 0;
};

// The heights units share along their edges (format.h: a shared vertex has one canonical value),
// checked as the merge copies the nodes: what terrain-inspect --verify checks between west and
// south neighbours, for the pairs of nodes that lie in different units (a unit's own nodes were
// cooked in one session). Only nodes on a unit's edge are decoded (their heights, and their albedo
// when they have holes). Held: the east column of the current row's edge nodes and the north row of
// a band's top row of nodes, one level at a time (129 values per node: a row of nodes across the
// world at most).
class EdgeCheck {
 public:
  EdgeCheck(const PlanFile& plan, const std::array<uint8_t, kLevelCount>& steps) : steps_(steps) {
    for (const UnitPlan& u : plan.units) {
      grid_x1_ = std::max(grid_x1_, u.roots.x1);
      grid_y1_ = std::max(grid_y1_, u.roots.y1);
    }
  }
  void start_level() {
    east_.clear();
    north_.clear();
  }
  // Node `r` of unit `u` (the nodes of a level in the merge's order: bands south to north, rows
  // south to north, units west to east). `problem` gets a message when an edge disagrees;
  // a failure status when the payload cannot be decoded.
  Status node(const NodeRecord& r, std::span<const uint8_t> payload, const UnitPlan& u, std::string& problem) {
    const int level = int(r.key.level);
    const int up = kRootLevel - level;
    const uint32_t x0 = u.roots.x0 << up, x1 = u.roots.x1 << up, y0 = u.roots.y0 << up, y1 = u.roots.y1 << up;
    if (r.key.y != row_) {  // a new row: the east columns of the last one met their neighbours
      east_.clear();
      row_ = r.key.y;
    }
    const bool west = r.key.x == x0 && u.roots.x0 > 0, south = r.key.y == y0 && u.roots.y0 > 0;
    const bool east = r.key.x + 1 == x1 && u.roots.x1 < grid_x1_, north = r.key.y + 1 == y1 && u.roots.y1 < grid_y1_;
    if (!west && !south && !east && !north) return Status::success();
    const auto west_of = west ? east_.find(r.key.x - 1) : east_.end();
    auto south_of = south ? north_.find(r.key.x) : north_.end();
    if (south_of != north_.end() && south_of->second.y + 1 != r.key.y) south_of = north_.end();  // not adjacent
    if (west_of == east_.end() && south_of == north_.end() && !east && !north) return Status::success();
    const bool holes = (r.flags & kNodeFlagHasHoles) != 0;
    TERRAIN_TRY(decode_node_payload(payload, kSectionHeights | (holes ? kSectionAlbedo : 0u), data_));
    if (holes) decode_hole_mask(data_, mask_.data());
    const int step = steps_[size_t(level)];
    auto at = [&](int i, int j) {  // vertex (i, j): its units, or kHole
      const size_t k = size_t(j * kHeightSamples + i);
      return holes && mask_[k] ? kHole : vertex_units(r.height_offset, data_.heights[k], step);
    };
    auto compare = [&](const Edge& other, bool column, const char* side, uint32_t ox, uint32_t oy) {
      for (int k = 0; k < kHeightSamples && problem.empty(); ++k) {
        const int32_t mine = column ? at(0, k) : at(k, 0);
        if (mine == kHole || other[size_t(k)] == kHole || mine == other[size_t(k)]) continue;
        problem = fmt::format("node {} vertex ({}, {}) = {} units but its {} neighbour {} (another unit) stores {} at "
                              "the same point", node_name(r.key), column ? 0 : k, column ? k : 0, mine, side,
                              node_name({r.key.level, ox, oy}), other[size_t(k)]);
      }
    };
    if (west_of != east_.end()) compare(west_of->second, true, "west", r.key.x - 1, r.key.y);
    if (south_of != north_.end()) compare(south_of->second.edge, false, "south", r.key.x, r.key.y - 1);
    if (south_of != north_.end()) north_.erase(south_of);
    if (east) {
      Edge& e = east_[r.key.x];
      for (int k = 0; k < kHeightSamples; ++k) e[size_t(k)] = at(kQuadsPerSide, k);
    }
    if (north) {
      RowEdge& e = north_[r.key.x];
      e.y = r.key.y;
      for (int k = 0; k < kHeightSamples; ++k) e.edge[size_t(k)] = at(k, kQuadsPerSide);
    }
    return Status::success();
  }

 private:
  static constexpr int32_t kHole = INT32_MIN;
  using Edge = std::array<int32_t, kHeightSamples>;
  const std::array<uint8_t, kLevelCount>& steps_;
  uint32_t grid_x1_ = 0, grid_y1_ = 0;
  uint32_t row_ = UINT32_MAX;
  struct RowEdge {
    uint32_t y = 0;
    Edge edge{};
  };
  std::map<uint32_t, Edge> east_;       // by node x: the east columns of the current row's nodes
  std::map<uint32_t, RowEdge> north_;  // by node x: the north rows of the bands' top rows (the last per x)
  std::unique_ptr<NodeData> holder_ = std::make_unique<NodeData>();
  NodeData& data_ = *holder_;
  std::array<uint8_t, kHeightCount> mask_{};
};

// Merges every unit of the plan into `writer`, which it opens (ordered, ArchiveWriter::open_ordered)
// on `output`, in canonical order, and sums their stats (in unit order) into `totals` and
// `report`. Reads each unit's head, then each unit file front to back once (its CRC checked as its
// payloads are copied). Memory does not grow with the archive: one unit's node table at a time
// (56 bytes per node of the largest unit) while checking, then a read buffer per unit of a band
// (64-256 KB, 4 MB in all) and the writer's buffers. Fails naming a unit that is missing or
// bad, or two units whose heights disagree along the edge they share (the check terrain-inspect
// --verify makes between neighbours, made on the nodes of the units' edges only, decoded with the
// plan's quantization `steps`); the caller then aborts the writer. `extend_shape` (optional), called
// once every unit is checked and before the writer opens, adds the nodes the caller will add after
// the units' (the overview levels).
Status merge_unit_files(const std::string& work_dir, const PlanFile& plan, const std::array<uint8_t, kLevelCount>& steps,
                        const std::string& output, ArchiveWriter& writer, PyramidTotals& totals, CookReport& report,
                        const ProgressFn& progress, const std::function<Status(ArchiveShape&)>& extend_shape) {
  // Two passes, memory independent of the archive's size. First every unit's head (header,
  // table, stats) is checked, one unit at a time: what the archive will hold per level, and per
  // unit where each level starts. Then the payloads are copied in the archive's order: a level at
  // a time, the units of one band of roots (the plan's units in a row) side by side, row by row
  // of nodes; each unit is read front to back once, its CRC checked as it is copied (the payload
  // CRC the writer computes anyway, combined into the unit's). The writer is ordered: it writes
  // each directory entry in place. A unit failing a check fails the merge, and the archive is only
  // renamed into place by finish(), so nothing is merged.
  auto bad_unit = [&](uint32_t unit, const std::string& why) {
    return Status::failure(Error::no_data, fmt::format("unit {} ({}): {}; nothing merged (run `terrain-cook unit {} {}`)",
                                                       unit, unit_file(work_dir, unit), why, work_dir, unit));
  };
  const std::string damaged = kUnitDamaged;
  remove_stale_staging_in(units_dir(work_dir));  // staged files of unit runs killed on this host
  std::vector<MergeUnit> units(plan.units.size());
  ArchiveShape shape;
  for (const UnitPlan& u : plan.units) {
    UnitContents c;
    if (Status st = read_unit(unit_file(work_dir, u.index), u.index, u.fingerprint, UnitCheck::head, c); !st.ok())
      return bad_unit(u.index, st.message);
    MergeUnit& m = units[u.index];
    m.crc = c.head_crc;
    m.stored_crc = c.stored_crc;
    m.nodes = m.left = c.nodes.size();
    if (c.nodes.empty() && c.head_crc != c.stored_crc) return bad_unit(u.index, damaged);
    // Levels in the table: 5 first (canonical order); each node inside the unit's roots, so the
    // band of the unit is where the merge looks for it.
    std::array<uint64_t, kLevelCount> count{};
    for (const auto& [r, off] : c.nodes) {
      const int up = kRootLevel - int(r.key.level);
      const uint32_t rx = r.key.x >> up, ry = r.key.y >> up;
      if (rx < u.roots.x0 || rx >= u.roots.x1 || ry < u.roots.y0 || ry >= u.roots.y1) {
        uint32_t crc = c.head_crc;
        const int fd = ::open(unit_file(work_dir, u.index).c_str(), O_RDONLY | O_CLOEXEC);
        const bool whole = fd >= 0 && crc_range(fd, c.payload_start, c.size - 8, crc, unit_file(work_dir, u.index));
        if (fd >= 0) ::close(fd);
        return bad_unit(u.index, !whole || crc != c.stored_crc ? damaged : fmt::format("node {} lies outside its roots", node_name(r.key)));
      }
      ++count[r.key.level];
    }
    uint64_t index = 0, at = c.payload_start;
    for (int l = kRootLevel; l >= 0; --l) {
      m.level_begin[size_t(l)] = index;
      m.level_payload[size_t(l)] = at;
      for (uint64_t k = 0; k < count[size_t(l)]; ++k) at += c.nodes[size_t(index + k)].first.payload_size;
      m.level_bytes[size_t(l)] = at - m.level_payload[size_t(l)];
      index += count[size_t(l)];
      shape.level_nodes[size_t(l)] += count[size_t(l)];
    }
    m.level_nodes = count;
    shape.payload_bytes += at - c.payload_start;
    TERRAIN_TRY(add_unit_stats(c, u.index, totals, report));
    if (progress && !progress(0.05 * double(u.index + 1) / double(plan.units.size()), "checking units"))
      return Status::failure(Error::cancelled, "cancelled");
  }
  // Bands: the units of one row of the plan's blocks, west to east.
  std::map<std::pair<uint32_t, uint32_t>, std::vector<uint32_t>> bands;
  for (const UnitPlan& u : plan.units) bands[{u.roots.y0, u.roots.y1}].push_back(u.index);
  uint32_t band_end = 0;
  for (auto& [rows, list] : bands) {
    if (rows.first < band_end) return Status::failure(Error::internal, "the plan's units overlap");
    band_end = rows.second;
    std::sort(list.begin(), list.end(), [&](uint32_t a, uint32_t b) { return plan.units[a].roots.x0 < plan.units[b].roots.x0; });
  }
  uint64_t total = 0, copied = 0;
  for (uint64_t n : shape.level_nodes) total += n;
  if (extend_shape)
    TERRAIN_TRY(extend_shape(shape));
  TERRAIN_TRY(writer.open_ordered(output, shape));
  size_t widest = 0;
  for (const auto& [rows, list] : bands) widest = std::max(widest, list.size());
  std::vector<ReadBuffer> buffers(widest);
  EdgeCheck edges(plan, steps);
  for (int level = kRootLevel; level >= 0; --level) {
    const int up = kRootLevel - level;
    edges.start_level();
    for (const auto& [rows, list] : bands) {
      // The band's files, each with a share of a 4 MB read budget (64-256 KB each: larger reads
      // gained nothing measurable, their fresh pages cost page faults).
      const size_t chunk = std::clamp<size_t>((size_t(4) << 20) / list.size(), size_t(64) << 10, size_t(256) << 10);
      std::vector<std::string> paths;
      std::vector<int> fds;
      std::vector<LevelCursor> cursors;
      paths.reserve(list.size());
      cursors.reserve(list.size());
      struct Closer {
        std::vector<int>& fds;
        ~Closer() { for (int fd : fds) ::close(fd); }
      } closer{fds};
      for (uint32_t unit : list) {
        paths.push_back(unit_file(work_dir, unit));
        const int fd = ::open(paths.back().c_str(), O_RDONLY | O_CLOEXEC);
        if (fd < 0) return bad_unit(unit, fmt::format("cannot open: {}", std::strerror(errno)));
        fds.push_back(fd);
        cursors.emplace_back(fd, paths.back(), units[unit], level, chunk, buffers[cursors.size()]);
      }
      const uint32_t row_end = rows.second << up;
      for (uint32_t row = rows.first << up; row < row_end; ++row)
        for (size_t k = 0; k < list.size(); ++k) {
          const uint32_t unit = list[k];
          LevelCursor& cur = cursors[k];
          MergeUnit& u = units[unit];
          NodeRecord r;
          while (!cur.done()) {
            if (Status st = cur.peek(r); !st.ok()) return bad_unit(unit, st.message);
            if (r.key.y != row) break;
            const uint64_t at = r.payload_offset;
            std::span<const uint8_t> payload;
            if (Status st = cur.take(r.payload_size, payload); !st.ok()) return bad_unit(unit, st.message);
            // A payload refused (by the writer, or undecodable on a unit's edge): name the unit, as
            // damaged when its CRC says so.
            auto is_damaged = [&] {
              uint32_t whole_crc = detail::crc32_update(u.crc, payload);
              struct stat fs {};
              const bool whole = ::fstat(fds[k], &fs) == 0 &&
                                 crc_range(fds[k], at + r.payload_size, uint64_t(fs.st_size) - 8, whole_crc, paths[k]);
              return !whole || whole_crc != u.stored_crc;
            };
            auto refused = [&](const std::string& why) {
              writer.abort();
              return bad_unit(unit, is_damaged() ? damaged : why);
            };
            uint32_t crc = 0;
            if (Status st = writer.add_node(r, payload, &crc); !st.ok()) return refused(st.message);
            std::string disagree;
            if (Status st = edges.node(r, payload, plan.units[unit], disagree); !st.ok()) return refused(st.message);
            if (!disagree.empty()) {
              writer.abort();
              if (is_damaged()) return bad_unit(unit, damaged);
              return Status::failure(
                  Error::no_data,
                  fmt::format("unit {} ({}): {}: the units disagree along their shared edge (cooked from inputs that "
                              "differ, which their fingerprints did not show); nothing merged (run `terrain-cook plan` "
                              "again, remove the unit files of both units and cook them again)",
                              unit, unit_file(work_dir, unit), disagree));
            }
            u.crc = detail::crc32_combine(u.crc, crc, r.payload_size);
            if (--u.left == 0 && u.crc != u.stored_crc) return bad_unit(unit, damaged);
            if (progress && ++copied % 4096 == 0 &&
                !progress(0.05 + 0.95 * double(copied) / double(std::max<uint64_t>(total, 1)), "merging"))
              return Status::failure(Error::cancelled, "cancelled");
          }
        }
      for (size_t k = 0; k < list.size(); ++k)
        if (!cursors[k].done()) return bad_unit(list[k], "its table is not in canonical order");
    }
  }
  return Status::success();
}


// The roots of every unit file (checked as the merge checks them), for the overview levels: their
// records and a reader of their payloads.
Status unit_roots(const std::string& work_dir, const PlanFile& plan, RootSource& out) {
  struct Where {
    uint32_t unit;
    uint64_t offset;
    uint32_t size;
  };
  auto where = std::make_shared<std::vector<Where>>();
  out = RootSource{};
  for (const UnitPlan& u : plan.units) {
    UnitContents c;
    if (Status st = read_unit(unit_file(work_dir, u.index), u.index, u.fingerprint, UnitCheck::head, c); !st.ok())
      return Status::failure(Error::no_data, fmt::format("unit {}: {}", u.index, st.message));
    for (const auto& [r, off] : c.nodes)
      if (r.key.level == uint32_t(kRootLevel)) {
        out.roots.push_back(r);
        where->push_back({u.index, off, r.payload_size});
      }
  }
  out.read = [work_dir, where](size_t i, std::vector<uint8_t>& bytes) {
    const Where& w = (*where)[i];
    const std::string path = unit_file(work_dir, w.unit);
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return Status::failure(Error::io_open, fmt::format("{}: {}", path, std::strerror(errno)));
    bytes.resize(w.size);
    Status st = read_at(fd, bytes.data(), bytes.size(), w.offset, path);
    ::close(fd);
    return st;
  };
  return Status::success();
}

// The merge's session: the plan's decisions without any input opened.
void session_for_merge(const PlanData& data, CookSession& s) {
  s.options = data.options;
  s.frame = data.frame;
  s.world = data.world;
  s.ctx.step_log2 = data.steps;
  restore_overview_steps(data.world.overview_step_log2, s);
  s.ctx.finest_level = data.report.finest_level;
  s.ctx.tolerance_m = data.report.tolerance_m;
  s.descriptions = data.descriptions;
}

}  // namespace

Status spool_overview_levels(const CookSession& s, const RootSource& roots, const std::string& output, NodeSpool& spool,
                             CookReport& report) {
  if (s.world.overview_step_log2.empty()) return Status::success();
  const double c0 = process_cpu_seconds();
  Status st = spool.open(staging_path(output, "overview"));
  OverviewSettings settings = overview_settings(s);
  settings.scratch_path = staging_path(output, "lattice");
  OverviewStats built;
  if (st.ok())
    st = write_overview_levels(settings, roots,
                               [&](const NodeRecord& r, std::span<const uint8_t> p) { return spool.add(r, p); }, built);
  report.overview_nodes = built.nodes;
  report.overview_error_max_m = built.error_max_m;
  report.cpu_overview = process_cpu_seconds() - c0;
  return st;
}

ArchiveShape shape_of(std::initializer_list<const NodeSpool*> parts, ArchiveShape shape) {
  for (const NodeSpool* p : parts) {
    const ArchiveShape s = p->shape();
    for (size_t l = 0; l < size_t(kMaxLevels); ++l) shape.level_nodes[l] += s.level_nodes[l];
    shape.payload_bytes += s.payload_bytes;
  }
  return shape;
}

Status merge_into(const PlanData& data, const std::string& work_dir, const std::string& output, int threads,
                  const ProgressFn& progress, CookReport& report) {
  CookSession s;
  session_for_merge(data, s);
  s.options.output = output;
  SurfaceOptions so;
  so.materials_path = data.resolved.materials_path;
  TERRAIN_TRY(load_material_rules(so, s.rules));
  ArchiveWriter writer;
  PyramidTotals totals;
  CookReport merged;  // what the merge itself adds: the inputs' bytes read by the units, the overview levels
  // The overview levels (built from the units' roots once every unit is checked) are spooled
  // first: the ordered writer places the directory after every payload, theirs included.
  NodeSpool overview;
  auto with_overview = [&](ArchiveShape& shape) {
    if (s.world.overview_step_log2.empty()) return Status::success();
    s.threads = threads;
    RootSource roots;
    Status st = unit_roots(work_dir, data.plan, roots);
    if (st.ok()) st = spool_overview_levels(s, roots, output, overview, merged);
    if (st.ok()) shape = shape_of({&overview}, shape);
    return st;
  };
  Status st = merge_unit_files(work_dir, data.plan, data.steps, output, writer, totals, merged, progress, with_overview);
  if (st.ok() && overview.nodes()) st = overview.drain(writer);
  if (!st.ok()) {
    writer.abort();
    return st;
  }
  finish_levels(s, totals);
  if (Status fin = finish_archive(s, totals, data.report, writer); !fin.ok()) return fin;
  // The report, once: the plan's part, then what the units and the merge added.
  report = data.report;
  report.surface_layers = !data.options.heights_only;
  report.input_bytes_read = merged.input_bytes_read;
  report.overview_nodes = merged.overview_nodes;
  report.overview_error_max_m = merged.overview_error_max_m;
  report.cpu_overview = merged.cpu_overview;
  report_blocks(s, totals, report);
  report_archive(s, report);
  return Status::success();
}

}  // namespace terrain::cook
