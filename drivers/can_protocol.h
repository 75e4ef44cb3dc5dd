#pragma once
// The controller <-> robot driver CAN protocol (drivers/README.md, drivers/visco.dbc): CANopen-style identifiers,
// classic CAN frames of 8 bytes, little-endian (Intel) signals, and in every command and status frame the low 8 bits
// of a 32-bit counter and a CRC-8 that also covers the driver's 32-bit session nonce and the counter's upper 24
// bits (which the frame does not carry). Pure encode/decode, independent of SocketCAN: every function here is real-time
// safe (no allocation, no exception, no I/O) and returns an enum class status.
//
//   id            dir                what                                  bytes
//   0x000         controller->all    NMT (byte0 command, byte1 node or 0)  2
//   0x080+node    driver->all        EMCY (CANopen emergency)              8
//   0x180+node    driver->controller status: seq, command seq, velocity    8 (TPDO1)
//   0x200+node    controller->driver velocity command                      8 (RPDO1)
//   0x280+node    driver->controller position                              8 (TPDO2)
//   0x380+node    driver->controller contact force and fault bits          8 (TPDO3)
//   0x480+node    driver->all        session: nonce, status epoch          8 (TPDO4)
//   0x700+node    driver->all        heartbeat (NMT state)                 1

#include <cstdint>

#include "drivers/robot_link.h"

namespace visco::drivers::can {

// SocketCAN's id flags (linux/can.h), repeated here so that the protocol does not need Linux headers.
inline constexpr std::uint32_t kEffFlag = 0x80000000U;  // extended (29-bit) frame
inline constexpr std::uint32_t kRtrFlag = 0x40000000U;  // remote transmission request
inline constexpr std::uint32_t kErrFlag = 0x20000000U;  // error frame (linux/can/error.h)
inline constexpr std::uint32_t kSffMask = 0x000007FFU;

/// One classic CAN frame, laid out like Linux's struct can_frame's meaningful parts.
struct Frame {
  std::uint32_t id = 0;  // 11-bit id, or with kEffFlag / kRtrFlag / kErrFlag as in SocketCAN
  std::uint8_t dlc = 0;  // 0..8
  std::uint8_t data[8] = {0, 0, 0, 0, 0, 0, 0, 0};
};

// Function codes (CANopen predefined connection set); the node id is added.
inline constexpr std::uint32_t kNmtId = 0x000;
inline constexpr std::uint32_t kEmcyBase = 0x080;
inline constexpr std::uint32_t kStatusBase = 0x180;    // TPDO1
inline constexpr std::uint32_t kCommandBase = 0x200;   // RPDO1
inline constexpr std::uint32_t kPositionBase = 0x280;  // TPDO2
inline constexpr std::uint32_t kForceBase = 0x380;     // TPDO3
inline constexpr std::uint32_t kSessionBase = 0x480;   // TPDO4
inline constexpr std::uint32_t kHeartbeatBase = 0x700;
inline constexpr int kMinNode = 1;
inline constexpr int kMaxNode = 127;

// Scales of the signals (physical = raw * scale).
inline constexpr double kVelocityScale = 1e-4;  // m/s per bit, int16: +-3.2767 m/s
inline constexpr double kPositionScale = 1e-5;  // m per bit, int24: +-83.886 m
inline constexpr double kForceScale = 1e-2;     // N per bit, int16: +-327.67 N
inline constexpr double kMaxVelocity = 32767 * kVelocityScale;

// Command flags (byte 1 of the command frame). Other bits are reserved and must be zero.
inline constexpr std::uint8_t kFlagEStop = 0x01;
inline constexpr std::uint8_t kFlagReset = 0x02;
inline constexpr std::uint8_t kFlagQuickStop = 0x04;  // the controller's stop: quick stop now, STOPPED

// NMT commands (byte 0 of an NMT frame).
inline constexpr std::uint8_t kNmtStart = 0x01;  // -> operational: no effect on the drive (it never enables or clears)
inline constexpr std::uint8_t kNmtStop = 0x02;   // -> stopped: the driver latches an e-stop
inline constexpr std::uint8_t kNmtPreOperational = 0x80;
inline constexpr std::uint8_t kNmtResetNode = 0x81;  // the driver restarts: new session, disabled (an e-stop stays)
inline constexpr std::uint8_t kNmtResetCommunication = 0x82;  // the same as reset node

// EMCY error codes (CANopen CiA 301 / 402 meanings).
inline constexpr std::uint16_t kEmcyNoError = 0x0000;          // error reset: the fault has cleared
inline constexpr std::uint16_t kEmcyGeneric = 0x1000;          // generic error (used for e-stop)
inline constexpr std::uint16_t kEmcyBusOff = 0x8100;           // communication error: bus-off or interface down
inline constexpr std::uint16_t kEmcyCanOverrun = 0x8110;       // CAN overrun (frames lost)
inline constexpr std::uint16_t kEmcyCanPassive = 0x8120;       // CAN in error passive mode
inline constexpr std::uint16_t kEmcyBusOffRecovered = 0x8140;  // recovered from bus-off
inline constexpr std::uint16_t kEmcyProtocol = 0x8200;         // protocol error (checksum, reserved bits, sequence)
inline constexpr std::uint16_t kEmcyPdoLength = 0x8210;        // PDO not processed due to length error
inline constexpr std::uint16_t kEmcyRpdoTimeout = 0x8250;      // RPDO timeout: the command watchdog expired
inline constexpr std::uint16_t kEmcyVelocityLimit = 0x8400;    // velocity speed controller (command limited)
inline constexpr std::uint16_t kEmcyBounds = 0x8612;           // reference limit (workspace bounds)
// Manufacturer-specific (0xFF00-0xFFFF): a reset or NMT start refused because an e-stop is latched (the operator must
// release it); a quick stop at the controller's request; a CAN error warning (reported only, no stop).
inline constexpr std::uint16_t kEmcyResetRefused = 0xFF01;
inline constexpr std::uint16_t kEmcyQuickStop = 0xFF02;
inline constexpr std::uint16_t kEmcyCanWarning = 0xFF03;

static_assert(DriverFaultWhat(kEmcyResetRefused) != nullptr, "robot_link.h explains the refused reset");

/// Result of decoding a frame.
enum class DecodeStatus : std::uint8_t {
  kOk = 0,
  kWrongId,      // not the frame kind this decoder reads (or an extended / RTR / error frame)
  kBadLength,    // DLC differs from the protocol's
  kBadChecksum,  // CRC-8 mismatch
  kBadReserved,  // reserved bits or bytes not zero, or an unknown enum value
};
const char* ToString(DecodeStatus status);

/// Result of encoding a frame.
enum class EncodeStatus : std::uint8_t {
  kOk = 0,
  kOutOfRange,  // a value does not fit the signal (commands only; status signals saturate)
  kBadNode,     // node id outside 1..127
  kNotFinite,   // NaN or infinity
};
const char* ToString(EncodeStatus status);

/// CRC-8/SAE-J1850 (polynomial 0x1D, init 0xFF, final xor 0xFF) of the frame's 11-bit id (two bytes, little-endian)
/// followed by data[0..6]: byte 7 of the session frame. Covering the id catches a frame that arrives under the wrong
/// id. Real-time safe.
std::uint8_t FrameCrc(std::uint32_t id, const std::uint8_t* data7);
/// The session key of one frame: f(nonce ^ f(counter ^ f(id))), f = murmur3's 32-bit finaliser, id the 11-bit
/// identifier. A CRC is linear: over the raw nonce, the CRC of a frame of another session would differ from the valid
/// one by a constant that depends only on the two nonces, so 1 session in 256 would have every frame valid in the
/// current one (and 1 counter offset in 256 every replayed frame). Through this mix a frame of another session, or of
/// another counter, passes the 8-bit CRC by chance independently of every other frame (1 in 256 each; the three
/// frames of a status update too, since the id is mixed in). Not cryptographic: the nonce is on the bus.
std::uint32_t SessionKey(std::uint32_t id, std::uint32_t session, std::uint32_t counter);
/// The CRC of command and status frames (byte 7): CRC-8/SAE-J1850 of the 11-bit id (two bytes, little-endian), the
/// session key SessionKey(id, nonce, counter) (four bytes, little-endian), the counter's upper 24 bits (`counter >> 8`,
/// three bytes, little-endian; byte 0 of the frame carries `counter & 0xFF`) and data[0..6]. A frame of another
/// session, or one replayed 256 or more counts later, fails it (but for 1 in 256 by chance). Real-time safe.
std::uint8_t SessionCrc(std::uint32_t id, std::uint32_t session, std::uint32_t counter, const std::uint8_t* data7);
/// Plain CRC-8/SAE-J1850 of `size` bytes (check value of "123456789" is 0x4B). Real-time safe.
std::uint8_t Crc8SaeJ1850(const std::uint8_t* bytes, int size);

/// The wire form of a command (what RobotLink sends, what the driver receives). Byte 0 is `seq & 0xFF`, byte 6 the
/// session tag `session & 0xFF`; the CRC covers all of both.
struct CommandFrame {
  std::uint32_t seq = 0;      // command counter in the session (DecodeCommand: the frame's low 8 bits only)
  std::uint32_t session = 0;  // the driver's session nonce (DecodeCommand: the frame's tag, the low 8 bits)
  bool estop = false;
  bool reset = false;
  bool quick_stop = false;
  double velocity[2] = {0.0, 0.0};  // m/s, world frame, quantised to kVelocityScale
};

/// The three status frames' content (one status update = TPDO1 + TPDO2 + TPDO3 with the same seq).
struct StatusFrames {
  std::uint32_t seq = 0;         // status counter (the frames carry its low 8 bits in byte 0)
  std::uint32_t session = 0;     // the driver's session nonce (only in the CRC)
  std::uint8_t command_seq = 0;  // low 8 bits of the last accepted command's number
  double velocity[2] = {0.0, 0.0};
  RobotState state = RobotState::kDisabled;
  bool contact = false;
  double position[2] = {0.0, 0.0};
  double contact_force[2] = {0.0, 0.0};
  std::uint16_t fault_bits = 0;
};

/// An EMCY frame's content. Bytes: 0-1 error code, 2 error register (CiA 301 bits: 0x01 generic, 0x10 communication),
/// 3 visco fault code (fault_t::CODE_*), 4-5 fault bits, 6 flags (bit0 robot stopped, bit1 cleared), 7 counter.
struct EmcyFrame {
  std::uint16_t error_code = 0;
  std::uint8_t error_register = 0;
  std::uint8_t code = 0;
  std::uint16_t fault_bits = 0;
  bool robot_stopped = false;
  bool cleared = false;
  std::uint8_t counter = 0;
};

/// The session frame's content (TPDO4, 0x480+N): bytes 0-3 the session nonce, bytes 4-6 the status epoch (bits 8..31
/// of the counter of the last status update sent, so that a listener can check the next statuses' CRCs), byte 7
/// FrameCrc. Sent at every new session and with every heartbeat.
struct SessionFrame {
  std::uint32_t session = 0;       // never 0
  std::uint32_t status_epoch = 0;  // 24 bits
};

/// The kind of a frame from its id alone.
enum class FrameKind : std::uint8_t {
  kOther = 0,
  kNmt,
  kEmcy,
  kStatus,
  kCommand,
  kPosition,
  kForce,
  kSession,
  kHeartbeat,
  kError,
};
/// Classifies `frame` for `node` (frames of other nodes and extended/RTR frames are kOther). Real-time safe.
FrameKind Classify(const Frame& frame, int node);

EncodeStatus EncodeCommand(int node, const CommandFrame& command, Frame& out);
/// Decodes a command's layout (id, length, reserved bits and values) without its CRC, which needs the receiver's
/// session and counter (JudgeCommand): `out.seq` and `out.session` get the frame's low 8 bits. Real-time safe.
DecodeStatus DecodeCommand(int node, const Frame& frame, CommandFrame& out);

/// What the driver makes of a command frame whose layout decoded (drivers/README.md, "Sessions").
enum class CommandVerdict : std::uint8_t {
  kAccept = 0,    // current session, 1..window ahead of the last accepted command
  kStale,         // current session, not ahead: a duplicate or a replay
  kAhead,         // current session, more than the window ahead
  kWrongSession,  // another session's tag
  kBadChecksum,   // the CRC fails for the current session and every plausible counter
  kRepeat,        // passes as 1..window ahead, but is a copy of a frame accepted earlier in the session (a replay)
};
const char* ToString(CommandVerdict verdict);

/// The last command frame of each low byte of the number that a receiver accepted (or a sender sent) in the current
/// session: the frames of the last wrap of the counter, 256 commands. A replay of a frame one wrap old carries the low
/// byte of a number in the window, and the CRC tells the two numbers apart only 255 times in 256: the CRC is linear,
/// so for 1 number pair in 256 every payload passes under both numbers (drivers/README.md, "Replays"). The driver
/// rejects a byte-identical copy of the frame it accepted one wrap earlier (CommandVerdict::kRepeat); a sender
/// skips a number whose frame would be such a copy (the same payload as one wrap earlier under a colliding pair, 1
/// command in 256 at a constant velocity), so that no live command is rejected. Older wraps are not kept: a frame
/// identical to one of them is a new command as often as a replay. Real-time safe, 2.3 KB.
class FrameHistory {
 public:
  bool Contains(const Frame& frame) const;
  void Add(const Frame& frame);
  void Clear();

 private:
  std::uint64_t frames_[256] = {};
  bool have_[256] = {};
};

/// Judges a command frame against the receiver's `session` and the last accepted counter `last`: reconstructs the
/// counter from the frame's low 8 bits (ahead: last + 1..255; behind: last - 0..255) and checks the CRC with it.
/// `seq` gets the reconstructed counter (for kAccept, kStale, kAhead, kRepeat). With `accepted` (the receiver's
/// history of the session), a frame that would be accepted but is a copy of the one accepted a wrap earlier under its
/// low byte is kRepeat. Real-time safe.
CommandVerdict JudgeCommand(const Frame& frame, std::uint32_t session, std::uint32_t last, std::uint32_t window,
                            std::uint32_t& seq, const FrameHistory* accepted = nullptr);

/// The counter value nearest after `last` (1..256 ahead) whose low 8 bits are `low`; minus 256 for the one behind.
/// Real-time safe.
inline std::uint32_t CounterAhead(std::uint32_t last, std::uint8_t low) {
  const std::uint32_t k = static_cast<std::uint8_t>(low - static_cast<std::uint8_t>(last));
  return last + (k == 0 ? 256 : k);
}

/// Encodes the three status frames (status, position, force; in that order) of `status.session` and counter
/// `status.seq`. Values beyond a signal's range saturate; NaN is sent as zero. Real-time safe.
EncodeStatus EncodeStatusFrames(int node, const StatusFrames& status, Frame out[3]);
/// Decoders of the three status frames for session `session` and status counter `seq` (byte 0 must be its low 8
/// bits and the CRC must match, else kBadChecksum): each fills only its own fields of `out` (and seq, session).
DecodeStatus DecodeStatusFrame(int node, const Frame& frame, std::uint32_t session, std::uint32_t seq,
                               StatusFrames& out);
DecodeStatus DecodePositionFrame(int node, const Frame& frame, std::uint32_t session, std::uint32_t seq,
                                 StatusFrames& out);
DecodeStatus DecodeForceFrame(int node, const Frame& frame, std::uint32_t session, std::uint32_t seq,
                              StatusFrames& out);

/// The session frame (plain FrameCrc). Nonce 0 is invalid (kBadReserved), as are epochs beyond 24 bits.
EncodeStatus EncodeSession(int node, const SessionFrame& session, Frame& out);
DecodeStatus DecodeSession(int node, const Frame& frame, SessionFrame& out);

EncodeStatus EncodeHeartbeat(int node, NmtState state, Frame& out);
DecodeStatus DecodeHeartbeat(int node, const Frame& frame, NmtState& out);

EncodeStatus EncodeEmcy(int node, const EmcyFrame& emcy, Frame& out);
DecodeStatus DecodeEmcy(int node, const Frame& frame, EmcyFrame& out);

/// NMT: command and target node (0 = all nodes).
EncodeStatus EncodeNmt(std::uint8_t command, int target_node, Frame& out);
/// Decodes an NMT frame addressed to `node` (or to all nodes). kWrongId also when addressed to another node.
DecodeStatus DecodeNmt(int node, const Frame& frame, std::uint8_t& command);

/// What a SocketCAN error frame (id with kErrFlag, linux/can/error.h) says about the bus.
struct ErrorFrameInfo {
  bool bus_off = false;
  bool restarted = false;      // the controller recovered from bus-off
  bool error_passive = false;  // rx or tx error passive
  bool error_warning = false;  // rx or tx error warning
  bool back_to_active = false;
  bool rx_overflow = false;  // controller rx buffer overflow
  bool tx_timeout = false;
  bool protocol_or_bus_error = false;  // protocol violation, transceiver, no ack, bus error, lost arbitration
};
/// Decodes a SocketCAN error frame; kWrongId if `frame` is not one. Real-time safe.
DecodeStatus DecodeErrorFrame(const Frame& frame, ErrorFrameInfo& out);

// Linux error-frame class bits (in the id) and controller-status bits (data[1]), from linux/can/error.h.
inline constexpr std::uint32_t kErrTxTimeout = 0x001;
inline constexpr std::uint32_t kErrLostArb = 0x002;
inline constexpr std::uint32_t kErrCrtl = 0x004;
inline constexpr std::uint32_t kErrProt = 0x008;
inline constexpr std::uint32_t kErrTrx = 0x010;
inline constexpr std::uint32_t kErrAck = 0x020;
inline constexpr std::uint32_t kErrBusOff = 0x040;
inline constexpr std::uint32_t kErrBusError = 0x080;
inline constexpr std::uint32_t kErrRestarted = 0x100;
inline constexpr std::uint8_t kCrtlRxOverflow = 0x01;
inline constexpr std::uint8_t kCrtlTxOverflow = 0x02;
inline constexpr std::uint8_t kCrtlRxWarning = 0x04;
inline constexpr std::uint8_t kCrtlTxWarning = 0x08;
inline constexpr std::uint8_t kCrtlRxPassive = 0x10;
inline constexpr std::uint8_t kCrtlTxPassive = 0x20;
inline constexpr std::uint8_t kCrtlActive = 0x40;

}  // namespace visco::drivers::can
