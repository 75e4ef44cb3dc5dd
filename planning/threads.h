#pragma once
// Threads for the planner's parallel parts (slices, candidates): how many the machine has, and a parallel loop that
// hands out indices to worker threads.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace visco::planning {

/// The machine's hardware threads (at least 1): the commands' default for `threads` (results do not depend on it).
int MachineThreads();

namespace internal {

// Runs task(i) for i in [0, n) on `threads` threads; the calling thread reports progress.
template <typename Task>
void ParallelFor(size_t n, int threads, const std::function<void(double)>& progress, double base, double span,
                 Task&& task) {
  std::atomic<size_t> next{0}, done{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto worker = [&] {
    for (;;) {
      const size_t i = next.fetch_add(1);
      if (i >= n) return;
      try {
        task(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        next = n;
      }
      done.fetch_add(1);
    }
  };
  // With more than one thread the calling thread only reports progress.
  const int extra = threads > 1 ? std::min<int>(threads, static_cast<int>(n)) : 0;
  std::vector<std::thread> pool;
  for (int t = 0; t < extra; ++t) pool.emplace_back(worker);
  if (extra == 0) {
    for (;;) {
      const size_t i = next.fetch_add(1);
      if (i >= n) break;
      task(i);
      done.fetch_add(1);
      if (progress && (i % 8 == 0)) progress(base + span * static_cast<double>(i + 1) / static_cast<double>(n));
    }
  } else {
    while (done.load() < n && !error) {
      if (progress) progress(base + span * static_cast<double>(done.load()) / static_cast<double>(n));
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (next.load() >= n) break;
    }
    for (auto& t : pool) t.join();
  }
  if (error) std::rethrow_exception(error);
  if (progress) progress(base + span);
}

}  // namespace internal
}  // namespace visco::planning
