// The CAN protocol against the DBC file (read by a slow reference parser) and a textbook CRC, on seeded random
// values and random frames.

#include "drivers/can_protocol.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "tests/drivers/dbc_reference.h"

namespace visco::drivers::can {
namespace {

using visco::drivers::testing::Dbc;
using visco::drivers::testing::ReferenceCrc8;

const Dbc& TheDbc() {
  static const Dbc dbc("drivers/visco.dbc");
  return dbc;
}

double Sig(const Frame& frame, const char* name) {
  const auto& message = TheDbc().message(frame.id & kSffMask);
  return Dbc::Physical(message.signals.at(name), frame.data);
}
std::int64_t RawSig(const Frame& frame, const char* name) {
  const auto& message = TheDbc().message(frame.id & kSffMask);
  return Dbc::Raw(message.signals.at(name), frame.data);
}

std::uint8_t ReferenceFrameCrc(const Frame& frame) {
  std::uint8_t bytes[9] = {static_cast<std::uint8_t>(frame.id & 0xFF),
                           static_cast<std::uint8_t>((frame.id >> 8) & 0x7)};
  std::memcpy(bytes + 2, frame.data, 7);
  return ReferenceCrc8(bytes, 9);
}

TEST(CanProtocol, Crc8CheckValue) {
  const std::uint8_t check[] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  EXPECT_EQ(Crc8SaeJ1850(check, 9), 0x4B);
  EXPECT_EQ(ReferenceCrc8(check, 9), 0x4B);
}

TEST(CanProtocol, CrcMatchesTextbookOnRandomBytes) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 2000; ++trial) {
    std::uint8_t bytes[16];
    const int size = static_cast<int>(rng() % 17);
    for (auto& b : bytes) b = static_cast<std::uint8_t>(rng());
    ASSERT_EQ(Crc8SaeJ1850(bytes, size), ReferenceCrc8(bytes, size)) << "size " << size;
  }
}

TEST(CanProtocol, DbcDescribesEveryFrameOfNodeOne) {
  const auto& messages = TheDbc().messages();
  EXPECT_EQ(messages.at(0x000).dlc, 2);
  EXPECT_EQ(messages.at(kEmcyBase + 1).dlc, 8);
  EXPECT_EQ(messages.at(kStatusBase + 1).dlc, 8);
  EXPECT_EQ(messages.at(kCommandBase + 1).dlc, 8);
  EXPECT_EQ(messages.at(kPositionBase + 1).dlc, 8);
  EXPECT_EQ(messages.at(kForceBase + 1).dlc, 8);
  EXPECT_EQ(messages.at(kHeartbeatBase + 1).dlc, 1);
  EXPECT_EQ(messages.size(), 7U);
}

TEST(CanProtocol, CommandRoundTripAgreesWithDbc) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> speed(-kMaxVelocity, kMaxVelocity);
  for (int trial = 0; trial < 5000; ++trial) {
    CommandFrame command;
    command.seq = static_cast<std::uint8_t>(rng());
    command.estop = rng() % 2;
    command.reset = rng() % 2;
    command.velocity[0] = speed(rng);
    command.velocity[1] = speed(rng);
    Frame frame;
    ASSERT_EQ(EncodeCommand(1, command, frame), EncodeStatus::kOk);
    EXPECT_EQ(frame.id, 0x201U);
    EXPECT_EQ(frame.dlc, 8);
    EXPECT_EQ(RawSig(frame, "CommandSeq"), command.seq);
    EXPECT_EQ(RawSig(frame, "EStop"), command.estop ? 1 : 0);
    EXPECT_EQ(RawSig(frame, "Reset"), command.reset ? 1 : 0);
    EXPECT_EQ(RawSig(frame, "Reserved"), 0);
    EXPECT_NEAR(Sig(frame, "VelocityX"), command.velocity[0], kVelocityScale / 2 + 1e-12);
    EXPECT_NEAR(Sig(frame, "VelocityY"), command.velocity[1], kVelocityScale / 2 + 1e-12);
    EXPECT_EQ(RawSig(frame, "Crc"), ReferenceFrameCrc(frame));
    CommandFrame decoded;
    ASSERT_EQ(DecodeCommand(1, frame, decoded), DecodeStatus::kOk);
    EXPECT_EQ(decoded.seq, command.seq);
    EXPECT_EQ(decoded.estop, command.estop);
    EXPECT_EQ(decoded.reset, command.reset);
    EXPECT_DOUBLE_EQ(decoded.velocity[0], Sig(frame, "VelocityX"));
    EXPECT_DOUBLE_EQ(decoded.velocity[1], Sig(frame, "VelocityY"));
  }
}

TEST(CanProtocol, CommandRejectsWhatTheWireCannotCarry) {
  Frame frame;
  CommandFrame command;
  command.velocity[0] = 3.3;
  EXPECT_EQ(EncodeCommand(1, command, frame), EncodeStatus::kOutOfRange);
  command.velocity[0] = std::nan("");
  EXPECT_EQ(EncodeCommand(1, command, frame), EncodeStatus::kNotFinite);
  command.velocity[0] = 0.0;
  EXPECT_EQ(EncodeCommand(0, command, frame), EncodeStatus::kBadNode);
  EXPECT_EQ(EncodeCommand(128, command, frame), EncodeStatus::kBadNode);
  EXPECT_EQ(EncodeCommand(127, command, frame), EncodeStatus::kOk);
  EXPECT_EQ(frame.id, 0x27FU);
}

TEST(CanProtocol, StatusRoundTripAgreesWithDbc) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> speed(-3.2, 3.2), pos(-80.0, 80.0), force(-300.0, 300.0);
  for (int trial = 0; trial < 3000; ++trial) {
    StatusFrames status;
    status.seq = static_cast<std::uint8_t>(rng());
    status.command_seq = static_cast<std::uint8_t>(rng());
    status.velocity[0] = speed(rng);
    status.velocity[1] = speed(rng);
    status.state = static_cast<RobotState>(rng() % 5);
    status.contact = rng() % 2;
    status.position[0] = pos(rng);
    status.position[1] = pos(rng);
    status.contact_force[0] = force(rng);
    status.contact_force[1] = force(rng);
    status.fault_bits = static_cast<std::uint16_t>(rng() & fault_bits::kAll);
    Frame frames[3];
    ASSERT_EQ(EncodeStatusFrames(5, status, frames), EncodeStatus::kOk);
    EXPECT_EQ(frames[0].id, 0x185U);
    EXPECT_EQ(frames[1].id, 0x285U);
    EXPECT_EQ(frames[2].id, 0x385U);
    // The DBC describes node 1; the layouts of node 5 are the same, so read them with node 1's messages.
    Frame as_node1[3];
    for (int i = 0; i < 3; ++i) {
      as_node1[i] = frames[i];
      as_node1[i].id -= 4;
      EXPECT_EQ(frames[i].data[7], ReferenceFrameCrc(frames[i])) << i;
    }
    EXPECT_EQ(RawSig(as_node1[0], "StatusSeq"), status.seq);
    EXPECT_EQ(RawSig(as_node1[0], "CommandSeq"), status.command_seq);
    EXPECT_NEAR(Sig(as_node1[0], "VelocityX"), status.velocity[0], kVelocityScale / 2 + 1e-12);
    EXPECT_NEAR(Sig(as_node1[0], "VelocityY"), status.velocity[1], kVelocityScale / 2 + 1e-12);
    EXPECT_EQ(RawSig(as_node1[0], "State"), static_cast<int>(status.state));
    EXPECT_EQ(RawSig(as_node1[0], "Contact"), status.contact ? 1 : 0);
    EXPECT_EQ(RawSig(as_node1[1], "StatusSeq"), status.seq);
    EXPECT_NEAR(Sig(as_node1[1], "PositionX"), status.position[0], kPositionScale / 2 + 1e-9);
    EXPECT_NEAR(Sig(as_node1[1], "PositionY"), status.position[1], kPositionScale / 2 + 1e-9);
    EXPECT_NEAR(Sig(as_node1[2], "ForceX"), status.contact_force[0], kForceScale / 2 + 1e-9);
    EXPECT_NEAR(Sig(as_node1[2], "ForceY"), status.contact_force[1], kForceScale / 2 + 1e-9);
    const char* bit_names[] = {"FaultWatchdog", "FaultBadFrame", "FaultSequence", "FaultLimit",
                               "FaultBounds",   "FaultBus",      "FaultEStop"};
    for (int bit = 0; bit < 7; ++bit) {
      EXPECT_EQ(RawSig(as_node1[2], bit_names[bit]), (status.fault_bits >> bit) & 1) << bit_names[bit];
    }

    StatusFrames decoded;
    ASSERT_EQ(DecodeStatusFrame(5, frames[0], decoded), DecodeStatus::kOk);
    ASSERT_EQ(DecodePositionFrame(5, frames[1], decoded), DecodeStatus::kOk);
    ASSERT_EQ(DecodeForceFrame(5, frames[2], decoded), DecodeStatus::kOk);
    EXPECT_EQ(decoded.seq, status.seq);
    EXPECT_EQ(decoded.command_seq, status.command_seq);
    EXPECT_EQ(decoded.state, status.state);
    EXPECT_EQ(decoded.contact, status.contact);
    EXPECT_EQ(decoded.fault_bits, status.fault_bits);
    EXPECT_DOUBLE_EQ(decoded.position[0], Sig(as_node1[1], "PositionX"));
    EXPECT_DOUBLE_EQ(decoded.contact_force[1], Sig(as_node1[2], "ForceY"));
    // Frames of one kind are not accepted as another, nor for another node.
    EXPECT_EQ(DecodePositionFrame(5, frames[0], decoded), DecodeStatus::kWrongId);
    EXPECT_EQ(DecodeStatusFrame(4, frames[0], decoded), DecodeStatus::kWrongId);
  }
}

TEST(CanProtocol, StatusSaturatesInsteadOfWrapping) {
  StatusFrames status;
  status.position[0] = 1e6;
  status.position[1] = -1e6;
  status.velocity[0] = 100.0;
  status.contact_force[0] = std::nan("");
  Frame frames[3];
  ASSERT_EQ(EncodeStatusFrames(1, status, frames), EncodeStatus::kOk);
  StatusFrames decoded;
  ASSERT_EQ(DecodeStatusFrame(1, frames[0], decoded), DecodeStatus::kOk);
  ASSERT_EQ(DecodePositionFrame(1, frames[1], decoded), DecodeStatus::kOk);
  ASSERT_EQ(DecodeForceFrame(1, frames[2], decoded), DecodeStatus::kOk);
  EXPECT_NEAR(decoded.position[0], 83.88607, 1e-9);
  EXPECT_NEAR(decoded.position[1], -83.88607, 1e-9);
  EXPECT_NEAR(decoded.velocity[0], kMaxVelocity, 1e-12);
  EXPECT_EQ(decoded.contact_force[0], 0.0);
}

// A reference acceptance rule for command frames, written from the README's table: id, length, CRC, reserved.
bool ReferenceAcceptsCommand(const Frame& frame) {
  if (frame.id != 0x201 || frame.dlc != 8) return false;
  if (frame.data[7] != ReferenceFrameCrc(frame)) return false;
  if (RawSig(frame, "Reserved") != 0 || (frame.data[1] & 0xFC) != 0) return false;
  return RawSig(frame, "VelocityX") != -32768 && RawSig(frame, "VelocityY") != -32768;
}

TEST(CanProtocol, RandomAndCorruptedFramesAgreeWithReference) {
  std::mt19937 rng(17);
  int accepted = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    Frame frame;
    if (trial % 2 == 0) {
      // A valid command with one random corruption: a flipped bit, a changed length, a changed id.
      CommandFrame command;
      command.seq = static_cast<std::uint8_t>(rng());
      command.velocity[0] = (static_cast<int>(rng() % 60001) - 30000) * kVelocityScale;
      ASSERT_EQ(EncodeCommand(1, command, frame), EncodeStatus::kOk);
      switch (rng() % 4) {
        case 0:
          frame.data[rng() % 8] ^= static_cast<std::uint8_t>(1U << (rng() % 8));
          break;
        case 1:
          frame.dlc = static_cast<std::uint8_t>(rng() % 9);
          break;
        case 2:
          frame.id ^= 1U << (rng() % 11);
          break;
        default:
          break;  // unchanged
      }
    } else {
      frame.id = 0x201;
      frame.dlc = static_cast<std::uint8_t>(rng() % 9);
      for (auto& b : frame.data) b = static_cast<std::uint8_t>(rng());
      if (rng() % 4 == 0) frame.data[7] = ReferenceFrameCrc(frame);  // valid CRC over random content
    }
    CommandFrame decoded;
    const bool fast = DecodeCommand(1, frame, decoded) == DecodeStatus::kOk;
    ASSERT_EQ(fast, ReferenceAcceptsCommand(frame)) << "trial " << trial;
    if (fast) {
      ++accepted;
      EXPECT_DOUBLE_EQ(decoded.velocity[0], Sig(frame, "VelocityX"));
      EXPECT_EQ(decoded.seq, RawSig(frame, "CommandSeq"));
    }
  }
  EXPECT_GT(accepted, 2000);  // both branches are exercised
}

TEST(CanProtocol, EverySingleBitFlipOfACommandIsDetected) {
  CommandFrame command;
  command.seq = 77;
  command.velocity[0] = 0.1234;
  command.velocity[1] = -0.5;
  Frame frame;
  ASSERT_EQ(EncodeCommand(1, command, frame), EncodeStatus::kOk);
  for (int bit = 0; bit < 64; ++bit) {
    Frame corrupted = frame;
    corrupted.data[bit / 8] ^= static_cast<std::uint8_t>(1U << (bit % 8));
    CommandFrame decoded;
    EXPECT_NE(DecodeCommand(1, corrupted, decoded), DecodeStatus::kOk) << "bit " << bit;
  }
}

TEST(CanProtocol, HeartbeatEmcyNmt) {
  Frame frame;
  ASSERT_EQ(EncodeHeartbeat(3, NmtState::kOperational, frame), EncodeStatus::kOk);
  EXPECT_EQ(frame.id, 0x703U);
  EXPECT_EQ(frame.dlc, 1);
  NmtState state{};
  EXPECT_EQ(DecodeHeartbeat(3, frame, state), DecodeStatus::kOk);
  EXPECT_EQ(state, NmtState::kOperational);
  frame.data[0] = 9;
  EXPECT_EQ(DecodeHeartbeat(3, frame, state), DecodeStatus::kBadReserved);

  EmcyFrame emcy;
  emcy.error_code = kEmcyRpdoTimeout;
  emcy.error_register = 0x11;
  emcy.code = 4;
  emcy.fault_bits = fault_bits::kWatchdog;
  emcy.robot_stopped = true;
  emcy.counter = 9;
  ASSERT_EQ(EncodeEmcy(1, emcy, frame), EncodeStatus::kOk);
  EXPECT_EQ(frame.id, 0x81U);
  EXPECT_EQ(RawSig(frame, "ErrorCode"), 0x8250);
  EXPECT_EQ(RawSig(frame, "FaultCode"), 4);
  EXPECT_EQ(RawSig(frame, "FaultBits"), 1);
  EXPECT_EQ(RawSig(frame, "RobotStopped"), 1);
  EXPECT_EQ(RawSig(frame, "Cleared"), 0);
  EXPECT_EQ(RawSig(frame, "EmcyCounter"), 9);
  EmcyFrame decoded;
  ASSERT_EQ(DecodeEmcy(1, frame, decoded), DecodeStatus::kOk);
  EXPECT_EQ(decoded.error_code, kEmcyRpdoTimeout);
  EXPECT_TRUE(decoded.robot_stopped);
  EXPECT_FALSE(decoded.cleared);

  ASSERT_EQ(EncodeNmt(kNmtStop, 1, frame), EncodeStatus::kOk);
  std::uint8_t command = 0;
  EXPECT_EQ(DecodeNmt(1, frame, command), DecodeStatus::kOk);
  EXPECT_EQ(command, kNmtStop);
  EXPECT_EQ(DecodeNmt(2, frame, command), DecodeStatus::kWrongId);
  ASSERT_EQ(EncodeNmt(kNmtResetNode, 0, frame), EncodeStatus::kOk);
  EXPECT_EQ(DecodeNmt(2, frame, command), DecodeStatus::kOk);
  EXPECT_EQ(command, kNmtResetNode);
}

TEST(CanProtocol, ErrorFrames) {
  Frame frame;
  frame.id = kErrFlag | kErrBusOff;
  frame.dlc = 8;
  ErrorFrameInfo info;
  ASSERT_EQ(DecodeErrorFrame(frame, info), DecodeStatus::kOk);
  EXPECT_TRUE(info.bus_off);
  EXPECT_FALSE(info.restarted);
  frame.id = kErrFlag | kErrCrtl;
  frame.data[1] = kCrtlTxPassive;
  ASSERT_EQ(DecodeErrorFrame(frame, info), DecodeStatus::kOk);
  EXPECT_TRUE(info.error_passive);
  EXPECT_FALSE(info.bus_off);
  frame.id = kErrFlag | kErrRestarted;
  ASSERT_EQ(DecodeErrorFrame(frame, info), DecodeStatus::kOk);
  EXPECT_TRUE(info.restarted);
  EXPECT_EQ(Classify(frame, 1), FrameKind::kError);
  frame.id = 0x201;
  EXPECT_EQ(DecodeErrorFrame(frame, info), DecodeStatus::kWrongId);
}

TEST(CanProtocol, SequenceRule) {
  EXPECT_TRUE(SequenceAdvances(0, 1));
  EXPECT_TRUE(SequenceAdvances(255, 0));
  EXPECT_TRUE(SequenceAdvances(10, 137));   // 127 ahead: gap tolerated
  EXPECT_FALSE(SequenceAdvances(10, 138));  // 128 ahead: treated as older
  EXPECT_FALSE(SequenceAdvances(10, 10));   // duplicate
  EXPECT_FALSE(SequenceAdvances(10, 9));    // older
  EXPECT_FALSE(SequenceAdvances(0, 255));
}

TEST(CanProtocol, Classify) {
  Frame frame;
  frame.id = 0x181;
  EXPECT_EQ(Classify(frame, 1), FrameKind::kStatus);
  EXPECT_EQ(Classify(frame, 2), FrameKind::kOther);
  frame.id = 0x201 | kEffFlag;
  EXPECT_EQ(Classify(frame, 1), FrameKind::kOther);
  frame.id = 0x201 | kRtrFlag;
  EXPECT_EQ(Classify(frame, 1), FrameKind::kOther);
  frame.id = 0x000;
  EXPECT_EQ(Classify(frame, 1), FrameKind::kNmt);
}

}  // namespace
}  // namespace visco::drivers::can
