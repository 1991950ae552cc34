#include "load_queue.h"

#include <algorithm>
#include <chrono>

#include "terrain/cpu_clock.h"

namespace terrain::detail {

LoadQueue::LoadQueue(const ArchiveReader& reader, unsigned sections, uint32_t fetch_threads, uint32_t decode_threads,
                     uint32_t capacity)
    : reader_(reader), sections_(sections), surfaces_((sections & kSectionHeights) != 0), capacity_(capacity) {
  publish_mark_.assign(reader.nodes().size(), 0);
  taken_.assign(reader.nodes().size(), 0);
  workers_.reserve(size_t(fetch_threads) + decode_threads);
  for (uint32_t i = 0; i < fetch_threads; ++i) workers_.emplace_back([this] { fetch_main(); });
  for (uint32_t i = 0; i < decode_threads; ++i) workers_.emplace_back([this] { decode_main(); });
}

LoadQueue::~LoadQueue() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  work_ready_.notify_all();
  fetched_ready_.notify_all();
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
      publish_mark_[node] = generation_;
      if (!taken_[node]) next.push_back(node);
    }
    for (ActiveRead* read : active_) {
      const bool wanted = std::any_of(read->run.begin(), read->run.end(),
                                      [&](uint32_t node) { return publish_mark_[node] == generation_; });
      if (!wanted) read->cancel.store(true);
    }
    for (size_t i = queue_pos_; i < queue_.size(); ++i)
      if (queue_[i] != kTakenEntry && publish_mark_[queue_[i]] != generation_) dropped.push_back(queue_[i]);
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

bool LoadQueue::next_request() {
  while (queue_pos_ < queue_.size() && queue_[queue_pos_] == kTakenEntry) ++queue_pos_;
  return queue_pos_ < queue_.size();
}

std::vector<uint32_t> LoadQueue::take_run() {
  auto take = [&](uint32_t node) {
    taken_[node] = 1;
    ++counters_.in_flight;
    ++counters_.loads_started;
  };
  std::vector<uint32_t> run{queue_[queue_pos_++]};
  take(run[0]);
  uint64_t bytes = reader_.nodes()[run[0]].payload_size;
  // Queued requests whose payloads continue the run at either end join it while the room lasts.
  const size_t end = std::min(queue_.size(), queue_pos_ + kRunLookahead);
  for (bool grew = true; grew;) {
    grew = false;
    for (size_t i = queue_pos_; i < end && run.size() < kMaxRunNodes && counters_.in_flight < capacity_; ++i) {
      const uint32_t node = queue_[i];
      if (node == kTakenEntry) continue;
      const uint64_t size = reader_.nodes()[node].payload_size;
      if (bytes + size > kMaxRunBytes) continue;
      if (reader_.payloads_adjacent(run.back(), node))
        run.push_back(node);
      else if (reader_.payloads_adjacent(node, run.front()))
        run.insert(run.begin(), node);
      else
        continue;
      take(node);
      bytes += size;
      queue_[i] = kTakenEntry;
      grew = true;
    }
  }
  ++counters_.fetches;
  counters_.bytes_read += bytes;
  return run;
}

void LoadQueue::fetch_main() {
  std::unique_lock lock(mutex_);
  for (;;) {
    work_ready_.wait(lock, [&] { return stop_ || (counters_.in_flight < capacity_ && next_request()); });
    if (stop_) return;
    ActiveRead read;
    read.run = take_run();
    const std::vector<uint32_t>& run = read.run;
    active_.push_back(&read);
    lock.unlock();

    // All source access (pread, or a range request) happens here, off the owner's thread.
    auto bytes = std::make_shared<std::vector<uint8_t>>();
    const auto t0 = std::chrono::steady_clock::now();
    const Status status = reader_.read_payload_run(run, *bytes, &read.cancel);

    // A run that failed is read again node by node, so only the nodes whose bytes are unreadable
    // (past a truncated file's end, say) fail.
    std::vector<Fetched> done;
    if (status.ok() || run.size() == 1 || status.code == Error::cancelled) {
      size_t offset = 0;
      for (uint32_t node : run) {
        done.push_back({node, bytes, offset, status});
        offset += reader_.nodes()[node].payload_size;
      }
    } else {
      for (uint32_t node : run) {
        auto one = std::make_shared<std::vector<uint8_t>>();
        Status s = reader_.read_payload_run({&node, 1}, *one);
        done.push_back({node, std::move(one), 0, std::move(s)});
      }
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    lock.lock();
    active_.erase(std::find(active_.begin(), active_.end(), &read));
    counters_.fetch_seconds += seconds;
    if (status.code == Error::cancelled)
      ++counters_.reads_cancelled;
    else if (!(status.ok() || run.size() == 1))
      counters_.fetches += run.size();
    // Failed and cancelled reads skip the decoders: their results carry no data.
    for (Fetched& f : done) {
      if (f.status.ok()) {
        fetched_.push_back(std::move(f));
      } else {
        results_.push_back({f.node, nullptr, {}, std::move(f.status), 0, 0});
        result_ready_.notify_one();
      }
    }
    fetched_ready_.notify_all();
  }
}

void LoadQueue::decode_main() {
  std::unique_lock lock(mutex_);
  for (;;) {
    fetched_ready_.wait(lock, [&] { return stop_ || !fetched_.empty(); });
    if (stop_) return;
    Fetched f = std::move(fetched_.front());
    fetched_.pop_front();
    NodeData* data = nullptr;
    if (!free_buffers_.empty()) {
      data = free_buffers_.back();
      free_buffers_.pop_back();
    }
    lock.unlock();

    std::unique_ptr<NodeData> fresh;
    if (!data) {
      fresh = std::make_unique<NodeData>();
      data = fresh.get();
    }
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = thread_cpu_seconds();
    const uint64_t bytes = reader_.nodes()[f.node].payload_size;
    Status status = f.status;
    if (status.ok())
      status = reader_.decode_payload(f.node, std::span<const uint8_t>(*f.run).subspan(f.offset, size_t(bytes)), *data,
                                      sections_);
    f.run.reset();  // the read's buffer goes when its last node is decoded
    std::shared_ptr<const NodeSurface> surface;
    if (status.ok() && surfaces_) surface = make_node_surface(reader_, f.node, *data, (sections_ & kSectionAlbedo) != 0);
    const double cpu_seconds = thread_cpu_seconds() - c0;
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    lock.lock();
    if (fresh) {
      buffers_.push_back(std::move(fresh));
      ++counters_.buffers_allocated;
    }
    counters_.decode_seconds += seconds;
    counters_.decode_cpu_seconds += cpu_seconds;
    results_.push_back({f.node, data, std::move(surface), std::move(status), bytes, seconds});
    result_ready_.notify_one();
  }
}

}  // namespace terrain::detail
