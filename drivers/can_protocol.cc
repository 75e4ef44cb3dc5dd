#include "drivers/can_protocol.h"

#include <algorithm>
#include <cmath>

namespace visco::drivers::can {
namespace {

bool ValidNode(int node) { return node >= kMinNode && node <= kMaxNode; }

// True if `frame` is a plain data frame (standard id, no RTR/error flag) with id `expected`.
bool IsDataFrame(const Frame& frame, std::uint32_t expected) {
  return (frame.id & (kEffFlag | kRtrFlag | kErrFlag)) == 0 && frame.id == expected;
}

void PutU16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v & 0xFF);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
std::uint16_t GetU16(const std::uint8_t* p) { return static_cast<std::uint16_t>(p[0] | (p[1] << 8)); }
void PutI16(std::uint8_t* p, std::int16_t v) { PutU16(p, static_cast<std::uint16_t>(v)); }
std::int16_t GetI16(const std::uint8_t* p) { return static_cast<std::int16_t>(GetU16(p)); }
void PutI24(std::uint8_t* p, std::int32_t v) {
  const auto u = static_cast<std::uint32_t>(v);
  p[0] = static_cast<std::uint8_t>(u & 0xFF);
  p[1] = static_cast<std::uint8_t>((u >> 8) & 0xFF);
  p[2] = static_cast<std::uint8_t>((u >> 16) & 0xFF);
}
std::int32_t GetI24(const std::uint8_t* p) {
  std::uint32_t u = static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
                    (static_cast<std::uint32_t>(p[2]) << 16);
  if (u & 0x800000U) u |= 0xFF000000U;  // sign-extend
  return static_cast<std::int32_t>(u);
}

// Rounds value/scale to the nearest integer and saturates to [lo, hi]; NaN becomes 0.
std::int32_t Quantise(double value, double scale, std::int32_t lo, std::int32_t hi) {
  if (std::isnan(value)) return 0;
  const double raw = std::nearbyint(value / scale);
  if (raw <= lo) return lo;
  if (raw >= hi) return hi;
  return static_cast<std::int32_t>(raw);
}

constexpr std::int32_t kI16Min = -32768;
constexpr std::int32_t kI16Max = 32767;
constexpr std::int32_t kI24Min = -8388608;
constexpr std::int32_t kI24Max = 8388607;

// Finishes a checksummed 8-byte frame of a session.
void Seal(Frame& frame, std::uint32_t session, std::uint32_t counter) {
  frame.dlc = 8;
  frame.data[7] = SessionCrc(frame.id, session, counter, frame.data);
}

// Checks id, length, counter byte and CRC of a checksummed 8-byte frame of a session.
DecodeStatus CheckSealed(const Frame& frame, std::uint32_t expected_id, std::uint32_t session, std::uint32_t counter) {
  if (!IsDataFrame(frame, expected_id)) return DecodeStatus::kWrongId;
  if (frame.dlc != 8) return DecodeStatus::kBadLength;
  if (frame.data[0] != (counter & 0xFF) || SessionCrc(frame.id, session, counter, frame.data) != frame.data[7]) {
    return DecodeStatus::kBadChecksum;
  }
  return DecodeStatus::kOk;
}

bool CommandCrcOk(const Frame& frame, std::uint32_t session, std::uint32_t counter) {
  return SessionCrc(frame.id, session, counter, frame.data) == frame.data[7];
}

}  // namespace

const char* ToString(DecodeStatus status) {
  switch (status) {
    case DecodeStatus::kOk:
      return "ok";
    case DecodeStatus::kWrongId:
      return "wrong id";
    case DecodeStatus::kBadLength:
      return "bad length";
    case DecodeStatus::kBadChecksum:
      return "bad checksum";
    case DecodeStatus::kBadReserved:
      return "reserved bits set";
  }
  return "?";
}

const char* ToString(EncodeStatus status) {
  switch (status) {
    case EncodeStatus::kOk:
      return "ok";
    case EncodeStatus::kOutOfRange:
      return "out of range";
    case EncodeStatus::kBadNode:
      return "bad node id";
    case EncodeStatus::kNotFinite:
      return "not finite";
  }
  return "?";
}

std::uint8_t Crc8SaeJ1850(const std::uint8_t* bytes, int size) {
  std::uint8_t crc = 0xFF;
  for (int i = 0; i < size; ++i) {
    crc ^= bytes[i];
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x80) ? static_cast<std::uint8_t>((crc << 1) ^ 0x1D) : static_cast<std::uint8_t>(crc << 1);
    }
  }
  return static_cast<std::uint8_t>(crc ^ 0xFF);
}

std::uint8_t FrameCrc(std::uint32_t id, const std::uint8_t* data7) {
  std::uint8_t bytes[9];
  const std::uint32_t sff = id & kSffMask;
  bytes[0] = static_cast<std::uint8_t>(sff & 0xFF);
  bytes[1] = static_cast<std::uint8_t>(sff >> 8);
  for (int i = 0; i < 7; ++i) bytes[2 + i] = data7[i];
  return Crc8SaeJ1850(bytes, 9);
}

namespace {
std::uint32_t Fmix32(std::uint32_t h) {
  h ^= h >> 16;
  h *= 0x85EBCA6BU;
  h ^= h >> 13;
  h *= 0xC2B2AE35U;
  h ^= h >> 16;
  return h;
}
}  // namespace

std::uint32_t SessionKey(std::uint32_t id, std::uint32_t session, std::uint32_t counter) {
  return Fmix32(session ^ Fmix32(counter ^ Fmix32(id & kSffMask)));
}

std::uint8_t SessionCrc(std::uint32_t id, std::uint32_t session, std::uint32_t counter, const std::uint8_t* data7) {
  std::uint8_t bytes[16];
  const std::uint32_t sff = id & kSffMask;
  bytes[0] = static_cast<std::uint8_t>(sff & 0xFF);
  bytes[1] = static_cast<std::uint8_t>(sff >> 8);
  const std::uint32_t key = SessionKey(sff, session, counter);
  for (int i = 0; i < 4; ++i) bytes[2 + i] = static_cast<std::uint8_t>(key >> (8 * i));
  for (int i = 0; i < 3; ++i) bytes[6 + i] = static_cast<std::uint8_t>(counter >> (8 * (i + 1)));
  for (int i = 0; i < 7; ++i) bytes[9 + i] = data7[i];
  return Crc8SaeJ1850(bytes, 16);
}

const char* ToString(CommandVerdict verdict) {
  switch (verdict) {
    case CommandVerdict::kAccept:
      return "accepted";
    case CommandVerdict::kStale:
      return "stale (a duplicate or a replay)";
    case CommandVerdict::kAhead:
      return "too far ahead";
    case CommandVerdict::kWrongSession:
      return "of another session";
    case CommandVerdict::kBadChecksum:
      return "bad checksum";
    case CommandVerdict::kRepeat:
      return "a copy of an accepted frame (a replay)";
  }
  return "?";
}

CommandVerdict JudgeCommand(const Frame& frame, std::uint32_t session, std::uint32_t last, std::uint32_t window,
                            std::uint32_t& seq, const FrameHistory* accepted) {
  if (frame.data[6] != (session & 0xFF)) return CommandVerdict::kWrongSession;
  const std::uint32_t ahead = CounterAhead(last, frame.data[0]);  // last + 1..256
  if (ahead - last <= window && CommandCrcOk(frame, session, ahead)) {
    seq = ahead;
    return accepted != nullptr && accepted->Contains(frame) ? CommandVerdict::kRepeat : CommandVerdict::kAccept;
  }
  const std::uint32_t behind = ahead - 256;  // last - 0..255
  if (CommandCrcOk(frame, session, behind)) {
    seq = behind;
    return CommandVerdict::kStale;
  }
  if (ahead - last > window && CommandCrcOk(frame, session, ahead)) {
    seq = ahead;
    return CommandVerdict::kAhead;
  }
  return CommandVerdict::kBadChecksum;
}

namespace {
std::uint64_t FrameBytes(const Frame& frame) {
  std::uint64_t key = 0;
  for (int i = 0; i < 8; ++i) key |= static_cast<std::uint64_t>(frame.data[i]) << (8 * i);
  return key;
}
}  // namespace

bool FrameHistory::Contains(const Frame& frame) const {
  return have_[frame.data[0]] && frames_[frame.data[0]] == FrameBytes(frame);
}

void FrameHistory::Add(const Frame& frame) {
  frames_[frame.data[0]] = FrameBytes(frame);
  have_[frame.data[0]] = true;
}

void FrameHistory::Clear() { std::fill(std::begin(have_), std::end(have_), false); }

FrameKind Classify(const Frame& frame, int node) {
  if (frame.id & kErrFlag) return FrameKind::kError;
  if (frame.id & (kEffFlag | kRtrFlag)) return FrameKind::kOther;
  const std::uint32_t id = frame.id & kSffMask;
  if (id == kNmtId) return FrameKind::kNmt;
  if (!ValidNode(node)) return FrameKind::kOther;
  const auto n = static_cast<std::uint32_t>(node);
  if (id == kEmcyBase + n) return FrameKind::kEmcy;
  if (id == kStatusBase + n) return FrameKind::kStatus;
  if (id == kCommandBase + n) return FrameKind::kCommand;
  if (id == kPositionBase + n) return FrameKind::kPosition;
  if (id == kForceBase + n) return FrameKind::kForce;
  if (id == kSessionBase + n) return FrameKind::kSession;
  if (id == kHeartbeatBase + n) return FrameKind::kHeartbeat;
  return FrameKind::kOther;
}

EncodeStatus EncodeCommand(int node, const CommandFrame& command, Frame& out) {
  if (!ValidNode(node)) return EncodeStatus::kBadNode;
  for (double v : command.velocity) {
    if (!std::isfinite(v)) return EncodeStatus::kNotFinite;
    const double raw = std::nearbyint(v / kVelocityScale);
    if (raw < kI16Min + 1 || raw > kI16Max) return EncodeStatus::kOutOfRange;
  }
  out = Frame{};
  out.id = kCommandBase + static_cast<std::uint32_t>(node);
  out.data[0] = static_cast<std::uint8_t>(command.seq & 0xFF);
  out.data[1] = static_cast<std::uint8_t>((command.estop ? kFlagEStop : 0) | (command.reset ? kFlagReset : 0) |
                                          (command.quick_stop ? kFlagQuickStop : 0));
  PutI16(&out.data[2], static_cast<std::int16_t>(Quantise(command.velocity[0], kVelocityScale, kI16Min, kI16Max)));
  PutI16(&out.data[4], static_cast<std::int16_t>(Quantise(command.velocity[1], kVelocityScale, kI16Min, kI16Max)));
  out.data[6] = static_cast<std::uint8_t>(command.session & 0xFF);
  Seal(out, command.session, command.seq);
  return EncodeStatus::kOk;
}

DecodeStatus DecodeCommand(int node, const Frame& frame, CommandFrame& out) {
  if (!ValidNode(node)) return DecodeStatus::kWrongId;
  if (!IsDataFrame(frame, kCommandBase + static_cast<std::uint32_t>(node))) return DecodeStatus::kWrongId;
  if (frame.dlc != 8) return DecodeStatus::kBadLength;
  const std::uint8_t flags = frame.data[1];
  if ((flags & ~(kFlagEStop | kFlagReset | kFlagQuickStop)) != 0) return DecodeStatus::kBadReserved;
  const std::int16_t vx = GetI16(&frame.data[2]);
  const std::int16_t vy = GetI16(&frame.data[4]);
  // -32768 is reserved so that the range is symmetric.
  if (vx == kI16Min || vy == kI16Min) return DecodeStatus::kBadReserved;
  out.seq = frame.data[0];
  out.session = frame.data[6];
  out.estop = (flags & kFlagEStop) != 0;
  out.reset = (flags & kFlagReset) != 0;
  out.quick_stop = (flags & kFlagQuickStop) != 0;
  out.velocity[0] = vx * kVelocityScale;
  out.velocity[1] = vy * kVelocityScale;
  return DecodeStatus::kOk;
}

EncodeStatus EncodeStatusFrames(int node, const StatusFrames& status, Frame out[3]) {
  if (!ValidNode(node)) return EncodeStatus::kBadNode;
  const auto n = static_cast<std::uint32_t>(node);
  Frame& s = out[0];
  s = Frame{};
  s.id = kStatusBase + n;
  s.data[0] = static_cast<std::uint8_t>(status.seq & 0xFF);
  s.data[1] = status.command_seq;
  PutI16(&s.data[2], static_cast<std::int16_t>(Quantise(status.velocity[0], kVelocityScale, kI16Min + 1, kI16Max)));
  PutI16(&s.data[4], static_cast<std::int16_t>(Quantise(status.velocity[1], kVelocityScale, kI16Min + 1, kI16Max)));
  s.data[6] = static_cast<std::uint8_t>((static_cast<std::uint8_t>(status.state) & 0x0F) | (status.contact ? 0x10 : 0));
  Seal(s, status.session, status.seq);

  Frame& p = out[1];
  p = Frame{};
  p.id = kPositionBase + n;
  p.data[0] = static_cast<std::uint8_t>(status.seq & 0xFF);
  PutI24(&p.data[1], Quantise(status.position[0], kPositionScale, kI24Min + 1, kI24Max));
  PutI24(&p.data[4], Quantise(status.position[1], kPositionScale, kI24Min + 1, kI24Max));
  Seal(p, status.session, status.seq);

  Frame& f = out[2];
  f = Frame{};
  f.id = kForceBase + n;
  f.data[0] = static_cast<std::uint8_t>(status.seq & 0xFF);
  PutI16(&f.data[1], static_cast<std::int16_t>(Quantise(status.contact_force[0], kForceScale, kI16Min + 1, kI16Max)));
  PutI16(&f.data[3], static_cast<std::int16_t>(Quantise(status.contact_force[1], kForceScale, kI16Min + 1, kI16Max)));
  PutU16(&f.data[5], static_cast<std::uint16_t>(status.fault_bits & fault_bits::kAll));
  Seal(f, status.session, status.seq);
  return EncodeStatus::kOk;
}

DecodeStatus DecodeStatusFrame(int node, const Frame& frame, std::uint32_t session, std::uint32_t seq,
                               StatusFrames& out) {
  if (!ValidNode(node)) return DecodeStatus::kWrongId;
  const DecodeStatus status = CheckSealed(frame, kStatusBase + static_cast<std::uint32_t>(node), session, seq);
  if (status != DecodeStatus::kOk) return status;
  const std::uint8_t state_byte = frame.data[6];
  const std::uint8_t state = state_byte & 0x0F;
  if ((state_byte & 0xE0) != 0 || state > static_cast<std::uint8_t>(RobotState::kEStop)) {
    return DecodeStatus::kBadReserved;
  }
  out.seq = seq;
  out.session = session;
  out.command_seq = frame.data[1];
  out.velocity[0] = GetI16(&frame.data[2]) * kVelocityScale;
  out.velocity[1] = GetI16(&frame.data[4]) * kVelocityScale;
  out.state = static_cast<RobotState>(state);
  out.contact = (state_byte & 0x10) != 0;
  return DecodeStatus::kOk;
}

DecodeStatus DecodePositionFrame(int node, const Frame& frame, std::uint32_t session, std::uint32_t seq,
                                 StatusFrames& out) {
  if (!ValidNode(node)) return DecodeStatus::kWrongId;
  const DecodeStatus status = CheckSealed(frame, kPositionBase + static_cast<std::uint32_t>(node), session, seq);
  if (status != DecodeStatus::kOk) return status;
  out.seq = seq;
  out.session = session;
  out.position[0] = GetI24(&frame.data[1]) * kPositionScale;
  out.position[1] = GetI24(&frame.data[4]) * kPositionScale;
  return DecodeStatus::kOk;
}

DecodeStatus DecodeForceFrame(int node, const Frame& frame, std::uint32_t session, std::uint32_t seq,
                              StatusFrames& out) {
  if (!ValidNode(node)) return DecodeStatus::kWrongId;
  const DecodeStatus status = CheckSealed(frame, kForceBase + static_cast<std::uint32_t>(node), session, seq);
  if (status != DecodeStatus::kOk) return status;
  const std::uint16_t bits = GetU16(&frame.data[5]);
  if ((bits & ~fault_bits::kAll) != 0) return DecodeStatus::kBadReserved;
  out.seq = seq;
  out.session = session;
  out.contact_force[0] = GetI16(&frame.data[1]) * kForceScale;
  out.contact_force[1] = GetI16(&frame.data[3]) * kForceScale;
  out.fault_bits = bits;
  return DecodeStatus::kOk;
}

EncodeStatus EncodeSession(int node, const SessionFrame& session, Frame& out) {
  if (!ValidNode(node)) return EncodeStatus::kBadNode;
  if (session.session == 0 || session.status_epoch > 0xFFFFFFU) return EncodeStatus::kOutOfRange;
  out = Frame{};
  out.id = kSessionBase + static_cast<std::uint32_t>(node);
  for (int i = 0; i < 4; ++i) out.data[i] = static_cast<std::uint8_t>(session.session >> (8 * i));
  PutI24(&out.data[4], static_cast<std::int32_t>(session.status_epoch));
  out.dlc = 8;
  out.data[7] = FrameCrc(out.id, out.data);
  return EncodeStatus::kOk;
}

DecodeStatus DecodeSession(int node, const Frame& frame, SessionFrame& out) {
  if (!ValidNode(node) || !IsDataFrame(frame, kSessionBase + static_cast<std::uint32_t>(node))) {
    return DecodeStatus::kWrongId;
  }
  if (frame.dlc != 8) return DecodeStatus::kBadLength;
  if (FrameCrc(frame.id, frame.data) != frame.data[7]) return DecodeStatus::kBadChecksum;
  const std::uint32_t nonce =
      static_cast<std::uint32_t>(frame.data[0]) | (static_cast<std::uint32_t>(frame.data[1]) << 8) |
      (static_cast<std::uint32_t>(frame.data[2]) << 16) | (static_cast<std::uint32_t>(frame.data[3]) << 24);
  if (nonce == 0) return DecodeStatus::kBadReserved;
  out.session = nonce;
  out.status_epoch = static_cast<std::uint32_t>(GetI24(&frame.data[4])) & 0xFFFFFFU;
  return DecodeStatus::kOk;
}

EncodeStatus EncodeHeartbeat(int node, NmtState state, Frame& out) {
  if (!ValidNode(node)) return EncodeStatus::kBadNode;
  out = Frame{};
  out.id = kHeartbeatBase + static_cast<std::uint32_t>(node);
  out.dlc = 1;
  out.data[0] = static_cast<std::uint8_t>(state);
  return EncodeStatus::kOk;
}

DecodeStatus DecodeHeartbeat(int node, const Frame& frame, NmtState& out) {
  if (!ValidNode(node) || !IsDataFrame(frame, kHeartbeatBase + static_cast<std::uint32_t>(node))) {
    return DecodeStatus::kWrongId;
  }
  if (frame.dlc != 1) return DecodeStatus::kBadLength;
  switch (frame.data[0]) {
    case static_cast<std::uint8_t>(NmtState::kBootUp):
    case static_cast<std::uint8_t>(NmtState::kStopped):
    case static_cast<std::uint8_t>(NmtState::kOperational):
    case static_cast<std::uint8_t>(NmtState::kPreOperational):
      out = static_cast<NmtState>(frame.data[0]);
      return DecodeStatus::kOk;
    default:
      return DecodeStatus::kBadReserved;
  }
}

EncodeStatus EncodeEmcy(int node, const EmcyFrame& emcy, Frame& out) {
  if (!ValidNode(node)) return EncodeStatus::kBadNode;
  out = Frame{};
  out.id = kEmcyBase + static_cast<std::uint32_t>(node);
  out.dlc = 8;
  PutU16(&out.data[0], emcy.error_code);
  out.data[2] = emcy.error_register;
  out.data[3] = emcy.code;
  PutU16(&out.data[4], static_cast<std::uint16_t>(emcy.fault_bits & fault_bits::kAll));
  out.data[6] = static_cast<std::uint8_t>((emcy.robot_stopped ? 0x01 : 0) | (emcy.cleared ? 0x02 : 0));
  out.data[7] = emcy.counter;
  return EncodeStatus::kOk;
}

DecodeStatus DecodeEmcy(int node, const Frame& frame, EmcyFrame& out) {
  if (!ValidNode(node) || !IsDataFrame(frame, kEmcyBase + static_cast<std::uint32_t>(node))) {
    return DecodeStatus::kWrongId;
  }
  if (frame.dlc != 8) return DecodeStatus::kBadLength;
  if ((frame.data[6] & ~0x03) != 0) return DecodeStatus::kBadReserved;
  out.error_code = GetU16(&frame.data[0]);
  out.error_register = frame.data[2];
  out.code = frame.data[3];
  out.fault_bits = static_cast<std::uint16_t>(GetU16(&frame.data[4]) & fault_bits::kAll);
  out.robot_stopped = (frame.data[6] & 0x01) != 0;
  out.cleared = (frame.data[6] & 0x02) != 0;
  out.counter = frame.data[7];
  return DecodeStatus::kOk;
}

EncodeStatus EncodeNmt(std::uint8_t command, int target_node, Frame& out) {
  if (target_node != 0 && !ValidNode(target_node)) return EncodeStatus::kBadNode;
  out = Frame{};
  out.id = kNmtId;
  out.dlc = 2;
  out.data[0] = command;
  out.data[1] = static_cast<std::uint8_t>(target_node);
  return EncodeStatus::kOk;
}

DecodeStatus DecodeNmt(int node, const Frame& frame, std::uint8_t& command) {
  if (!IsDataFrame(frame, kNmtId)) return DecodeStatus::kWrongId;
  if (frame.dlc != 2) return DecodeStatus::kBadLength;
  if (frame.data[1] != 0 && frame.data[1] != node) return DecodeStatus::kWrongId;
  switch (frame.data[0]) {
    case kNmtStart:
    case kNmtStop:
    case kNmtPreOperational:
    case kNmtResetNode:
    case kNmtResetCommunication:
      command = frame.data[0];
      return DecodeStatus::kOk;
    default:
      return DecodeStatus::kBadReserved;
  }
}

DecodeStatus DecodeErrorFrame(const Frame& frame, ErrorFrameInfo& out) {
  if ((frame.id & kErrFlag) == 0) return DecodeStatus::kWrongId;
  const std::uint32_t cls = frame.id & 0x1FFFFFFFU;
  const std::uint8_t crtl = frame.dlc >= 2 ? frame.data[1] : 0;
  out = ErrorFrameInfo{};
  out.bus_off = (cls & kErrBusOff) != 0;
  out.restarted = (cls & kErrRestarted) != 0;
  out.tx_timeout = (cls & kErrTxTimeout) != 0;
  out.protocol_or_bus_error = (cls & (kErrLostArb | kErrProt | kErrTrx | kErrAck | kErrBusError)) != 0;
  if (cls & kErrCrtl) {
    out.error_passive = (crtl & (kCrtlRxPassive | kCrtlTxPassive)) != 0;
    out.error_warning = (crtl & (kCrtlRxWarning | kCrtlTxWarning)) != 0;
    out.back_to_active = (crtl & kCrtlActive) != 0;
    out.rx_overflow = (crtl & (kCrtlRxOverflow | kCrtlTxOverflow)) != 0;
  }
  return DecodeStatus::kOk;
}

}  // namespace visco::drivers::can
