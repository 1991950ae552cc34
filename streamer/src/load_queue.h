// Background loading in two stages. Fetch threads take requests in priority order and read the
// stored payload bytes (pread of a file, or a range request over HTTP: the bound on reads in flight
// is the number of fetch threads, apart from the decoders, so round trips overlap without more
// decoding), taking queued requests whose payloads lie back to back in the file along in the same
// read. Decode threads check and decode fetched payloads into pooled buffers and hand back results.
// The owner thread replaces the whole request list each frame, so requests that are no longer
// wanted are dropped before any work is done.
#pragma once
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <span>
#include <thread>
#include <vector>

#include "resident_surface.h"
#include "terrain/archive_reader.h"
#include "terrain/status.h"

namespace terrain::detail {

class LoadQueue {
 public:
  struct Result {
    uint32_t node = 0;
    NodeData* data = nullptr;  // owned by the pool; give back with free_buffer()
    // The node's surface for queries (when the sections hold heights), made here on the worker so
    // that the owner's update() only links it in (streamer/README.md gives the cost it moves).
    std::shared_ptr<const NodeSurface> surface;
    Status status;
    uint64_t bytes_read = 0;
    double seconds = 0;
  };
  struct Counters {
    uint64_t loads_started = 0;
    uint64_t fetches = 0;           // source reads issued (one per run of adjacent payloads)
    uint64_t reads_cancelled = 0;   // reads stopped because none of their nodes was wanted any more
    uint64_t bytes_read = 0;
    double fetch_seconds = 0;       // wall clock of the reads, summed over fetch threads
    double decode_seconds = 0;      // wall clock, summed over workers
    double decode_cpu_seconds = 0;  // CPU time of the workers' threads in decode (excludes waiting for a core)
    uint64_t buffers_allocated = 0;
    uint32_t in_flight = 0;
  };

  // The most nodes and stored bytes one fetch takes together, and how far down the request list it
  // looks for payloads adjacent to the one it took.
  static constexpr size_t kMaxRunNodes = 32;
  static constexpr uint64_t kMaxRunBytes = 2u << 20;
  static constexpr size_t kRunLookahead = 64;

  // Starts `fetch_threads` readers and `decode_threads` decoders of `sections` of nodes of `reader`
  // (which must outlive this). At most `capacity` requests are taken and not yet released at any
  // time (see set_capacity).
  LoadQueue(const ArchiveReader& reader, unsigned sections, uint32_t fetch_threads, uint32_t decode_threads,
            uint32_t capacity);
  ~LoadQueue();  // stops the threads after their current read or decode and joins them
  LoadQueue(const LoadQueue&) = delete;
  LoadQueue& operator=(const LoadQueue&) = delete;

  // Replaces the request list (highest priority first). Requests of the previous list not yet
  // taken and absent from the new one are appended to `dropped`. Nodes already taken by a worker
  // are skipped (their result is on its way); a read in progress none of whose nodes is in the new
  // list is stopped, and its nodes come back as results with status `cancelled` (no data).
  void publish(const std::vector<uint32_t>& requests, std::vector<uint32_t>& dropped);
  // Moves finished results into `out` (appended). With `wait`, blocks until there is one.
  void collect(std::vector<Result>& out, bool wait);
  // The owner consumed `count` results (delivered, discarded or failed): frees in-flight room.
  void release(uint32_t count);
  // Changes the in-flight limit (the owner keeps resident + in flight within its memory bound).
  void set_capacity(uint32_t capacity);
  // Returns buffers from Results (or resident nodes) to the pool; nulls are ignored.
  void free_buffers(std::span<NodeData* const> data);
  Counters counters() const;

 private:
  static constexpr uint32_t kTakenEntry = UINT32_MAX;  // a queue entry a fetch took out of order

  // A read in progress: its nodes, and the flag that stops it when none of them is wanted any more.
  struct ActiveRead {
    std::vector<uint32_t> run;
    std::atomic<bool> cancel{false};
  };

  struct Fetched {
    uint32_t node = 0;
    std::shared_ptr<const std::vector<uint8_t>> run;  // the read holding this node's bytes
    size_t offset = 0;                                // where they start in it
    Status status;                                    // the read's
  };

  void fetch_main();
  void decode_main();
  bool next_request();  // advances queue_pos_ past entries taken out of order; true when one is left
  std::vector<uint32_t> take_run();  // under the lock: the next request and adjacent queued ones

  const ArchiveReader& reader_;
  const unsigned sections_;
  const bool surfaces_;  // the sections hold heights: make each node's query surface

  mutable std::mutex mutex_;
  std::condition_variable work_ready_;     // fetch threads wait here
  std::condition_variable fetched_ready_;  // decode threads wait here
  std::condition_variable result_ready_;   // collect(wait) waits here
  bool stop_ = false;
  std::vector<uint32_t> queue_;           // current request list
  size_t queue_pos_ = 0;                  // next request to take
  std::vector<uint32_t> publish_mark_;    // per node: generation of the list holding it
  std::vector<uint8_t> taken_;            // per node: a worker took it, result not collected
  uint32_t generation_ = 0;
  uint32_t capacity_ = 0;
  std::vector<ActiveRead*> active_;       // reads in progress (owned by their fetch threads)
  std::deque<Fetched> fetched_;           // read, waiting for a decoder (in the order read)
  std::vector<Result> results_;
  std::vector<std::unique_ptr<NodeData>> buffers_;  // every buffer ever allocated
  std::vector<NodeData*> free_buffers_;
  Counters counters_;
  std::vector<std::thread> workers_;
};

}  // namespace terrain::detail
