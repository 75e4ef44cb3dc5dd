// The driver's safety logic with a scripted transport and its own clock: watchdog, sequence, malformed commands,
// e-stop, bus-off, reset; and the simulated robot's limits.

#include "drivers/driver.h"

#include <gtest/gtest.h>

#include <cmath>
#include <deque>
#include <vector>

#include "common/error.h"
#include "drivers/simulated_robot.h"

namespace visco::drivers {
namespace {

class FakeTransport final : public DriverTransport {
 public:
  void Wait(std::int64_t) override {}
  bool NextEvent(std::int64_t now_us, DriverEvent& out) override {
    if (events.empty()) return false;
    out = events.front();
    out.receive_us = now_us;
    events.pop_front();
    return true;
  }
  LinkResult SendStatus(const RobotStatus& status) override {
    statuses.push_back(status);
    return LinkResult::kOk;
  }
  LinkResult SendHeartbeat(NmtState state) override {
    heartbeats.push_back(state);
    return LinkResult::kOk;
  }
  LinkResult SendFault(const DriverFault& fault) override {
    faults.push_back(fault);
    return LinkResult::kOk;
  }
  std::uint32_t sequence_modulus() const override { return 256; }
  LinkCounters counters() const override { return {}; }

  void Command(std::uint32_t seq, double vx, double vy, bool estop = false, bool reset = false) {
    DriverEvent e;
    e.kind = DriverEventKind::kCommand;
    e.seq = seq;
    e.command.velocity[0] = vx;
    e.command.velocity[1] = vy;
    e.command.estop = estop;
    e.command.reset = reset;
    events.push_back(e);
  }
  void Event(DriverEventKind kind, can::DecodeStatus decode = can::DecodeStatus::kOk) {
    DriverEvent e;
    e.kind = kind;
    e.decode = decode;
    events.push_back(e);
  }

  std::deque<DriverEvent> events;
  std::vector<RobotStatus> statuses;
  std::vector<NmtState> heartbeats;
  std::vector<DriverFault> faults;
};

struct Rig {
  Rig() : robot(SimulatedRobotConfig{}), driver(DriverConfig{}, transport, robot) { driver.Start(now); }
  // Advances time in 1 ms steps for `ms` milliseconds.
  void Run(int ms) {
    for (int i = 0; i < ms; ++i) {
      now += 1000;
      driver.Update(now);
    }
  }
  double Speed() const {
    const RobotFeedback f = robot.Read();
    return std::hypot(f.velocity[0], f.velocity[1]);
  }
  FakeTransport transport;
  SimulatedRobot robot;
  Driver driver;
  std::int64_t now = 1'000'000;
};

TEST(Driver, BootsAndAnswersEveryCommand) {
  Rig rig;
  ASSERT_FALSE(rig.transport.heartbeats.empty());
  EXPECT_EQ(rig.transport.heartbeats.front(), NmtState::kBootUp);
  rig.transport.statuses.clear();
  rig.transport.Command(1, 0.2, 0.0);
  rig.Run(1);
  ASSERT_FALSE(rig.transport.statuses.empty());
  EXPECT_EQ(rig.transport.statuses.front().command_seq, 1U);
  EXPECT_EQ(rig.driver.state(), RobotState::kMoving);
  rig.Run(200);  // 0.2 m/s at 2 m/s^2: reached after 100 ms; the watchdog stops it at 100 ms without commands
  EXPECT_EQ(rig.driver.state(), RobotState::kStopped);
}

TEST(Driver, WatchdogStopsWithinPeriodAndResetRecovers) {
  Rig rig;
  std::uint32_t seq = 0;
  for (int i = 0; i < 300; ++i) {  // 300 ms of commands at 1 kHz
    rig.transport.Command(++seq, 0.3, 0.0);
    rig.Run(1);
  }
  EXPECT_NEAR(rig.Speed(), 0.3, 1e-9);
  const std::int64_t silent_since = rig.now;
  int stopped_after_ms = -1;
  for (int ms = 1; ms <= 300; ++ms) {
    rig.Run(1);
    if (rig.Speed() == 0.0 && rig.driver.state() == RobotState::kStopped) {
      stopped_after_ms = ms;
      break;
    }
  }
  // Watchdog 100 ms, then a quick stop from 0.3 m/s at 50 m/s^2 takes 6 ms.
  ASSERT_GT(stopped_after_ms, 0);
  EXPECT_LE(stopped_after_ms, 100 + 8);
  EXPECT_GT(rig.now - silent_since, 100'000 - 1);
  EXPECT_TRUE(rig.driver.fault_bits() & fault_bits::kWatchdog);
  ASSERT_FALSE(rig.transport.faults.empty());
  EXPECT_EQ(rig.transport.faults.back().emcy_code, can::kEmcyRpdoTimeout);
  EXPECT_TRUE(rig.transport.faults.back().robot_stopped);

  // Commands alone do not restart a stopped robot; a reset does.
  rig.transport.Command(++seq, 0.3, 0.0);
  rig.Run(10);
  EXPECT_EQ(rig.driver.state(), RobotState::kStopped);
  EXPECT_EQ(rig.Speed(), 0.0);
  rig.transport.Command(++seq, 0.0, 0.0, false, true);
  rig.Run(1);
  EXPECT_EQ(rig.driver.state(), RobotState::kReady);
  EXPECT_EQ(rig.driver.fault_bits(), 0);
  EXPECT_TRUE(rig.transport.faults.back().cleared);
  rig.transport.Command(++seq, 0.0, 0.1);
  rig.Run(60);
  EXPECT_EQ(rig.driver.state(), RobotState::kMoving);
  EXPECT_NEAR(rig.Speed(), 0.1, 1e-9);
}

TEST(Driver, OutOfSequenceAndMalformedCommandsAreIgnoredAndReported) {
  Rig rig;
  rig.transport.Command(10, 0.1, 0.0);
  rig.Run(1);
  rig.transport.Command(10, 0.5, 0.0);  // duplicate
  rig.transport.Command(5, 0.5, 0.0);   // older
  rig.Run(1);
  EXPECT_TRUE(rig.driver.fault_bits() & fault_bits::kSequence);
  EXPECT_EQ(rig.driver.stats().out_of_sequence, 2U);
  EXPECT_EQ(rig.transport.faults.size(), 1U);  // one announcement per episode
  EXPECT_EQ(rig.transport.faults.back().emcy_code, can::kEmcyProtocol);
  rig.transport.Event(DriverEventKind::kBadCommand, can::DecodeStatus::kBadLength);
  rig.Run(1);
  EXPECT_TRUE(rig.driver.fault_bits() & fault_bits::kBadFrame);
  EXPECT_EQ(rig.transport.faults.back().emcy_code, can::kEmcyPdoLength);
  rig.Run(100);
  // The robot never took the bad commands' 0.5 m/s.
  EXPECT_LE(rig.Speed(), 0.1 + 1e-9);
  // Only garbage for a whole watchdog period: stopped.
  for (int i = 0; i < 150; ++i) {
    rig.transport.Event(DriverEventKind::kBadCommand, can::DecodeStatus::kBadChecksum);
    rig.Run(1);
  }
  EXPECT_EQ(rig.driver.state(), RobotState::kStopped);
  EXPECT_EQ(rig.Speed(), 0.0);
  // Gaps are tolerated: 200 is 190 ahead of 10 modulo 256? No: 190 > 127 means older. 100 is 90 ahead: accepted.
  rig.transport.Command(100, 0.0, 0.0, false, true);
  rig.Run(1);
  EXPECT_EQ(rig.driver.state(), RobotState::kReady);
  EXPECT_EQ(rig.driver.stats().sequence_gaps, 89U);
}

TEST(Driver, ABacklogIsReadBeforeTheWatchdogJudges) {
  Rig rig;
  rig.transport.Command(1, 0.1, 0.0);
  rig.Run(1);
  // The driver was away for 150 ms (> watchdog); meanwhile 20 garbage frames and then a valid command queued up.
  for (int i = 0; i < 20; ++i) rig.transport.Event(DriverEventKind::kBadCommand, can::DecodeStatus::kBadChecksum);
  rig.transport.Command(2, 0.1, 0.0);
  rig.now += 150'000;
  rig.driver.Update(rig.now);  // handles the first 16 events only: no verdict yet
  rig.driver.Update(rig.now);  // the rest, including the valid command
  EXPECT_EQ(rig.driver.state(), RobotState::kMoving);
  EXPECT_FALSE(rig.driver.fault_bits() & fault_bits::kWatchdog);
  EXPECT_EQ(rig.driver.stats().bad_commands, 20U);
}

TEST(Driver, EStopLatchesUntilReset) {
  Rig rig;
  rig.transport.Command(1, 0.2, 0.2);
  rig.Run(50);
  rig.transport.Command(2, 0.2, 0.2, true);
  rig.Run(10);
  EXPECT_EQ(rig.driver.state(), RobotState::kEStop);
  EXPECT_EQ(rig.Speed(), 0.0);
  EXPECT_TRUE(rig.driver.fault_bits() & fault_bits::kEStop);
  rig.transport.Event(DriverEventKind::kResetRequest);
  rig.Run(1);
  EXPECT_EQ(rig.driver.state(), RobotState::kReady);
  rig.transport.Event(DriverEventKind::kEStop);  // NMT stop
  rig.Run(1);
  EXPECT_EQ(rig.driver.state(), RobotState::kEStop);
}

TEST(Driver, BusOffStopsAndRecoveryNeedsReset) {
  Rig rig;
  std::uint32_t seq = 0;
  rig.transport.Command(++seq, 0.2, 0.0);
  rig.Run(50);
  rig.transport.Event(DriverEventKind::kBusOff);
  rig.Run(10);
  EXPECT_EQ(rig.driver.state(), RobotState::kStopped);
  EXPECT_EQ(rig.Speed(), 0.0);
  EXPECT_TRUE(rig.driver.fault_bits() & fault_bits::kBus);
  rig.transport.Command(++seq, 0.0, 0.0, false, true);  // reset refused while bus-off
  rig.Run(1);
  EXPECT_EQ(rig.driver.state(), RobotState::kStopped);
  rig.transport.Event(DriverEventKind::kBusRestarted);
  rig.Run(1);
  EXPECT_FALSE(rig.driver.fault_bits() & fault_bits::kBus);
  EXPECT_EQ(rig.transport.faults.back().emcy_code, can::kEmcyBusOffRecovered);
  rig.transport.Command(++seq, 0.0, 0.0, false, true);
  rig.Run(1);
  EXPECT_EQ(rig.driver.state(), RobotState::kReady);
}

TEST(Driver, SpeedLimitClampsAndReports) {
  Rig rig;
  for (std::uint32_t seq = 1; seq <= 50; ++seq) {  // 5 m/s > 1 m/s, for 500 ms
    rig.transport.Command(seq, 3.0, 4.0);
    rig.Run(10);
  }
  EXPECT_NEAR(rig.Speed(), 1.0, 1e-6);
  EXPECT_TRUE(rig.driver.fault_bits() & fault_bits::kLimit);
  EXPECT_EQ(rig.transport.faults.back().emcy_code, can::kEmcyVelocityLimit);
}

TEST(Driver, LeavingTheWorkspaceStopsAndReportsOncePerEpisode) {
  SimulatedRobotConfig robot_config;
  robot_config.workspace = true;
  robot_config.workspace_max[0] = 1.0;
  robot_config.workspace_max[1] = 1.0;
  robot_config.start[0] = 0.95;
  robot_config.start[1] = 0.5;
  FakeTransport transport;
  SimulatedRobot robot(robot_config);
  Driver driver(DriverConfig{}, transport, robot);
  std::int64_t now = 1'000'000;
  driver.Start(now);
  auto run = [&](std::uint32_t& seq, double vx, int ms) {
    for (int i = 0; i < ms; ++i) {
      if (i % 5 == 0) transport.Command(++seq, vx, 0.0);
      now += 1000;
      driver.Update(now);
    }
  };
  std::uint32_t seq = 0;
  run(seq, 0.2, 600);  // 0.2 m/s towards x = 1: out after ~0.3 s
  EXPECT_EQ(driver.state(), RobotState::kStopped);
  EXPECT_TRUE(driver.fault_bits() & fault_bits::kBounds);
  EXPECT_EQ(driver.stats().bounds_stops, 1U);
  const RobotFeedback f = robot.Read();
  EXPECT_GT(f.position[0], 1.0);
  EXPECT_LT(f.position[0], 1.0 + 0.2 * 0.002 + 0.2 * 0.2 / (2 * 50.0) + 1e-9);  // detected within a period
  EXPECT_EQ(f.velocity[0], 0.0);
  ASSERT_FALSE(transport.faults.empty());
  const DriverFault& fault = transport.faults.back();
  EXPECT_EQ(fault.emcy_code, can::kEmcyBounds);
  EXPECT_EQ(fault.code, 7);  // fault_t::CODE_LIMIT
  EXPECT_TRUE(fault.robot_stopped);
  EXPECT_TRUE(fault.fault_bits & fault_bits::kBounds);
  EXPECT_NE(std::string(fault.message).find("outside its workspace"), std::string::npos);
  EXPECT_EQ(transport.statuses.back().fault_bits & fault_bits::kBounds, fault_bits::kBounds);

  // A reset lets it move back in without a new fault; inside again ends the episode, leaving again stops again.
  transport.Command(++seq, 0.0, 0.0, false, true);
  run(seq, -0.2, 500);
  EXPECT_EQ(driver.state(), RobotState::kMoving);
  EXPECT_LT(robot.Read().position[0], 1.0);
  EXPECT_EQ(driver.stats().bounds_stops, 1U);
  run(seq, 0.4, 600);
  EXPECT_EQ(driver.state(), RobotState::kStopped);
  EXPECT_EQ(driver.stats().bounds_stops, 2U);
}

TEST(SimulatedRobot, WallsGiveContactAndForce) {
  SimulatedRobotConfig config;
  config.walls = true;
  config.bounds_max[0] = 1.0;
  config.bounds_max[1] = 1.0;
  config.start[0] = 0.5;
  config.start[1] = 0.05;
  SimulatedRobot robot(config);
  const double down[2] = {0.0, -0.1};
  robot.SetVelocity(down);
  for (int i = 0; i < 1000; ++i) robot.Step(0.001);
  const RobotFeedback f = robot.Read();
  EXPECT_TRUE(f.contact);
  EXPECT_EQ(f.position[1], 0.0);
  EXPECT_NEAR(f.contact_force[1], 200.0 * 0.1, 1e-9);
  EXPECT_EQ(f.contact_force[0], 0.0);
}

TEST(SimulatedRobot, RejectsBadConfiguration) {
  SimulatedRobotConfig config;
  config.max_acceleration = 0.0;
  EXPECT_THROW(SimulatedRobot{config}, InputError);
  config.max_acceleration = 1.0;
  config.walls = true;
  EXPECT_THROW(SimulatedRobot{config}, InputError);
  config.walls = false;
  config.workspace = true;  // empty
  EXPECT_THROW(SimulatedRobot{config}, InputError);
  config.workspace_max[0] = config.workspace_max[1] = 1.0;
  config.start[0] = 2.0;  // outside
  EXPECT_THROW(SimulatedRobot{config}, InputError);
}

}  // namespace
}  // namespace visco::drivers
