// libFuzzer target for the CAN decoders: arbitrary bytes become frames (any id, flags, length, payload, node) and go
// through every decoder. Properties checked on every input:
// - no decoder crashes, reads out of bounds or hits undefined behaviour (ASan/UBSan in the fuzz build);
// - a command the session rule accepts (JudgeCommand) re-encodes to exactly the same frame (only canonical frames);
// - accepted status/position/force frames decode to values that re-encode and decode to the same values;
// - decoders accept a frame only for its own id.
// Built with clang -fsanitize=fuzzer (tests/drivers/CMakeLists.txt); the same file with VISCO_FUZZ_STANDALONE is a
// seeded random driver for the normal (gcc, ASan) builds.

#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "drivers/can_protocol.h"
#include "drivers/robot_link.h"

namespace {

using namespace visco::drivers::can;
using visco::drivers::NmtState;

void Require(bool condition) {
  if (!condition) std::abort();
}

bool SameFrame(const Frame& a, const Frame& b) {
  return a.id == b.id && a.dlc == b.dlc && std::memcmp(a.data, b.data, a.dlc) == 0;
}

// The session the fuzzed frames are judged in: its tag is the frame's own (so that the CRC is reached), the nonce's
// upper bits fixed; the last accepted command is 1..8 behind the frame's number.
constexpr std::uint32_t kSessionHigh = 0x5EC0DE00U;

void CheckOne(const Frame& frame, int node) {
  const std::uint32_t session = kSessionHigh | frame.data[6];
  CommandFrame command;
  if (DecodeCommand(node, frame, command) == DecodeStatus::kOk) {
    Require(Classify(frame, node) == FrameKind::kCommand);
    const std::uint32_t last = 0x1000U + frame.data[0] - 1 - (frame.data[5] & 7);
    std::uint32_t seq = 0;
    const CommandVerdict verdict = JudgeCommand(frame, session, last, visco::drivers::kCommandWindow, seq);
    if (verdict == CommandVerdict::kAccept) {
      Require(seq - last >= 1 && seq - last <= visco::drivers::kCommandWindow && (seq & 0xFF) == frame.data[0]);
      command.seq = seq;
      command.session = session;
      Frame again;
      Require(EncodeCommand(node, command, again) == EncodeStatus::kOk);
      Require(SameFrame(frame, again));
    }
  }
  StatusFrames status;
  const std::uint32_t counter = 0x2000U | frame.data[0];
  const bool s = DecodeStatusFrame(node, frame, session, counter, status) == DecodeStatus::kOk;
  const bool p = DecodePositionFrame(node, frame, session, counter, status) == DecodeStatus::kOk;
  const bool f = DecodeForceFrame(node, frame, session, counter, status) == DecodeStatus::kOk;
  Require(int{s} + int{p} + int{f} <= 1);
  if (s || p || f) {
    Require(status.seq == counter && status.session == session);
    Frame frames[3];
    Require(EncodeStatusFrames(node, status, frames) == EncodeStatus::kOk);
    StatusFrames again = status;
    const Frame& mine = frames[s ? 0 : (p ? 1 : 2)];
    if (s) Require(DecodeStatusFrame(node, mine, session, counter, again) == DecodeStatus::kOk);
    if (p) Require(DecodePositionFrame(node, mine, session, counter, again) == DecodeStatus::kOk);
    if (f) Require(DecodeForceFrame(node, mine, session, counter, again) == DecodeStatus::kOk);
    Require(again.seq == status.seq && again.command_seq == status.command_seq && again.state == status.state &&
            again.contact == status.contact && again.fault_bits == status.fault_bits);
    for (int i = 0; i < 2; ++i) {
      // Saturation at the reserved minimum may move a value by one step, never more.
      Require(std::abs(again.velocity[i] - status.velocity[i]) <= kVelocityScale * 1.0001);
      Require(std::abs(again.position[i] - status.position[i]) <= kPositionScale * 1.0001);
      Require(std::abs(again.contact_force[i] - status.contact_force[i]) <= kForceScale * 1.0001);
    }
  }
  SessionFrame announced;
  if (DecodeSession(node, frame, announced) == DecodeStatus::kOk) {
    Require(announced.session != 0 && Classify(frame, node) == FrameKind::kSession);
    Frame again;
    Require(EncodeSession(node, announced, again) == EncodeStatus::kOk && SameFrame(frame, again));
  }
  NmtState nmt;
  if (DecodeHeartbeat(node, frame, nmt) == DecodeStatus::kOk) {
    Frame again;
    Require(EncodeHeartbeat(node, nmt, again) == EncodeStatus::kOk && SameFrame(frame, again));
  }
  EmcyFrame emcy;
  if (DecodeEmcy(node, frame, emcy) == DecodeStatus::kOk) {
    Frame again;
    Require(EncodeEmcy(node, emcy, again) == EncodeStatus::kOk);
    Require(again.id == frame.id && again.dlc == 8);
  }
  std::uint8_t nmt_command = 0;
  if (DecodeNmt(node, frame, nmt_command) == DecodeStatus::kOk) Require(frame.id == kNmtId);
  ErrorFrameInfo info;
  Require((DecodeErrorFrame(frame, info) == DecodeStatus::kOk) == ((frame.id & kErrFlag) != 0));
}

}  // namespace

// Input layout, repeated: 4 bytes id (little-endian, flags included), 1 byte dlc (0..15, clamped to 8), 8 bytes
// payload, 1 byte node.
extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  while (size >= 14) {
    Frame frame;
    std::uint32_t id = 0;
    std::memcpy(&id, data, 4);
    // Mostly ids near the protocol's, so that the fuzzer spends its time in the decoders.
    if ((data[13] & 0x80) == 0) id &= (kErrFlag | 0x7FF);
    frame.id = id;
    frame.dlc = static_cast<std::uint8_t>(data[4] > 8 ? 8 : data[4]);
    std::memcpy(frame.data, data + 5, 8);
    const int node = data[13] & 0x7F;  // 0 (invalid) .. 127
    CheckOne(frame, node);
    data += 14;
    size -= 14;
  }
  return 0;
}

#ifdef VISCO_FUZZ_STANDALONE
#include <cstdio>
#include <random>

// Seeded random inputs, a quarter of them valid frames with one mutation, for builds without libFuzzer.
int main(int argc, char** argv) {
  const long runs = argc > 1 ? std::atol(argv[1]) : 200000;
  std::mt19937 rng(20261122);
  std::uint8_t input[14];
  for (long run = 0; run < runs; ++run) {
    for (auto& b : input) b = static_cast<std::uint8_t>(rng());
    if (run % 4 == 0) {
      CommandFrame command;
      command.velocity[0] = (static_cast<int>(rng() % 60001) - 30000) * kVelocityScale;
      command.velocity[1] = 0.0;
      Frame frame;
      // In the session and window CheckOne judges in (its last: 0x1000 + seq - 1 - (vy's low bits & 7) = seq - 1).
      const std::uint8_t low = static_cast<std::uint8_t>(rng());
      const std::uint8_t tag = static_cast<std::uint8_t>(rng());
      command.seq = 0x1000U + low;
      command.session = kSessionHigh | tag;
      const int node = 1 + static_cast<int>(rng() % 127);
      EncodeCommand(node, command, frame);
      std::memcpy(input, &frame.id, 4);
      input[4] = frame.dlc;
      std::memcpy(input + 5, frame.data, 8);
      input[13] = static_cast<std::uint8_t>(node);
      if (rng() % 2) input[5 + rng() % 8] ^= static_cast<std::uint8_t>(1U << (rng() % 8));
    }
    LLVMFuzzerTestOneInput(input, sizeof(input));
  }
  std::printf("can_decoder_fuzz: %ld seeded inputs, all properties held\n", runs);
  return 0;
}
#endif
