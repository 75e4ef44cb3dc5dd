// The controller's CAN link (drivers/socketcan_link.cc) over ports in memory: what it writes for the commands it is
// given.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <vector>

#include "drivers/can_protocol.h"
#include "drivers/robot_link.h"
#include "drivers/socketcan.h"
#include "tests/drivers/memory_port.h"

namespace visco::drivers {
namespace {

constexpr int kNode = 1;

using visco::drivers::testing::MemoryPort;

bool SameBytes(const can::Frame& a, const can::Frame& b) { return std::equal(a.data, a.data + 8, b.data); }

// A link over ports in memory that has heard the driver announce `session` and its first status (no command
// accepted yet): the session is the link's to use. `written` gets the link's frames.
std::unique_ptr<RobotLink> LinkInSession(std::uint32_t session, std::vector<can::Frame>*& written) {
  auto rx = std::make_unique<MemoryPort>();
  auto tx = std::make_unique<MemoryPort>();
  MemoryPort& bus_in = *rx;
  written = &tx->written;
  RobotLinkConfig config;
  config.node_id = kNode;
  config.heartbeat_timeout_us = 1'000'000'000;
  auto link = MakeCanRobotLink(config, std::move(rx), std::move(tx));
  can::Frame announcement;
  EXPECT_EQ(can::EncodeSession(kNode, can::SessionFrame{session, 0}, announcement), can::EncodeStatus::kOk);
  can::StatusFrames status;
  status.session = session;
  status.seq = 1;
  can::Frame triple[3];
  EXPECT_EQ(can::EncodeStatusFrames(kNode, status, triple), can::EncodeStatus::kOk);
  bus_in.queue.push_back({announcement, 1'000});
  for (const can::Frame& f : triple) bus_in.queue.push_back({f, 1'000});
  link->Poll(1'000);
  RobotStatus seen;
  EXPECT_EQ(link->TakeStatus(seen), LinkResult::kOk);
  return link;
}

// A command whose frame at number n would repeat, byte for byte, the frame the link sent at n - 256 (the same
// payload, and the CRC is linear: for 1 number pair in 256 the two numbers' CRCs coincide for every payload) goes out
// under the next number instead: the driver takes such a repeat for a replay and would reject the live command.
// Against a reference that numbers the commands by that rule, at a constant velocity (every colliding pair repeats).
TEST(CanLink, ANumberWhoseFrameWouldRepeatTheLastWrapsIsSkipped) {
  constexpr std::uint32_t kSession = 0x5EC7105E;
  std::vector<can::Frame>* written = nullptr;
  auto link = LinkInSession(kSession, written);
  std::int64_t now = 1'000;

  constexpr int kCommands = 3000;
  VelocityCommand command;
  command.velocity[0] = 0.05;
  for (int i = 0; i < kCommands; ++i) {
    now += 2'000;
    ASSERT_EQ(link->SendCommand(command, now), LinkResult::kOk) << "command " << i;
  }
  ASSERT_EQ(written->size(), static_cast<std::size_t>(kCommands));

  // Reference: the next number, and the one after while its frame equals the last one sent with its low byte.
  std::vector<can::Frame> by_low(256);
  std::vector<bool> have(256, false);
  std::uint32_t number = 0;
  int skipped = 0;
  for (int i = 0; i < kCommands; ++i) {
    can::CommandFrame wire;
    wire.session = kSession;
    wire.velocity[0] = 0.05;
    can::Frame expected;
    for (wire.seq = number + 1;; ++wire.seq) {
      ASSERT_EQ(can::EncodeCommand(kNode, wire, expected), can::EncodeStatus::kOk);
      const std::uint8_t low = expected.data[0];
      if (!(have[low] && SameBytes(by_low[low], expected))) break;
      ++skipped;
    }
    ASSERT_LE(wire.seq - number, kCommandWindow);
    ASSERT_TRUE(SameBytes((*written)[i], expected)) << "command " << i << ", number " << wire.seq;
    by_low[expected.data[0]] = expected;
    have[expected.data[0]] = true;
    number = wire.seq;
  }
  EXPECT_EQ(link->last_command_seq(), number);
  // About kCommands / 256 colliding pairs after the first wrap: the rule was exercised.
  EXPECT_GE(skipped, 3);
  std::printf("%d commands, %d numbers skipped\n", kCommands, skipped);
}

// The same commands through the driver's acceptance rule: each is accepted (the CRC and the last wrap's history),
// so a link that skips repeats never has a live command rejected as a replay.
TEST(CanLink, EveryCommandItSendsPassesTheDriversRule) {
  constexpr std::uint32_t kSession = 0x0BADCAFE;
  std::vector<can::Frame>* written = nullptr;
  auto link = LinkInSession(kSession, written);
  VelocityCommand command;
  std::uint32_t last = 0;
  can::FrameHistory accepted;
  for (int i = 0; i < 5000; ++i) {
    command.velocity[0] = (i / 700) % 2 == 0 ? 0.0 : 0.1;  // long stretches at a constant velocity
    ASSERT_EQ(link->SendCommand(command, 2'000 * (i + 1)), LinkResult::kOk);
    const can::Frame& frame = written->back();
    std::uint32_t seq = 0;
    ASSERT_EQ(can::JudgeCommand(frame, kSession, last, kCommandWindow, seq, &accepted), can::CommandVerdict::kAccept)
        << "command " << i;
    ASSERT_FALSE(accepted.Contains(frame)) << "command " << i << " repeats the last wrap's frame";
    accepted.Add(frame);
    last = seq;
  }
}

}  // namespace
}  // namespace visco::drivers
