#pragma once
// The robot driver's side of the link: receive commands (and NMT / bus events), send status, heartbeats and
// faults. SocketCAN and LCM implementations; the driver logic (drivers/driver.h) uses only this header.

#include <cstdint>
#include <memory>
#include <string>

#include "drivers/can_protocol.h"
#include "drivers/robot_link.h"

namespace visco::drivers {

enum class DriverEventKind : std::uint8_t {
  kCommand = 0,    // a well-formed command (session, sequence and, on CAN, CRC not yet checked)
  kBadCommand,     // a command frame that failed to decode (see `decode`)
  kEStop,          // NMT stop addressed to us
  kResetRequest,   // NMT reset node / reset communication addressed to us: the driver restarts its session
  kNmtStart,       // NMT start addressed to us: no effect on the drive (it never enables nor clears a stop)
  kBusOff,         // error frame: bus-off, or the interface went down
  kBusRestarted,   // error frame: restarted after bus-off, or the interface came back
  kBusPassive,     // error frame: error passive
  kBusWarning,     // error frame: error warning (error counters above 96)
  kBusActive,      // error frame: back to error active
  kFramesDropped,  // the kernel dropped `count` received frames (SO_RXQ_OVFL)
};
const char* ToString(DriverEventKind kind);

struct DriverEvent {
  DriverEventKind kind = DriverEventKind::kCommand;
  std::int64_t receive_us = 0;  // arrival, monotonic clock of the driver (>= now_us)
  std::uint32_t seq = 0;        // kCommand: the command's number (CAN: the frame's low 8 bits; LCM: 31 bits)
  std::uint32_t session = 0;    // kCommand: the session it claims (CAN: the frame's tag, 8 bits; LCM: the nonce)
  bool has_frame = false;       // kCommand on CAN: `frame` holds the frame, whose CRC the driver checks
  can::Frame frame;             // kCommand on CAN
  VelocityCommand command;      // kCommand
  can::DecodeStatus decode = can::DecodeStatus::kOk;  // kBadCommand
  std::uint32_t count = 0;                            // kFramesDropped
};

/// The driver's event for a command frame of `node` as it arrives on CAN: kCommand with the frame (the driver checks
/// its CRC with the session), or kBadCommand with the decode status when it does not decode (length, reserved bits).
/// Real-time safe.
inline DriverEvent CommandFrameEvent(int node, const can::Frame& frame, std::int64_t receive_us) {
  DriverEvent e;
  e.receive_us = receive_us;
  can::CommandFrame wire;
  e.decode = can::DecodeCommand(node, frame, wire);
  if (e.decode != can::DecodeStatus::kOk) {
    e.kind = DriverEventKind::kBadCommand;
    return e;
  }
  e.kind = DriverEventKind::kCommand;
  e.seq = wire.seq;
  e.session = wire.session;
  e.has_frame = true;
  e.frame = frame;
  e.command.velocity[0] = wire.velocity[0];
  e.command.velocity[1] = wire.velocity[1];
  e.command.estop = wire.estop;
  e.command.reset = wire.reset;
  e.command.quick_stop = wire.quick_stop;
  return e;
}

/// A fault the driver announces (CAN: EMCY; LCM: fault_t).
struct DriverFault {
  std::uint16_t emcy_code = 0;   // can::kEmcy*
  std::int32_t code = 0;         // fault_t::CODE_*
  std::int8_t severity = 0;      // fault_t::SEVERITY_*
  std::uint16_t fault_bits = 0;  // the driver's fault bits after this event
  bool robot_stopped = false;
  bool cleared = false;
  char message[120] = {};  // the reason in words (LCM only; CAN carries the codes)
};

class DriverTransport {
 public:
  virtual ~DriverTransport() = default;
  /// Blocks until input may be available or `timeout_us` passed.
  virtual void Wait(std::int64_t timeout_us) = 0;
  /// Takes the next event (non-blocking); false when there is none.
  virtual bool NextEvent(std::int64_t now_us, DriverEvent& out) = 0;
  virtual LinkResult SendStatus(const RobotStatus& status) = 0;
  virtual LinkResult SendHeartbeat(NmtState state) = 0;
  virtual LinkResult SendFault(const DriverFault& fault) = 0;
  /// Announces the driver's session: CAN sends the session frame; LCM carries the nonce in every heartbeat and
  /// status from now on. `status_seq` is the counter of the last status sent.
  virtual LinkResult SendSession(std::uint32_t session, std::uint32_t status_seq) = 0;
  /// Sequence numbers of commands wrap at this modulus (CAN 256, LCM 2^31).
  virtual std::uint32_t sequence_modulus() const = 0;
  virtual LinkCounters counters() const = 0;
};

/// The LCM twin of can::JudgeCommand: a command claiming session `claimed` with number `seq` against the driver's
/// `session` and last accepted number `last` (numbers modulo `modulus`). Real-time safe.
can::CommandVerdict JudgeSequence(std::uint32_t claimed, std::uint32_t seq, std::uint32_t session, std::uint32_t last,
                                  std::uint32_t window, std::uint32_t modulus);

struct DriverTransportConfig {
  int node_id = 1;
  std::string can_interface;  // for MakeSocketCanDriverTransport
  std::string lcm_url;        // for MakeLcmDriverTransport
  LockstepBus lockstep;       // MakeLcmDriverTransport only: a lockstep simulation's bus and clock (robot_link.h)
};

/// @throws visco::JobFailed when the CAN socket cannot be opened; visco::InputError for a bad node id.
std::unique_ptr<DriverTransport> MakeSocketCanDriverTransport(const DriverTransportConfig& config);
/// @throws visco::JobFailed when LCM cannot be initialised.
std::unique_ptr<DriverTransport> MakeLcmDriverTransport(const DriverTransportConfig& config);

}  // namespace visco::drivers
