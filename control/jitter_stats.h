#pragma once
// Wake-up latency statistics of the control loop (controller_telemetry_t's jitter fields).

#include <cstdint>
#include <limits>

namespace visco::control {

inline constexpr int kJitterBins = 16;

/// Histogram bin of a latency: bin 0 covers [0, 2) us, bin i >= 1 covers [2^i, 2^(i+1)) us, the last bin is
/// open-ended. Real-time safe.
inline int JitterBin(std::int64_t latency_ns) {
  const std::uint64_t us = latency_ns <= 0 ? 0 : static_cast<std::uint64_t>(latency_ns) / 1000;
  if (us < 2) return 0;
  const int bin = 63 - __builtin_clzll(us);
  return bin >= kJitterBins - 1 ? kJitterBins - 1 : bin;
}

/// Accumulates latencies. Real-time safe.
struct JitterStats {
  std::int64_t count = 0;
  std::int64_t min_ns = std::numeric_limits<std::int64_t>::max();
  std::int64_t max_ns = 0;
  double sum_ns = 0.0;
  std::int32_t histogram[kJitterBins] = {};

  void Record(std::int64_t latency_ns) {
    if (latency_ns < 0) latency_ns = 0;
    ++count;
    if (latency_ns < min_ns) min_ns = latency_ns;
    if (latency_ns > max_ns) max_ns = latency_ns;
    sum_ns += static_cast<double>(latency_ns);
    ++histogram[JitterBin(latency_ns)];
  }
  double mean_ns() const { return count > 0 ? sum_ns / static_cast<double>(count) : 0.0; }
  void Reset() { *this = JitterStats{}; }
};

}  // namespace visco::control
