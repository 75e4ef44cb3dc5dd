#pragma once
// Lock-free single-writer / many-reader snapshot of a plain struct (a sequence lock).
// The writer (a real-time thread: the robot driver's loop) publishes whole values without locks, waiting or
// allocation; any number of other threads read the newest whole value, retrying while a publication is under way.
// Unlike LatestValue (a triple buffer for one consumer that takes each value once), reading leaves the value in place,
// so every thread that asks sees the latest state (for summaries, tests and monitors).
//
// The value lives in relaxed-atomic 64-bit words, so no access is a data race in the C++ memory model (and
// ThreadSanitizer has nothing to report); the sequence counter is odd while a publication is in progress. Ordering
// (Boehm, "Can seqlocks get along with programming language memory models?", 2012), without standalone fences (which
// ThreadSanitizer does not model): the writer stores the odd count, then the words with release, then the even count
// with release; a reader loads the count with acquire, the words with acquire, then the count again. A reader that
// saw any word of a later publication sees a later count, so equal even counts mean a whole value.

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <thread>
#include <type_traits>

namespace visco {

template <typename T>
class SharedSnapshot {
  static_assert(std::is_trivially_copyable_v<T>, "SharedSnapshot<T> copies T across threads; keep T a plain struct");

 public:
  SharedSnapshot() { Publish(T{}); }
  explicit SharedSnapshot(const T& initial) { Publish(initial); }
  SharedSnapshot(const SharedSnapshot&) = delete;
  SharedSnapshot& operator=(const SharedSnapshot&) = delete;

  /// Publishes `value` (one writer thread only). Real-time safe: wait-free, no allocation, no system call.
  void Publish(const T& value) {
    std::uint64_t words[kWords] = {};
    std::memcpy(words, &value, sizeof(T));
    const std::uint64_t seq = seq_.load(std::memory_order_relaxed);
    seq_.store(seq + 1, std::memory_order_relaxed);
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(words[i], std::memory_order_release);
    seq_.store(seq + 2, std::memory_order_release);
  }

  /// The newest whole value (any thread, any number of readers). Not real-time safe: it retries (yielding) while
  /// the writer is in the middle of a publication, a few dozen stores, which a preempted writer can stretch. Never
  /// blocks the writer.
  T Read() const {
    std::uint64_t words[kWords];
    for (;;) {
      const std::uint64_t before = seq_.load(std::memory_order_acquire);
      if ((before & 1U) != 0) {
        std::this_thread::yield();
        continue;
      }
      for (std::size_t i = 0; i < kWords; ++i) words[i] = words_[i].load(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) == before) break;
    }
    T value;
    std::memcpy(&value, words, sizeof(T));
    return value;
  }

  /// Number of values published so far, the initial one included (any thread; for diagnostics and tests).
  std::uint64_t published() const { return seq_.load(std::memory_order_relaxed) / 2; }

 private:
  static constexpr std::size_t kWords = (sizeof(T) + sizeof(std::uint64_t) - 1) / sizeof(std::uint64_t);
  std::atomic<std::uint64_t> seq_{0};
  std::atomic<std::uint64_t> words_[kWords];
};

}  // namespace visco
