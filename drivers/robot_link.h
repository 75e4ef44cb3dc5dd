#pragma once
// The controller's view of the robot driver: send velocity commands, poll the driver's status, its heartbeat and its
// faults. One interface, two transports: SocketCAN (drivers/can_protocol.h, drivers/README.md) and LCM (the
// velocity_command_t / robot_status_t / heartbeat_t / fault_t messages). The controller's loop uses only this header.
//
// Threading: one RobotLink is used by one thread (the real-time loop). Everything marked "Real-time safe" does no
// allocation, takes no lock, throws nothing and never blocks; the factories are not real-time safe (they open
// sockets, start threads, validate their configuration and throw).
//
// Clocks: every `now_us` argument is the caller's monotonic clock in microseconds (e.g. MonotonicMicros() below);
// the link keeps its peer timers on that clock. Message times (`utime`) are wall-clock microseconds since the epoch.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace lcm {
class LCM;
}

namespace visco::drivers {

/// Lockstep simulation (docs/replay.md, "Lockstep runs"): the LCM link and transport on one LCM instance that the
/// caller serves on its own thread (a memq:// bus it pumps with handleTimeout(0)), with no I/O thread of their own
/// (what they send is published at once, on the caller's thread), and message times (`utime`) from a simulated
/// clock instead of the wall clock. Not for live use: SendCommand then allocates.
struct LockstepBus {
  lcm::LCM* bus = nullptr;                  // the shared instance (null: the link opens its own and serves it)
  std::function<std::int64_t()> utime_now;  // microseconds since the epoch (empty: the wall clock)
};

/// Robot driver state, the same numbers as visco::robot_status_t::STATE_*.
enum class RobotState : std::uint8_t {
  kDisabled = 0,  // after boot-up, an NMT reset or an operator's e-stop release: needs a reset command of the session
  kReady = 1,     // enabled, zero velocity
  kMoving = 2,    // executing a velocity command
  kStopped = 3,   // stopped by its command watchdog or a fault; needs a reset command
  kEStop = 4,     // e-stop latched; needs a reset command
};

/// Fault bits of the driver (RobotStatus::fault_bits), the same values as visco::robot_status_t::FAULT_*.
namespace fault_bits {
inline constexpr std::uint16_t kWatchdog = 1;   // no valid command within the watchdog period
inline constexpr std::uint16_t kBadFrame = 2;   // malformed command (checksum, length, reserved bits)
inline constexpr std::uint16_t kSequence = 4;   // command out of sequence (duplicate or older)
inline constexpr std::uint16_t kLimit = 8;      // command beyond the velocity limit (clamped)
inline constexpr std::uint16_t kBounds = 16;    // position outside the workspace bounds
inline constexpr std::uint16_t kBus = 32;       // CAN error passive, bus-off, or the interface went down
inline constexpr std::uint16_t kEStop = 64;     // e-stop requested
inline constexpr std::uint16_t kSession = 128;  // command of another session (a stale controller or a replay)
inline constexpr std::uint16_t kAll = 255;
}  // namespace fault_bits

/// The session rules (drivers/README.md, "Sessions"). A driver accepts a command only if it carries the driver's
/// current session nonce and its number is 1..kCommandWindow ahead of the last command it accepted in that session:
/// up to kCommandWindow - 1 lost commands in a row are tolerated (at 500 Hz, 14 ms; the watchdog covers longer
/// silences). A status is accepted by the controller only if it belongs to the current session and its number is
/// 1..kStatusWindow ahead of the last accepted status (CAN, whose frames carry 8 bits of it; over LCM, whose numbers
/// are 31 bits, up to half their range ahead: any run of lost statuses is a gap there).
inline constexpr std::uint32_t kCommandWindow = 8;
inline constexpr std::uint32_t kStatusWindow = 127;

/// A velocity command for the robot's reference point. The link numbers the commands and binds them to the driver's
/// session itself.
struct VelocityCommand {
  double velocity[2] = {0.0, 0.0};  // m/s, world frame (x right, y up)
  bool estop = false;               // stop now and latch until the operator releases it at the driver
  bool quick_stop = false;          // stop now with the robot's quick-stop deceleration: STOPPED, cleared by a reset
  bool reset = false;  // enable: clear a disabled or stopped driver (not an e-stop); send with zero velocity
};

/// The driver's feedback.
struct RobotStatus {
  std::int64_t utime = 0;           // wall-clock time of the status (LCM: the driver's; CAN: the kernel receive time)
  std::int64_t receive_us = 0;      // caller's monotonic clock when the link received it (the Poll() time)
  std::uint32_t session = 0;        // the driver's session nonce (never 0)
  std::uint32_t seq = 0;            // status counter (CAN carries its low 8 bits; the CRC covers the rest)
  std::uint32_t command_seq = 0;    // number of the last command the driver accepted in this session (0: none)
  double position[2] = {0.0, 0.0};  // metres, reference point in the world frame
  double velocity[2] = {0.0, 0.0};  // m/s, actual reference point velocity in the world frame
  bool contact = false;             // the robot touches something
  double contact_force[2] = {0.0, 0.0};  // newtons, contact force on the robot, world frame
  RobotState state = RobotState::kDisabled;
  std::uint16_t fault_bits = 0;  // OR of fault_bits::k*
};

/// CANopen NMT state carried by heartbeats (the same numbers as visco::heartbeat_t::STATE_*).
enum class NmtState : std::uint8_t {
  kBootUp = 0x00,
  kStopped = 0x04,
  kOperational = 0x05,
  kPreOperational = 0x7F,
};

/// Liveness of the driver as seen through its heartbeats.
/// Liveness of the driver. Heartbeats carry no checksum or number, so a replayed one proves nothing: the driver is
/// alive while statuses of its current session, in sequence, keep arriving (it sends one at least every status
/// period and after every command).
enum class PeerState : std::uint8_t {
  kUnknown = 0,  // no accepted status yet
  kAlive = 1,    // last accepted status younger than the heartbeat timeout
  kLost = 2,     // accepted statuses before, but none within the timeout: the controller must stop
};

/// A fault announced by the driver (CAN: an EMCY frame; LCM: a fault_t message) or detected by the link itself
/// (bus errors, bus-off, receive overflows).
struct LinkFault {
  std::int64_t receive_us = 0;   // caller's monotonic clock at reception / detection
  std::uint16_t emcy_code = 0;   // CANopen emergency error code (0 = error reset / cleared), see can_protocol.h
  std::int32_t code = 0;         // visco::fault_t::CODE_* (e.g. CODE_PEER_TIMEOUT, CODE_CAN_ERROR)
  std::uint16_t fault_bits = 0;  // the driver's fault bits at that moment
  bool robot_stopped = false;    // the driver stopped the robot because of it
  bool cleared = false;          // announces that the fault has cleared
  bool local = false;            // detected by this link (bus state, session), not reported by the driver
  const char* what = nullptr;    // the reason in words when the link has one (a static string), or nullptr
  // Reported by the driver while it had accepted none of this link's commands in its session: about another (e.g.
  // the previous) controller's session, such as its watchdog stop. A refused reset (0xFF01) is never foreign.
  bool foreign = false;
};

/// The reason in words of a driver fault that needs one on the controller's side (LinkFault::what), or nullptr: a
/// refused reset (EMCY 0xFF01) means the operator must release the driver's e-stop. Real-time safe.
constexpr const char* DriverFaultWhat(std::uint16_t emcy_code) {
  return emcy_code == 0xFF01 ? "the driver's e-stop is latched: only the operator can release it, at the driver "
                               "(SIGUSR1)"
                             : nullptr;
}

/// A driver's EMCY code in words (the codes of can_protocol.h), for the controller's stop reason; "a driver fault"
/// for a code it does not know. Real-time safe.
constexpr const char* EmcyWhat(std::uint16_t emcy_code) {
  switch (emcy_code) {
    case 0x1000:
      return "e-stop";
    case 0x8100:
      return "CAN bus-off or its interface down";
    case 0x8110:
      return "CAN overrun, frames lost";
    case 0x8120:
      return "CAN error passive";
    case 0x8130:
      return "a drive of the robot lost (its heartbeat)";
    case 0x8140:
      return "CAN recovered from bus-off";
    case 0x8200:
      return "protocol error (checksum, reserved bits or sequence)";
    case 0x8210:
      return "command of the wrong length";
    case 0x8250:
      return "no valid command within its watchdog period";
    case 0x8400:
      return "commanded speed above the driver's limit";
    case 0x8612:
      return "the robot left its workspace";
    case 0xFF01:
      return "reset refused: the driver's e-stop is latched";
    case 0xFF02:
      return "quick stop at the controller's request";
    case 0xFF03:
      return "CAN error warning";
    default:
      return "a driver fault";
  }
}

/// LinkFault::what of the (foreign, non-stopping) fault a link reports when the driver's session turns out to be
/// another controller's. An array, not a pointer to a literal: one object with one address in every translation unit
/// (identical literals in different units need not share one; under ASan they never do), so `what ==` identifies it.
inline constexpr char kForeignSessionWhat[] =
    "the driver's session has accepted another controller's commands (one that just ended, or one still running): "
    "this controller waits for the fresh session the driver issues after a watchdog period without commands";

/// The (local, foreign, non-stopping) fault a link reports when the driver's session turns out to be another
/// controller's; `code` is visco::fault_t::CODE_BAD_MESSAGE (this header does not include the LCM types). Real-time
/// safe.
inline LinkFault ForeignSessionFault(std::int64_t now_us, std::int32_t code) {
  LinkFault fault;
  fault.receive_us = now_us;
  fault.code = code;
  fault.local = true;
  fault.foreign = true;  // reported, no reason to stop: this controller has commanded nothing
  fault.what = kForeignSessionWhat;
  return fault;
}

/// Result of a real-time link call.
enum class LinkResult : std::uint8_t {
  kOk = 0,
  kNoData,      // nothing new (Take* calls)
  kBusOff,      // the bus is off or the interface is down; the command was not sent
  kBufferFull,  // the kernel's transmit queue (or the LCM hand-off) is full; the command was not sent
  kOutOfRange,  // the command cannot be represented on the wire (|v| beyond the frame's range); not sent
  kError,       // another I/O error (counted in LinkCounters::io_errors)
  kNoSession,   // no session to command in yet (none announced, its first status not seen, or another controller's):
                // not sent (stops are always sent)
};

/// Returns a short name for a result ("ok", "bus-off", ...). Real-time safe.
const char* ToString(LinkResult result);
/// Returns a short name for a state ("ready", "estop", ...). Real-time safe.
const char* ToString(RobotState state);
/// Returns a short name for a peer state. Real-time safe.
const char* ToString(PeerState state);

/// Monotonically increasing counters of one link (all since creation).
struct LinkCounters {
  std::uint64_t frames_read = 0;  // SocketCAN: frames (data and error) read from the receive socket; LCM: 0
  std::uint64_t commands_sent = 0;
  std::uint64_t send_failures = 0;      // SendCommand calls that did not send
  std::uint64_t statuses_received = 0;  // complete status updates
  std::uint64_t heartbeats_received = 0;
  std::uint64_t faults_received = 0;    // EMCY frames / fault_t messages from the driver
  std::uint64_t bad_frames = 0;         // frames for us that failed to decode (checksum, length)
  std::uint64_t unverified_frames = 0;  // status frames dropped because no session was known yet
  std::uint64_t status_gaps = 0;        // status sequence numbers skipped (lost statuses)
  std::uint64_t error_frames = 0;       // CAN error frames seen
  std::uint64_t bus_off_events = 0;     // transitions into bus-off / interface down
  std::uint64_t rx_overflow_drops = 0;  // frames the kernel dropped because our receive queue was full (SO_RXQ_OVFL)
  std::uint64_t faults_dropped = 0;     // faults lost because the caller did not take them fast enough
  std::uint64_t io_errors = 0;
  std::uint64_t session_changes = 0;     // announcements of a session other than the current one
  std::uint64_t stale_statuses = 0;      // statuses of the current session out of sequence (replays, duplicates)
  std::uint64_t reordered_statuses = 0;  // LCM: statuses a few behind the last or copies of it (UDP reordering)
  std::uint64_t boot_ups = 0;            // boot-up heartbeats after the driver had been seen operational
};

/// Bus state as the link sees it (always kActive for LCM).
enum class BusState : std::uint8_t { kActive = 0, kWarning, kPassive, kBusOff };

/// The controller's view of the driver's session (drivers/README.md, "Sessions"), shared by the SocketCAN and LCM
/// links. The driver issues a new nonce at boot-up, at an NMT reset, at every stop and when its session expires; the
/// link numbers its commands in the session it knows, from 1. Real-time safe.
class SessionView {
 public:
  /// What an announcement (CAN: the session frame; LCM: a heartbeat or status) did.
  enum class Change : std::uint8_t {
    kNone = 0,  // the current session
    kFirst,     // the first session seen: adopted
    kAdopted,   // another session, while this link had no command accepted in the old one: adopted
    kLost,      // another session while this link's commands were being accepted: adopted, and a fault
  };
  Change OnAnnounce(std::uint32_t nonce) {
    if (nonce == 0) return Change::kNone;  // 0 is never a session
    if (have_ && nonce == session_) return Change::kNone;
    const bool first = !have_;
    const bool owned = owned_;
    have_ = true;
    session_ = nonce;
    last_ = 0;
    owned_ = false;
    checked_ = false;
    foreign_ = false;
    if (first) return Change::kFirst;
    return owned ? Change::kLost : Change::kAdopted;
  }
  /// A boot-up heartbeat: true if the driver had been seen operational before (it restarted). The session is
  /// forgotten until the next announcement.
  bool OnHeartbeat(bool boot_up) {
    if (!boot_up) {
      operational_ = true;
      return false;
    }
    const bool restarted = operational_;
    operational_ = false;
    have_ = false;
    owned_ = false;
    checked_ = false;
    foreign_ = false;
    last_ = 0;
    return restarted;
  }
  /// An accepted status of the current session saying the driver accepted `accepted` (0: none yet). The first one
  /// decides whether the session is this link's to use: a session that accepted commands before this link sent any
  /// is another controller's (one that ran just before and whose session has not expired yet, or one still running);
  /// numbering from 1 in it would be refused as stale, and its expiry would void this link's run midway. Returns
  /// true when that is found (once per session).
  bool OnStatus(std::uint32_t accepted) {
    if (!checked_) {
      checked_ = true;
      foreign_ = accepted != 0 && last_ == 0;
      if (foreign_) return true;
    }
    if (!foreign_ && accepted != 0 && accepted <= last_) owned_ = true;
    return false;
  }
  /// The session is known, its first status said it is fresh, and it is not another controller's: commands may be
  /// numbered in it. Until then a link sends only e-stops and quick stops (LinkResult::kNoSession).
  bool usable() const { return have_ && checked_ && !foreign_; }
  /// The current session accepted another controller's commands: its statuses are not this link's to act on.
  bool foreign() const { return have_ && foreign_; }
  bool have() const { return have_; }
  std::uint32_t session() const { return session_; }
  /// The number of the next command; call Sent() once it went out.
  std::uint32_t Next() const { return last_ + 1; }
  void Sent(std::uint32_t seq) { last_ = seq; }
  std::uint32_t last() const { return last_; }
  /// True once the driver accepted this link's commands in the current session.
  bool owned() const { return owned_; }

 private:
  bool have_ = false;
  bool owned_ = false;
  bool operational_ = false;
  bool checked_ = false;  // the session's first status was seen
  bool foreign_ = false;  // ... and said it had accepted commands before this link sent any
  std::uint32_t session_ = 0;
  std::uint32_t last_ = 0;
};

/// The controller side of the robot link.
class RobotLink {
 public:
  virtual ~RobotLink() = default;

  /// Sends one command, numbering it with the next sequence number. Real-time safe (CAN: one non-blocking
  /// write; LCM: a lock-free hand-off to the publisher thread).
  virtual LinkResult SendCommand(const VelocityCommand& command, std::int64_t now_us) = 0;

  /// Processes everything that arrived since the last call (non-blocking): statuses, heartbeats, faults, bus
  /// errors. Call once per control period before the Take* calls. Real-time safe.
  virtual void Poll(std::int64_t now_us) = 0;

  /// Copies the newest status into `out` if a new one arrived since the last call; kNoData otherwise.
  /// Real-time safe.
  virtual LinkResult TakeStatus(RobotStatus& out) = 0;

  /// Takes the oldest pending fault (a small fixed queue; overflow is counted). Real-time safe.
  virtual LinkResult TakeFault(LinkFault& out) = 0;

  /// The driver's liveness at `now_us`, judged by its accepted statuses (PeerState); the driver's NMT state is the
  /// last heartbeat's content. Real-time safe.
  virtual PeerState peer_state(std::int64_t now_us) const = 0;
  virtual NmtState peer_nmt_state() const = 0;

  /// Bus state (CAN error frames, bus-off, interface down). Real-time safe.
  virtual BusState bus_state() const = 0;

  /// Number of the last command sent in the current session (0 before the first). Real-time safe.
  virtual std::uint32_t last_command_seq() const = 0;
  /// The driver's session nonce as the link knows it (0: none yet). Real-time safe.
  virtual std::uint32_t session() const = 0;

  virtual LinkCounters counters() const = 0;
};

/// Configuration of a RobotLink.
struct RobotLinkConfig {
  int node_id = 1;                              // the robot's CAN node id, 1..127 (also LCM node_id)
  std::int64_t heartbeat_timeout_us = 300'000;  // peer lost when no accepted status for this long
  std::string can_interface;                    // SocketCAN interface ("vcan0"); for MakeSocketCanRobotLink
  std::string lcm_url;                          // LCM provider URL ("" = LCM's default); for MakeLcmRobotLink
  LockstepBus lockstep;                         // MakeLcmRobotLink only: a lockstep simulation's bus and clock
};

/// Opens a SocketCAN robot link on `config.can_interface`. Not real-time safe.
/// @throws visco::JobFailed if the socket cannot be opened or bound (the message names the interface and errno).
/// @throws visco::InputError if the node id is outside 1..127.
std::unique_ptr<RobotLink> MakeSocketCanRobotLink(const RobotLinkConfig& config);

class CanPort;  // drivers/socketcan.h
/// The same link over given ports instead of sockets on `config.can_interface`: `receive` delivers the frames of
/// the bus (no kernel filter: the link ignores other nodes' frames itself), commands go to `send`. For tests and
/// fuzzers of the link's protocol logic on machines without CAN. @throws visco::InputError on a bad node id.
std::unique_ptr<RobotLink> MakeCanRobotLink(const RobotLinkConfig& config, std::unique_ptr<CanPort> receive,
                                            std::unique_ptr<CanPort> send);

/// Opens an LCM robot link (publishes VISCO_COMMAND, subscribes VISCO_STATUS, VISCO_HEARTBEAT_DRIVER,
/// VISCO_FAULT) and starts its I/O thread. Not real-time safe.
/// @throws visco::JobFailed if LCM cannot be initialised with `config.lcm_url`.
std::unique_ptr<RobotLink> MakeLcmRobotLink(const RobotLinkConfig& config);

/// CLOCK_MONOTONIC in microseconds. Real-time safe.
std::int64_t MonotonicMicros();
/// CLOCK_REALTIME in microseconds since the epoch. Real-time safe.
std::int64_t WallMicros();

}  // namespace visco::drivers
