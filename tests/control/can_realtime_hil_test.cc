// The real-time guard on the production path: the controller's loop (ControlLoop + Executor, as
// `visco run --can` runs it) over the SocketCAN link against a `visco-rt driver --can vcan0` process, with SCHED_FIFO
// and mlockall on, under a RealtimeGuard on the loop thread. Runs inside the VM of scripts/hil-vm
// (tests/drivers/hil/run_in_vm.sh), never on the host: the host kernel has no CAN.
//
// Each scenario warms up first (driver start-up, reset, the first motion: page faults and first calls happen there),
// then runs guarded to its end. Every stop path is driven under the guard: goal, e-stop, link fault (the driver
// killed), the driver's bounds fault, step time-out, bus-off, and overruns (the whole process stopped for 60 ms). In
// each: no allocation, free, lock or throw on the loop thread; socket calls bounded by the frames read plus one
// empty read and one write per period (the link reads and writes the non-blocking CAN sockets from the loop
// thread); no minor or major page fault after the warm-up; the robot stopped (or at the goal) as the driver reports.

#include <gtest/gtest.h>
#include <sched.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "control/control_loop.h"
#include "control/executor.h"
#include "drivers/can_protocol.h"
#include "drivers/robot_link.h"
#include "drivers/socketcan.h"
#include "tests/control/harness.h"
#include "tests/control/realtime_guard.h"
#include "tests/drivers/hil/driver_process.h"

namespace visco::control {
namespace {

using testing::RealtimeCounts;
using testing::RealtimeGuard;

constexpr int kNode = 5;  // not the drivers HIL test's node 1: its frames stay apart in the boot's candump
constexpr std::int64_t kStartTimeoutUs = 120'000'000;

// A driver process of its own per scenario (a fresh session, no latched e-stop).
class DriverProcess : public drivers::testing::DriverProcess {
 public:
  explicit DriverProcess(const std::vector<std::string>& extra) : drivers::testing::DriverProcess(Args(extra)) {}

 private:
  static std::vector<std::string> Args(const std::vector<std::string>& extra) {
    std::vector<std::string> args = {"--can",   "vcan0",       "--node", std::to_string(kNode), "--watchdog-ms",
                                     "300",     "--max-speed", "0.5",    "--velocity-cone-deg", "0",
                                     "--start", "0",           "0"};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  }
};

struct PageFaults {
  long minor = 0;
  long major = 0;
};

PageFaults ThreadPageFaults() {
  rusage usage{};
  getrusage(RUSAGE_THREAD, &usage);
  return {usage.ru_minflt, usage.ru_majflt};
}

// What a scenario did.
struct Outcome {
  RealtimeSetup setup;
  Mode mode = Mode::kIdle;
  FaultCode stop_code = FaultCode::kNone;
  std::string stop_reason;
  RealtimeCounts counts;
  PageFaults faults;
  std::int64_t guarded_cycles = 0;
  std::int64_t overruns = 0;
  std::uint64_t frames_read = 0;  // by the link during the guarded part
  std::vector<FaultEvent> events;
  drivers::RobotStatus final_status;  // the driver's, read after the run
  bool have_final_status = false;
};

struct Scenario {
  Task task;
  ExecutorConfig config;
  std::vector<std::string> driver_args;
  // Runs on the test's thread once the guarded part has started: the fault to inject.
  std::function<void(DriverProcess& driver, std::atomic<bool>& estop)> during = [](DriverProcess&, std::atomic<bool>&) {
  };
  std::int64_t warmup_cycles = 400;  // 0.8 s at 500 Hz: start-up, reset, the first motion
  std::int64_t max_cycles = 5000;
};

Task StraightTask(double theta, double timeout_s, std::optional<Polygon> goal) {
  Task task;
  Step step;
  step.theta = theta;
  step.terminate = TerminateKind::kGoal;
  step.timeout_s = timeout_s;
  task.steps.push_back(step);
  task.speed = 0.2;
  task.goal = std::move(goal);
  return task;
}

ExecutorConfig BaseConfig() {
  ExecutorConfig config;
  config.period_s = 0.002;  // 500 Hz, `visco run`'s default
  config.limits.max_speed = 0.3;
  config.limits.max_accel = 2.0;  // the default limits (the driver's quick stop is 50 m/s^2)
  config.goal_from_odometry = true;
  // The emulated CPU of the VM stalls the driver process for up to ~100 ms when the host is busy.
  config.heartbeat_timeout_s = 0.5;
  config.startup_timeout_s = 60.0;
  return config;
}

drivers::RobotLinkConfig LinkConfig() {
  drivers::RobotLinkConfig config;
  config.node_id = kNode;
  config.can_interface = "vcan0";
  config.heartbeat_timeout_us = 500'000;
  return config;
}

// Waits (outside any guard) for the driver's heartbeat on a link of its own: the process start on the emulated CPU.
bool WaitForDriver() {
  const auto link = drivers::MakeSocketCanRobotLink(LinkConfig());
  const std::int64_t end = drivers::MonotonicMicros() + kStartTimeoutUs;
  while (drivers::MonotonicMicros() < end) {
    link->Poll(drivers::MonotonicMicros());
    if (link->peer_state(drivers::MonotonicMicros()) == drivers::PeerState::kAlive) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

Outcome RunScenario(Scenario& s) {
  Outcome out;
  // This process on CPU 0, the driver on CPU 1 (as in the drivers HIL test): vcan hands frames to per-CPU backlog
  // queues, so a sender migrating between CPUs could have its frames delivered out of order.
  cpu_set_t cpus;
  CPU_ZERO(&cpus);
  CPU_SET(0, &cpus);
  sched_setaffinity(0, sizeof(cpus), &cpus);
  DriverProcess driver(s.driver_args);
  EXPECT_TRUE(driver.started());
  if (!driver.started() || !WaitForDriver()) {
    ADD_FAILURE() << "no heartbeat from the driver process";
    return out;
  }
  const auto link = drivers::MakeSocketCanRobotLink(LinkConfig());
  Executor executor(s.task, s.config);
  Outbox outbox;
  LoopConfig loop_config;
  loop_config.period_s = s.config.period_s;
  loop_config.realtime = true;
  std::atomic<bool> estop{false};
  LoopSources sources{link.get(), nullptr, nullptr, &estop};
  ControlLoop loop(executor, sources, loop_config, outbox);

  std::atomic<bool> stop{false};
  std::atomic<bool> guarded{false};
  std::atomic<bool> loop_done{false};
  std::thread consumer([&] {  // the publisher's side: empties the queues
    TelemetrySnapshot t;
    FaultEvent f;
    for (;;) {
      const bool last = loop_done.load(std::memory_order_acquire);
      outbox.Wait(0.01);
      while (outbox.telemetry.TryPop(t)) {
      }
      while (outbox.faults.TryPop(f)) out.events.push_back(f);
      if (last) break;
    }
  });
  std::thread rt([&] {
    out.setup = ConfigureRealtime(loop_config.priority, true);
    executor.Start(MonotonicNs());
    loop.Run(stop, s.warmup_cycles);
    const std::uint64_t read_before = link->counters().frames_read;
    const std::int64_t cycles_before = loop.cycles();
    const PageFaults before = ThreadPageFaults();
    {
      guarded.store(true, std::memory_order_release);
      RealtimeGuard guard;
      loop.Run(stop, s.max_cycles);
      out.counts = guard.counts();
    }
    const PageFaults after = ThreadPageFaults();
    out.faults = {after.minor - before.minor, after.major - before.major};
    out.guarded_cycles = loop.cycles() - cycles_before;
    out.frames_read = link->counters().frames_read - read_before;
    loop_done.store(true, std::memory_order_release);
  });
  while (!guarded.load(std::memory_order_acquire) && !loop_done.load(std::memory_order_acquire)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  if (guarded.load()) s.during(driver, estop);
  rt.join();
  consumer.join();
  out.mode = executor.mode();
  out.stop_code = executor.stop_code();
  out.stop_reason = executor.stop_reason();
  out.overruns = loop.overruns();
  // What the driver says now (unless it was killed): read on this thread, after the loop.
  const std::int64_t end = drivers::MonotonicMicros() + 1'000'000;
  while (drivers::MonotonicMicros() < end) {
    link->Poll(drivers::MonotonicMicros());
    drivers::RobotStatus status;
    if (link->TakeStatus(status) == drivers::LinkResult::kOk) {
      out.final_status = status;
      out.have_final_status = true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return out;
}

// A run the host starved: the loop never got going (10 periods or fewer before it stopped) or stalled for longer
// than `max_stall_ms` in all (overruns). On a busy host the emulated CPU can lose a second at a time; the loop then
// rightly stops for what that looks like (the kernel dropping the driver's frames, its heartbeat lost), which tests
// the starvation, not the scenario. A starved run that did not end as `expected` (mode and stop code) is printed and
// run again, at most three times in all: a scenario that fails for its own reasons fails every time.
Outcome RunOnAHostThatKeepsUp(Scenario& s, Mode mode, FaultCode code, double max_stall_ms = 200) {
  Outcome o;
  for (int attempt = 1; attempt <= 3; ++attempt) {
    o = RunScenario(s);
    const double stall_ms = static_cast<double>(o.overruns) * s.config.period_s * 1e3;
    const bool starved = o.guarded_cycles <= 10 || stall_ms >= max_stall_ms;
    if (!starved || (o.mode == mode && (mode == Mode::kDone || o.stop_code == code))) break;
    std::printf("hil-rt: run %d starved by the host (%lld guarded periods, about %.0f ms of overruns, stop: %s)%s\n",
                attempt, static_cast<long long>(o.guarded_cycles), stall_ms, o.stop_reason.c_str(),
                attempt < 3 ? ": run again" : "");
  }
  return o;
}

void ExpectRealtimeClean(const Outcome& o, const char* name) {
  SCOPED_TRACE(name);
  EXPECT_TRUE(o.setup.fifo) << o.setup.message;
  EXPECT_TRUE(o.setup.locked) << o.setup.message;
  EXPECT_TRUE(testing::FullHooksActive());
  EXPECT_GT(o.guarded_cycles, 10);
  EXPECT_EQ(o.counts.allocations, 0);
  EXPECT_EQ(o.counts.frees, 0);
  EXPECT_EQ(o.counts.locks, 0);
  EXPECT_EQ(o.counts.throws, 0);
  // Per period: the frames read, one read that finds the queue empty, one command written.
  EXPECT_LE(o.counts.io, static_cast<std::int64_t>(o.frames_read) + 2 * o.guarded_cycles);
  EXPECT_EQ(o.faults.minor, 0) << "minor page faults on the loop thread after the warm-up";
  EXPECT_EQ(o.faults.major, 0) << "major page faults on the loop thread after the warm-up";
  std::printf(
      "hil-rt: %-10s %s: %lld guarded periods, %lld socket calls (%llu frames read), page faults %ld/%ld, "
      "overruns %lld, stop: %s\n",
      name, ToString(o.mode), static_cast<long long>(o.guarded_cycles), static_cast<long long>(o.counts.io),
      static_cast<unsigned long long>(o.frames_read), o.faults.minor, o.faults.major,
      static_cast<long long>(o.overruns), o.stop_reason.empty() ? "-" : o.stop_reason.c_str());
}

bool Reported(const Outcome& o, FaultCode code, bool stopped) {
  for (const FaultEvent& f : o.events) {
    if (f.code == code && f.robot_stopped == stopped && !f.cleared) return true;
  }
  return false;
}

void ExpectStoppedByTheDriver(const Outcome& o) {
  ASSERT_TRUE(o.have_final_status) << "no status from the driver after the run";
  EXPECT_EQ(o.final_status.velocity[0], 0.0);
  EXPECT_EQ(o.final_status.velocity[1], 0.0);
  EXPECT_NE(o.final_status.state, drivers::RobotState::kMoving);
}

TEST(CanRealtimeHil, GoalWithOverrunsUnderTheGuard) {
  Scenario s;
  s.task = StraightTask(0.0, 0.0, testing::Square({0.35, 0.0}, 0.03));
  s.config = BaseConfig();
  // The whole process (loop thread included) stopped for 60 ms from outside: the loop misses ~30 deadlines,
  // counts them and reports an overrun, still under the guard.
  s.during = [](DriverProcess&, std::atomic<bool>&) {
    const std::string pid = std::to_string(getpid());
    const std::string cmd = "(sleep 0.2; kill -STOP " + pid + "; sleep 0.06; kill -CONT " + pid + ") &";
    ASSERT_EQ(std::system(cmd.c_str()), 0);
  };
  // The pause is 60 ms (~30 periods) when the (emulated) machine keeps up; a busy host can stretch it past the
  // driver's 300 ms watchdog, which then rightly stops the robot: that run tested the watchdog, not the overrun.
  const Outcome o = RunOnAHostThatKeepsUp(s, Mode::kDone, FaultCode::kNone);
  ExpectRealtimeClean(o, "goal");
  EXPECT_EQ(o.mode, Mode::kDone) << o.stop_reason;
  EXPECT_GT(o.overruns, 10);
  EXPECT_TRUE(Reported(o, FaultCode::kOverrun, false)) << "the overrun was not reported";
  ExpectStoppedByTheDriver(o);
  EXPECT_NEAR(o.final_status.position[0], 0.35, 0.05);
}

TEST(CanRealtimeHil, EStopUnderTheGuard) {
  Scenario s;
  s.task = StraightTask(0.0, 0.0, testing::Square({5.0, 0.0}, 0.03));
  s.config = BaseConfig();
  // As `visco run`'s LCM bridge sets it on VISCO_ESTOP.
  s.during = [](DriverProcess&, std::atomic<bool>& estop) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    estop.store(true, std::memory_order_release);
  };
  const Outcome o = RunOnAHostThatKeepsUp(s, Mode::kStopped, FaultCode::kEstop);
  ExpectRealtimeClean(o, "e-stop");
  EXPECT_EQ(o.mode, Mode::kStopped);
  EXPECT_EQ(o.stop_code, FaultCode::kEstop) << o.stop_reason;
  EXPECT_TRUE(Reported(o, FaultCode::kEstop, true));
  ExpectStoppedByTheDriver(o);
  EXPECT_EQ(o.final_status.state, drivers::RobotState::kEStop) << "the driver latched the e-stop";
}

TEST(CanRealtimeHil, KilledDriverUnderTheGuard) {
  Scenario s;
  s.task = StraightTask(0.0, 0.0, testing::Square({5.0, 0.0}, 0.03));
  s.config = BaseConfig();
  s.during = [](DriverProcess& driver, std::atomic<bool>&) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    driver.Kill(SIGKILL);
  };
  const Outcome o = RunOnAHostThatKeepsUp(s, Mode::kStopped, FaultCode::kPeerTimeout);
  ExpectRealtimeClean(o, "link fault");
  EXPECT_EQ(o.mode, Mode::kStopped);
  EXPECT_EQ(o.stop_code, FaultCode::kPeerTimeout) << o.stop_reason;
  EXPECT_TRUE(Reported(o, FaultCode::kPeerTimeout, true));
}

TEST(CanRealtimeHil, DriverBoundsFaultUnderTheGuard) {
  Scenario s;
  // Towards the driver's workspace border at x = 0.3: the driver stops the robot on it and raises its bounds fault.
  s.task = StraightTask(0.0, 0.0, testing::Square({5.0, 0.0}, 0.03));
  s.config = BaseConfig();
  s.driver_args = {"--workspace", "-1", "-1", "0.3", "1"};
  const Outcome o = RunOnAHostThatKeepsUp(s, Mode::kStopped, FaultCode::kLimit);
  ExpectRealtimeClean(o, "bounds");
  EXPECT_EQ(o.mode, Mode::kStopped);
  EXPECT_EQ(o.stop_code, FaultCode::kLimit) << o.stop_reason;
  ExpectStoppedByTheDriver(o);
  EXPECT_LE(o.final_status.position[0], 0.3 + 1e-6);
}

TEST(CanRealtimeHil, StepTimeOutUnderTheGuard) {
  Scenario s;
  s.task = StraightTask(0.0, 1.5, testing::Square({5.0, 0.0}, 0.03));
  s.config = BaseConfig();
  const Outcome o = RunOnAHostThatKeepsUp(s, Mode::kStopped, FaultCode::kStepTimeout);
  ExpectRealtimeClean(o, "time-out");
  EXPECT_EQ(o.mode, Mode::kStopped);
  EXPECT_EQ(o.stop_code, FaultCode::kStepTimeout) << o.stop_reason;
  ExpectStoppedByTheDriver(o);
}

TEST(CanRealtimeHil, BusOffUnderTheGuard) {
  Scenario s;
  s.task = StraightTask(0.0, 0.0, testing::Square({5.0, 0.0}, 0.03));
  s.config = BaseConfig();
  s.during = [](DriverProcess&, std::atomic<bool>&) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    drivers::CanSocketOptions options;
    options.interface = "vcan0";
    options.receive = false;
    drivers::CanSocket injector(options);
    drivers::can::Frame off;
    off.id = drivers::can::kErrFlag | drivers::can::kErrBusOff;
    off.dlc = 8;
    ASSERT_EQ(injector.Write(off), drivers::CanIo::kOk);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    drivers::can::Frame restarted = off;
    restarted.id = drivers::can::kErrFlag | drivers::can::kErrRestarted;
    ASSERT_EQ(injector.Write(restarted), drivers::CanIo::kOk);
  };
  const Outcome o = RunOnAHostThatKeepsUp(s, Mode::kStopped, FaultCode::kCanError);
  ExpectRealtimeClean(o, "bus-off");
  EXPECT_EQ(o.mode, Mode::kStopped);
  EXPECT_EQ(o.stop_code, FaultCode::kCanError) << o.stop_reason;
  ExpectStoppedByTheDriver(o);
}

}  // namespace
}  // namespace visco::control
