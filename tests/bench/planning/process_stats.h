#pragma once
// What a planning benchmark reports of its own process beside the timings: its peak resident memory and its CPU time
// (both threads counted).

#include <time.h>

#include <fstream>
#include <string>

namespace visco::planning::bench {

// Peak memory of one benchmark: Linux resets the process's peak resident set (VmHWM) when "5" is written to
// /proc/self/clear_refs, so each benchmark reports its own peak, not the largest of the run so far. 0 where unknown.
inline void ResetPeakMemory() { std::ofstream("/proc/self/clear_refs") << "5"; }

inline double PeakMemoryMiB() {
  std::ifstream status("/proc/self/status");
  std::string key;
  while (status >> key) {
    if (key == "VmHWM:") {
      double kib = 0;
      status >> kib;
      return kib / 1024.0;
    }
    status.ignore(1 << 20, '\n');
  }
  return 0.0;
}

inline double ProcessCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

}  // namespace visco::planning::bench
