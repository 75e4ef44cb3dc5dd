#include "common/stop_signals.h"

#include <signal.h>

namespace visco {
namespace {

std::atomic<std::atomic<bool>*> g_stop{nullptr};
std::atomic<void (*)(void*)> g_release{nullptr};
std::atomic<void*> g_release_context{nullptr};

void OnStop(int) {
  if (std::atomic<bool>* stop = g_stop.load()) stop->store(true);
}

void OnRelease(int) {
  if (void (*release)(void*) = g_release.load()) release(g_release_context.load());
}

}  // namespace

void StopOnSignals(std::atomic<bool>& stop) {
  g_stop.store(&stop);
  struct sigaction action {};
  action.sa_handler = OnStop;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

void ReleaseOnSignal(void (*release)(void* context), void* context) {
  g_release_context.store(context);
  g_release.store(release);
  struct sigaction action {};
  action.sa_handler = OnRelease;
  action.sa_flags = SA_RESTART;
  sigaction(SIGUSR1, &action, nullptr);
}

void IgnoreReleaseSignal() {
  signal(SIGUSR1, SIG_IGN);
  g_release.store(nullptr);
  g_release_context.store(nullptr);
}

}  // namespace visco
