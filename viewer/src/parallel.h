// A parallel loop for independent per-item work (the viewer's per-node upload preparation).
#pragma once
#include <algorithm>
#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

namespace terrain::view {

// Calls f(i) for i = 0 .. n-1 on up to `max_threads` threads (the caller's included; 0 = one per
// hardware thread), items handed out in turn. f must not throw, and calls must be independent.
template <class F>
void parallel_for(size_t n, F&& f, unsigned max_threads = 0) {
  const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
  const size_t workers = std::min<size_t>(n, max_threads ? max_threads : hw);
  if (workers <= 1) {
    for (size_t i = 0; i < n; ++i) f(i);
    return;
  }
  std::atomic<size_t> next{0};
  auto run = [&] {
    for (size_t i; (i = next.fetch_add(1, std::memory_order_relaxed)) < n;) f(i);
  };
  std::vector<std::jthread> threads;
  threads.reserve(workers - 1);
  for (size_t t = 1; t < workers; ++t) threads.emplace_back(run);
  run();
}

}  // namespace terrain::view
