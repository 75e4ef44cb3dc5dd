// pthread_once without glibc's system call per initialisation.
//
// CGAL 5.5's thread-safe lazy exact kernel (Epeck, used by every sweep) runs std::call_once on each lazy number or
// point the first time its exact value is needed, including those built from an exact value. glibc's pthread_once
// ends every first run with an unconditional futex_wake system call, waiters or not: a system call per exact
// evaluation, 25-35 % of `visco plan`'s time on this project's (paravirtualised) machines (perf;
// docs/planning_strategy.md "Speed"). This definition replaces glibc's for the whole process (the linker takes it from
// the planning archive before libc, and exports it, so shared libraries call it too): the same contract, and it wakes
// only when a thread waits. States: 0 not run (PTHREAD_ONCE_INIT), 1 running, 2 running with waiters, 3 done. An
// initialiser that throws (std::call_once with a throwing callable) resets the state to 0 and wakes the waiters, one of
// which runs it again. Not fork-generation aware: a child forked while another thread runs an initialiser must exec
// before using the same once control (visco's children exec at once).

#include <linux/futex.h>
#include <pthread.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <climits>

namespace {

constexpr int kNotRun = 0, kRunning = 1, kWaiting = 2, kDone = 3;

static_assert(sizeof(pthread_once_t) == sizeof(std::atomic<int>) && PTHREAD_ONCE_INIT == kNotRun);

void FutexWait(std::atomic<int>* state, int expected) {
  syscall(SYS_futex, reinterpret_cast<int*>(state), FUTEX_WAIT_PRIVATE, expected, nullptr, nullptr, 0);
}

void FutexWakeAll(std::atomic<int>* state) {
  syscall(SYS_futex, reinterpret_cast<int*>(state), FUTEX_WAKE_PRIVATE, INT_MAX, nullptr, nullptr, 0);
}

}  // namespace

extern "C" __attribute__((visibility("default"))) int pthread_once(pthread_once_t* control, void (*init)()) {
  auto* state = reinterpret_cast<std::atomic<int>*>(control);
  for (;;) {
    int seen = state->load(std::memory_order_acquire);
    if (seen == kDone) return 0;
    if (seen == kNotRun) {
      if (!state->compare_exchange_strong(seen, kRunning, std::memory_order_acquire)) continue;
      struct ResetIfThrown {
        std::atomic<int>* state;
        bool finished = false;
        ~ResetIfThrown() {
          if (!finished && state->exchange(kNotRun, std::memory_order_release) == kWaiting) FutexWakeAll(state);
        }
      } guard{state};
      init();
      guard.finished = true;
      if (state->exchange(kDone, std::memory_order_release) == kWaiting) FutexWakeAll(state);
      return 0;
    }
    if (seen == kRunning && !state->compare_exchange_strong(seen, kWaiting, std::memory_order_relaxed)) continue;
    FutexWait(state, kWaiting);
  }
}
