// Property fuzzer of the driver's session, sequence and state logic: arbitrary bytes become a sequence of
// events for a Driver with a scripted CAN transport (commands of the session at any number, of other sessions,
// corrupted, replays of earlier frames, NMT, bus events, the operator's release, time passing). After every event:
// - a command moves the robot only if it is of the current session and 1..kCommandWindow ahead (the README's rule);
// - the e-stop is left only through the operator's release, never by a reset or an NMT message;
// - a new session is never announced as READY or MOVING, and its nonce is never 0 nor the previous one;
// - the driver is READY or MOVING only after an accepted reset of the current session, and a robot that is not
//   enabled never speeds up.
// Built as a seeded random driver for every build (VISCO_FUZZ_STANDALONE, `drivers.driver_fuzz_seeded`); the same
// LLVMFuzzerTestOneInput can be linked with libFuzzer.

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <vector>

#include "drivers/can_protocol.h"
#include "drivers/driver.h"
#include "drivers/driver_transport.h"
#include "drivers/simulated_robot.h"

namespace {

using namespace visco::drivers;

#define Require(condition) RequireAt((condition), #condition)
void RequireAt(bool condition, const char* what) {
  if (!condition) {
    std::fprintf(stderr, "driver_fuzz: property failed: %s\n", what);
    std::abort();
  }
}

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
  LinkResult SendStatus(const RobotStatus& status) override {
    last_status = status;
    return LinkResult::kOk;
  }
  LinkResult SendHeartbeat(NmtState) override { return LinkResult::kOk; }
  LinkResult SendFault(const DriverFault&) override { return LinkResult::kOk; }
  LinkResult SendSession(std::uint32_t nonce, std::uint32_t) override {
    if (nonce != session) {
      Require(nonce != 0 && nonce != session);
      session = nonce;
      new_session = true;
    }
    return LinkResult::kOk;
  }
  std::uint32_t sequence_modulus() const override { return 256; }
  LinkCounters counters() const override { return {}; }

  void Frame(const can::Frame& frame) { events.push_back(CommandFrameEvent(1, frame, 0)); }

  std::deque<DriverEvent> events;
  RobotStatus last_status;
  std::uint32_t session = 0;
  bool new_session = false;
};

// What the runs exercised (so that a documented run shows the properties were not vacuous).
struct Exercised {
  std::uint64_t applied = 0, resets = 0, estops = 0, releases = 0, rejected = 0, sessions = 0;
  std::uint64_t foreign = 0;     // frames of another session, corrupted ones or replays of earlier sessions
  std::uint64_t collisions = 0;  // ... of them valid by chance: tag and 8-bit CRC both matched (about 1 in 65 536)
} g_exercised;

// A frame the model calls invalid (another session's, corrupted) that the acceptance rule takes anyway: its tag and
// its CRC under the session's key match by chance (drivers/README.md, "CRC"). It is then indistinguishable from a
// valid command and counted; the properties treat it as one. Fills the number it has in the session.
bool ValidByChance(const can::Frame& frame, std::uint32_t session, std::uint32_t last, std::uint32_t& seq) {
  return can::JudgeCommand(frame, session, last, kCommandWindow, seq) == can::CommandVerdict::kAccept;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Transport transport;
  SimulatedRobot robot(SimulatedRobotConfig{});
  DriverConfig config;
  config.session_seed = 1 + (size > 0 ? data[0] : 0);
  Driver driver(config, transport, robot);
  std::int64_t now = 1'000'000;
  driver.Start(now);
  std::uint32_t last = 0;  // the model: last accepted number in the session
  struct Sent {
    can::Frame frame;
    std::uint32_t session;
    std::uint32_t seq;
    bool reset;
  };
  std::vector<Sent> recorded;          // frames sent so far (replay material), with what they were encoded with
  bool enabled_since_session = false;  // an accepted reset since the last new session
  for (std::size_t i = 1; i + 3 <= size; i += 3) {
    const std::uint8_t op = data[i], a = data[i + 1], b = data[i + 2];
    const RobotState before = driver.state();
    const RobotFeedback feedback_before = robot.Read();
    const double speed_before = std::hypot(feedback_before.velocity[0], feedback_before.velocity[1]);
    const std::uint64_t applied_before = driver.stats().commands_applied;
    transport.new_session = false;
    bool valid_command = false;
    bool operator_release = false;
    bool reset_command = false;
    switch (op % 8) {
      case 0:
      case 1:
      case 2: {  // a command of the current session, a..: offset from the window, flags, velocity
        can::CommandFrame wire;
        const std::uint32_t k = 1 + (a % 12);  // 1..12: in and beyond the window
        wire.seq = last + k;
        wire.session = transport.session;
        wire.reset = (b & 1) != 0;
        wire.estop = (b & 0x3E) == 0x3E;  // 1 in 32: an e-stop ends most of what follows
        wire.quick_stop = (b & 0x70) == 0x70;
        wire.velocity[0] = ((b >> 1) % 7) * 0.05;
        can::Frame frame;
        Require(can::EncodeCommand(1, wire, frame) == can::EncodeStatus::kOk);
        recorded.push_back({frame, wire.session, wire.seq, wire.reset && !wire.estop && !wire.quick_stop});
        transport.Frame(frame);
        valid_command = k <= kCommandWindow;
        reset_command = valid_command && wire.reset && !wire.estop && !wire.quick_stop;
        if (valid_command) last += k;
        break;
      }
      case 3: {  // another session's command, or a corrupted one
        can::CommandFrame wire;
        wire.seq = last + 1;
        wire.session = transport.session ^ (1U << (a % 32));
        wire.reset = true;
        wire.velocity[0] = 0.2;
        can::Frame frame;
        Require(can::EncodeCommand(1, wire, frame) == can::EncodeStatus::kOk);
        if (b & 1) {
          wire.session = transport.session;
          Require(can::EncodeCommand(1, wire, frame) == can::EncodeStatus::kOk);
          frame.data[b % 8] ^= static_cast<std::uint8_t>(1U << (a % 8));
          if ((frame.data[1] & (can::kFlagEStop | can::kFlagQuickStop)) != 0) break;  // a stop flag would be honoured
        }
        ++g_exercised.foreign;
        std::uint32_t seq = 0;
        if (ValidByChance(frame, transport.session, last, seq)) {
          ++g_exercised.collisions;
          valid_command = true;
          reset_command = (frame.data[1] & can::kFlagReset) != 0;
          last = seq;
        }
        transport.Frame(frame);
        break;
      }
      case 4:  // a replay of an earlier frame: valid again only if of the current session and now in the window
        if (!recorded.empty()) {
          const Sent& sent = recorded[(a | (b << 8)) % recorded.size()];
          if ((sent.frame.data[1] & (can::kFlagEStop | can::kFlagQuickStop)) == 0) {
            transport.Frame(sent.frame);
            valid_command =
                sent.session == transport.session && sent.seq - last >= 1 && sent.seq - last <= kCommandWindow;
            reset_command = valid_command && sent.reset;
            if (valid_command) last = sent.seq;
            std::uint32_t seq = 0;
            if (sent.session != transport.session) {
              ++g_exercised.foreign;
              if (ValidByChance(sent.frame, transport.session, last, seq)) {
                ++g_exercised.collisions;
                valid_command = true;
                reset_command = sent.reset;
                last = seq;
              }
            }
          }
        }
        break;
      case 5: {  // NMT and bus events
        DriverEvent e;
        const DriverEventKind kinds[] = {DriverEventKind::kNmtStart,     DriverEventKind::kEStop,
                                         DriverEventKind::kResetRequest, DriverEventKind::kBusPassive,
                                         DriverEventKind::kBusWarning,   DriverEventKind::kBusActive,
                                         DriverEventKind::kBusOff,       DriverEventKind::kBusRestarted};
        e.kind = kinds[a % 8];
        transport.events.push_back(e);
        break;
      }
      case 6:
        driver.RequestOperatorRelease();
        operator_release = true;
        break;
      default:  // time passes
        now += 1000 * (1 + a % 150);
        break;
    }
    now += 1000;
    driver.Update(now);
    driver.Update(now);  // (events beyond 16 per update: none here, one event per step)
    if (transport.new_session) {
      last = 0;
      enabled_since_session = false;
      Require(transport.last_status.session == transport.session);
      Require(transport.last_status.state != RobotState::kReady && transport.last_status.state != RobotState::kMoving);
    }
    if (reset_command && driver.state() == RobotState::kReady) enabled_since_session = true;
    // Only a command of the session within the window moves the robot.
    if (driver.stats().commands_applied != applied_before) Require(valid_command);
    // Leaving the e-stop needs the operator.
    if (before == RobotState::kEStop && driver.state() != RobotState::kEStop) Require(operator_release);
    // Enabled only by an accepted reset of the session.
    if (driver.state() == RobotState::kReady || driver.state() == RobotState::kMoving) Require(enabled_since_session);
    // A robot that is not enabled never speeds up (it may still be decelerating from a stop).
    const RobotFeedback after = robot.Read();
    const double speed_after = std::hypot(after.velocity[0], after.velocity[1]);
    if (driver.state() != RobotState::kReady && driver.state() != RobotState::kMoving && before != RobotState::kReady &&
        before != RobotState::kMoving) {
      Require(speed_after <= speed_before + 1e-12);
    }
  }
  const DriverStats& stats = driver.stats();
  g_exercised.applied += stats.commands_applied;
  g_exercised.resets += stats.resets;
  g_exercised.estops += stats.estops;
  g_exercised.releases += stats.operator_releases;
  g_exercised.rejected += stats.wrong_session + stats.out_of_sequence + stats.bad_commands;
  g_exercised.sessions += stats.sessions;
  return 0;
}

#ifdef VISCO_FUZZ_STANDALONE
#include <spdlog/spdlog.h>

#include <cstdio>
#include <random>

// Seeded random inputs for builds without libFuzzer: `driver_fuzz RUNS` (each run a sequence of up to 200 events).
int main(int argc, char** argv) {
  const long runs = argc > 1 ? std::atol(argv[1]) : 2000;
  spdlog::set_level(spdlog::level::off);  // the driver logs every event
  std::mt19937 rng(20261201);
  std::vector<std::uint8_t> input;
  long events = 0;
  for (long run = 0; run < runs; ++run) {
    input.resize(1 + 3 * (1 + rng() % 200));
    for (auto& byte : input) byte = static_cast<std::uint8_t>(rng());
    events += static_cast<long>(input.size() / 3);
    LLVMFuzzerTestOneInput(input.data(), input.size());
  }
  // Chance collisions are about 1 in 256 for corrupted frames whose number byte changed and 1 in 65 536 for other
  // sessions' frames; a broken check would take them by the thousand.
  Require(g_exercised.collisions <= 3 + g_exercised.foreign / 100);
  std::printf(
      "driver_fuzz: %ld seeded runs, %ld events, all properties held (commands applied %llu, rejected %llu, resets "
      "%llu, e-stops %llu, operator releases %llu, sessions %llu; frames of other sessions or corrupted %llu, valid "
      "by chance %llu)\n",
      runs, events, static_cast<unsigned long long>(g_exercised.applied),
      static_cast<unsigned long long>(g_exercised.rejected), static_cast<unsigned long long>(g_exercised.resets),
      static_cast<unsigned long long>(g_exercised.estops), static_cast<unsigned long long>(g_exercised.releases),
      static_cast<unsigned long long>(g_exercised.sessions), static_cast<unsigned long long>(g_exercised.foreign),
      static_cast<unsigned long long>(g_exercised.collisions));
  return 0;
}
#endif
