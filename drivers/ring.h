#pragma once
// Fixed-capacity queues without allocation: a single-thread FIFO and a lock-free single-producer/single-consumer
// FIFO for hand-offs between a real-time thread and an I/O thread.

#include <array>
#include <atomic>
#include <cstddef>
#include <type_traits>

namespace visco::drivers {

/// Single-thread FIFO of at most N values. Real-time safe.
template <typename T, std::size_t N>
class FixedQueue {
 public:
  /// Appends `value`; false (value dropped) when full.
  bool Push(const T& value) {
    if (size_ == N) return false;
    items_[(head_ + size_) % N] = value;
    ++size_;
    return true;
  }
  bool Pop(T& out) {
    if (size_ == 0) return false;
    out = items_[head_];
    head_ = (head_ + 1) % N;
    --size_;
    return true;
  }
  std::size_t size() const { return size_; }

 private:
  std::array<T, N> items_{};
  std::size_t head_ = 0;
  std::size_t size_ = 0;
};

/// Lock-free SPSC FIFO of at most N-1 values (one producer thread, one consumer thread). Wait-free, no allocation.
template <typename T, std::size_t N>
class SpscQueue {
  static_assert(std::is_trivially_copyable_v<T>, "SpscQueue copies T across threads; keep T a plain struct");

 public:
  bool Push(const T& value) {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    const std::size_t next = (tail + 1) % N;
    if (next == head_.load(std::memory_order_acquire)) return false;
    items_[tail] = value;
    tail_.store(next, std::memory_order_release);
    return true;
  }
  bool Pop(T& out) {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head == tail_.load(std::memory_order_acquire)) return false;
    out = items_[head];
    head_.store((head + 1) % N, std::memory_order_release);
    return true;
  }

 private:
  std::array<T, N> items_{};
  std::atomic<std::size_t> head_{0};
  std::atomic<std::size_t> tail_{0};
};

}  // namespace visco::drivers
