#include "load_queue.h"

#include <chrono>

#include "terrain/cpu_clock.h"

namespace terrain::detail {

LoadQueue::LoadQueue(const ArchiveReader& reader, unsigned sections, uint32_t threads, uint32_t capacity)
    : reader_(reader), sections_(sections), surfaces_((sections & kSectionHeights) != 0), capacity_(capacity) {
  publish_mark_.assign(reader.nodes().size(), 0);
  taken_.assign(reader.nodes().size(), 0);
  workers_.reserve(threads);
  for (uint32_t i = 0; i < threads; ++i) workers_.emplace_back([this] { worker_main(); });
}

LoadQueue::~LoadQueue() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  work_ready_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void LoadQueue::publish(const std::vector<uint32_t>& requests, std::vector<uint32_t>& dropped) {
  {
    std::lock_guard lock(mutex_);
    ++generation_;
    if (generation_ == 0) {  // wrapped: marks of old lists could collide
      std::fill(publish_mark_.begin(), publish_mark_.end(), 0u);
      generation_ = 1;
    }
    std::vector<uint32_t> next;
    next.reserve(requests.size());
    for (uint32_t node : requests) {
      if (taken_[node]) continue;
      publish_mark_[node] = generation_;
      next.push_back(node);
    }
    for (size_t i = queue_pos_; i < queue_.size(); ++i)
      if (publish_mark_[queue_[i]] != generation_) dropped.push_back(queue_[i]);
    queue_ = std::move(next);
    queue_pos_ = 0;
  }
  work_ready_.notify_all();
}

void LoadQueue::collect(std::vector<Result>& out, bool wait) {
  std::unique_lock lock(mutex_);
  if (wait) result_ready_.wait(lock, [&] { return !results_.empty(); });
  for (Result& r : results_) {
    taken_[r.node] = 0;
    out.push_back(std::move(r));
  }
  results_.clear();
}

void LoadQueue::release(uint32_t count) {
  if (count == 0) return;
  {
    std::lock_guard lock(mutex_);
    counters_.in_flight -= count;
  }
  work_ready_.notify_all();
}

void LoadQueue::set_capacity(uint32_t capacity) {
  {
    std::lock_guard lock(mutex_);
    if (capacity == capacity_) return;
    capacity_ = capacity;
  }
  work_ready_.notify_all();
}

void LoadQueue::free_buffers(std::span<NodeData* const> data) {
  if (data.empty()) return;
  std::lock_guard lock(mutex_);
  for (NodeData* d : data)
    if (d) free_buffers_.push_back(d);
}

LoadQueue::Counters LoadQueue::counters() const {
  std::lock_guard lock(mutex_);
  return counters_;
}

void LoadQueue::worker_main() {
  std::unique_lock lock(mutex_);
  for (;;) {
    work_ready_.wait(lock, [&] {
      return stop_ || (queue_pos_ < queue_.size() && counters_.in_flight < capacity_);
    });
    if (stop_) return;
    const uint32_t node = queue_[queue_pos_++];
    taken_[node] = 1;
    ++counters_.in_flight;
    ++counters_.loads_started;
    NodeData* data = nullptr;
    if (!free_buffers_.empty()) {
      data = free_buffers_.back();
      free_buffers_.pop_back();
    }
    lock.unlock();

    // All file access (pread of the payload) and decompression happen here, off the owner's thread.
    std::unique_ptr<NodeData> fresh;
    if (!data) {
      fresh = std::make_unique<NodeData>();
      data = fresh.get();
    }
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = thread_cpu_seconds();
    Status status = reader_.decode_node(node, *data, sections_);
    std::shared_ptr<const NodeSurface> surface;
    if (status.ok() && surfaces_) surface = make_node_surface(reader_, node, *data, (sections_ & kSectionAlbedo) != 0);
    const double cpu_seconds = thread_cpu_seconds() - c0;
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const uint64_t bytes = reader_.nodes()[node].payload_size;

    lock.lock();
    if (fresh) {
      buffers_.push_back(std::move(fresh));
      ++counters_.buffers_allocated;
    }
    counters_.bytes_read += bytes;
    counters_.decode_seconds += seconds;
    counters_.decode_cpu_seconds += cpu_seconds;
    results_.push_back({node, data, std::move(surface), std::move(status), bytes, seconds});
    result_ready_.notify_one();
  }
}

}  // namespace terrain::detail
