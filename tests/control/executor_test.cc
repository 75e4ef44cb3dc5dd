// The executor's state machine in closed loop with a kinematic plant and a synthetic camera: goal, visual guarded,
// visual compliant and contact steps; holds on stale vision; stops on heartbeat loss, driver faults, time-outs,
// e-stop and workspace bounds, each with its reason.

#include "control/executor.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>

#include "common/error.h"
#include "control/servo_camera.h"
#include "tests/control/harness.h"

namespace visco::control {
namespace {

using testing::Harness;
using testing::MakeRay;
using testing::Square;

constexpr double kPi = std::numbers::pi;

ExecutorConfig Config() {
  ExecutorConfig config;
  config.period_s = 0.002;
  config.default_speed = 0.05;
  config.limits.max_speed = 0.2;
  config.limits.max_accel = 1.0;
  return config;
}

Step MakeStep(double theta, TerminateKind kind, int terminate_ray = -1, std::vector<int> active = {}) {
  Step step;
  step.theta = theta;
  step.terminate = kind;
  step.terminate_ray = terminate_ray;
  step.active_rays = std::move(active);
  return step;
}

bool HasFault(const std::vector<FaultEvent>& faults, FaultCode code, bool cleared) {
  for (const FaultEvent& f : faults) {
    if (f.code == code && f.cleared == cleared) return true;
  }
  return false;
}

TEST(Executor, FreeMotionReachesGoalKernel) {
  Task task;
  task.steps.push_back(MakeStep(0.0, TerminateKind::kGoal));
  task.goal = Square({1.5, 1.0}, 0.1);
  task.position_uncertainty = 0.02;
  Harness h(task, Config(), {1.0, 1.0});
  h.Start();
  // Idle until the driver is ready and vision has sent its first estimate (the camera's latency), then step 0.
  EXPECT_EQ(h.Tick().mode, Mode::kIdle);
  int ticks = 1;
  while (h.Tick().mode == Mode::kIdle) ++ticks;
  EXPECT_LE(ticks * 0.002, 0.02 + 0.004);
  h.RunUntilFinished(30.0);
  ASSERT_EQ(h.executor().mode(), Mode::kDone) << h.executor().stop_reason();
  // Recognised inside the kernel: at least eps_p inside the goal's left edge (x = 1.4), with at most the motion of
  // one camera period plus its latency beyond it.
  EXPECT_GE(h.plant.position.x, 1.4 + 0.02);
  EXPECT_LE(h.plant.position.x, 1.4 + 0.02 + 0.05 * (1.0 / 30 + 0.02 + 0.01));
  EXPECT_EQ(h.executor().step_index(), 1);
  EXPECT_NE(std::string(h.executor().stop_reason()).find("goal recognised"), std::string::npos);
  // Stopped: the command is zero after the end.
  EXPECT_EQ(Norm(h.Tick().command.velocity), 0.0);
}

TEST(Executor, VisualGuardedStopsWhenTheVertexCrossesTheLine) {
  // A vertical VC ray x = 2 (obstacle vertex (2, 0), camera (2, 5)); the CM vertex is the robot's corner (0.1, 0).
  Task task;
  task.rays.push_back(MakeRay("vc0.cm1", {2.0, 0.0}, {2.0, 5.0}, 1, {0.1, 0.0}));
  testing::IndexRays(task);
  task.steps.push_back(MakeStep(0.0, TerminateKind::kVisualGuarded, 0));
  Harness h(task, Config(), {1.5, 1.0});
  h.Start();
  for (int i = 0; i < 20; ++i) h.Tick();
  EXPECT_EQ(h.executor().mode(), Mode::kVisualGuarded);
  h.RunUntilFinished(30.0);
  ASSERT_EQ(h.executor().mode(), Mode::kDone) << h.executor().stop_reason();
  // The vertex (x + 0.1) crossed x = 2; overshoot bounded by speed * (camera period + latency) + band.
  const double vertex_x = h.plant.position.x + 0.1;
  EXPECT_GE(vertex_x, 2.0 - 1.0 * 4.0 / 800.0);
  EXPECT_LE(vertex_x, 2.0 + 0.05 * (1.0 / 30 + 0.02 + 0.004));
}

// Near a VC line not yet reached, the speed is cut so that the motion goes past it by at most approach_tolerance_m
// before the event is seen (the planner's strip half-width); at full speed the camera's period and latency carry it
// further (measured in the demo: 0.03-0.06 m past a ray's end at 0.6 m/s, onto the wrong face of the slot's lip).
TEST(Executor, ApproachToAVcLineKeepsTheOvershootWithinTheTolerance) {
  auto overshoot = [](double tolerance) {
    Task task;
    task.rays.push_back(MakeRay("vc0.cm1", {2.0, 0.0}, {2.0, 5.0}, 1, {0.1, 0.0}));
    testing::IndexRays(task);
    task.steps.push_back(MakeStep(0.0, TerminateKind::kVisualGuarded, 0));
    ExecutorConfig config = Config();
    config.default_speed = 0.6;
    config.limits.max_speed = 1.0;
    config.limits.max_accel = 4.0;
    config.approach_tolerance_m = tolerance;
    Harness h(task, config, {0.5, 1.0});
    h.Start();
    h.RunUntilFinished(30.0);
    EXPECT_EQ(h.executor().mode(), Mode::kDone) << h.executor().stop_reason();
    return h.plant.position.x + 0.1 - 2.0;
  };
  const double full = overshoot(0.0), cut = overshoot(0.01);
  std::printf("overshoot past the line: %.4f m at full speed, %.4f m with the approach cut\n", full, cut);
  EXPECT_GT(full, 0.012);  // the harness camera: 30 Hz, 20 ms latency
  EXPECT_LE(cut, 0.01 + 1e-3);
  EXPECT_GE(cut, -1.0 * 4.0 / 800.0);
}

TEST(Executor, VisualCompliantMotionServoesAlongTheRayUntilContact) {
  // Slanted VC ray from obstacle vertex (2, 0) to the camera (0, 4); a wall y >= 0 (floor) ends the motion.
  // The robot's CM vertex is its corner (0.1, -0.1); it starts left of the ray and is commanded down-right.
  Task task;
  task.rays.push_back(MakeRay("vc0.cm2", {2.0, 0.0}, {0.0, 4.0}, 2, {0.1, -0.1}));
  testing::IndexRays(task);
  task.steps.push_back(MakeStep(-kPi / 4, TerminateKind::kContact, -1, {0}));
  ExecutorConfig config = Config();
  Harness h(task, config, {1.2, 1.0});
  h.plant.walls.push_back({{0.0, 0.1}, {0.0, 1.0}});  // reference point y >= 0.1 (vertex on the floor y = 0)
  h.plant.disturbance = 5.0 * kPi / 180;              // inside the velocity cone
  h.plant.friction = 80.0 * kPi / 180;                // the floor sticks
  h.Start();
  double max_error_px = 0;
  bool engaged = false;
  int ticks = 0;
  for (int total = 0; !h.executor().finished() && total < 30000; ++total) {
    const ExecutorOutput& out = h.Tick();
    ++ticks;
    if (out.mode == Mode::kVisualCompliant && !h.plant.contact) {
      if (!engaged) ticks = 0;  // count from engagement
      engaged = true;
      if (ticks > 500) max_error_px = std::max(max_error_px, std::abs(h.camera().SignedDistance(0, h.plant.position)));
    }
  }
  ASSERT_TRUE(engaged);
  ASSERT_EQ(h.executor().mode(), Mode::kDone) << h.executor().stop_reason();
  // After one second of servoing the vertex stays within a few pixels of the line despite the 5 degree disturbance.
  EXPECT_LT(max_error_px, 3.0);
  // It slid down the ray to the floor: the vertex ends near the ray's foot (2, 0).
  EXPECT_NEAR(h.plant.position.x + 0.1, 2.0, 0.02);
  EXPECT_NEAR(h.plant.position.y, 0.1, 1e-6);
}

// The compliant motion seen by the default scene's tilted camera (data/sim: 9 m up, 33 degrees from the vertical),
// on the ray vc9 from the right lip (5.2, 2) to the camera's foot point (9.5, 7.5). The step moves up the ray at 30
// degrees towards it from 10 cm on its right, engages when the vertex reaches the line, then servos. Returns the decay
// rate of the true |d| (1/s, fitted on ln|d| from 0.1 s to 1.1 s after engagement) and the largest |d| late.
struct CompliantDecay {
  double rate = 0;
  double late_px = 0;
  bool engaged = false;
};

CompliantDecay TiltedCompliantDecay(bool calibrated) {
  const ServoCamera camera =
      LoadServoCamera("data/sim/slot_camera.xml", "data/sim/slot_extrinsics.json", "data/sim/slot_objects.json");
  Task task;
  task.rays.push_back(MakeRay("vc9.cm0", {5.2, 2.0}, {9.5, 7.5}, 0, {0.0, 0.0}));
  testing::IndexRays(task);
  const Vec2 t = task.rays[0].direction;
  task.steps.push_back(MakeStep(std::atan2(t.y, t.x) + kPi / 6, TerminateKind::kContact, -1, {0}));
  ExecutorConfig config = Config();
  config.limits.max_speed = 1.0;
  config.limits.max_accel = 50.0;
  config.servo.max_normal_speed = 1.0;  // no saturation: the rate is the law's
  config.servo.focal_px = camera.px;    // the planar law's best guess: the calibration's focal length
  if (calibrated) config.servo.camera = camera;
  Harness h(task, config, Vec2{5.2, 2.0} + 1.0 * t - 0.1 * LeftNormal(t), 1, &camera);
  h.camera_period_s = 0.002;  // a frame every period, no latency: the continuous law's rate, up to the 2 ms step
  h.camera_latency_s = 0.0;
  h.Start();
  CompliantDecay out;
  double sum_t = 0, sum_l = 0, sum_tt = 0, sum_tl = 0;
  int n = 0, since = -1;
  for (int total = 0; total < 5000 && since < 700; ++total) {
    const ExecutorOutput& o = h.Tick();
    if (o.mode == Mode::kVisualCompliant) out.engaged = true;
    if (!out.engaged) continue;
    ++since;
    const double time = since * 0.002, d = std::abs(h.camera().SignedDistance(0, h.plant.position));
    if (time >= 0.1 && time <= 1.1) {
      const double l = std::log(d);
      sum_t += time, sum_l += l, sum_tt += time * time, sum_tl += time * l;
      ++n;
    }
    if (time >= 1.0) out.late_px = std::max(out.late_px, d);
  }
  out.rate = -(n * sum_tl - sum_t * sum_l) / (n * sum_tt - sum_t * sum_t);
  return out;
}

TEST(Executor, VisualCompliantMotionWithATiltedCameraConvergesAtTheGainsRate) {
  const double gain = ServoConfig{}.gain;
  const CompliantDecay exact = TiltedCompliantDecay(true);
  const CompliantDecay planar = TiltedCompliantDecay(false);
  ASSERT_TRUE(exact.engaged && planar.engaged);
  std::printf(
      "executor, default scene's tilted camera, gain %.1f/s: calibrated law %.3f/s, planar f/range law %.3f/s\n", gain,
      exact.rate, planar.rate);
  // The 2 ms period: |d| shrinks by (1 - 2 ms gain) a period, a rate of gain * 1.004.
  EXPECT_NEAR(exact.rate / gain, 1.0, 0.02);
  EXPECT_LT(exact.late_px, 0.05);
  EXPECT_LT(planar.rate / gain, 0.8);  // the planar law with f = px is measurably slower on this camera
}

TEST(Executor, CompliantStepAfterAGuardedStopOnItsRayStartsEngaged) {
  // VC ray from obstacle vertex (2, 0) up-right to the camera (4, 4). Step 0 moves right until the CM vertex (the
  // reference point itself) reaches it; the stop overshoots to the right of the ray (camera latency). Step 1 moves
  // down complying to the same ray: straight down would lead away from it, so it must start engaged and slide down
  // the ray to its foot (2, 0) -- not fall straight to the floor at the overshoot's x.
  Task task;
  task.rays.push_back(MakeRay("vc0.cm0", {2.0, 0.0}, {4.0, 4.0}, 0, {0.0, 0.0}));
  testing::IndexRays(task);
  task.steps.push_back(MakeStep(0.0, TerminateKind::kVisualGuarded, 0));
  task.steps.push_back(MakeStep(-kPi / 2, TerminateKind::kContact, -1, {0}));
  ExecutorConfig config = Config();
  config.default_speed = 0.3;
  config.limits.max_speed = 0.5;
  Harness h(task, config, {1.0, 1.0});                // the camera's latency (20 ms) and frame period make it overshoot
  h.plant.walls.push_back({{0.0, 0.0}, {0.0, 1.0}});  // the floor y >= 0
  h.plant.friction = 80.0 * kPi / 180;                // sticks
  h.Start();
  bool compliant_right_away = false;
  double overshoot_px = 0;
  int step1_ticks = -1;
  for (int total = 0; !h.executor().finished() && total < 30000; ++total) {
    const ExecutorOutput& out = h.Tick();
    if (out.step_index == 1 && step1_ticks < 0) step1_ticks = 0;
    if (step1_ticks >= 0 && ++step1_ticks <= 3 && out.mode == Mode::kVisualCompliant) compliant_right_away = true;
    if (step1_ticks >= 0 && step1_ticks < 250) {
      overshoot_px = std::max(overshoot_px, std::abs(h.camera().SignedDistance(0, h.plant.position)));
    }
  }
  ASSERT_EQ(h.executor().mode(), Mode::kDone) << h.executor().stop_reason();
  EXPECT_GT(overshoot_px, 0.5);  // it did overshoot
  EXPECT_TRUE(compliant_right_away);
  EXPECT_NEAR(h.plant.position.x, 2.0, 0.03);  // the ray's foot, not the overshoot's x (~2.55)
  EXPECT_NEAR(h.plant.position.y, 0.0, 1e-6);
}

TEST(Executor, ContactStepEndsWhenTheRobotSticks) {
  Task task;
  task.steps.push_back(MakeStep(-kPi / 2, TerminateKind::kContact));
  Harness h(task, Config(), {1.0, 0.3});
  h.plant.walls.push_back({{0.0, 0.0}, {0.0, 1.0}});
  h.plant.friction = 0.3;
  h.Start();
  h.RunUntilFinished(30.0);
  ASSERT_EQ(h.executor().mode(), Mode::kDone) << h.executor().stop_reason();
  EXPECT_NEAR(h.plant.position.y, 0.0, 1e-9);
  EXPECT_NE(std::string(h.executor().stop_reason()).find("contact"), std::string::npos);
}

TEST(Executor, MultiStepStrategyRunsEveryStepInOrder) {
  // Step 0: move right until the vertex crosses x = 2; step 1: move down to the floor (contact); step 2: move right
  // into the goal.
  Task task;
  task.rays.push_back(MakeRay("vc0.cm1", {2.0, 0.0}, {2.0, 5.0}, 1, {0.1, 0.0}));
  testing::IndexRays(task);
  task.steps.push_back(MakeStep(0.0, TerminateKind::kVisualGuarded, 0));
  task.steps.push_back(MakeStep(-kPi / 2, TerminateKind::kContact));
  task.steps.push_back(MakeStep(0.0, TerminateKind::kGoal));
  task.goal = Square({2.5, 0.05}, 0.1);
  task.position_uncertainty = 0.01;
  Harness h(task, Config(), {1.5, 0.5});
  h.plant.walls.push_back({{0.0, 0.0}, {0.0, 1.0}});
  h.plant.friction = 0.3;
  h.Start();
  std::vector<int> steps_seen;
  for (int i = 0; i < 40000 && !h.executor().finished(); ++i) {
    const int step = h.Tick().step_index;
    if (steps_seen.empty() || steps_seen.back() != step) steps_seen.push_back(step);
  }
  ASSERT_EQ(h.executor().mode(), Mode::kDone) << h.executor().stop_reason();
  EXPECT_EQ(steps_seen, (std::vector<int>{-1, 0, 1, 2, 3}));
}

TEST(Executor, StaleVisionZeroesTheCommandWithinOnePeriodAndResumes) {
  Task task;
  task.rays.push_back(MakeRay("vc0.cm1", {5.0, 0.0}, {5.0, 5.0}, 1, {0.1, 0.0}));
  testing::IndexRays(task);
  task.steps.push_back(MakeStep(0.0, TerminateKind::kVisualGuarded, 0));
  ExecutorConfig config = Config();
  config.max_vision_age_s = 0.1;
  Harness h(task, config, {1.0, 1.0});
  h.Start();
  for (int i = 0; i < 500; ++i) h.Tick();
  ASSERT_GT(Norm(h.Tick().command.velocity), 0.04);
  // The camera stops. The last frame was captured at most one camera period before; the command must be zero in
  // the very first period in which the newest frame is older than max_vision_age_s.
  h.camera_on = false;
  int ticks = 0;
  while (true) {
    const ExecutorOutput& out = h.Tick();
    ++ticks;
    const double age = static_cast<double>(h.now_ns() - h.input().frame.capture_ns) * 1e-9;
    if (age > config.max_vision_age_s) {
      EXPECT_EQ(Norm(out.command.velocity), 0.0) << "age " << age;
      EXPECT_TRUE(out.holding);
      EXPECT_NE(std::string(out.stop_reason).find("visual events"), std::string::npos) << out.stop_reason;
      break;
    }
    EXPECT_GT(Norm(out.command.velocity), 0.0);
    ASSERT_LT(ticks, 1000);
  }
  EXPECT_TRUE(HasFault(h.faults, FaultCode::kVisionStale, false));
  for (int i = 0; i < 100; ++i) EXPECT_EQ(Norm(h.Tick().command.velocity), 0.0);
  // The camera comes back: the step resumes and the fault is cleared.
  h.camera_on = true;
  for (int i = 0; i < 100; ++i) h.Tick();
  EXPECT_GT(Norm(h.Tick().command.velocity), 0.0);
  EXPECT_TRUE(HasFault(h.faults, FaultCode::kVisionStale, true));
  EXPECT_EQ(h.executor().mode(), Mode::kVisualGuarded);
}

TEST(Executor, VisionLostForTooLongStops) {
  Task task;
  task.steps.push_back(MakeStep(0.0, TerminateKind::kGoal));
  task.goal = Square({5.0, 1.0}, 0.1);
  ExecutorConfig config = Config();
  config.max_hold_s = 0.5;
  Harness h(task, config, {1.0, 1.0});
  h.Start();
  for (int i = 0; i < 100; ++i) h.Tick();
  h.estimate_on = false;
  h.RunUntilFinished(5.0);
  EXPECT_EQ(h.executor().mode(), Mode::kStopped);
  EXPECT_EQ(h.executor().stop_code(), FaultCode::kVisionStale);
  EXPECT_NE(std::string(h.executor().stop_reason()).find("not restored"), std::string::npos);
}

TEST(Executor, UnobservedRayHolds) {
  // The watched ray's vertex is behind the camera: STATE_UNKNOWN.
  Task task;
  task.rays.push_back(MakeRay("vc0.cm1", {2.0, 0.0}, {2.0, 5.0}, 1, {0.0, 0.0}));
  testing::IndexRays(task);
  task.steps.push_back(MakeStep(0.0, TerminateKind::kVisualGuarded, 0));
  Harness h(task, Config(), {1.0, 6.0});
  h.Start();
  for (int i = 0; i < 200; ++i) EXPECT_EQ(Norm(h.Tick().command.velocity), 0.0);
  EXPECT_TRUE(HasFault(h.faults, FaultCode::kVisionLost, false));
}

TEST(Executor, HeartbeatLossStops) {
  Task task;
  task.steps.push_back(MakeStep(0.0, TerminateKind::kContact));
  ExecutorConfig config = Config();
  config.heartbeat_timeout_s = 0.05;
  Harness h(task, config, {1.0, 1.0});
  h.Start();
  for (int i = 0; i < 100; ++i) h.Tick();
  h.driver_alive = false;
  int ticks = 0;
  while (!h.executor().finished()) {
    h.Tick();
    ++ticks;
  }
  // Stopped in the first period past the time-out (25 periods of 2 ms), with the reason.
  EXPECT_EQ(ticks, 26);
  EXPECT_EQ(h.executor().stop_code(), FaultCode::kPeerTimeout);
  EXPECT_NE(std::string(h.executor().stop_reason()).find("no status or heartbeat"), std::string::npos);
  EXPECT_EQ(Norm(h.Tick().command.velocity), 0.0);
  EXPECT_TRUE(HasFault(h.faults, FaultCode::kPeerTimeout, false));
}

TEST(Executor, DriverNeverReadyStopsAfterStartupTimeout) {
  Task task;
  task.steps.push_back(MakeStep(0.0, TerminateKind::kContact));
  ExecutorConfig config = Config();
  config.startup_timeout_s = 0.2;
  Harness h(task, config, {1.0, 1.0});
  h.driver_alive = false;
  h.Start();
  const ExecutorOutput& out = h.Tick();
  EXPECT_TRUE(out.command.reset);
  EXPECT_EQ(out.mode, Mode::kIdle);
  h.RunUntilFinished(1.0);
  EXPECT_EQ(h.executor().stop_code(), FaultCode::kPeerTimeout);
  EXPECT_NE(std::string(h.executor().stop_reason()).find("no status or heartbeat from the driver"), std::string::npos);
}

// A driver whose e-stop is latched refuses the executor's reset (drivers/README.md, "Sessions"): the run does not
// start, and says that the operator must release the e-stop at the driver.
TEST(Executor, ALatchedDriverEStopIsNotClearedAndTheStopSaysWhatToDo) {
  Task task;
  task.steps.push_back(MakeStep(0.0, TerminateKind::kContact));
  ExecutorConfig config = Config();
  config.startup_timeout_s = 0.2;
  Harness h(task, config, {1.0, 1.0});
  h.driver_fault_bits = robot_status_t::FAULT_ESTOP;
  h.Start();
  EXPECT_TRUE(h.Tick().command.reset);
  h.RunUntilFinished(1.0);
  EXPECT_EQ(h.executor().mode(), Mode::kStopped);
  EXPECT_EQ(h.executor().step_index(), -1);  // never started
  EXPECT_NE(std::string(h.executor().stop_reason()).find("e-stop latched"), std::string::npos)
      << h.executor().stop_reason();
}

// Error passive sets the driver's bus bit while it keeps the robot going (drivers/README.md): no reason to stop.
TEST(Executor, TheBusBitAloneDoesNotStop) {
  Task task;
  task.steps.push_back(MakeStep(0.0, TerminateKind::kContact));
  Harness h(task, Config(), {1.0, 1.0});
  h.Start();
  for (int i = 0; i < 10; ++i) h.Tick();
  h.driver_fault_bits = robot_status_t::FAULT_BUS;
  for (int i = 0; i < 50; ++i) h.Tick();
  EXPECT_NE(h.executor().mode(), Mode::kStopped) << h.executor().stop_reason();
  EXPECT_GT(Norm(h.Tick().command.velocity), 0.0);
}

TEST(Executor, DriverFaultStopsWithItsNames) {
  Task task;
  task.steps.push_back(MakeStep(0.0, TerminateKind::kContact));
  Harness h(task, Config(), {1.0, 1.0});
  h.Start();
  for (int i = 0; i < 10; ++i) h.Tick();
  EXPECT_FALSE(h.Tick().command.quick_stop);
  h.driver_fault_bits = robot_status_t::FAULT_WATCHDOG;
  h.Tick();
  EXPECT_EQ(h.executor().mode(), Mode::kStopped);
  // From the stop on, every command asks the driver for a quick stop (not only its watchdog, later).
  EXPECT_TRUE(h.Tick().command.quick_stop);
  EXPECT_EQ(Norm(h.Tick().command.velocity), 0.0);
  EXPECT_EQ(h.executor().stop_code(), FaultCode::kPeerTimeout);
  EXPECT_NE(std::string(h.executor().stop_reason()).find("watchdog"), std::string::npos);
}

TEST(Executor, StepTimeoutStops) {
  Task task;
  task.steps.push_back(MakeStep(0.0, TerminateKind::kContact));
  task.steps.back().timeout_s = 0.3;
  Harness h(task, Config(), {1.0, 1.0});
  h.Start();
  const int ticks = h.RunUntilFinished(5.0);
  EXPECT_EQ(h.executor().stop_code(), FaultCode::kStepTimeout);
  EXPECT_NEAR(ticks * 0.002, 0.3, 0.006);
}

// A goal step whose motion sticks on a wall away from the goal (a push inside the friction cone) fails once it has
// not moved for stuck_s, with CODE_STRATEGY_FAILED and where it stuck, not at the step's time-out; a slow slide
// along the same wall (outside the friction cone) is not stuck, and a robot resting in contact inside the goal is
// left to goal recognition.
TEST(Executor, StuckAwayFromTheGoalFailsEarlyButASlowSlideDoesNot) {
  Task task;
  task.steps.push_back(MakeStep(-M_PI / 2, TerminateKind::kGoal));  // straight down onto the floor y = 0
  task.steps.back().timeout_s = 60;
  task.goal = Polygon{{{5.0, 0.0}, {6.0, 0.0}, {6.0, 1.0}, {5.0, 1.0}}};
  task.position_uncertainty = 0.05;
  ExecutorConfig config = Config();
  config.stuck_s = 1.0;
  {
    Harness h(task, config, {1.0, 0.3});
    h.plant.walls = {testing::Wall{{0, 0}, {0, 1}}};
    h.plant.friction = 0.3;  // the push (straight down) sticks
    h.Start();
    const int ticks = h.RunUntilFinished(10.0);
    EXPECT_EQ(h.executor().stop_code(), FaultCode::kStrategyFailed);
    EXPECT_NE(std::string(h.executor().stop_reason()).find("stuck in contact"), std::string::npos)
        << h.executor().stop_reason();
    EXPECT_LT(ticks * 0.002, 10.0);
    EXPECT_GT(ticks * 0.002, 1.0);
  }
  {
    // The same push tilted 80° from the normal: it slides right at about 0.05 * sin(80°) m/s along the floor.
    Task sliding = task;
    sliding.steps.back().theta = -M_PI / 2 + 80.0 * M_PI / 180;
    Harness h(sliding, config, {1.0, 0.02});
    h.plant.walls = {testing::Wall{{0, 0}, {0, 1}}};
    h.plant.friction = 0.3;
    h.Start();
    for (int i = 0; i < 2000; ++i) h.Tick();  // 4 s in contact, moving
    EXPECT_FALSE(h.executor().finished()) << h.executor().stop_reason();
  }
  {
    // Resting in contact inside the goal: not "stuck" (the goal's own recognition decides).
    Task in_goal = task;
    in_goal.goal = Polygon{{{0.5, 0.0}, {1.5, 0.0}, {1.5, 0.02}, {0.5, 0.02}}};  // too thin for the kernel
    Harness h(in_goal, config, {1.0, 0.01});
    h.plant.walls = {testing::Wall{{0, 0}, {0, 1}}};
    h.plant.friction = 0.3;
    h.Start();
    for (int i = 0; i < 2000; ++i) h.Tick();
    EXPECT_NE(h.executor().stop_code(), FaultCode::kStrategyFailed) << h.executor().stop_reason();
  }
}

TEST(Executor, EstopLatchesAndCommandsEstop) {
  Task task;
  task.steps.push_back(MakeStep(0.0, TerminateKind::kContact));
  Harness h(task, Config(), {1.0, 1.0});
  h.Start();
  for (int i = 0; i < 100; ++i) h.Tick();
  h.estop = true;
  const ExecutorOutput& out = h.Tick();
  EXPECT_TRUE(out.command.estop);
  EXPECT_EQ(Norm(out.command.velocity), 0.0);
  EXPECT_EQ(h.executor().stop_code(), FaultCode::kEstop);
  h.estop = false;
  EXPECT_TRUE(h.Tick().command.estop);  // latched
}

TEST(Executor, LeavingTheWorkspaceStops) {
  Task task;
  task.steps.push_back(MakeStep(0.0, TerminateKind::kContact));
  task.bounds = Bounds{{0.0, 0.0}, {1.2, 2.0}};
  ExecutorConfig config = Config();
  Harness h(task, config, {1.0, 1.0});
  h.plant.disturbance = 0.0;
  h.Start();
  // The outward velocity component is removed at the bound: the robot stops at the margin, never outside.
  for (int i = 0; i < 3000; ++i) h.Tick();
  EXPECT_LE(h.plant.position.x, 1.2);
  EXPECT_GE(h.plant.position.x, 1.2 - config.limits.bounds_margin - 0.001);
  // Pushed outside (e.g. by a collision), the controller stops with CODE_LIMIT.
  h.plant.position.x = 1.25;
  h.Tick();
  EXPECT_EQ(h.executor().stop_code(), FaultCode::kLimit);
  EXPECT_NE(std::string(h.executor().stop_reason()).find("outside the workspace"), std::string::npos);
}

TEST(Executor, CommandsRespectSpeedAndAccelerationLimits) {
  Task task;
  task.speed = 1.0;  // above the limit
  task.steps.push_back(MakeStep(0.3, TerminateKind::kContact));
  ExecutorConfig config = Config();
  config.limits.max_speed = 0.1;
  config.limits.max_accel = 0.5;
  Harness h(task, config, {1.0, 1.0});
  h.Start();
  Vec2 previous{};
  for (int i = 0; i < 1000; ++i) {
    const Vec2 v = h.Tick().command.velocity;
    EXPECT_LE(Norm(v), 0.1 + 1e-12);
    EXPECT_LE(Norm(v - previous), 0.5 * 0.002 + 1e-12);
    previous = v;
  }
  EXPECT_NEAR(Norm(previous), 0.1, 1e-9);
}

TEST(Executor, StartWaitsForVisionAndGivesUp) {
  Task task;
  task.steps.push_back(MakeStep(0.0, TerminateKind::kGoal));
  task.goal = Square({5.0, 1.0}, 0.1);
  ExecutorConfig config = Config();
  config.startup_timeout_s = 0.3;
  Harness h(task, config, {1.0, 1.0});
  h.estimate_on = false;
  h.Start();
  for (int i = 0; i < 100; ++i) EXPECT_EQ(h.Tick().mode, Mode::kIdle);
  h.RunUntilFinished(1.0);
  EXPECT_EQ(h.executor().stop_code(), FaultCode::kVisionStale);
  EXPECT_NE(std::string(h.executor().stop_reason()).find("no robot estimate from vision"), std::string::npos);
}

TEST(Executor, RejectsCompliantStepsWithoutRayGeometry) {
  Task task;
  CvcRay ray;
  ray.id = "vc9.cm0";
  task.rays.push_back(ray);
  testing::IndexRays(task);
  task.steps.push_back(MakeStep(0.0, TerminateKind::kContact, -1, {0}));
  EXPECT_THROW(Executor(task, Config()), InputError);
}

}  // namespace
}  // namespace visco::control
