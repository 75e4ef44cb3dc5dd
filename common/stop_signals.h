#pragma once
// The signals of visco's long-running commands (`visco run`, `visco sim`, `visco driver`), set up in one place:
// SIGINT and SIGTERM ask the command to stop through a flag it polls; SIGUSR1 is the operator's e-stop release at a
// robot driver (drivers/README.md), an action at the driver, never a bus message. The handlers only load and store
// atomics and call the given async-signal-safe function. Not real-time safe (set-up).

#include <atomic>

namespace visco {

/// From now on SIGINT and SIGTERM set `stop` to true. `stop` must live as long as the process (a static).
void StopOnSignals(std::atomic<bool>& stop);

/// From now on SIGUSR1 calls `release(context)`, which must be async-signal-safe (e.g. an atomic store such as
/// drivers::Driver::RequestOperatorRelease); system calls it interrupts restart.
void ReleaseOnSignal(void (*release)(void* context), void* context);

/// SIGUSR1 is ignored again and the release function forgotten (before its context goes away).
void IgnoreReleaseSignal();

}  // namespace visco
