#pragma once
// A LimitMalloc-style guard for tests: while a RealtimeGuard is alive on a thread, every heap allocation or free,
// mutex lock, C++ throw and stdio/socket I/O call made *by that thread* is counted. The hooks interpose the C
// library's functions in the test executable (operator new/delete everywhere; malloc, pthread_mutex_lock,
// __cxa_throw and I/O only in builds without sanitizers, which own those symbols themselves).

#include <cstdint>

namespace visco::control::testing {

struct RealtimeCounts {
  std::int64_t allocations = 0;  // malloc, calloc, realloc, aligned allocations, operator new
  std::int64_t frees = 0;        // free, operator delete
  std::int64_t locks = 0;        // pthread_mutex_lock / trylock
  std::int64_t throws = 0;       // __cxa_throw
  std::int64_t io = 0;           // read, write, send*, recv*, poll, select, printf family, fwrite, puts
};

/// True if malloc, locks, throws and I/O are hooked in this build (operator new/delete always are).
bool FullHooksActive();

class RealtimeGuard {
 public:
  RealtimeGuard();
  ~RealtimeGuard();
  RealtimeGuard(const RealtimeGuard&) = delete;
  RealtimeGuard& operator=(const RealtimeGuard&) = delete;
  /// What the guarded thread did since the guard was created.
  RealtimeCounts counts() const;
};

}  // namespace visco::control::testing
