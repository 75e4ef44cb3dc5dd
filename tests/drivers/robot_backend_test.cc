// The backend seam: the example plugin loaded with dlopen through its C factory (configuration as JSON), its
// lifecycle and motion; a plugin that cannot be loaded or refuses its configuration is a clear error; the driver's
// rule for a robot's own fault (stop, report with the robot's EMCY code, Reset() on the driver's reset, a fault that
// persists stops again), with a scripted robot.

#include "drivers/robot_backend.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <functional>
#include <string>
#include <vector>

#include "common/error.h"
#include "drivers/driver.h"
#include "drivers/simulated_robot_options.h"

#ifndef VISCO_EXAMPLE_PLUGIN
#error "VISCO_EXAMPLE_PLUGIN: the example plugin's path, set by tests/drivers/CMakeLists.txt"
#endif

namespace visco::drivers {
namespace {

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(RobotPlugin, TheExampleLoadsRunsItsLifecycleAndFollowsTheCommand) {
  std::unique_ptr<RobotInterface> robot =
      LoadRobotPlugin(VISCO_EXAMPLE_PLUGIN, R"({"time_constant_s": 0.02, "max_acceleration": 5, "start": [0.1, 0.2],
                                               "workspace": [-1, -1, 1, 1]})");
  EXPECT_EQ(robot->Read().position[0], 0.1);
  EXPECT_EQ(robot->Read().position[1], 0.2);
  robot->Configure();
  robot->Activate();
  const double v[2] = {0.3, -0.1};
  robot->SetVelocity(v);
  for (int i = 0; i < 1000; ++i) robot->Step(0.001);  // 1 s: the lag (20 ms) long settled
  const RobotFeedback f = robot->Read();
  EXPECT_NEAR(f.velocity[0], 0.3, 1e-6);
  EXPECT_NEAR(f.velocity[1], -0.1, 1e-6);
  // The position is the integral: 1 s at the commanded speed less the lag's ~20 ms (and the acceleration ramp).
  EXPECT_NEAR(f.position[0], 0.1 + 0.3 * (1.0 - 0.02), 0.01);
  EXPECT_NEAR(f.position[1], 0.2 - 0.1 * (1.0 - 0.02), 0.005);
  EXPECT_FALSE(f.out_of_bounds);
  robot->QuickStop();  // 0.3 m/s at 20 m/s^2: 15 ms
  for (int i = 0; i < 16; ++i) robot->Step(0.001);
  EXPECT_EQ(robot->Read().velocity[0], 0.0);
  EXPECT_EQ(robot->Read().velocity[1], 0.0);
  robot->SetVelocity(v);
  for (int i = 0; i < 3000; ++i) robot->Step(0.001);  // x reaches the workspace's edge at 1 m
  EXPECT_TRUE(robot->Read().out_of_bounds);
  robot->Deactivate();
  robot->Deactivate();  // safe more than once
}

TEST(RobotPlugin, ABadLibraryOrConfigurationIsAClearError) {
  EXPECT_NE(ErrorOf([] { LoadRobotPlugin("/nonexistent/libnothing.so", "{}"); }).find("cannot load the robot plugin"),
            std::string::npos);
  // A shared library that is no robot plugin: the missing symbol is named.
  const std::string not_plugin = ErrorOf([] { LoadRobotPlugin("libm.so.6", "{}"); });
  EXPECT_NE(not_plugin.find("visco_robot_plugin_abi"), std::string::npos) << not_plugin;
  const std::string unknown = ErrorOf([] { LoadRobotPlugin(VISCO_EXAMPLE_PLUGIN, R"({"time_constant": 1})"); });
  EXPECT_NE(unknown.find("time_constant: unknown key"), std::string::npos) << unknown;
  const std::string negative = ErrorOf([] { LoadRobotPlugin(VISCO_EXAMPLE_PLUGIN, R"({"max_acceleration": -1})"); });
  EXPECT_NE(negative.find("max_acceleration: must be a positive number"), std::string::npos) << negative;
  const std::string box = ErrorOf([] { LoadRobotPlugin(VISCO_EXAMPLE_PLUGIN, R"({"workspace": [1, 0, 0, 1]})"); });
  EXPECT_NE(box.find("workspace"), std::string::npos) << box;
}

TEST(RobotBackend, TheKindIsChosenByConfiguration) {
  SimulatedRobotOptions sim;
  SimulatedRobot* simulated = nullptr;
  RobotBackendOptions options;
  EXPECT_NE(MakeRobot(options, sim, &simulated), nullptr);
  EXPECT_NE(simulated, nullptr);
  options.kind = "plugin";
  options.plugin_path = VISCO_EXAMPLE_PLUGIN;
  EXPECT_NE(MakeRobot(options, sim, &simulated), nullptr);
  EXPECT_EQ(simulated, nullptr);
  options.config_path = "/nonexistent/stage.json";
  EXPECT_NE(ErrorOf([&] { MakeRobot(options, sim, nullptr); }).find("/nonexistent/stage.json"), std::string::npos);
  options.kind = "stepper";
  EXPECT_NE(ErrorOf([&] {
              MakeRobot(options, sim, nullptr);
            }).find("--robot: unknown robot 'stepper' (simulated, cia402, plugin)"),
            std::string::npos);
  options = RobotBackendOptions{};
  options.kind = "plugin";
  EXPECT_NE(ErrorOf([&] { MakeRobot(options, sim, nullptr); }).find("--robot-plugin"), std::string::npos);
}

// A robot whose faults the test scripts; it counts the driver's calls.
class ScriptedRobot final : public RobotInterface {
 public:
  void SetVelocity(const double v[2]) override { velocity[0] = v[0], velocity[1] = v[1]; }
  void QuickStop() override { ++quick_stops, velocity[0] = velocity[1] = 0.0; }
  void Reset() override {
    ++resets;
    feedback.fault = false;  // as a fault reset does; a cause that persists raises it again
  }
  void Step(double) override {
    if (persistent_fault) Fault(0x8130, true, "node 3: heartbeat lost");
  }
  RobotFeedback Read() const override { return feedback; }
  void Fault(std::uint16_t code, bool bus, const char* message) {
    feedback.fault = true;
    feedback.fault_bus = bus;
    feedback.fault_code = code;
    std::snprintf(feedback.fault_message, sizeof(feedback.fault_message), "%s", message);
  }
  double velocity[2] = {0.0, 0.0};
  int quick_stops = 0;
  int resets = 0;
  bool persistent_fault = false;
  RobotFeedback feedback;
};

// The driver over LCM-style events (the transport's events are scripted).
class Transport final : public DriverTransport {
 public:
  void Wait(std::int64_t) override {}
  bool NextEvent(std::int64_t now_us, DriverEvent& out) override {
    if (events.empty()) return false;
    out = events.front();
    out.receive_us = now_us;
    events.pop_front();
    return true;
  }
  LinkResult SendStatus(const RobotStatus& s) override { return statuses.push_back(s), LinkResult::kOk; }
  LinkResult SendHeartbeat(NmtState) override { return LinkResult::kOk; }
  LinkResult SendFault(const DriverFault& f) override { return faults.push_back(f), LinkResult::kOk; }
  LinkResult SendSession(std::uint32_t nonce, std::uint32_t) override {
    if (nonce != session) session = nonce, next = 1;
    return LinkResult::kOk;
  }
  std::uint32_t sequence_modulus() const override { return 0x80000000U; }
  LinkCounters counters() const override { return {}; }
  void Command(double vx, bool reset = false) {
    DriverEvent e;
    e.kind = DriverEventKind::kCommand;
    e.seq = next++;
    e.session = session;
    e.command.velocity[0] = vx;
    e.command.reset = reset;
    events.push_back(e);
  }
  std::uint32_t session = 0, next = 1;
  std::deque<DriverEvent> events;
  std::vector<RobotStatus> statuses;
  std::vector<DriverFault> faults;
};

TEST(Driver, ARobotFaultStopsReportsItsCodeAndTheResetResetsTheRobot) {
  Transport transport;
  ScriptedRobot robot;
  DriverConfig config;
  config.session_seed = 5;
  Driver driver(config, transport, robot);
  std::int64_t now = 1'000'000;
  driver.Start(now);
  auto run = [&](int ms) {
    for (int i = 0; i < ms; ++i) driver.Update(now += 1000);
  };
  transport.Command(0.0, true);
  run(1);
  ASSERT_EQ(driver.state(), RobotState::kReady);
  EXPECT_EQ(robot.resets, 1);  // the driver's reset enables the robot
  transport.Command(0.2);
  run(1);
  EXPECT_EQ(robot.velocity[0], 0.2);
  // A drive's EMCY: STOPPED, quick stop, reported with the drive's code and words, no bus bit.
  robot.Fault(0x2310, false, "node 2 EMCY 0x2310: continuous over-current");
  run(1);
  EXPECT_EQ(driver.state(), RobotState::kStopped);
  EXPECT_GE(robot.quick_stops, 1);
  ASSERT_FALSE(transport.faults.empty());
  EXPECT_EQ(transport.faults.back().emcy_code, 0x2310);
  EXPECT_TRUE(transport.faults.back().robot_stopped);
  EXPECT_STREQ(transport.faults.back().message, "node 2 EMCY 0x2310: continuous over-current");
  EXPECT_EQ(driver.fault_bits() & fault_bits::kBus, 0);
  EXPECT_EQ(driver.stats().robot_faults, 1U);
  run(50);
  EXPECT_EQ(driver.stats().robot_faults, 1U);  // once per episode
  // The reset of the new session resets the robot; it moves again.
  transport.Command(0.0, true);
  run(1);
  EXPECT_EQ(driver.state(), RobotState::kReady);
  EXPECT_EQ(robot.resets, 2);
  transport.Command(0.1);
  run(1);
  EXPECT_EQ(driver.state(), RobotState::kMoving);
  // A communication fault that persists: the bus bit; after the reset it stops the robot again at once.
  robot.persistent_fault = true;
  run(1);
  EXPECT_EQ(driver.state(), RobotState::kStopped);
  EXPECT_NE(driver.fault_bits() & fault_bits::kBus, 0);
  EXPECT_EQ(transport.faults.back().emcy_code, 0x8130);
  transport.Command(0.0, true);
  run(2);
  EXPECT_EQ(driver.state(), RobotState::kStopped);
  EXPECT_EQ(driver.stats().robot_faults, 3U);
}

}  // namespace
}  // namespace visco::drivers
