// The CAN protocol against the DBC file (read by a slow reference parser) and a textbook CRC, on seeded random
// values and random frames.

#include "drivers/can_protocol.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include "drivers/driver_transport.h"
#include "tests/drivers/dbc_reference.h"

namespace visco::drivers::can {
namespace {

using visco::drivers::JudgeSequence;
using visco::drivers::kCommandWindow;

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

// The README's session key: f(nonce ^ f(counter ^ f(id))), f = murmur3's 32-bit finaliser.
std::uint32_t ReferenceFinaliser(std::uint32_t h) {
  h = (h ^ (h >> 16)) * 0x85EBCA6BU;
  h = (h ^ (h >> 13)) * 0xC2B2AE35U;
  return h ^ (h >> 16);
}

// The README's CRC of command and status frames: id, session key, the counter's upper 24 bits, bytes 0..6.
std::uint8_t ReferenceSessionCrc(const Frame& frame, std::uint32_t session, std::uint32_t counter) {
  const std::uint32_t key =
      ReferenceFinaliser(session ^ ReferenceFinaliser(counter ^ ReferenceFinaliser(frame.id & 0x7FF)));
  std::uint8_t bytes[16] = {static_cast<std::uint8_t>(frame.id & 0xFF),
                            static_cast<std::uint8_t>((frame.id >> 8) & 0x7),
                            static_cast<std::uint8_t>(key),
                            static_cast<std::uint8_t>(key >> 8),
                            static_cast<std::uint8_t>(key >> 16),
                            static_cast<std::uint8_t>(key >> 24),
                            static_cast<std::uint8_t>(counter >> 8),
                            static_cast<std::uint8_t>(counter >> 16),
                            static_cast<std::uint8_t>(counter >> 24)};
  std::memcpy(bytes + 9, frame.data, 7);
  return ReferenceCrc8(bytes, 16);
}

// Found by the link's fuzzer: a CRC is linear, so over the raw nonce a frame of another session passed or
// failed by a constant of the two nonces: 1 session in 256 had *every* frame valid in the current one. With the
// session key each frame passes by chance 1 in 256, independently of the others: measured on seeded random sessions,
// frames and numbers, no other session has more than a few of 16 consecutive numbers valid, and the three frames of
// a status update pass together about 1 in 2^24.
TEST(CanProtocol, FramesOfAnotherSessionPassTheCrcIndependentlyOneIn256) {
  std::mt19937 rng(15);
  constexpr int kSessions = 4000;
  int passed = 0, frames = 0, worst_run = 0, triples = 0;
  for (int i = 0; i < kSessions; ++i) {
    const std::uint32_t session = rng() | 1u;
    const std::uint32_t other = session ^ (rng() | 1u);
    CommandFrame c;
    c.session = other;
    c.velocity[0] = 0.1;
    int valid_here = 0;
    for (std::uint32_t n = 1; n <= 16; ++n) {
      c.seq = n;
      Frame f;
      ASSERT_EQ(EncodeCommand(1, c, f), EncodeStatus::kOk);
      const bool ok = SessionCrc(f.id, session, n, f.data) == f.data[7];
      passed += ok ? 1 : 0;
      valid_here += ok ? 1 : 0;
      ++frames;
    }
    worst_run = std::max(worst_run, valid_here);
    StatusFrames s;
    s.session = other;
    s.seq = rng() & 0xFFFFFF;
    Frame t[3];
    ASSERT_EQ(EncodeStatusFrames(1, s, t), EncodeStatus::kOk);
    StatusFrames d;
    triples += DecodeStatusFrame(1, t[0], session, s.seq, d) == DecodeStatus::kOk &&
               DecodePositionFrame(1, t[1], session, s.seq, d) == DecodeStatus::kOk &&
               DecodeForceFrame(1, t[2], session, s.seq, d) == DecodeStatus::kOk;
  }
  const double rate = static_cast<double>(passed) / frames;
  EXPECT_NEAR(rate, 1.0 / 256, 0.0015) << passed << " of " << frames;  // 64 000 frames: sd 0.00024
  EXPECT_LE(worst_run, 4) << "a session with most of its frames valid in another: the CRC is linear in the nonce";
  EXPECT_EQ(triples, 0);
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
  EXPECT_EQ(messages.at(kSessionBase + 1).dlc, 8);
  EXPECT_EQ(messages.at(kHeartbeatBase + 1).dlc, 1);
  EXPECT_EQ(messages.size(), 8U);
}

TEST(CanProtocol, CommandRoundTripAgreesWithDbc) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> speed(-kMaxVelocity, kMaxVelocity);
  for (int trial = 0; trial < 5000; ++trial) {
    CommandFrame command;
    command.seq = static_cast<std::uint32_t>(rng());
    command.session = static_cast<std::uint32_t>(rng()) | 1U;
    command.estop = rng() % 2;
    command.reset = rng() % 2;
    command.quick_stop = rng() % 2;
    command.velocity[0] = speed(rng);
    command.velocity[1] = speed(rng);
    Frame frame;
    ASSERT_EQ(EncodeCommand(1, command, frame), EncodeStatus::kOk);
    EXPECT_EQ(frame.id, 0x201U);
    EXPECT_EQ(frame.dlc, 8);
    EXPECT_EQ(RawSig(frame, "CommandSeq"), command.seq & 0xFF);
    EXPECT_EQ(RawSig(frame, "EStop"), command.estop ? 1 : 0);
    EXPECT_EQ(RawSig(frame, "Reset"), command.reset ? 1 : 0);
    EXPECT_EQ(RawSig(frame, "QuickStop"), command.quick_stop ? 1 : 0);
    EXPECT_EQ(RawSig(frame, "SessionTag"), command.session & 0xFF);
    EXPECT_NEAR(Sig(frame, "VelocityX"), command.velocity[0], kVelocityScale / 2 + 1e-12);
    EXPECT_NEAR(Sig(frame, "VelocityY"), command.velocity[1], kVelocityScale / 2 + 1e-12);
    EXPECT_EQ(RawSig(frame, "Crc"), ReferenceSessionCrc(frame, command.session, command.seq));
    CommandFrame decoded;
    ASSERT_EQ(DecodeCommand(1, frame, decoded), DecodeStatus::kOk);
    EXPECT_EQ(decoded.seq, command.seq & 0xFF);
    EXPECT_EQ(decoded.session, command.session & 0xFF);
    std::uint32_t seq = 0;
    EXPECT_EQ(JudgeCommand(frame, command.session, command.seq - 1, kCommandWindow, seq), CommandVerdict::kAccept);
    EXPECT_EQ(seq, command.seq);
    EXPECT_EQ(decoded.estop, command.estop);
    EXPECT_EQ(decoded.reset, command.reset);
    EXPECT_EQ(decoded.quick_stop, command.quick_stop);
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
    status.seq = static_cast<std::uint32_t>(rng());
    status.session = static_cast<std::uint32_t>(rng()) | 1U;
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
      EXPECT_EQ(frames[i].data[7], ReferenceSessionCrc(frames[i], status.session, status.seq)) << i;
    }
    EXPECT_EQ(RawSig(as_node1[0], "StatusSeq"), status.seq & 0xFF);
    EXPECT_EQ(RawSig(as_node1[0], "CommandSeq"), status.command_seq);
    EXPECT_NEAR(Sig(as_node1[0], "VelocityX"), status.velocity[0], kVelocityScale / 2 + 1e-12);
    EXPECT_NEAR(Sig(as_node1[0], "VelocityY"), status.velocity[1], kVelocityScale / 2 + 1e-12);
    EXPECT_EQ(RawSig(as_node1[0], "State"), static_cast<int>(status.state));
    EXPECT_EQ(RawSig(as_node1[0], "Contact"), status.contact ? 1 : 0);
    EXPECT_EQ(RawSig(as_node1[1], "StatusSeq"), status.seq & 0xFF);
    EXPECT_NEAR(Sig(as_node1[1], "PositionX"), status.position[0], kPositionScale / 2 + 1e-9);
    EXPECT_NEAR(Sig(as_node1[1], "PositionY"), status.position[1], kPositionScale / 2 + 1e-9);
    EXPECT_NEAR(Sig(as_node1[2], "ForceX"), status.contact_force[0], kForceScale / 2 + 1e-9);
    EXPECT_NEAR(Sig(as_node1[2], "ForceY"), status.contact_force[1], kForceScale / 2 + 1e-9);
    const char* bit_names[] = {"FaultWatchdog", "FaultBadFrame", "FaultSequence", "FaultLimit",
                               "FaultBounds",   "FaultBus",      "FaultEStop",    "FaultSession"};
    for (int bit = 0; bit < 8; ++bit) {
      EXPECT_EQ(RawSig(as_node1[2], bit_names[bit]), (status.fault_bits >> bit) & 1) << bit_names[bit];
    }

    StatusFrames decoded;
    ASSERT_EQ(DecodeStatusFrame(5, frames[0], status.session, status.seq, decoded), DecodeStatus::kOk);
    ASSERT_EQ(DecodePositionFrame(5, frames[1], status.session, status.seq, decoded), DecodeStatus::kOk);
    ASSERT_EQ(DecodeForceFrame(5, frames[2], status.session, status.seq, decoded), DecodeStatus::kOk);
    // Another session, or the same low byte in another wrap of the counter: each frame passes the 8-bit CRC by
    // chance 1 in 256, independently (SessionKey), so the whole update fails but for 1 in 2^24.
    const auto whole = [&](std::uint32_t session, std::uint32_t seq) {
      StatusFrames d;
      return DecodeStatusFrame(5, frames[0], session, seq, d) == DecodeStatus::kOk &&
             DecodePositionFrame(5, frames[1], session, seq, d) == DecodeStatus::kOk &&
             DecodeForceFrame(5, frames[2], session, seq, d) == DecodeStatus::kOk;
    };
    EXPECT_FALSE(whole(status.session ^ 0x100, status.seq));
    EXPECT_FALSE(whole(status.session, status.seq + 256));
    EXPECT_EQ(DecodePositionFrame(5, frames[1], status.session, status.seq + 1, decoded), DecodeStatus::kBadChecksum);
    ASSERT_EQ(DecodeStatusFrame(5, frames[0], status.session, status.seq, decoded), DecodeStatus::kOk);
    ASSERT_EQ(DecodePositionFrame(5, frames[1], status.session, status.seq, decoded), DecodeStatus::kOk);
    ASSERT_EQ(DecodeForceFrame(5, frames[2], status.session, status.seq, decoded), DecodeStatus::kOk);
    EXPECT_EQ(decoded.seq, status.seq);
    EXPECT_EQ(decoded.command_seq, status.command_seq);
    EXPECT_EQ(decoded.state, status.state);
    EXPECT_EQ(decoded.contact, status.contact);
    EXPECT_EQ(decoded.fault_bits, status.fault_bits);
    EXPECT_DOUBLE_EQ(decoded.position[0], Sig(as_node1[1], "PositionX"));
    EXPECT_DOUBLE_EQ(decoded.contact_force[1], Sig(as_node1[2], "ForceY"));
    // Frames of one kind are not accepted as another, nor for another node.
    EXPECT_EQ(DecodePositionFrame(5, frames[0], status.session, status.seq, decoded), DecodeStatus::kWrongId);
    EXPECT_EQ(DecodeStatusFrame(4, frames[0], status.session, status.seq, decoded), DecodeStatus::kWrongId);
  }
}

TEST(CanProtocol, StatusSaturatesInsteadOfWrapping) {
  StatusFrames status;
  status.position[0] = 1e6;
  status.position[1] = -1e6;
  status.velocity[0] = 100.0;
  status.contact_force[0] = std::nan("");
  status.session = 77;
  status.seq = 1000;
  Frame frames[3];
  ASSERT_EQ(EncodeStatusFrames(1, status, frames), EncodeStatus::kOk);
  StatusFrames decoded;
  ASSERT_EQ(DecodeStatusFrame(1, frames[0], 77, 1000, decoded), DecodeStatus::kOk);
  ASSERT_EQ(DecodePositionFrame(1, frames[1], 77, 1000, decoded), DecodeStatus::kOk);
  ASSERT_EQ(DecodeForceFrame(1, frames[2], 77, 1000, decoded), DecodeStatus::kOk);
  EXPECT_NEAR(decoded.position[0], 83.88607, 1e-9);
  EXPECT_NEAR(decoded.position[1], -83.88607, 1e-9);
  EXPECT_NEAR(decoded.velocity[0], kMaxVelocity, 1e-12);
  EXPECT_EQ(decoded.contact_force[0], 0.0);
}

// A reference acceptance rule for command frames, written from the README's table and "Sessions" rules: id, length,
// reserved bits, then the session tag and the CRC over the nonce and the counter reconstructed 1..window ahead.
bool ReferenceLayoutOk(const Frame& frame) {
  if (frame.id != 0x201 || frame.dlc != 8) return false;
  if ((frame.data[1] & 0xF8) != 0) return false;
  return RawSig(frame, "VelocityX") != -32768 && RawSig(frame, "VelocityY") != -32768;
}
bool ReferenceAccepts(const Frame& frame, std::uint32_t session, std::uint32_t last) {
  if (!ReferenceLayoutOk(frame) || RawSig(frame, "SessionTag") != (session & 0xFF)) return false;
  for (std::uint32_t k = 1; k <= kCommandWindow; ++k) {
    const std::uint32_t counter = last + k;
    if ((counter & 0xFF) == RawSig(frame, "CommandSeq") &&
        ReferenceSessionCrc(frame, session, counter) == frame.data[7]) {
      return true;
    }
  }
  return false;
}

TEST(CanProtocol, RandomAndCorruptedFramesAgreeWithReference) {
  std::mt19937 rng(17);
  int accepted = 0;
  const std::uint32_t session = 0xC0FFEE11;
  for (int trial = 0; trial < 20000; ++trial) {
    const std::uint32_t last = static_cast<std::uint32_t>(rng() % 100000);
    Frame frame;
    if (trial % 2 == 0) {
      // A valid command near the window with one random corruption: a flipped bit, a changed length, a changed id,
      // another session, another wrap of the counter.
      CommandFrame command;
      command.seq = last + 1 + rng() % 10;
      command.session = session;
      command.velocity[0] = (static_cast<int>(rng() % 60001) - 30000) * kVelocityScale;
      switch (rng() % 8) {
        case 0:
          ASSERT_EQ(EncodeCommand(1, command, frame), EncodeStatus::kOk);
          frame.data[rng() % 8] ^= static_cast<std::uint8_t>(1U << (rng() % 8));
          break;
        case 1:
          ASSERT_EQ(EncodeCommand(1, command, frame), EncodeStatus::kOk);
          frame.dlc = static_cast<std::uint8_t>(rng() % 9);
          break;
        case 2:
          ASSERT_EQ(EncodeCommand(1, command, frame), EncodeStatus::kOk);
          frame.id ^= 1U << (rng() % 11);
          break;
        case 3:
          command.session ^= 1U << (rng() % 32);
          ASSERT_EQ(EncodeCommand(1, command, frame), EncodeStatus::kOk);
          break;
        case 4:
          command.seq -= 256 * (1 + rng() % 3);
          ASSERT_EQ(EncodeCommand(1, command, frame), EncodeStatus::kOk);
          break;
        default:  // 3 in 8: unchanged
          ASSERT_EQ(EncodeCommand(1, command, frame), EncodeStatus::kOk);
          break;
      }
    } else {
      frame.id = 0x201;
      frame.dlc = static_cast<std::uint8_t>(rng() % 9);
      for (auto& b : frame.data) b = static_cast<std::uint8_t>(rng());
      if (rng() % 2 == 0) frame.data[6] = session & 0xFF;
      if (rng() % 2 == 0) frame.data[0] = static_cast<std::uint8_t>(last + 1 + rng() % 8);
      if (rng() % 4 != 0) frame.data[7] = ReferenceSessionCrc(frame, session, CounterAhead(last, frame.data[0]));
    }
    CommandFrame decoded;
    const bool layout = DecodeCommand(1, frame, decoded) == DecodeStatus::kOk;
    ASSERT_EQ(layout, ReferenceLayoutOk(frame)) << "trial " << trial;
    std::uint32_t seq = 0;
    const bool fast = layout && JudgeCommand(frame, session, last, kCommandWindow, seq) == CommandVerdict::kAccept;
    ASSERT_EQ(fast, ReferenceAccepts(frame, session, last)) << "trial " << trial;
    if (fast) {
      ++accepted;
      EXPECT_DOUBLE_EQ(decoded.velocity[0], Sig(frame, "VelocityX"));
      EXPECT_EQ(seq & 0xFF, RawSig(frame, "CommandSeq"));
      EXPECT_GT(seq - last, 0U);
      EXPECT_LE(seq - last, kCommandWindow);
    }
  }
  EXPECT_GT(accepted, 2000);  // both branches are exercised
}

TEST(CanProtocol, EverySingleBitFlipOfACommandIsDetected) {
  CommandFrame command;
  command.seq = 77;
  command.session = 0x12345678;
  command.velocity[0] = 0.1234;
  command.velocity[1] = -0.5;
  Frame frame;
  ASSERT_EQ(EncodeCommand(1, command, frame), EncodeStatus::kOk);
  std::uint32_t seq = 0;
  ASSERT_EQ(JudgeCommand(frame, command.session, 76, kCommandWindow, seq), CommandVerdict::kAccept);
  for (int bit = 0; bit < 64; ++bit) {
    Frame corrupted = frame;
    corrupted.data[bit / 8] ^= static_cast<std::uint8_t>(1U << (bit % 8));
    CommandFrame decoded;
    const bool accepted = DecodeCommand(1, corrupted, decoded) == DecodeStatus::kOk &&
                          JudgeCommand(corrupted, command.session, 76, kCommandWindow, seq) == CommandVerdict::kAccept;
    EXPECT_FALSE(accepted) << "bit " << bit;
  }
  // Every single-bit change of the session nonce or of the counter's upper bits is detected too.
  for (int bit = 0; bit < 32; ++bit) {
    EXPECT_NE(JudgeCommand(frame, command.session ^ (1U << bit), 76, kCommandWindow, seq), CommandVerdict::kAccept)
        << "session bit " << bit;
  }
  for (int bit = 8; bit < 32; ++bit) {
    const std::uint32_t last = 76 ^ (1U << bit);
    EXPECT_NE(JudgeCommand(frame, command.session, last, kCommandWindow, seq), CommandVerdict::kAccept)
        << "counter bit " << bit;
  }
}

TEST(CanProtocol, JudgeCommandClassifiesStaleAheadWrongSessionAndCorrupted) {
  const std::uint32_t session = 0xA1B2C3D4;
  auto frame_of = [&](std::uint32_t seq, std::uint32_t in_session) {
    CommandFrame command;
    command.seq = seq;
    command.session = in_session;
    Frame frame;
    EXPECT_EQ(EncodeCommand(3, command, frame), EncodeStatus::kOk);
    return frame;
  };
  const std::uint32_t last = 1000;
  std::uint32_t seq = 0;
  for (std::uint32_t k = 1; k <= kCommandWindow; ++k) {
    EXPECT_EQ(JudgeCommand(frame_of(last + k, session), session, last, kCommandWindow, seq), CommandVerdict::kAccept);
    EXPECT_EQ(seq, last + k);
  }
  EXPECT_EQ(JudgeCommand(frame_of(last + kCommandWindow + 1, session), session, last, kCommandWindow, seq),
            CommandVerdict::kAhead);
  EXPECT_EQ(JudgeCommand(frame_of(last, session), session, last, kCommandWindow, seq), CommandVerdict::kStale);
  EXPECT_EQ(JudgeCommand(frame_of(last - 200, session), session, last, kCommandWindow, seq), CommandVerdict::kStale);
  EXPECT_EQ(seq, last - 200);
  // 256 - k earlier: the same low byte as last + k; stale (the CRC covers the upper bits), never accepted.
  for (std::uint32_t k = 1; k <= kCommandWindow; ++k) {
    EXPECT_EQ(JudgeCommand(frame_of(last + k - 256, session), session, last, kCommandWindow, seq),
              CommandVerdict::kStale);
    EXPECT_EQ(JudgeCommand(frame_of(last + k - 512, session), session, last, kCommandWindow, seq),
              CommandVerdict::kBadChecksum);
  }
  const std::uint32_t other = session ^ 0x0000FF00;  // the same tag, another nonce
  EXPECT_EQ(JudgeCommand(frame_of(last + 1, other), session, last, kCommandWindow, seq), CommandVerdict::kBadChecksum);
  EXPECT_EQ(JudgeCommand(frame_of(last + 1, session + 1), session, last, kCommandWindow, seq),
            CommandVerdict::kWrongSession);
  // The fresh session of a driver (last 0) accepts 1..8.
  EXPECT_EQ(JudgeCommand(frame_of(1, session), session, 0, kCommandWindow, seq), CommandVerdict::kAccept);
  EXPECT_EQ(JudgeCommand(frame_of(9, session), session, 0, kCommandWindow, seq), CommandVerdict::kAhead);
}

// The history of accepted frames against a slow obvious reference (the list of every frame added: the last one
// with the probe's low byte), on seeded random frames with few distinct payloads so that repeats are common.
TEST(CanProtocol, FrameHistoryKeepsTheLastFrameOfEachLowByte) {
  FrameHistory history;
  std::vector<Frame> added;
  std::mt19937_64 rng(5);
  auto random_frame = [&] {
    Frame f;
    f.id = kCommandBase + 1;
    f.dlc = 8;
    f.data[0] = static_cast<std::uint8_t>(rng() % 3);
    f.data[2] = static_cast<std::uint8_t>(rng() % 3);
    f.data[7] = static_cast<std::uint8_t>(rng() % 2);
    return f;
  };
  auto reference = [&](const Frame& f) {
    for (auto it = added.rbegin(); it != added.rend(); ++it) {
      if (it->data[0] == f.data[0]) return std::equal(it->data, it->data + 8, f.data);
    }
    return false;
  };
  int hits = 0;
  for (int i = 0; i < 20000; ++i) {
    if (i == 12000) {
      history.Clear();
      added.clear();
    }
    const Frame probe = random_frame();
    const bool expected = reference(probe);
    ASSERT_EQ(history.Contains(probe), expected) << "step " << i;
    hits += expected;
    if (rng() % 2 == 0) {
      const Frame f = random_frame();
      history.Add(f);
      added.push_back(f);
    }
  }
  EXPECT_GT(hits, 1000);
  EXPECT_LT(hits, 19000);
}

TEST(CanProtocol, SessionFrame) {
  SessionFrame announce;
  announce.session = 0xDEADBEEF;
  announce.status_epoch = 0x123456;
  Frame frame;
  ASSERT_EQ(EncodeSession(2, announce, frame), EncodeStatus::kOk);
  EXPECT_EQ(frame.id, 0x482U);
  EXPECT_EQ(frame.dlc, 8);
  Frame as_node1 = frame;
  as_node1.id = 0x481;
  EXPECT_EQ(static_cast<std::uint32_t>(RawSig(as_node1, "SessionNonce")), 0xDEADBEEFU);
  EXPECT_EQ(RawSig(as_node1, "StatusEpoch"), 0x123456);
  EXPECT_EQ(frame.data[7], ReferenceFrameCrc(frame));
  SessionFrame decoded;
  ASSERT_EQ(DecodeSession(2, frame, decoded), DecodeStatus::kOk);
  EXPECT_EQ(decoded.session, announce.session);
  EXPECT_EQ(decoded.status_epoch, announce.status_epoch);
  EXPECT_EQ(Classify(frame, 2), FrameKind::kSession);
  frame.data[2] ^= 1;
  EXPECT_EQ(DecodeSession(2, frame, decoded), DecodeStatus::kBadChecksum);
  announce.session = 0;
  EXPECT_EQ(EncodeSession(2, announce, frame), EncodeStatus::kOutOfRange);
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

TEST(CanProtocol, LcmSequenceRule) {
  constexpr std::uint32_t kMod = 0x80000000U;
  EXPECT_EQ(JudgeSequence(5, 1, 5, 0, kCommandWindow, kMod), CommandVerdict::kAccept);
  EXPECT_EQ(JudgeSequence(5, 8, 5, 0, kCommandWindow, kMod), CommandVerdict::kAccept);
  EXPECT_EQ(JudgeSequence(5, 9, 5, 0, kCommandWindow, kMod), CommandVerdict::kAhead);
  EXPECT_EQ(JudgeSequence(5, 10, 5, 10, kCommandWindow, kMod), CommandVerdict::kStale);  // duplicate
  EXPECT_EQ(JudgeSequence(5, 9, 5, 10, kCommandWindow, kMod), CommandVerdict::kStale);   // older
  EXPECT_EQ(JudgeSequence(6, 11, 5, 10, kCommandWindow, kMod), CommandVerdict::kWrongSession);
  EXPECT_EQ(JudgeSequence(5, 0, 5, kMod - 1, kCommandWindow, kMod), CommandVerdict::kAccept);  // wraps
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
