// The LCM twin of the CAN link: the controller's LcmRobotLink against the driver logic on LcmDriverTransport, over
// a real LCM bus (UDP multicast with ttl=0 on a per-process port), in one process with the driver on its own thread.

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <string>
#include <thread>

#include "drivers/driver.h"
#include "drivers/driver_transport.h"
#include "drivers/robot_link.h"
#include "drivers/simulated_robot.h"

namespace visco::drivers {
namespace {

std::string Url() { return "udpm://239.255.76.67:" + std::to_string(30000 + getpid() % 20000) + "?ttl=0"; }

class LcmLink : public ::testing::Test {
 protected:
  void SetUp() override {
    DriverTransportConfig transport_config;
    transport_config.lcm_url = Url();
    transport_ = MakeLcmDriverTransport(transport_config);
    DriverConfig config;
    config.watchdog_us = 100'000;
    robot_ = std::make_unique<SimulatedRobot>(SimulatedRobotConfig{});
    driver_ = std::make_unique<Driver>(config, *transport_, *robot_);
    RobotLinkConfig link_config;
    link_config.lcm_url = Url();
    link_config.heartbeat_timeout_us = 300'000;
    link_ = MakeLcmRobotLink(link_config);
    thread_ = std::thread([this] { driver_->Run(stop_); });
  }
  void TearDown() override {
    StopDriver();
    link_.reset();
  }
  void StopDriver() {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
  }
  bool RunUntil(std::int64_t timeout_us, const std::function<bool()>& done, bool send) {
    const std::int64_t end = MonotonicMicros() + timeout_us;
    while (MonotonicMicros() < end) {
      link_->Poll(MonotonicMicros());
      RobotStatus status;
      if (link_->TakeStatus(status) == LinkResult::kOk) last_ = status;
      LinkFault fault;
      while (link_->TakeFault(fault) == LinkResult::kOk) faults_.push_back(fault);
      if (send) {
        EXPECT_EQ(link_->SendCommand(command_, MonotonicMicros()), LinkResult::kOk);
      }
      if (done()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    return false;
  }

  std::unique_ptr<DriverTransport> transport_;
  std::unique_ptr<SimulatedRobot> robot_;
  std::unique_ptr<Driver> driver_;
  std::unique_ptr<RobotLink> link_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
  VelocityCommand command_;
  RobotStatus last_;
  std::vector<LinkFault> faults_;
};

TEST_F(LcmLink, CommandsWatchdogResetAndHeartbeat) {
  ASSERT_TRUE(RunUntil(
      3'000'000, [&] { return link_->peer_state(MonotonicMicros()) == PeerState::kAlive; }, false));
  command_.velocity[0] = 0.2;
  ASSERT_TRUE(RunUntil(
      3'000'000, [&] { return std::abs(last_.velocity[0] - 0.2) < 1e-9; }, true));
  EXPECT_EQ(last_.state, RobotState::kMoving);
  EXPECT_GT(last_.position[0], 0.0);
  EXPECT_LE(link_->last_command_seq() - last_.command_seq, 10U);

  // Silence: the driver's watchdog stops the robot and says so on VISCO_FAULT.
  ASSERT_TRUE(RunUntil(
      2'000'000, [&] { return last_.state == RobotState::kStopped && last_.velocity[0] == 0.0; }, false));
  EXPECT_TRUE(last_.fault_bits & fault_bits::kWatchdog);
  ASSERT_TRUE(RunUntil(
      500'000, [&] { return !faults_.empty(); }, false));
  EXPECT_EQ(faults_.front().code, 4);  // fault_t::CODE_PEER_TIMEOUT
  EXPECT_TRUE(faults_.front().robot_stopped);
  // The same fields as the CAN path's EMCY frame: the CANopen error code and the driver's fault bits.
  EXPECT_EQ(faults_.front().emcy_code, can::kEmcyRpdoTimeout);
  EXPECT_EQ(faults_.front().fault_bits, fault_bits::kWatchdog);
  EXPECT_FALSE(faults_.front().local);

  command_ = VelocityCommand{};
  command_.reset = true;
  ASSERT_TRUE(RunUntil(
      2'000'000, [&] { return last_.state == RobotState::kReady && last_.fault_bits == 0; }, true));

  StopDriver();
  ASSERT_TRUE(RunUntil(
      2'000'000, [&] { return link_->peer_state(MonotonicMicros()) == PeerState::kLost; }, false));
}

TEST_F(LcmLink, ARestartedControllerContinuesTheDriversNumbering) {
  command_.velocity[0] = 0.1;
  ASSERT_TRUE(RunUntil(
      3'000'000, [&] { return last_.state == RobotState::kMoving && link_->last_command_seq() > 50; }, true));
  // The controller dies; a new one (numbering from scratch) takes over: its reset and commands are accepted.
  link_.reset();
  RobotLinkConfig link_config;
  link_config.lcm_url = Url();
  link_config.heartbeat_timeout_us = 300'000;
  link_ = MakeLcmRobotLink(link_config);
  last_ = RobotStatus{};
  command_ = VelocityCommand{};
  command_.reset = true;
  ASSERT_TRUE(RunUntil(
      3'000'000,
      [&] {
        return last_.state == RobotState::kReady && last_.command_seq > 50 &&
               link_->last_command_seq() - last_.command_seq < 10;  // the driver accepts the new link's commands
      },
      true));
  command_ = VelocityCommand{};
  command_.velocity[1] = 0.1;
  ASSERT_TRUE(RunUntil(
      2'000'000, [&] { return last_.state == RobotState::kMoving && last_.velocity[1] > 0.05; }, true));
  EXPECT_GT(link_->last_command_seq(), 50U);  // it continued the old numbering
  EXPECT_EQ(last_.fault_bits & fault_bits::kSequence, 0);
}

TEST(CommandSequence, SyncsToAForeignNumberingUntilAcknowledged) {
  CommandSequence seq(256);
  for (std::uint32_t i = 0; i < 3; ++i) seq.Sent(seq.Next());  // 1, 2, 3: rejected by a driver at 200
  seq.OnStatus(200);
  EXPECT_EQ(seq.Next(), 201U);
  seq.Sent(seq.Next());
  seq.OnStatus(200);  // a late answer to a rejected command: no change
  EXPECT_EQ(seq.Next(), 202U);
  seq.Sent(seq.Next());
  seq.OnStatus(201);  // ours: acknowledged, the numbering is ours from now on
  EXPECT_TRUE(seq.acknowledged());
  seq.OnStatus(17);
  EXPECT_EQ(seq.Next(), 203U);
  // A fresh driver (nothing accepted yet: 0) does not move the numbering; wrapping works.
  CommandSequence fresh(256);
  fresh.Sent(fresh.Next());
  fresh.OnStatus(0);
  EXPECT_EQ(fresh.Next(), 2U);
  fresh.OnStatus(1);
  EXPECT_TRUE(fresh.acknowledged());
  CommandSequence wrap(256);
  wrap.OnStatus(255);
  EXPECT_EQ(wrap.Next(), 0U);
  wrap.Sent(wrap.Next());
  wrap.OnStatus(0);
  EXPECT_TRUE(wrap.acknowledged());
}

}  // namespace
}  // namespace visco::drivers
