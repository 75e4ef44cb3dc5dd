#pragma once
// CANopen (CiA 301) and the CiA 402 drive profile, as far as a velocity master needs them: NMT, SYNC, heartbeat,
// expedited SDO, EMCY, the drive's state machine (statusword -> state, controlword toward a wanted state) and the PDOs
// the CiA 402 backend maps (drivers/cia402_robot.h). Written by hand from the specifications: no CANopen stack is
// packaged for Debian. Pure encode/decode: real-time safe (no allocation, no exception, no I/O).
//
// The PDOs the backend maps on every drive (node n), all classic 8-byte-or-less frames, little-endian:
//   RPDO1 0x200+n  master->drive  controlword 0x6040 (u16), target velocity 0x60FF (i32)          6 bytes
//   TPDO1 0x180+n  drive->master  statusword 0x6041 (u16), velocity actual value 0x606C (i32)     6 bytes
//   TPDO2 0x280+n  drive->master  position actual value 0x6064 (i32)                              4 bytes
// TPDOs are synchronous (transmission type 1: every SYNC); RPDO1 is asynchronous (255) in profile velocity mode and
// synchronous (1: applied at the next SYNC) in cyclic synchronous velocity mode.

#include <cstdint>

#include "drivers/can_protocol.h"

namespace visco::drivers::cia402 {

using can::Frame;

// CiA 301 predefined connection set.
inline constexpr std::uint32_t kNmt = 0x000;
inline constexpr std::uint32_t kSync = 0x080;
inline constexpr std::uint32_t kEmcy = 0x080;  // + node
inline constexpr std::uint32_t kTpdo1 = 0x180;
inline constexpr std::uint32_t kRpdo1 = 0x200;
inline constexpr std::uint32_t kTpdo2 = 0x280;
inline constexpr std::uint32_t kSdoServerToClient = 0x580;  // + node: the drive's SDO answers
inline constexpr std::uint32_t kSdoClientToServer = 0x600;  // + node: the master's SDO requests
inline constexpr std::uint32_t kHeartbeat = 0x700;

// NMT commands and states (CiA 301 7.2.8.3).
inline constexpr std::uint8_t kNmtStart = 0x01;
inline constexpr std::uint8_t kNmtStop = 0x02;
inline constexpr std::uint8_t kNmtEnterPreOperational = 0x80;
inline constexpr std::uint8_t kNmtResetNode = 0x81;
inline constexpr std::uint8_t kNmtResetCommunication = 0x82;
inline constexpr std::uint8_t kStateBootUp = 0x00;
inline constexpr std::uint8_t kStateStopped = 0x04;
inline constexpr std::uint8_t kStateOperational = 0x05;
inline constexpr std::uint8_t kStatePreOperational = 0x7F;
const char* NmtStateName(std::uint8_t state);

// Objects (CiA 301, CiA 402).
inline constexpr std::uint16_t kDeviceType = 0x1000;
inline constexpr std::uint16_t kConsumerHeartbeatTime = 0x1016;
inline constexpr std::uint16_t kProducerHeartbeatTime = 0x1017;
inline constexpr std::uint16_t kRpdo1Communication = 0x1400;
inline constexpr std::uint16_t kRpdo1Mapping = 0x1600;
inline constexpr std::uint16_t kTpdo1Communication = 0x1800;
inline constexpr std::uint16_t kTpdo1Mapping = 0x1A00;
inline constexpr std::uint16_t kControlword = 0x6040;
inline constexpr std::uint16_t kStatusword = 0x6041;
inline constexpr std::uint16_t kQuickStopOptionCode = 0x605A;
inline constexpr std::uint16_t kModesOfOperation = 0x6060;
inline constexpr std::uint16_t kPositionActualValue = 0x6064;
inline constexpr std::uint16_t kVelocityActualValue = 0x606C;
inline constexpr std::uint16_t kMaxProfileVelocity = 0x607F;
inline constexpr std::uint16_t kProfileAcceleration = 0x6083;
inline constexpr std::uint16_t kProfileDeceleration = 0x6084;
inline constexpr std::uint16_t kQuickStopDeceleration = 0x6085;
inline constexpr std::uint16_t kTargetVelocity = 0x60FF;
inline constexpr std::uint16_t kSupportedDriveModes = 0x6502;
inline constexpr std::uint16_t kDeviceProfile402 = 402;  // 0x1000 bits 0..15
inline constexpr std::int8_t kModeProfileVelocity = 3;
inline constexpr std::int8_t kModeCyclicSynchronousVelocity = 9;

/// A PDO mapping entry (CiA 301 7.4.7.1): index << 16 | subindex << 8 | length in bits.
constexpr std::uint32_t MappingEntry(std::uint16_t index, std::uint8_t sub, std::uint8_t bits) {
  return static_cast<std::uint32_t>(index) << 16 | static_cast<std::uint32_t>(sub) << 8 | bits;
}
inline constexpr std::uint32_t kPdoInvalid = 0x80000000U;  // COB-ID bit 31: the PDO does not exist (disabled)

Frame Nmt(std::uint8_t command, int node);  // node 1..127 (the backend never broadcasts to node 0)
Frame Sync();
Frame Heartbeat(int node, std::uint8_t state);

// Expedited SDO (CiA 301 7.2.4.3): 4 data bytes at most.
/// Download (write) `size` bytes (1, 2 or 4) of `value` to index:sub of `node`.
Frame SdoDownload(int node, std::uint16_t index, std::uint8_t sub, std::uint32_t value, int size);
/// Upload (read) index:sub of `node`.
Frame SdoUpload(int node, std::uint16_t index, std::uint8_t sub);

enum class SdoReplyKind : std::uint8_t { kDownloaded, kUploaded, kAborted, kUnsupported };
struct SdoReply {
  SdoReplyKind kind = SdoReplyKind::kUnsupported;
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint32_t value = 0;  // kUploaded: the value (size bytes, zero-extended); kAborted: the abort code
  int size = 0;             // kUploaded: bytes (1..4); 0 when the drive did not say
};
/// Decodes a drive's answer on 0x580+node; false for a frame of another id or shorter than 8 bytes. A segmented or
/// block transfer's answer is kUnsupported.
bool DecodeSdoReply(int node, const Frame& frame, SdoReply& out);
/// CiA 301 table 22, the SDO abort codes, in words ("" never: an unknown code gives "unknown abort code").
const char* SdoAbortText(std::uint32_t code);

// EMCY (CiA 301 7.2.7): error code, error register, 5 manufacturer bytes.
struct Emcy {
  std::uint16_t code = 0;
  std::uint8_t error_register = 0;
};
bool DecodeEmcy(int node, const Frame& frame, Emcy& out);
/// The error code's meaning (CiA 301 table 21 and CiA 402's drive codes), most specific first.
const char* EmcyText(std::uint16_t code);

// The CiA 402 state machine (CiA 402-2 figure "State machine"; statusword bits 0-3, 5, 6).
enum class DriveState : std::uint8_t {
  kNotReadyToSwitchOn,
  kSwitchOnDisabled,
  kReadyToSwitchOn,
  kSwitchedOn,
  kOperationEnabled,
  kQuickStopActive,
  kFaultReactionActive,
  kFault,
};
DriveState StateOf(std::uint16_t statusword);
const char* ToString(DriveState state);

// Controlword commands (bits 7, 3..0).
inline constexpr std::uint16_t kCwDisableVoltage = 0x0000;
inline constexpr std::uint16_t kCwQuickStop = 0x0002;
inline constexpr std::uint16_t kCwShutdown = 0x0006;
inline constexpr std::uint16_t kCwSwitchOn = 0x0007;  // also "disable operation"
inline constexpr std::uint16_t kCwEnableOperation = 0x000F;
inline constexpr std::uint16_t kCwFaultReset = 0x0080;  // its rising edge

/// What the master wants of a drive.
enum class Want : std::uint8_t {
  kDisabled,    // switch on disabled (no power)
  kSwitchedOn,  // power on, drive function disabled (the driver is DISABLED)
  kEnabled,     // operation enabled, following the target velocity (READY/MOVING), through a fault reset if needed
  kQuickStop,   // quick stop (every stop of the driver)
};
/// The controlword that moves a drive in `state` one transition toward `want`; `previous` is the last controlword
/// sent (a fault reset needs a rising edge of bit 7: 0x80 and 0x00 alternate while the drive stays in FAULT).
std::uint16_t ControlwordToward(DriveState state, Want want, std::uint16_t previous);

Frame Rpdo1(int node, std::uint16_t controlword, std::int32_t target_velocity);
bool DecodeTpdo1(int node, const Frame& frame, std::uint16_t& statusword, std::int32_t& velocity);
bool DecodeTpdo2(int node, const Frame& frame, std::int32_t& position);

}  // namespace visco::drivers::cia402
