// The executor against the simulated robot and camera over real LCM (UDP multicast on a private port, ttl=0):
// `visco run`'s RunTask and `visco sim`'s SimSession in one process, talking only through LCM (commands, status,
// heartbeats, visual events, robot estimates, telemetry, faults). A hand-written strategy: visual compliant motion
// down a CVC ray until the robot sticks on a post, then a goal step. Then the faults: the camera stops (hold, then
// stop), the driver dies (stop), each announced on VISCO_FAULT and in telemetry.

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <lcm/lcm-cpp.hpp>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "app/sim/session.h"
#include "common/error.h"
#include "control/control_loop.h"
#include "control/run.h"
#include "lcmtypes/channels.h"
#include "visco/controller_telemetry_t.hpp"
#include "visco/fault_t.hpp"
#include "visco/motion_strategy_t.hpp"

namespace visco::control {
namespace {

// A private multicast port per test process, so parallel test runs on the machine never hear each other.
std::string PrivateUrl() { return "udpm://239.255.76.67:" + std::to_string(21000 + getpid() % 20000) + "?ttl=0"; }

class Listener {
 public:
  explicit Listener(const std::string& url) : lcm_(url) {
    lcm_.subscribe(channels::kFault, &Listener::OnFault, this);
    lcm_.subscribe(channels::kTelemetry, &Listener::OnTelemetry, this);
    thread_ = std::thread([this] {
      while (running_) lcm_.handleTimeout(20);
    });
  }
  ~Listener() {
    running_ = false;
    thread_.join();
  }
  std::vector<fault_t> faults() {
    std::lock_guard<std::mutex> lock(mutex_);
    return faults_;
  }
  std::vector<controller_telemetry_t> telemetry() {
    std::lock_guard<std::mutex> lock(mutex_);
    return telemetry_;
  }

 private:
  void OnFault(const lcm::ReceiveBuffer*, const std::string&, const fault_t* m) {
    std::lock_guard<std::mutex> lock(mutex_);
    faults_.push_back(*m);
  }
  void OnTelemetry(const lcm::ReceiveBuffer*, const std::string&, const controller_telemetry_t* m) {
    std::lock_guard<std::mutex> lock(mutex_);
    telemetry_.push_back(*m);
  }
  lcm::LCM lcm_;
  std::atomic<bool> running_{true};
  std::thread thread_;
  std::mutex mutex_;
  std::vector<fault_t> faults_;
  std::vector<controller_telemetry_t> telemetry_;
};

sim::SimOptions Sim(const std::string& url) {
  sim::SimOptions o;
  o.scene_path = "tests/control/data/post_scene.json";
  o.rays_path = "tests/control/data/post_rays.json";
  o.lcm_url = url;
  o.have_start = true;
  o.start = {1.84, 1.55};
  o.robot.seed = 7;
  o.noise_px = 0.2;
  o.latency_s = 0.01;
  return o;
}

RunOptions Controller(const std::string& url) {
  RunOptions o;
  o.strategy_path = "tests/control/data/post_plan.json";
  o.scene_path = "tests/control/data/post_scene.json";
  o.rays_path = "tests/control/data/post_rays.json";
  o.lcm_url = url;
  o.realtime = false;
  o.executor.limits.max_speed = 0.4;
  o.executor.limits.max_accel = 4.0;
  return o;
}

TEST(ControlIntegration, CompliantMotionContactAndGoalOverLcm) {
  const std::string url = PrivateUrl();
  Listener listener(url);
  sim::SimSession sim(Sim(url));
  sim.Start();
  const RunOptions options = Controller(url);
  const Task task = LoadTask(options);
  std::atomic<bool> stop{false};
  const RunResult result = RunTask(task, options, stop);
  const sim::SimSummary summary = sim.Summary();
  sim.Stop();
  ASSERT_EQ(result.mode, Mode::kDone) << result.ToJson();
  EXPECT_EQ(result.steps_completed, 2);
  EXPECT_NE(result.reason.find("goal recognised"), std::string::npos) << result.reason;
  // The robot is in the goal kernel (the goal eroded by 2 cm), above the table, past the post.
  EXPECT_GE(summary.position.x, 2.22 - 0.01);
  EXPECT_LE(summary.position.x, 2.68);
  EXPECT_GE(summary.position.y, 0.5 - 1e-9);
  EXPECT_GT(result.frames_received, 30u);
  EXPECT_GT(result.statuses_received, 500u);
  EXPECT_EQ(summary.driver.bad_commands, 0u);
  EXPECT_EQ(summary.driver.out_of_sequence, 0u);
  // Telemetry showed the compliant motion and the end, with the reason.
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  bool compliant = false, done = false;
  for (const controller_telemetry_t& t : listener.telemetry()) {
    compliant |= t.mode == controller_telemetry_t::MODE_VISUAL_COMPLIANT;
    if (t.mode == controller_telemetry_t::MODE_DONE) {
      done = true;
      EXPECT_NE(t.stop_reason.find("goal recognised"), std::string::npos);
    }
  }
  EXPECT_TRUE(compliant);
  EXPECT_TRUE(done);
}

TEST(ControlIntegration, CameraLossHoldsThenStopsWithTheReasonOnLcm) {
  const std::string url = PrivateUrl();
  Listener listener(url);
  sim::SimSession sim(Sim(url));
  sim.Start();
  RunOptions options = Controller(url);
  options.executor.max_hold_s = 0.5;
  const Task task = LoadTask(options);
  std::atomic<bool> stop{false};
  std::thread cut([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(1200));
    sim.SetCameraOn(false);
  });
  const RunResult result = RunTask(task, options, stop);
  cut.join();
  const sim::SimSummary before = sim.Summary();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const sim::SimSummary after = sim.Summary();
  sim.Stop();
  EXPECT_EQ(result.mode, Mode::kStopped);
  EXPECT_EQ(result.stop_code, FaultCode::kVisionStale) << result.reason;
  EXPECT_NE(result.reason.find("vision not restored"), std::string::npos) << result.reason;
  // The robot stands still after the stop.
  EXPECT_NEAR(after.position.x, before.position.x, 1e-9);
  EXPECT_NEAR(after.position.y, before.position.y, 1e-9);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  bool hold = false, stopped = false;
  for (const fault_t& f : listener.faults()) {
    if (f.source != "controller") continue;
    hold |= f.code == fault_t::CODE_VISION_STALE && f.severity == fault_t::SEVERITY_WARNING && f.robot_stopped;
    stopped |= f.code == fault_t::CODE_VISION_STALE && f.severity == fault_t::SEVERITY_ERROR && f.robot_stopped;
  }
  EXPECT_TRUE(hold);
  EXPECT_TRUE(stopped);
  bool telemetry_reason = false;
  for (const controller_telemetry_t& t : listener.telemetry()) {
    telemetry_reason |= t.mode == controller_telemetry_t::MODE_STOPPED && !t.stop_reason.empty();
  }
  EXPECT_TRUE(telemetry_reason);
}

TEST(ControlIntegration, DriverDeathStopsTheController) {
  const std::string url = PrivateUrl();
  Listener listener(url);
  sim::SimSession sim(Sim(url));
  sim.Start();
  const RunOptions options = Controller(url);
  const Task task = LoadTask(options);
  std::atomic<bool> stop{false};
  std::atomic<std::int64_t> killed_ns{0};
  std::thread kill([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(1000));
    killed_ns = MonotonicNs();
    sim.KillDriver();
  });
  const RunResult result = RunTask(task, options, stop);
  const std::int64_t ended_ns = MonotonicNs();
  kill.join();
  sim.Stop();
  EXPECT_EQ(result.mode, Mode::kStopped);
  EXPECT_EQ(result.stop_code, FaultCode::kPeerTimeout) << result.reason;
  // Stopped within the status time-out (100 ms) plus the loop's exit and reporting.
  EXPECT_LT(static_cast<double>(ended_ns - killed_ns) * 1e-9, 0.1 + 0.2);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  bool reported = false;
  for (const fault_t& f : listener.faults()) {
    reported |= f.source == "controller" && f.code == fault_t::CODE_PEER_TIMEOUT && f.robot_stopped;
  }
  EXPECT_TRUE(reported);
}

TEST(ControlIntegration, StrategyArrivesOnLcm) {
  // `visco run` without a strategy file takes the first VISCO_STRATEGY message (the planner's LCM output).
  const std::string url = PrivateUrl();
  std::atomic<bool> publishing{true};
  std::thread publisher([&] {
    lcm::LCM lcm(url);
    motion_strategy_t m;
    m.scene = "post";
    m.feasible = true;
    m.speed = 0.1;
    motion_step_t step;
    step.theta = -1.745;
    step.active_rays = {"vc6.cm1"};
    step.num_active_rays = 1;
    step.terminate_kind = motion_step_t::TERMINATE_CONTACT;
    step.timeout_s = 4;
    m.steps.push_back(step);
    m.num_steps = 1;
    while (publishing) {
      lcm.publish(channels::kStrategy, &m);
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });
  RunOptions options = Controller(url);
  options.strategy_path.clear();
  options.strategy_wait_s = 5;
  const Task task = LoadTask(options);
  publishing = false;
  publisher.join();
  ASSERT_EQ(task.steps.size(), 1u);
  EXPECT_DOUBLE_EQ(task.speed, 0.1);
  EXPECT_EQ(task.steps[0].terminate, TerminateKind::kContact);
  ASSERT_EQ(task.steps[0].active_rays.size(), 1u);
  EXPECT_EQ(task.rays[static_cast<std::size_t>(task.steps[0].active_rays[0])].id, "vc6.cm1");
  EXPECT_TRUE(task.rays[static_cast<std::size_t>(task.steps[0].active_rays[0])].has_cm_offset);
  // Nothing published: the wait ends with a clear failure.
  options.lcm_url = PrivateUrl();
  options.strategy_wait_s = 0.2;
  EXPECT_THROW(LoadTask(options), JobFailed);
}

}  // namespace
}  // namespace visco::control
