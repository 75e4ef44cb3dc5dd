#pragma once
// The robot driver's logic, independent of the transport (CAN or LCM) and of the robot (simulated or real):
// sequence and checksum checking, the command watchdog, e-stop and reset, bus faults, status replies, heartbeats and
// EMCY/fault announcements. `visco driver` runs it; tests drive Update() with their own clock.
//
// Safety rules (drivers/README.md):
// - Sessions: the driver issues a random 32-bit nonce at start-up, at an NMT reset, at every stop, at the operator's
//   e-stop release and when a session that accepted commands sees none for a watchdog period; it announces it
//   (DriverTransport::SendSession). Only commands of the current session, 1..kCommandWindow ahead of the last
//   accepted one (and on CAN with a CRC over the nonce and the full counter) count. Others are ignored and reported
//   (fault bit + EMCY once per episode); the bit clears with the next valid command.
// - The driver boots DISABLED: a reset command of the session enables it (READY).
// - The watchdog (armed by the first valid command of the session) quick-stops the robot when no valid command
//   arrives within the watchdog period: state STOPPED, FAULT_WATCHDOG, EMCY 0x8250 "RPDO timeout".
// - E-stop (a command's e-stop flag, whatever its session, number or CRC; NMT stop): quick stop, state ESTOP,
//   FAULT_ESTOP, latched until the operator releases it at the driver (RequestOperatorRelease(); `visco driver`:
//   SIGUSR1), which leaves the driver DISABLED. Resets and NMT start are refused meanwhile (EMCY 0xFF01, once).
// - Quick stop (a command's quick-stop flag, whatever its session, number or CRC: the controller stopped): quick stop
//   at once, state STOPPED, EMCY 0xFF02; a reset clears it.
// - Bus-off or interface down: quick stop, state STOPPED, FAULT_BUS until the bus recovers.
// - The robot's own fault (RobotFeedback::fault: a drive's fault or EMCY, a drive lost): quick stop, state STOPPED,
//   EMCY with the robot's code and message (the bus fault bit if it is a communication fault); the reset calls
//   RobotInterface::Reset() (a CiA 402 fault reset), and a fault that persists stops the robot again.
// - STOPPED is latched: a reset command with the faults gone returns the driver to READY. The reset command's
//   velocity is ignored. NMT start has no effect; NMT reset node restarts the session (DISABLED, or ESTOP if latched).

#include <array>
#include <atomic>
#include <cstdint>
#include <limits>

#include "common/shared_snapshot.h"
#include "drivers/can_protocol.h"
#include "drivers/driver_transport.h"
#include "drivers/robot_interface.h"
#include "drivers/robot_link.h"

namespace visco::drivers {

struct DriverConfig {
  std::int64_t watchdog_us = 100'000;      // command watchdog period
  std::int64_t period_us = 1'000;          // robot update period
  std::int64_t status_period_us = 10'000;  // status when no command arrives (a status also follows every command)
  std::int64_t heartbeat_period_us = 100'000;
  double max_speed = 1.0;          // m/s, commanded speeds above it are clamped (FAULT_LIMIT)
  std::uint64_t session_seed = 0;  // seed of the session nonces; 0: from the operating system (getrandom)
};

/// Counts of what the driver saw (for logs and tests).
struct DriverStats {
  std::uint64_t commands_applied = 0;
  std::uint64_t bad_commands = 0;
  std::uint64_t out_of_sequence = 0;  // stale (duplicates, replays) or too far ahead
  std::uint64_t wrong_session = 0;    // commands of another session
  std::uint64_t sequence_gaps = 0;    // command numbers skipped (lost commands)
  std::uint64_t watchdog_stops = 0;
  std::uint64_t bounds_stops = 0;  // the robot left its workspace
  std::uint64_t robot_faults = 0;  // the robot reported a fault of its own (RobotFeedback::fault)
  std::uint64_t estops = 0;
  std::uint64_t quick_stops = 0;  // at the controller's request (command flag)
  std::uint64_t resets = 0;
  std::uint64_t refused_resets = 0;  // resets while an e-stop was latched
  std::uint64_t nmt_starts = 0;      // NMT start (no effect)
  std::uint64_t nmt_resets = 0;
  std::uint64_t operator_releases = 0;
  std::uint64_t sessions = 0;  // sessions issued
  std::uint64_t bus_offs = 0;
  std::uint64_t frames_dropped = 0;  // by the kernel: the receive queue was full (SO_RXQ_OVFL)
  std::uint64_t statuses_sent = 0;
  std::uint64_t send_failures = 0;
  std::uint64_t faults_sent = 0;
};

/// The driver as other threads may see it: a whole copy of its state, published by the driver's thread at the end of
/// every Start() and Update() (and by the constructor).
struct DriverSnapshot {
  RobotState state = RobotState::kDisabled;
  std::uint16_t fault_bits = 0;
  std::uint32_t session = 0;
  DriverStats stats;
  RobotFeedback robot;  // the robot's feedback as the driver last read it (after its last Step)
};

/// Threads: Start(), Update() and Run() belong to one thread, the driver's (Run() is that thread's loop); state(),
/// fault_bits(), session() and stats() read the driver's own variables and are for that thread, or for any thread
/// once it has been joined. Other threads (a summary, a test, a monitor) read Snapshot(), and may call
/// RequestOperatorRelease() (an atomic flag); nothing else. The driver's thread never takes a lock for them.
class Driver {
 public:
  /// Not real-time safe. @throws visco::InputError for a non-positive period, watchdog or speed limit.
  Driver(const DriverConfig& config, DriverTransport& transport, RobotInterface& robot);

  /// Sends the boot-up heartbeat and announces the first session. Call once before the first Update().
  void Start(std::int64_t now_us);
  /// One iteration at `now_us` (monotonic): handles up to 16 pending events (taken to arrive at `now_us`), steps the
  /// robot by the time since the last call, runs the watchdog, sends the periodic status and heartbeat.
  /// No allocation.
  void Update(std::int64_t now_us);
  /// Runs Start() and Update() at the configured period until `stop` becomes true.
  void Run(const std::atomic<bool>& stop);

  /// The operator's e-stop release (an explicit action at the driver, never a bus message): the next Update() clears
  /// a latched e-stop and leaves the driver DISABLED in a new session. Async-signal-safe (one atomic store).
  void RequestOperatorRelease() { operator_release_.store(true, std::memory_order_relaxed); }

  /// The driver's thread only (or after it was joined); other threads: Snapshot().
  RobotState state() const { return state_; }
  std::uint16_t fault_bits() const { return fault_bits_; }
  std::uint32_t session() const { return session_; }
  const DriverStats& stats() const { return stats_; }

  /// State, fault bits, session, counts and robot feedback as of the end of the last Start() or Update(). Any
  /// thread; lock-free (a sequence lock: the driver's thread publishes wait-free and is never blocked by readers).
  DriverSnapshot Snapshot() const { return snapshot_.Read(); }

 private:
  void OnCommand(const DriverEvent& event, std::int64_t now_us);
  void Reject(can::CommandVerdict verdict, const DriverEvent& event, std::uint32_t seq);
  void OnReset(std::int64_t now_us);
  void OnNmtReset();
  void OnNmtStart();
  void OnOperatorRelease();
  void RefuseWhileEStop(const char* what);
  void EStop(std::int64_t now_us, const char* why);
  void QuickStopRequested(bool valid);
  void StopRobot(RobotState state);
  void NewSession(std::int64_t now_us);
  std::uint32_t NextNonce();
  void SetFault(std::uint16_t bit, std::uint16_t emcy, std::int32_t code, bool stopped, const char* message);
  void ClearFault(std::uint16_t bit);
  void Announce(std::uint16_t emcy, std::int32_t code, bool stopped, bool cleared, const char* message);
  void SendStatus(std::int64_t now_us);
  void PublishSnapshot(const RobotFeedback& robot);

  const DriverConfig config_;
  DriverTransport& transport_;
  RobotInterface& robot_;
  RobotState state_ = RobotState::kDisabled;
  std::uint16_t fault_bits_ = 0;
  bool bus_off_ = false;
  bool out_of_bounds_ = false;  // the robot reported itself outside its workspace (one fault per episode)
  bool robot_fault_ = false;    // the robot reported a fault (one stop per episode; a reset ends it)
  std::uint64_t rng_ = 0;       // splitmix64 state of the nonces
  std::uint32_t session_ = 0;
  // The tag bytes (CAN: a nonce's low byte) of the last kRecentTags sessions: a new session never reuses one, so a
  // frame recorded in any of them fails the tag check outright. (Two sessions with the same tag would accept each
  // other's frames whenever the 8-bit CRC collides: 1 frame in 256.)
  static constexpr int kRecentTags = 64;
  std::array<std::uint8_t, kRecentTags> recent_tags_{};
  int recent_tag_count_ = 0;
  std::uint32_t last_seq_ = 0;  // last accepted command number in the session (0: none)
  // The session's last accepted frame of each low byte (CAN): a replay of one from the last wrap of the counter is
  // rejected even where its CRC matches the number it claims by chance (1 in 256).
  can::FrameHistory accepted_frames_;
  bool session_expired_ = false;  // a new session starts at the end of this Update()
  // The current session's announcement went out. A status is sent only after it (a status of a session nobody was told
  // of cannot be verified): when the bus or the interface failed the announcement, it is retried before the next one.
  bool session_announced_ = false;
  bool refusal_announced_ = false;
  std::atomic<bool> operator_release_{false};
  std::int64_t last_valid_us_ = -1;  // -1: watchdog not armed
  std::int64_t last_update_us_ = -1;
  std::int64_t next_status_us_ = 0;
  std::int64_t last_status_us_ = std::numeric_limits<std::int64_t>::min() / 2;  // when the last status went out
  std::uint64_t drops_unreported_ = 0;  // frames the kernel dropped since the last report
  std::int64_t last_drop_report_us_ = std::numeric_limits<std::int64_t>::min() / 2;
  static constexpr std::int64_t kRejectAnswerIntervalUs = 1'000;  // rejected frames: at most one answer per ms
  static constexpr std::int64_t kDropReportIntervalUs = 100'000;  // kernel drops: at most one EMCY per 100 ms
  std::int64_t next_heartbeat_us_ = 0;
  std::uint32_t status_seq_ = 0;
  DriverStats stats_;
  SharedSnapshot<DriverSnapshot> snapshot_;  // written by the driver's thread, read by any
};

}  // namespace visco::drivers
