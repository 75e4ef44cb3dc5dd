// The loop in real time (1 kHz, clock_nanosleep) against a simulated driver thread and a simulated camera thread,
// under a RealtimeGuard on the loop thread: a visual compliant motion to contact, a vision drop-out (hold and
// resume), goal recognition, then a driver whose heartbeat stops. The loop thread must not allocate, free, lock,
// throw or do I/O in any of it.

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <mutex>
#include <numbers>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "common/latest_value.h"
#include "control/control_loop.h"
#include "control/loopback_link.h"
#include "control/synthetic_camera.h"
#include "drivers/can_protocol.h"
#include "drivers/driver.h"
#include "drivers/driver_transport.h"
#include "drivers/robot_link.h"
#include "drivers/simulated_robot.h"
#include "tests/control/harness.h"
#include "tests/control/realtime_guard.h"

namespace visco::control {
namespace {

using testing::RealtimeCounts;
using testing::RealtimeGuard;

TEST(RealtimeGuard, CountsWhatItShould) {
  FILE* sink = std::fopen("/dev/null", "w");
  ASSERT_NE(sink, nullptr);
  RealtimeGuard guard;
  // Through a volatile pointer: GCC may otherwise drop a new/delete pair whose memory is never used (it did in the
  // TSan build, where only operator new/delete are hooked and nothing else counted a free).
  int* volatile p = new int(3);
  delete p;
  std::vector<int> v(10);
  v.clear();
  std::mutex m;
  m.lock();
  m.unlock();
  try {
    throw 1;
  } catch (int) {
  }
  std::fprintf(sink, "%d", 42);
  const RealtimeCounts c = guard.counts();
  std::fclose(sink);
  EXPECT_GE(c.allocations, 2);
  EXPECT_GE(c.frees, 1);
  if (testing::FullHooksActive()) {
    EXPECT_GE(c.locks, 1);
    EXPECT_GE(c.throws, 1);
    EXPECT_GE(c.io, 1);
  } else {
    // Not silently: in this build the real-time tests below check allocations and frees only.
    std::printf(
        "RealtimeGuard: sanitizer build: only operator new/delete are hooked (ASan/TSan own malloc, "
        "pthread_mutex_lock, __cxa_throw and the I/O calls); locks, throws and I/O are counted in the normal "
        "build only\n");
    RecordProperty("full_hooks", 0);
  }
}

// A driver thread at 1 kHz (plant, status, heartbeat) and a camera thread at 30 Hz (events, estimate), both fed
// through the same lock-free hand-offs the real bridge uses.
class World {
 public:
  /// `camera`: a calibrated camera measures (default: the planar model).
  World(const Task& task, Vec2 start, const ServoCamera* camera = nullptr) : camera_(task, {800.0, 1.0, 0.0}, 3) {
    if (camera != nullptr) camera_.UseCamera(*camera);
    plant_.position = start;
    plant_.walls.push_back({{0.0, 0.0}, {0.0, 1.0}});
    plant_.friction = 0.5;
  }
  ~World() { Stop(); }

  void Start() {
    running_ = true;
    driver_ = std::thread([this] { DriverLoop(); });
    camera_thread_ = std::thread([this] { CameraLoop(); });
  }
  void Stop() {
    running_ = false;
    if (driver_.joinable()) driver_.join();
    if (camera_thread_.joinable()) camera_thread_.join();
  }

  LoopbackLink link;
  LatestValue<VisualFrame> frames;
  LatestValue<PositionEstimate> estimates;
  std::atomic<bool> camera_on{true};
  std::atomic<bool> heartbeat_on{true};

  Vec2 position() {
    std::lock_guard<std::mutex> lock(mutex_);
    return plant_.position;
  }

 private:
  void DriverLoop() {
    LoopbackLink::Sent sent;
    std::uint32_t seq = 0;
    auto next = std::chrono::steady_clock::now();
    while (running_) {
      next += std::chrono::milliseconds(1);
      std::this_thread::sleep_until(next);
      link.RobotTakeCommand(sent);
      drivers::RobotStatus status;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        plant_.Step(sent.command.estop ? Vec2{} : Vec2{sent.command.velocity[0], sent.command.velocity[1]}, 0.001);
        status.position[0] = plant_.position.x;
        status.position[1] = plant_.position.y;
        status.velocity[0] = plant_.velocity.x;
        status.velocity[1] = plant_.velocity.y;
        status.contact = plant_.contact;
      }
      if (!heartbeat_on) continue;  // a dead driver: no status, no heartbeat
      status.seq = ++seq;
      status.command_seq = sent.seq;
      status.state = drivers::RobotState::kReady;
      link.RobotPublishStatus(status);
      if (seq % 10 == 0) link.RobotHeartbeat();
    }
  }
  void CameraLoop() {
    std::int64_t seq = 0;
    auto next = std::chrono::steady_clock::now();
    while (running_) {
      next += std::chrono::microseconds(33333);
      std::this_thread::sleep_until(next);
      if (!camera_on) continue;
      const std::int64_t capture = MonotonicNs();
      const Vec2 q = position();
      VisualFrame frame;
      camera_.Observe(q, ++seq, capture, frame);
      frames.Publish(frame);
      PositionEstimate estimate;
      estimate.capture_ns = capture;
      estimate.valid = true;
      estimate.position = q;
      estimates.Publish(estimate);
    }
  }

  SyntheticCamera camera_;
  std::mutex mutex_;  // plant shared by the two simulation threads (never touched by the loop)
  testing::TestPlant plant_;
  std::atomic<bool> running_{false};
  std::thread driver_;
  std::thread camera_thread_;
};

Task Scenario() {
  Task task;
  // A vertical VC ray x = 1.2 (obstacle vertex on the floor, camera above); the CM vertex is the reference point.
  task.rays.push_back(testing::MakeRay("vc0.cm0", {1.2, 0.0}, {1.2, 3.0}, 0, {0.0, 0.0}));
  testing::IndexRays(task);
  task.speed = 0.2;
  Step comply;  // down and slightly right: reach the ray, comply down along it to the floor
  comply.theta = -80.0 * std::numbers::pi / 180;
  comply.active_rays = {0};
  comply.terminate = TerminateKind::kContact;
  task.steps.push_back(comply);
  Step goal;  // along the floor into the goal
  goal.theta = 0.0;
  goal.terminate = TerminateKind::kGoal;
  task.steps.push_back(goal);
  task.goal = testing::Square({1.5, 0.05}, 0.1);
  task.position_uncertainty = 0.01;
  return task;
}

struct Collected {
  std::set<int> modes;
  std::vector<FaultEvent> faults;
  TelemetrySnapshot last;
};

// Drains the outbox on a non-real-time thread while the loop runs.
void Drain(Outbox& outbox, Collected& collected, std::mutex& mutex) {
  TelemetrySnapshot t;
  FaultEvent f;
  std::lock_guard<std::mutex> lock(mutex);
  while (outbox.telemetry.TryPop(t)) {
    collected.modes.insert(static_cast<int>(t.mode));
    collected.last = t;
  }
  while (outbox.faults.TryPop(f)) collected.faults.push_back(f);
}

// A camera 2.5 m above the ray's end (1.2, 3), looking at (1.2, 0.1) on the floor: 49 degrees from the vertical.
ServoCamera TiltedCamera() {
  const double eye[3] = {1.2, 3.0, 2.5}, target[3] = {1.2, 0.1, 0.0};
  double z[3] = {target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]};
  const double nz = std::sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]);
  for (double& c : z) c /= nz;
  double x[3] = {z[1], -z[0], 0.0};  // z x (0, 0, 1)
  const double nx = std::hypot(x[0], x[1]);
  x[0] /= nx, x[1] /= nx;
  const double y[3] = {z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]};
  const double wRc[3][3] = {{x[0], y[0], z[0]}, {x[1], y[1], z[1]}, {x[2], y[2], z[2]}};
  return MakeServoCamera(560, 560, 319.5, 239.5, wRc, eye, 0.3);
}

// The steady state of a two-step run (comply down the ray, then along the floor into the goal) with a vision
// drop-out, under the guard; with `camera`, the servo law's calibrated camera (servo_law.h) measures and servos.
void SteadyStateUnderTheGuard(const ServoCamera* camera) {
  const Task task = Scenario();
  ExecutorConfig config;
  if (camera != nullptr) config.servo.camera = *camera;
  config.period_s = 0.001;
  config.limits.max_speed = 0.3;
  config.limits.max_accel = 4.0;
  // Not 50 ms: the simulated driver is a plain thread that a loaded machine can starve for longer (seen: 70 ms
  // with two builds running); driver silence has its own test below.
  config.heartbeat_timeout_s = 0.5;
  Executor executor(task, config);
  World world(task, {1.19, 0.25}, camera);
  Outbox outbox;
  LoopConfig loop_config;
  loop_config.period_s = 0.001;
  loop_config.realtime = false;
  LoopSources sources{&world.link, &world.frames, &world.estimates, nullptr};
  // The period records of an event log (`visco run --log`) leave the loop too: pushing them is part of the proof.
  auto records = std::make_unique<CycleRecordQueue>();
  sources.records = records.get();
  ControlLoop loop(executor, sources, loop_config, outbox);

  Collected collected;
  std::mutex collected_mutex;
  std::atomic<bool> stop{false};
  std::atomic<bool> done{false};
  std::int64_t recorded = 0, record_order_errors = 0, next_record = 0;
  auto drain_records = [&] {
    CycleRecord r;
    while (records->TryPop(r)) {
      record_order_errors += r.cycle < next_record ? 1 : 0;
      next_record = r.cycle + 1;
      ++recorded;
    }
  };
  std::thread consumer([&] {
    while (!done) {
      outbox.Wait(0.01);
      Drain(outbox, collected, collected_mutex);
      drain_records();
    }
  });
  // Vision drops out for 200 ms while the robot slides down the ray, then returns.
  std::thread dropout([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(700));
    world.camera_on = false;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    world.camera_on = true;
  });
  world.Start();
  RealtimeCounts counts;
  std::thread rt([&] {
    executor.Start(MonotonicNs());
    RealtimeGuard guard;
    loop.Run(stop, 10000);
    counts = guard.counts();
  });
  rt.join();
  dropout.join();
  world.Stop();
  done = true;
  consumer.join();
  Drain(outbox, collected, collected_mutex);
  drain_records();

  EXPECT_EQ(executor.mode(), Mode::kDone) << executor.stop_reason();
  EXPECT_EQ(recorded + static_cast<std::int64_t>(records->dropped()), loop.cycles());  // one record per period
  EXPECT_GT(recorded, 0);
  EXPECT_EQ(record_order_errors, 0);
  EXPECT_TRUE(collected.modes.count(static_cast<int>(Mode::kVisualCompliant)));
  EXPECT_TRUE(collected.modes.count(static_cast<int>(Mode::kDone)));
  bool held = false, resumed = false;
  for (const FaultEvent& f : collected.faults) {
    held |= f.code == FaultCode::kVisionStale && !f.cleared;
    resumed |= f.code == FaultCode::kVisionStale && f.cleared;
  }
  EXPECT_TRUE(held);
  EXPECT_TRUE(resumed);
  // ~2800 periods at 1 kHz on an idle machine; a loaded one (CI runs tests two at a time, ASan too) wakes this
  // unprivileged thread late and runs far fewer (689 seen at load 6). Enough to have cycled through every mode.
  EXPECT_GT(loop.cycles(), 300);
  EXPECT_EQ(counts.allocations, 0);
  EXPECT_EQ(counts.frees, 0);
  EXPECT_EQ(counts.locks, 0);
  EXPECT_EQ(counts.throws, 0);
  EXPECT_EQ(counts.io, 0);
  // The jitter histogram accounts for every cycle.
  std::int64_t histogram_total = 0;
  for (int i = 0; i < kJitterBins; ++i) histogram_total += loop.total_jitter().histogram[i];
  EXPECT_EQ(histogram_total, loop.cycles());
  ::testing::Test::RecordProperty("cycles", static_cast<int>(loop.cycles()));
  ::testing::Test::RecordProperty("overruns", static_cast<int>(loop.overruns()));
}

TEST(RealtimeLoop, SteadyStateIsAllocationLockExceptionAndIoFree) { SteadyStateUnderTheGuard(nullptr); }

TEST(RealtimeLoop, SteadyStateWithTheCalibratedCameraIsAllocationLockExceptionAndIoFree) {
  const ServoCamera camera = TiltedCamera();
  SteadyStateUnderTheGuard(&camera);
}

TEST(RealtimeLoop, DriverSilenceStopsWithinTheTimeoutAllocationFree) {
  Task task;
  Step step;
  step.terminate = TerminateKind::kContact;
  task.steps.push_back(step);
  task.speed = 0.05;
  ExecutorConfig config;
  config.period_s = 0.001;
  config.heartbeat_timeout_s = 0.05;
  Executor executor(task, config);
  World world(task, {1.0, 0.5});
  Outbox outbox;
  LoopConfig loop_config;
  loop_config.period_s = 0.001;
  loop_config.realtime = false;
  LoopSources sources{&world.link, &world.frames, &world.estimates, nullptr};
  ControlLoop loop(executor, sources, loop_config, outbox);
  world.Start();
  std::atomic<bool> stop{false};
  std::int64_t silent_since = 0;
  std::thread killer([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    silent_since = MonotonicNs();
    world.heartbeat_on = false;
  });
  RealtimeCounts counts;
  std::int64_t stopped_at = 0;
  std::thread rt([&] {
    executor.Start(MonotonicNs());
    RealtimeGuard guard;
    loop.Run(stop, 5000, 0);
    stopped_at = MonotonicNs();
    counts = guard.counts();
  });
  rt.join();
  killer.join();
  world.Stop();
  EXPECT_EQ(executor.stop_code(), FaultCode::kPeerTimeout) << executor.stop_reason();
  // Stopped within the heartbeat time-out plus one driver period and scheduling slack (50 ms: CI runs this beside
  // other tests on 2 cores, under ASan too; without the time-out the loop would run its full 5 s).
  EXPECT_LT(static_cast<double>(stopped_at - silent_since) * 1e-9, 0.05 + 0.001 + 0.05);
  EXPECT_EQ(Norm(loop.last_output().command.velocity), 0.0);
  EXPECT_EQ(counts.allocations, 0);
  EXPECT_EQ(counts.locks, 0);
  EXPECT_EQ(counts.io, 0);
  FaultEvent fault;
  bool reported = false;
  while (outbox.faults.TryPop(fault)) reported |= fault.code == FaultCode::kPeerTimeout && fault.robot_stopped;
  EXPECT_TRUE(reported);
}

// The loop with the real LCM robot link (its I/O thread, SPSC hand-offs, eventfd wake-up) against the real driver
// logic and its LCM transport over UDP multicast (private port, ttl=0): the loop thread allocates, frees, locks and
// throws nothing; its only system call is the link's non-blocking eventfd write, at most one per command.
TEST(RealtimeLoop, RealLcmLinkAgainstTheDriverIsAllocationLockAndExceptionFree) {
  const std::string url = "udpm://239.255.76.67:" + std::to_string(42000 + getpid() % 20000) + "?ttl=0";
  drivers::DriverTransportConfig transport_config;
  transport_config.lcm_url = url;
  const auto transport = drivers::MakeLcmDriverTransport(transport_config);
  drivers::SimulatedRobot robot(drivers::SimulatedRobotConfig{});
  // Generous time-outs: this test is about what the loop thread calls, not about timing on a loaded machine.
  drivers::DriverConfig driver_config;
  driver_config.watchdog_us = 1'000'000;
  drivers::Driver driver(driver_config, *transport, robot);
  std::atomic<bool> stop_driver{false};
  std::thread driver_thread([&] { driver.Run(stop_driver); });
  drivers::RobotLinkConfig link_config;
  link_config.lcm_url = url;
  link_config.heartbeat_timeout_us = 2'000'000;
  const auto link = drivers::MakeLcmRobotLink(link_config);

  Task task;
  Step step;
  step.theta = 0.0;
  step.terminate = TerminateKind::kGoal;
  task.steps.push_back(step);
  task.speed = 0.3;
  task.goal = testing::Square({0.4, 0.0}, 0.05);
  ExecutorConfig config;
  config.period_s = 0.001;
  config.limits.max_speed = 0.5;
  config.limits.max_accel = 2.0;
  config.goal_from_odometry = true;
  config.heartbeat_timeout_s = 1.0;
  Executor executor(task, config);
  LatestValue<VisualFrame> frames;
  LatestValue<PositionEstimate> estimates;
  Outbox outbox;
  LoopConfig loop_config;
  loop_config.period_s = 0.001;
  loop_config.realtime = false;
  LoopSources sources{link.get(), &frames, &estimates, nullptr};
  ControlLoop loop(executor, sources, loop_config, outbox);
  std::atomic<bool> done{false};
  std::thread consumer([&] {  // the publisher's side: empties the queues
    Collected collected;
    std::mutex collected_mutex;
    while (!done) {
      outbox.Wait(0.01);
      Drain(outbox, collected, collected_mutex);
    }
  });
  RealtimeCounts counts;
  std::thread rt([&] {
    executor.Start(MonotonicNs());
    RealtimeGuard guard;
    std::atomic<bool> stop{false};
    loop.Run(stop, 10000);
    counts = guard.counts();
  });
  rt.join();
  done = true;
  consumer.join();
  stop_driver = true;
  driver_thread.join();

  EXPECT_EQ(executor.mode(), Mode::kDone) << executor.stop_reason();
  // ~1400 of each on an idle machine (1.4 s at 1 kHz); 400 seen at load 6. Enough for a steady state.
  EXPECT_GT(link->counters().statuses_received, 100U);
  EXPECT_GT(driver.stats().commands_applied, 100U);
  EXPECT_EQ(counts.allocations, 0);
  EXPECT_EQ(counts.frees, 0);
  EXPECT_EQ(counts.locks, 0);
  EXPECT_EQ(counts.throws, 0);
  EXPECT_LE(counts.io, loop.cycles());  // the eventfd wake-up of the link's I/O thread, non-blocking
  RecordProperty("io_calls", static_cast<int>(counts.io));
}

// The robot driver restarts during a run (a new process on the same bus, inside every time-out). The
// controller must not go on commanding it as if nothing happened: the boot-up heartbeat stops the run, and the stop
// says why; the restarted driver, disabled, never takes the old run's commands.
TEST(RealtimeLoop, ADriverRestartDuringARunStopsTheControllerAndSaysWhy) {
  const std::string url = "udpm://239.255.76.67:" + std::to_string(43000 + getpid() % 20000) + "?ttl=0";
  struct DriverProcess {
    explicit DriverProcess(const std::string& lcm_url, std::uint64_t seed) : robot(drivers::SimulatedRobotConfig{}) {
      drivers::DriverTransportConfig transport_config;
      transport_config.lcm_url = lcm_url;
      transport = drivers::MakeLcmDriverTransport(transport_config);
      drivers::DriverConfig config;
      config.watchdog_us = 1'000'000;
      config.session_seed = seed;
      driver = std::make_unique<drivers::Driver>(config, *transport, robot);
      thread = std::thread([this] { driver->Run(stop); });
    }
    ~DriverProcess() { Kill(); }
    void Kill() {
      stop = true;
      if (thread.joinable()) thread.join();
    }
    drivers::SimulatedRobot robot;
    std::unique_ptr<drivers::DriverTransport> transport;
    std::unique_ptr<drivers::Driver> driver;
    std::atomic<bool> stop{false};
    std::thread thread;
  };
  auto first = std::make_unique<DriverProcess>(url, 101);
  drivers::RobotLinkConfig link_config;
  link_config.lcm_url = url;
  link_config.heartbeat_timeout_us = 2'000'000;
  const auto link = drivers::MakeLcmRobotLink(link_config);

  Task task;
  Step step;
  step.theta = 0.0;
  step.terminate = TerminateKind::kGoal;
  task.steps.push_back(step);
  task.speed = 0.2;
  task.goal = testing::Square({5.0, 0.0}, 0.05);  // far: the run is still going when the driver restarts
  ExecutorConfig config;
  config.period_s = 0.002;
  config.limits.max_speed = 0.5;
  config.limits.max_accel = 2.0;
  config.goal_from_odometry = true;
  config.heartbeat_timeout_s = 1.0;
  config.startup_timeout_s = 10.0;
  Executor executor(task, config);
  LatestValue<VisualFrame> frames;
  LatestValue<PositionEstimate> estimates;
  Outbox outbox;
  LoopConfig loop_config;
  loop_config.period_s = 0.002;
  loop_config.realtime = false;
  LoopSources sources{link.get(), &frames, &estimates, nullptr};
  ControlLoop loop(executor, sources, loop_config, outbox);
  std::atomic<bool> stop{false};
  std::thread rt([&] {
    executor.Start(MonotonicNs());
    loop.Run(stop, 5000);
  });
  // Wait until the run moves the robot, seen through the loop's telemetry (its odometry estimate): this thread may
  // read neither the robot nor the executor while the driver and loop threads run.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  TelemetrySnapshot t;
  bool moving = false;
  while (std::chrono::steady_clock::now() < deadline && !moving) {
    while (outbox.telemetry.TryPop(t)) moving |= t.mode == Mode::kFree && t.estimate.x > 0.01;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(moving) << t.stop_reason;
  first.reset();                   // the driver process dies ...
  DriverProcess second(url, 102);  // ... and a new one starts at once, well within the time-outs
  rt.join();
  second.Kill();
  EXPECT_EQ(executor.mode(), Mode::kStopped);
  std::printf("driver restart during a run: controller stopped: %s\n", executor.stop_reason());
  EXPECT_NE(std::string(executor.stop_reason()).find("restarted"), std::string::npos) << executor.stop_reason();
  FaultEvent fault;
  bool reported = false;
  while (outbox.faults.TryPop(fault)) {
    reported |= fault.robot_stopped && std::string(fault.message).find("restarted") != std::string::npos;
  }
  EXPECT_TRUE(reported);
  EXPECT_EQ(second.driver->stats().commands_applied, 0U);
  EXPECT_EQ(second.driver->state(), drivers::RobotState::kDisabled);
  EXPECT_EQ(Norm(loop.last_output().command.velocity), 0.0);
}

// A link whose driver is always ready and whose faults the test queues: which faults stop the controller.
class ScriptedLink final : public drivers::RobotLink {
 public:
  drivers::LinkResult SendCommand(const drivers::VelocityCommand& command, std::int64_t) override {
    last = command;
    ++seq_;
    return drivers::LinkResult::kOk;
  }
  void Poll(std::int64_t now_us) override { now_us_ = now_us; }
  drivers::LinkResult TakeStatus(drivers::RobotStatus& out) override {
    out = drivers::RobotStatus{};
    out.receive_us = now_us_;
    out.session = 1;
    out.seq = ++status_seq_;
    out.command_seq = seq_;
    out.state = drivers::RobotState::kReady;
    return drivers::LinkResult::kOk;
  }
  drivers::LinkResult TakeFault(drivers::LinkFault& out) override {
    if (next_fault_ >= faults.size()) return drivers::LinkResult::kNoData;
    out = faults[next_fault_++];
    return drivers::LinkResult::kOk;
  }
  drivers::PeerState peer_state(std::int64_t) const override { return drivers::PeerState::kAlive; }
  drivers::NmtState peer_nmt_state() const override { return drivers::NmtState::kOperational; }
  drivers::BusState bus_state() const override { return drivers::BusState::kActive; }
  std::uint32_t last_command_seq() const override { return seq_; }
  std::uint32_t session() const override { return 1; }
  drivers::LinkCounters counters() const override { return {}; }

  std::vector<drivers::LinkFault> faults;  // set before the loop runs
  drivers::VelocityCommand last;

 private:
  std::size_t next_fault_ = 0;
  std::uint32_t seq_ = 0;
  std::uint32_t status_seq_ = 0;
  std::int64_t now_us_ = 0;
};

// Each bus state by its own code, and only bus-off (and the link's other stopping faults) stops the
// controller; error passive and warning, from the link or the driver, are reported only. A foreign fault (another
// controller's session) does not stop either.
TEST(RealtimeLoop, OnlyStoppingLinkFaultsStopTheController) {
  Task task;
  Step step;
  step.theta = 0.0;
  step.terminate = TerminateKind::kContact;
  task.steps.push_back(step);
  task.speed = 0.1;
  ExecutorConfig config;
  config.period_s = 0.002;
  config.startup_timeout_s = 10.0;
  const auto fault = [](std::uint16_t emcy, bool stopped, bool local, bool foreign) {
    drivers::LinkFault f;
    f.emcy_code = emcy;
    f.code = 5;  // fault_t::CODE_CAN_ERROR
    f.robot_stopped = stopped;
    f.local = local;
    f.foreign = foreign;
    return f;
  };
  for (const bool bus_off : {false, true}) {
    Executor executor(task, config);
    ScriptedLink link;
    link.faults = {fault(drivers::can::kEmcyCanWarning, false, true, false),
                   fault(drivers::can::kEmcyCanPassive, false, true, false),
                   fault(drivers::can::kEmcyCanPassive, false, false, false),
                   fault(drivers::can::kEmcyRpdoTimeout, true, false, true)};
    if (bus_off) {
      drivers::LinkFault off = fault(drivers::can::kEmcyBusOff, true, true, false);
      off.what = "CAN bus-off or the interface is down: nothing reaches the driver";
      link.faults.push_back(off);
    }
    Outbox outbox;
    LoopConfig loop_config;
    loop_config.period_s = 0.002;
    loop_config.realtime = false;
    LoopSources sources{&link, nullptr, nullptr, nullptr};
    ControlLoop loop(executor, sources, loop_config, outbox);
    executor.Start(MonotonicNs());
    std::atomic<bool> stop{false};
    loop.Run(stop, 100);
    if (bus_off) {
      EXPECT_EQ(executor.mode(), Mode::kStopped);
      EXPECT_NE(std::string(executor.stop_reason()).find("bus-off"), std::string::npos) << executor.stop_reason();
      EXPECT_TRUE(link.last.quick_stop);
    } else {
      EXPECT_NE(executor.mode(), Mode::kStopped) << executor.stop_reason();
      EXPECT_GT(link.last.velocity[0], 0.0);
    }
  }
}

}  // namespace
}  // namespace visco::control
