// The CiA 402 backend's real-time rule (drivers/robot_interface.h): in the loop, SetVelocity(), QuickStop(),
// Reset(), Step() and Read() never allocate, free, lock or throw, and their socket calls are the non-blocking reads
// and writes of the cyclic exchange. Cia402Robot in this process against the independent drive simulator
// (tests/drivers/hil/cia402_drive_sim.py, a python-can process) on vcan1, under a RealtimeGuard on the loop thread:
// motion, a quick stop, the driver's reset (re-enable), and the fault path (the simulator killed: the drives'
// heartbeats lost). Configure(), Activate() and Deactivate() (SDO traffic, waits) run outside the guard. Runs inside
// the VM of scripts/hil-vm (tests/drivers/hil/run_in_vm.sh), never on the host: the host kernel has no CAN.

#include <gtest/gtest.h>
#include <sched.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

#include "drivers/cia402_robot.h"
#include "drivers/robot_link.h"
#include "tests/control/realtime_guard.h"

extern char** environ;

namespace visco::drivers {
namespace {

using control::testing::FullHooksActive;
using control::testing::RealtimeCounts;
using control::testing::RealtimeGuard;

constexpr double kCounts = 100000.0;  // counts per metre, and counts/s per m/s

// The simulator as a process of its own (python3 and the repository top as the working directory, as in the VM),
// pinned to CPU 0 and the test to CPU 1: vcan hands frames to per-CPU backlog queues, so a sender that migrates
// between CPUs can have its frames delivered out of order (an old statusword after a new one), which a real bus
// cannot do.
class DriveSimulator {
 public:
  DriveSimulator() {
    std::vector<std::string> args = {"/usr/bin/taskset",
                                     "-c",
                                     "0",
                                     "/usr/bin/python3",
                                     "-S",
                                     "tests/drivers/hil/cia402_drive_sim.py",
                                     "--interface",
                                     "vcan1",
                                     "--nodes",
                                     "2",
                                     "3"};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, argv[0], nullptr, nullptr, argv.data(), environ) != 0) pid_ = -1;
  }
  ~DriveSimulator() { Kill(); }
  void Kill() {
    if (pid_ <= 0) return;
    kill(pid_, SIGKILL);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
  }
  bool started() const { return pid_ > 0; }

 private:
  pid_t pid_ = -1;
};

Cia402Config Config() {
  Cia402Config c;
  c.source = "cia402_realtime_hil_test";
  c.interface = "vcan1";
  c.mode = cia402::kModeCyclicSynchronousVelocity;
  c.sync_period_ms = 5.0;
  c.heartbeat_ms = 100.0;
  c.heartbeat_timeout_ms = 500.0;
  c.boot_timeout_ms = 30000.0;  // the simulator's python start-up under the emulated CPU
  c.sdo_timeout_ms = 1000.0;
  c.state_timeout_ms = 2000.0;
  for (int i = 0; i < 2; ++i) {
    c.axes[i].node = 2 + i;
    c.axes[i].counts_per_metre = kCounts;
    c.axes[i].velocity_units_per_mps = kCounts;
    c.axes[i].acceleration = 2.0;
    c.axes[i].quick_stop_deceleration = 20.0;
  }
  return c;
}

// The loop of the driver, at 1 kHz: `what` sets the command each period. Returns the longest Step() in µs. Runs for
// `seconds`, or until `done(robot.Read())` when given: the checks wait for a state, not for a time, which an
// emulated CPU under load stretches.
template <typename What, typename Done = std::nullptr_t>
double Loop(Cia402Robot& robot, double seconds, What what, Done done = nullptr) {
  const std::int64_t end = MonotonicMicros() + static_cast<std::int64_t>(seconds * 1e6);
  double longest_us = 0.0;
  timespec next{};
  clock_gettime(CLOCK_MONOTONIC, &next);
  while (MonotonicMicros() < end) {
    if constexpr (!std::is_same_v<Done, std::nullptr_t>) {
      if (done(robot.Read())) break;
    }
    what(robot);
    const std::int64_t before = MonotonicMicros();
    robot.Step(0.001);
    longest_us = std::max(longest_us, static_cast<double>(MonotonicMicros() - before));
    next.tv_nsec += 1'000'000;
    if (next.tv_nsec >= 1'000'000'000) {
      next.tv_nsec -= 1'000'000'000;
      ++next.tv_sec;
    }
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, nullptr);
  }
  return longest_us;
}

void ExpectRealtime(const RealtimeCounts& c, const char* phase) {
  EXPECT_EQ(c.allocations, 0) << phase;
  EXPECT_EQ(c.frees, 0) << phase;
  EXPECT_EQ(c.locks, 0) << phase;
  EXPECT_EQ(c.throws, 0) << phase;
  std::printf("cia402-rt: %-28s allocations %lld, frees %lld, locks %lld, throws %lld, socket calls %lld\n", phase,
              static_cast<long long>(c.allocations), static_cast<long long>(c.frees), static_cast<long long>(c.locks),
              static_cast<long long>(c.throws), static_cast<long long>(c.io));
}

TEST(Cia402RealtimeHil, TheLoopNeverAllocatesLocksOrThrowsInMotionStopsResetsAndFaults) {
  ASSERT_TRUE(FullHooksActive()) << "a sanitizer build: malloc, locks and I/O are not hooked";
  cpu_set_t cpu;
  CPU_ZERO(&cpu);
  CPU_SET(1, &cpu);
  ASSERT_EQ(sched_setaffinity(0, sizeof(cpu), &cpu), 0);
  DriveSimulator simulator;
  ASSERT_TRUE(simulator.started());
  Cia402Robot robot(Config(), Cia402DriverContext{0.5, 1, "vcan0"});
  robot.Configure();
  robot.Activate();
  robot.Reset();
  const double command[2] = {0.2, -0.1};
  const double zero[2] = {0.0, 0.0};
  // Warm-up: the drives enabled, the first motion (first calls of every path happen here), then 0.5 s at speed.
  Loop(
      robot, 5.0, [&](Cia402Robot& r) { r.SetVelocity(command); },
      [](const RobotFeedback& f) { return f.velocity[0] > 0.19 || f.fault; });
  Loop(robot, 0.5, [&](Cia402Robot& r) { r.SetVelocity(command); });
  ASSERT_FALSE(robot.Read().fault) << robot.Read().fault_message;
  ASSERT_EQ(robot.drive_state(0), cia402::DriveState::kOperationEnabled);

  {
    RealtimeGuard guard;
    double longest = Loop(robot, 1.0, [&](Cia402Robot& r) { r.SetVelocity(command); });
    const RobotFeedback moving = robot.Read();
    ExpectRealtime(guard.counts(), "motion (1 s)");
    EXPECT_NEAR(moving.velocity[0], 0.2, 1e-3);
    EXPECT_NEAR(moving.velocity[1], -0.1, 1e-3);
    EXPECT_FALSE(moving.fault) << moving.fault_message;
    std::printf("cia402-rt: motion: the drives report (%.4f, %.4f) m/s; longest Step() %.0f us\n", moving.velocity[0],
                moving.velocity[1], longest);
  }
  {
    RealtimeGuard guard;
    robot.QuickStop();
    Loop(
        robot, 3.0, [&](Cia402Robot& r) { r.SetVelocity(zero); },
        [](const RobotFeedback& f) { return (f.velocity[0] == 0.0 && f.velocity[1] == 0.0) || f.fault; });
    const RobotFeedback stopped = robot.Read();
    robot.Reset();
    // The drives go through shutdown, switch on and enable operation again, one SYNC-driven PDO exchange each,
    // then ramp up at 2 m/s^2: about 0.2 s on a quiet machine, several times that under emulation and load.
    const std::int64_t reset_at = MonotonicMicros();
    Loop(
        robot, 5.0, [&](Cia402Robot& r) { r.SetVelocity(command); },
        [](const RobotFeedback& f) { return f.velocity[0] > 0.1 || f.fault; });
    const double moving_after_s = static_cast<double>(MonotonicMicros() - reset_at) * 1e-6;
    const RobotFeedback again = robot.Read();
    ExpectRealtime(guard.counts(), "quick stop, reset, motion");
    EXPECT_EQ(stopped.velocity[0], 0.0);
    EXPECT_EQ(stopped.velocity[1], 0.0);
    EXPECT_FALSE(stopped.fault) << stopped.fault_message;
    EXPECT_GT(again.velocity[0], 0.1) << "moving again after the reset (waited " << moving_after_s << " s)";
    std::printf("cia402-rt: reset -> moving at > 0.1 m/s again after %.3f s\n", moving_after_s);
    EXPECT_FALSE(again.fault) << again.fault_message;
  }
  {
    simulator.Kill();  // outside the guard: the test's own process handling
    RealtimeGuard guard;
    Loop(robot, 1.0, [&](Cia402Robot& r) { r.SetVelocity(command); });
    const RobotFeedback lost = robot.Read();
    ExpectRealtime(guard.counts(), "drives lost (fault path)");
    EXPECT_TRUE(lost.fault);
    EXPECT_EQ(lost.fault_code, 0x8130) << lost.fault_message;
    std::printf("cia402-rt: drives lost: %s\n", lost.fault_message);
  }
  robot.Deactivate();
}

}  // namespace
}  // namespace visco::drivers
