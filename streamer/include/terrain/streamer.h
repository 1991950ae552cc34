// Streaming runtime: keeps the right nodes of a terrain archive resident while cameras move.
//
// The FC5 scheme (Far Cry 5 terrain talk, GDC 2018, sections 2-4): top nodes always resident, about 500 nodes
// chosen by screen-space error, loaded by background threads, handed to the caller one bounded
// batch per frame for upload into a GPU atlas slot, and the GPU-side quadtree state (the node
// descriptor table and the sparse residency index, terrain/residency_index.h) maintained
// incrementally with dirty lists.
//
// Use:
//   terrain::Streamer streamer;
//   if (auto s = streamer.open("world.terrain", config); !s.ok()) { report(s.to_string()); }
//   GPU side, once: an atlas of slot_count() layers, a descriptor buffer of slot_count() x 32 bytes,
//   the index's root grid (roots_x x roots_y uint16, e.g. an R16_UINT image) and its tree buffer
//   (index_tree_words(slot_count()) uint32); layout: terrain/surface_contract.h.
//   each frame:
//     const terrain::FrameUpdate& u = streamer.update(views);
//     const terrain::ResidencyIndex& index = streamer.residency();
//     for (auto& d : u.delivered) upload(*d.data, d.slot);          // into atlas layer d.slot
//     for (auto slot : u.dirty_slots) upload(streamer.slots()[slot], slot);
//     upload_rect(index.root_grid(), u.dirty_roots);               // root-grid cells
//     if (u.dirty_starts) upload_words(index.tree(), 0, kIndexTreeStart + slot_count());
//     for (auto s : u.dirty_children) upload_words(index.tree(), index_child_word(slot_count(), s), 2);
// (Contiguous slots of dirty_slots and dirty_children merge into one copy each.) The traversal
// starts at the tree's start list and follows resident children: see format/SPEC.md section 12.
//
// Memory (besides the resident payloads, budget + max_in_flight NodeData buffers): per archive
// node 54 bytes of the streamer's own (tree links 20, state 1+1+1, slot 2, data pointer 8, rank 4,
// load queue 5, the snapshot's key list 12: update() touches only the wanted nodes' entries, so its
// CPU does not grow with the archive), plus the ArchiveReader's decoded directory (sizeof(NodeRecord)
// = 56 bytes per node) and the residency index: 2 bytes per root, 12 per slot and a hash entry per
// resident or failed node.
//
// Units: positions in frame metres (the archive's projected frame: x east, y north, z up, the
// same vertical datum as the heights), always double on the CPU. Heights in the slot table are
// integer height units (1 unit = 2^-10 m, see format.h). Errors in metres (geometric) and
// pixels (projected).
//
// Threading: one Streamer is driven from one thread at a time (the "caller's thread"); none of
// its methods may run concurrently with another. Internally it owns worker threads that do all
// file reading (page faults on the memory map included) and decompression; update() only
// computes the wanted set, moves finished work into place and edits the index state, so its
// cost is independent of payload sizes. The destructor cancels outstanding work and joins.
//
// Top nodes: the nodes of the archive's top level (ArchiveReader::top_level()): the roots (level
// kRootLevel) of an archive without overview levels, exactly as in FC5; with K overview levels
// (format/SPEC.md section 19) the at most 16 nodes of level 5 + K. Below the top nothing differs:
// roots are nodes like any other, wanted when their parent splits.
//
// Invariants, true after open() and after every update() returns:
//  - every top node is resident (from the first update() on);
//  - a node is resident only if its parent is resident (so the resident set always covers
//    everything the top nodes cover: there is never an area without a resident node);
//  - resident nodes <= config.budget_nodes;
//  - a slot evicted in update() number F receives a new node no earlier than update() number
//    F + config.fence_frames (so GPU frames still in flight never see its contents change);
//  - a node whose payload fails to load is reported once (FrameUpdate::failed), marked failed
//    and never requested again; its parent keeps covering its area. Failing to load covers a bad
//    payload (checksum, section table, zstd) and a failed read: the workers read payloads with
//    pread, so a file truncated or replaced after open() fails the nodes whose bytes are gone
//    (`truncated`, naming the node and the file's new size) instead of raising SIGBUS. Over HTTP
//    (an http(s):// location) a read fails only after its transient errors (timeouts, resets,
//    5xx) were retried (HttpOptions' defaults, terrain/remote_source.h); an archive replaced on
//    the server fails its nodes with `io_changed`.
//
// The wanted set (recomputed by every update(), deterministic for the same views and state):
//  - projected error of node N from view V, in pixels:
//      e(N, V) = geometric_error_m(N) * ppr(V) / max(distance(V, box(N)), 0.001 m)
//    where box(N) is the node's footprint times [min_height, max_height] and the result is
//    multiplied by outside_frustum_error_scale when V has a frustum and box(N) lies outside it;
//    e(N) = max over views. priority(N) = e(N), but never above priority(parent(N)) (so
//    ancestors always rank at least as high as their descendants).
//  - start with every top node; repeatedly split the wanted node of highest priority (ties: coarser
//    level, then key order) that has e(N) > error_target_px * prefetch_ratio and at least one
//    child that exists and has not failed: its existing, non-failed children join the set. Stop
//    at the first split whose children would exceed budget_nodes.
//  - the required set: the same rule with error_target_px itself (no prefetch_ratio) and
//    budget_nodes * (1 - prefetch_reserve) nodes. It is a subset of the wanted set (its splits
//    all rank above error_target_px, every prefetch-only split ranks at or below it).
//  - requests (wanted, not resident) are served in split order, i.e. by priority.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "terrain/archive_reader.h"
#include "terrain/format.h"
#include "terrain/residency_index.h"
#include "terrain/status.h"
#include "terrain/surface_contract.h"

namespace terrain {

class ResidentSurface;  // terrain/queries.h

// ---- Configuration ----------------------------------------------------------------------------

// Automatic StreamerConfig::max_fetches over HTTP: 32 reads in flight make up to 640 requests a
// second at 50 ms round trips (streamer/README.md, "Over HTTP", measures what that buys).
inline constexpr uint32_t kRemoteFetches = 32;

struct StreamerConfig {
  // Most nodes resident at once, top nodes included. open() fails (invalid_argument) when the
  // archive has more top nodes than this (roots, when it has no overview levels). At most kMaxSlots.
  uint32_t budget_nodes = 512;
  // GPU atlas slots (layers) the caller allocates; slot ids are 0 .. slot_count-1.
  // 0 = automatic: budget_nodes + fence_frames * max_deliveries_per_frame (capped at kMaxSlots),
  // so evicted slots waiting out their fence never hold back deliveries. Set it to
  // budget_nodes for the smallest atlas: still correct, but after a large jump new nodes wait
  // for fenced slots. Must be >= budget_nodes.
  uint32_t slot_count = 0;
  // Background threads that read and decode payloads. 0 = std::thread::hardware_concurrency().
  uint32_t worker_threads = 0;
  // Screen-space error target in pixels: a node's children are required when its geometric
  // error, projected from the nearest view, exceeds this.
  double error_target_px = 2.0;
  // Prefetch: children are *wanted* (requested and kept) when the projected error exceeds
  // error_target_px * prefetch_ratio, so loads start before the target needs them. In (0, 1];
  // 1 = load exactly what the target requires.
  double prefetch_ratio = 0.75;
  // Fraction of the budget kept for prefetching: the required set (what the error target needs)
  // is limited to budget_nodes * (1 - prefetch_reserve) nodes, the wanted set to budget_nodes, so
  // a moving camera finds the nodes it newly requires already loaded. In [0, 1).
  double prefetch_reserve = 0.125;
  // Pixels per radian of a view that gives none (1920 px across 90 degrees ~ 960/tan(45deg)).
  double default_pixels_per_radian = 960.0;
  // Projected error of a node entirely outside a view's frustum is multiplied by this (0..1),
  // so nodes behind the camera keep some detail for a quick turn. Views without a frustum
  // treat every node as inside.
  double outside_frustum_error_scale = 0.25;
  // Frames an evicted slot stays untouched (GPU frames in flight). >= 1.
  uint32_t fence_frames = 3;
  // Most nodes delivered by one update() (bounds the caller's per-frame upload). The first
  // update() delivers all top nodes even if there are more. >= 1.
  uint32_t max_deliveries_per_frame = 128;
  // Decode buffers beyond the budget: resident nodes + loads in flight (taken by a worker, or
  // decoded and waiting for delivery) never exceed budget_nodes + max_in_flight, so memory stays
  // within (budget_nodes + max_in_flight) * sizeof(NodeData). Since the wanted set never exceeds
  // the budget, workers can decode a whole new wanted set ahead of the per-frame delivery cap.
  // 0 = automatic: max(2 * worker_threads, budget_nodes / 32). Requests beyond the room wait in
  // the priority queue, which is rebuilt each update(): requests that are no longer wanted are
  // dropped there without any work done; a read in progress whose nodes are all no longer wanted
  // is stopped (over HTTP its transfer ends; a file's pread is short and runs to its end), and its
  // nodes become idle, not failed. A worker holds one decode in progress, so a teleport never
  // waits behind the old position's requests.
  uint32_t max_in_flight = 0;
  // Payload reads in flight at once: threads that only read (pread, or one HTTP range request each,
  // so round trips overlap), apart from the worker_threads that decode. A read takes along queued
  // requests whose payloads follow each other in the file (up to 32 nodes, 2 MiB). Reads share the
  // max_in_flight room with decodes: a node read and waiting for a decoder holds its stored bytes
  // (at most 1 MiB, format/SPEC.md section 12) and counts as in flight. 0 = automatic:
  // kRemoteFetches for an HTTP source, worker_threads for a file. At most 256.
  uint32_t max_fetches = 0;
  // Payload sections decoded for the caller (terrain::Section bits); others stay untouched.
  unsigned sections = kSectionAll;
};

// ---- Views ------------------------------------------------------------------------------------

// A frustum plane relative to the view position p: a point q is inside when
// nx*(q.x-p.x) + ny*(q.y-p.y) + nz*(q.z-p.z) + d >= 0. The normal need not be unit length.
struct FrustumPlane {
  double nx = 0, ny = 0, nz = 0, d = 0;
};

struct View {
  double x = 0, y = 0, z = 0;       // eye position, frame metres (double: never float world positions)
  double pixels_per_radian = 0;     // projection scale: (viewport height px / 2) / tan(vfov / 2);
                                    // 0 = config.default_pixels_per_radian
  bool has_frustum = false;
  std::array<FrustumPlane, 6> frustum{};  // used when has_frustum (any order; all must pass)
};

// (viewport_px / 2) / tan(fov_rad / 2): the pixels_per_radian of a perspective projection.
double pixels_per_radian(double viewport_px, double fov_rad);

// ---- GPU-side state ---------------------------------------------------------------------------

// kIndexNotResident, kIndexNoNode, kMaxSlots, SlotDescriptor, slot_descriptor_of and the
// residency index's layout: the format library's terrain/surface_contract.h (the viewer's shaders
// read them as they are). The index itself (root grid, tree words, DirtyRect): residency_index.h.

// ---- Per-frame results ------------------------------------------------------------------------

struct NodeDelivery {
  NodeKey key;
  uint16_t slot = 0;                  // atlas slot to upload into (free of GPU use: fence passed)
  const NodeRecord* record = nullptr; // archive directory entry; valid while the Streamer is open
  // Decoded sections (config.sections) owned by the streamer. Valid from this delivery until
  // the update() whose FrameUpdate lists this node's eviction begins; read-only.
  const NodeData* data = nullptr;
};

struct NodeEviction {
  NodeKey key;
  uint16_t slot = 0;  // fenced: reused no earlier than update() number frame + fence_frames
};

struct NodeFailure {
  NodeKey key;
  Status status;  // e.g. payload_checksum naming the node and offset
};

// Everything one update() changed. Owned by the streamer; valid until the next update(), close
// or destruction. The caller must apply every FrameUpdate (dirty lists are per update, not
// accumulated): upload delivered data and dirty descriptors, then the dirty parts of the
// residency index (Streamer::residency()). The first update() marks the whole index dirty (the
// initial upload: every root cell, the start list and every slot's child words) and delivers the
// top nodes; before it nothing is resident.
struct FrameUpdate {
  uint64_t frame = 0;                            // 1 for the first update()
  std::span<const NodeDelivery> delivered;       // parents before children
  std::span<const NodeEviction> evicted;         // children before parents
  std::span<const NodeFailure> failed;           // each failed node appears exactly once
  std::span<const uint16_t> dirty_slots;         // slots whose descriptor changed (ascending)
  // The residency index (terrain/surface_contract.h "Residency index: GPU layout"):
  DirtyRect dirty_roots;                         // root-grid cells changed
  bool dirty_starts = false;                     // tree words [0, kIndexTreeStart + slot count) changed
  std::span<const uint16_t> dirty_children;      // slots whose two child words changed (ascending)
};

struct StreamerStats {
  uint64_t frame = 0;                // updates so far
  uint32_t resident = 0;             // nodes resident (<= budget)
  uint32_t wanted = 0;               // nodes in the wanted set (at target * prefetch_ratio)
  uint32_t wanted_missing = 0;       // wanted but not resident after this update
  uint32_t required = 0;             // nodes the error target itself requires (subset of wanted)
  uint32_t required_missing = 0;     // required but not resident: > 0 is a "gap" frame: somewhere
                                     // a coarser resident ancestor is drawn with an error above
                                     // the target (coverage itself never breaks: top nodes resident)
  uint32_t pending = 0;              // wanted, not resident, not failed: queued or in flight
  uint32_t in_flight = 0;            // taken by a worker (decoding or decoded awaiting delivery)
  uint32_t failed = 0;               // nodes marked failed so far
  uint32_t fenced_slots = 0;         // evicted slots waiting out their fence
  uint32_t free_slots = 0;           // slots ready for delivery
  uint64_t loads_started = 0;        // payload decodes begun by workers
  uint64_t loads_delivered = 0;
  uint64_t loads_discarded = 0;      // decoded, but no longer wanted when they finished
  uint64_t requests_dropped = 0;     // queued requests dropped (no longer wanted) before any work
  uint64_t fetches = 0;              // source reads (a run of adjacent payloads is one)
  uint64_t reads_cancelled = 0;      // reads stopped (HTTP: the transfer) once none of their nodes was wanted
  double fetch_seconds = 0;          // wall clock of those reads, summed over the fetch threads
  uint64_t bytes_read = 0;           // stored (compressed) payload bytes read
  uint64_t bytes_decoded = 0;        // raw bytes produced (requested sections)
  double decode_seconds = 0;         // sum over workers of time spent in decode (wall clock)
  double decode_cpu_seconds = 0;     // ... CPU time of those threads (the decode work itself)
  uint64_t buffer_bytes = 0;         // decode buffers allocated: <= (budget + max_in_flight) nodes
};

enum class NodeState : uint8_t {
  absent,     // no such node in the archive
  idle,       // exists, not wanted, not resident
  pending,    // wanted, queued or in flight
  resident,
  failed,
};

// ---- The streamer -----------------------------------------------------------------------------

class Streamer {
 public:
  Streamer();
  ~Streamer();
  Streamer(const Streamer&) = delete;
  Streamer& operator=(const Streamer&) = delete;

  // Opens the archive, a path (read with pread) or an http:// or https:// URL (range requests,
  // terrain/remote_source.h), validated by ArchiveReader::open; checks the config,
  // starts the workers and has them load every top node; returns when they are decoded (the
  // caller's thread waits, it does not decode). Any root count opens when the archive has
  // overview levels (their top level holds at most 16 nodes). Errors: the archive's own (io_open,
  // truncated, bad checksums, ...); invalid_argument for a budget below the top-node count or a
  // bad config; a top node whose payload is corrupt fails open() (there is no parent to cover it).
  // Reopening closes first.
  Status open(const std::string& archive_path, const StreamerConfig& config = {});
  // The same on an archive the caller opened (terrain::remote's open_archive(), or any ByteSource),
  // so that a caller who reads the directory first does not open it twice (over a URL, twice the
  // round trips). The streamer takes the reader over. Automatic max_fetches counts it as remote
  // when its source is an HTTP one.
  Status open(ArchiveReader&& reader, const StreamerConfig& config = {});
  void close();
  bool is_open() const;

  // One frame: recomputes the wanted set from `views` (at least one), evicts resident nodes
  // that are no longer wanted, re-prioritises the request queue (dropping requests that are no
  // longer wanted), and delivers up to max_deliveries_per_frame finished nodes into free slots.
  // An empty `views` keeps the previous wanted set. On a closed streamer: an empty FrameUpdate.
  const FrameUpdate& update(std::span<const View> views);

  // ---- State (reflects the last update(); empty values when not open) ----
  const ArchiveReader& archive() const;
  const WorldInfo& world() const;
  const StreamerConfig& config() const;  // with automatic values resolved
  uint32_t slot_count() const;
  std::span<const SlotDescriptor> slots() const;  // slot_count() entries
  // The residency index of the resident nodes (an empty one when not open): root cells of roots
  // kIndexNotResident until delivered, kIndexNoNode where the archive has no root or a payload
  // failed; overview nodes appear in the tree words (and the start list) like any other.
  const ResidencyIndex& residency() const;
  StreamerStats stats() const;

  NodeState node_state(const NodeKey& key) const;
  // Slot of a resident node, or -1.
  int32_t slot_of(const NodeKey& key) const;
  // Decoded data of a resident node (same lifetime as NodeDelivery::data), or nullptr.
  const NodeData* resident_data(const NodeKey& key) const;
  // Keys in directory order (directory_less: level, tiles of 32 x 32 nodes, y, x).
  std::vector<NodeKey> resident_nodes() const;
  std::vector<NodeKey> wanted_nodes() const;
  std::vector<NodeKey> required_nodes() const;

  // Snapshot of the resident surface at the end of the last update() that delivered or evicted
  // (terrain/queries.h: height, normal and ray queries). The one exception to the threading rule
  // above: callable from any thread while the streamer is open, also during update(); not during
  // open(), close() or destruction. Empty before the first update(), or when config.sections
  // lacks kSectionHeights.
  ResidentSurface resident_surface() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace terrain
