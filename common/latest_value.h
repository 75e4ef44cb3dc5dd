#pragma once
// Lock-free single-producer / single-consumer "latest value" hand-off (a triple buffer).
// The producer (a vision or LCM thread) publishes whole values; the consumer (the real-time loop) reads the newest
// one without locks, waiting or allocation. Values the consumer never saw are simply overwritten.

#include <atomic>
#include <cstdint>
#include <type_traits>

namespace visco {

template <typename T>
class LatestValue {
  static_assert(std::is_trivially_copyable_v<T>, "LatestValue<T> copies T across threads; keep T a plain struct");

 public:
  LatestValue() = default;
  LatestValue(const LatestValue&) = delete;
  LatestValue& operator=(const LatestValue&) = delete;

  /// Publishes `value` (producer side; one producer thread only). Real-time safe: wait-free, no allocation.
  void Publish(const T& value) {
    slots_[back_] = value;
    // Hand the freshly written slot to the middle position and take the old middle slot as the new back slot.
    const std::uint8_t previous =
        middle_.exchange(static_cast<std::uint8_t>(back_ | kFreshBit), std::memory_order_acq_rel);
    back_ = previous & kIndexMask;
    published_.fetch_add(1, std::memory_order_relaxed);
  }

  /// Copies the newest value into `out` if one was published since the last call (consumer side; one consumer
  /// thread only). Returns false, leaving `out` untouched, if nothing new arrived. Real-time safe: wait-free.
  bool TryTake(T& out) {
    if ((middle_.load(std::memory_order_relaxed) & kFreshBit) == 0) return false;
    const std::uint8_t previous = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = previous & kIndexMask;
    out = slots_[front_];
    return true;
  }

  /// Number of values published so far (any thread; for diagnostics).
  std::uint64_t published() const { return published_.load(std::memory_order_relaxed); }

 private:
  static constexpr std::uint8_t kFreshBit = 0x4;
  static constexpr std::uint8_t kIndexMask = 0x3;
  T slots_[3]{};
  std::uint8_t back_ = 0;                // producer-owned slot index
  std::atomic<std::uint8_t> middle_{1};  // shared slot index | kFreshBit when it holds an unread value
  std::uint8_t front_ = 2;               // consumer-owned slot index
  std::atomic<std::uint64_t> published_{0};
};

}  // namespace visco
