#pragma once
// Bounded lock-free single-producer / single-consumer queue of plain values (the real-time loop's outbox: commands,
// telemetry and faults go from the loop to the LCM publishing thread through these).

#include <array>
#include <atomic>
#include <cstddef>
#include <type_traits>

namespace visco::control {

/// Fixed-capacity ring buffer. One producer thread calls TryPush, one consumer thread calls TryPop. Capacity is
/// `N - 1` values (one slot tells full from empty). When full, TryPush drops the value and counts it.
template <typename T, std::size_t N>
class SpscQueue {
  static_assert(std::is_trivially_copyable_v<T>, "SpscQueue<T> copies T across threads; keep T a plain struct");
  static_assert(N >= 2 && (N & (N - 1)) == 0, "N must be a power of two >= 2");

 public:
  SpscQueue() = default;
  SpscQueue(const SpscQueue&) = delete;
  SpscQueue& operator=(const SpscQueue&) = delete;

  /// Appends `value` (producer only). Returns false and counts a drop if the queue is full.
  /// Real-time safe: wait-free, no allocation.
  bool TryPush(const T& value) {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    const std::size_t next = (head + 1) & (N - 1);
    if (next == tail_.load(std::memory_order_acquire)) {
      dropped_.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    slots_[head] = value;
    head_.store(next, std::memory_order_release);
    return true;
  }

  /// Removes the oldest value into `out` (consumer only). Returns false if empty. Real-time safe: wait-free.
  bool TryPop(T& out) {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return false;
    out = slots_[tail];
    tail_.store((tail + 1) & (N - 1), std::memory_order_release);
    return true;
  }

  /// Values dropped because the queue was full (any thread).
  std::size_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
  static constexpr std::size_t capacity() { return N - 1; }

 private:
  std::array<T, N> slots_{};
  alignas(64) std::atomic<std::size_t> head_{0};
  alignas(64) std::atomic<std::size_t> tail_{0};
  alignas(64) std::atomic<std::size_t> dropped_{0};
};

}  // namespace visco::control
