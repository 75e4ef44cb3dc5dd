#pragma once
// A `visco-rt driver --can vcan0` process for the HIL tests inside the VM (tests/drivers/hil/run_in_vm.sh): started
// pinned to CPU 1 (vcan hands frames to per-CPU backlog queues, so a sender that migrates between CPUs can have its
// frames delivered out of order, which a real bus cannot do and the driver would rightly reject), signalled, and
// killed and reaped with the test. The binary is $VISCO_BIN, else build/bin/visco-rt.

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <string>
#include <vector>

extern char** environ;

namespace visco::drivers::testing {

inline std::string VisCoRt() {
  const char* bin = std::getenv("VISCO_BIN");
  return bin != nullptr ? bin : "build/bin/visco-rt";
}

class DriverProcess {
 public:
  /// `driver_args`: what follows `visco-rt driver`.
  explicit DriverProcess(std::vector<std::string> driver_args) : args_(std::move(driver_args)) { Start(); }
  ~DriverProcess() { Kill(SIGTERM); }
  DriverProcess(const DriverProcess&) = delete;
  DriverProcess& operator=(const DriverProcess&) = delete;

  /// (Re)starts the process; false if it could not be spawned.
  bool Start() {
    std::vector<std::string> args = {"/usr/bin/taskset", "-c", "1", VisCoRt(), "driver"};
    args.insert(args.end(), args_.begin(), args_.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, argv[0], nullptr, nullptr, argv.data(), environ) != 0) pid_ = -1;
    return pid_ > 0;
  }
  bool started() const { return pid_ > 0; }
  /// Sends `signal` and reaps the process.
  void Kill(int signal) {
    if (pid_ <= 0) return;
    kill(pid_, signal);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
  }
  /// Sends `signal` (SIGSTOP/SIGCONT, SIGUSR1: the operator's e-stop release) without waiting.
  void Signal(int signal) {
    if (pid_ > 0) kill(pid_, signal);
  }

 private:
  std::vector<std::string> args_;
  pid_t pid_ = -1;
};

}  // namespace visco::drivers::testing
