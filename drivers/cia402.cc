#include "drivers/cia402.h"

namespace visco::drivers::cia402 {
namespace {

void PutU16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
void PutU32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
std::uint16_t GetU16(const std::uint8_t* p) { return static_cast<std::uint16_t>(p[0] | p[1] << 8); }
std::uint32_t GetU32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}
bool IsData(const Frame& frame, std::uint32_t id) {
  return (frame.id & (can::kEffFlag | can::kRtrFlag | can::kErrFlag)) == 0 && frame.id == id;
}

struct Text {
  std::uint32_t code;
  const char* text;
};

// CiA 301 table 22.
constexpr Text kAbortCodes[] = {
    {0x05030000, "toggle bit not alternated"},
    {0x05040000, "SDO protocol timed out"},
    {0x05040001, "client/server command specifier not valid or unknown"},
    {0x05040002, "invalid block size"},
    {0x05040003, "invalid sequence number"},
    {0x05040004, "CRC error"},
    {0x05040005, "out of memory"},
    {0x06010000, "unsupported access to an object"},
    {0x06010001, "attempt to read a write-only object"},
    {0x06010002, "attempt to write a read-only object"},
    {0x06020000, "object does not exist in the object dictionary"},
    {0x06040041, "object cannot be mapped to the PDO"},
    {0x06040042, "the number and length of the objects to be mapped would exceed the PDO length"},
    {0x06040043, "general parameter incompatibility"},
    {0x06040047, "general internal incompatibility in the device"},
    {0x06060000, "access failed due to a hardware error"},
    {0x06070010, "data type does not match, length of service parameter does not match"},
    {0x06070012, "data type does not match, length of service parameter too high"},
    {0x06070013, "data type does not match, length of service parameter too low"},
    {0x06090011, "sub-index does not exist"},
    {0x06090030, "invalid value for parameter"},
    {0x06090031, "value of parameter written too high"},
    {0x06090032, "value of parameter written too low"},
    {0x06090036, "maximum value is less than minimum value"},
    {0x060A0023, "resource not available: SDO connection"},
    {0x08000000, "general error"},
    {0x08000020, "data cannot be transferred or stored to the application"},
    {0x08000021, "data cannot be transferred or stored to the application because of local control"},
    {0x08000022, "data cannot be transferred or stored to the application because of the present device state"},
    {0x08000023, "object dictionary dynamic generation failed or no object dictionary is present"},
    {0x08000024, "no data available"},
};

// CiA 301 table 21 and the drive codes of CiA 402; EmcyText falls back to the class (high byte, then high nibble).
constexpr Text kEmcyCodes[] = {
    {0x0000, "error reset or no error"},
    {0x1000, "generic error"},
    {0x2000, "current"},
    {0x2100, "current, device input side"},
    {0x2200, "current inside the device"},
    {0x2300, "current, device output side"},
    {0x2310, "continuous over-current"},
    {0x2320, "short circuit / earth leakage"},
    {0x3000, "voltage"},
    {0x3100, "mains voltage"},
    {0x3200, "voltage inside the device"},
    {0x3210, "DC link over-voltage"},
    {0x3220, "DC link under-voltage"},
    {0x3300, "output voltage"},
    {0x4000, "temperature"},
    {0x4100, "ambient temperature"},
    {0x4200, "device temperature"},
    {0x4210, "excess temperature of the device"},
    {0x4310, "excess temperature of the drive"},
    {0x5000, "device hardware"},
    {0x6000, "device software"},
    {0x6100, "internal software"},
    {0x6200, "user software"},
    {0x6300, "data set"},
    {0x7000, "additional modules"},
    {0x7300, "sensor"},
    {0x7305, "incremental sensor 1 fault"},
    {0x8000, "monitoring"},
    {0x8100, "communication"},
    {0x8110, "CAN overrun (objects lost)"},
    {0x8120, "CAN in error passive mode"},
    {0x8130, "life guard or heartbeat error"},
    {0x8140, "recovered from bus off"},
    {0x8150, "CAN-ID collision"},
    {0x8200, "protocol error"},
    {0x8210, "PDO not processed due to length error"},
    {0x8220, "PDO length exceeded"},
    {0x8240, "unexpected SYNC data length"},
    {0x8250, "RPDO timeout"},
    {0x8300, "torque control"},
    {0x8400, "velocity speed controller"},
    {0x8500, "position controller"},
    {0x8600, "positioning controller"},
    {0x8611, "following error"},
    {0x8612, "reference limit"},
    {0x9000, "external error"},
    {0xF000, "additional functions"},
    {0xFF00, "device specific"},
};

template <std::size_t N>
const char* Find(const Text (&table)[N], std::uint32_t code) {
  for (const Text& t : table) {
    if (t.code == code) return t.text;
  }
  return nullptr;
}

}  // namespace

const char* NmtStateName(std::uint8_t state) {
  switch (state) {
    case kStateBootUp:
      return "boot-up";
    case kStateStopped:
      return "stopped";
    case kStateOperational:
      return "operational";
    case kStatePreOperational:
      return "pre-operational";
    default:
      return "unknown NMT state";
  }
}

Frame Nmt(std::uint8_t command, int node) {
  Frame f;
  f.id = kNmt;
  f.dlc = 2;
  f.data[0] = command;
  f.data[1] = static_cast<std::uint8_t>(node);
  return f;
}

Frame Sync() {
  Frame f;
  f.id = kSync;
  f.dlc = 0;
  return f;
}

Frame Heartbeat(int node, std::uint8_t state) {
  Frame f;
  f.id = kHeartbeat + static_cast<std::uint32_t>(node);
  f.dlc = 1;
  f.data[0] = state;
  return f;
}

Frame SdoDownload(int node, std::uint16_t index, std::uint8_t sub, std::uint32_t value, int size) {
  Frame f;
  f.id = kSdoClientToServer + static_cast<std::uint32_t>(node);
  f.dlc = 8;
  // ccs = 1 (initiate download), n = 4 - size unused bytes, e = 1 (expedited), s = 1 (size indicated).
  f.data[0] = static_cast<std::uint8_t>(0x20 | ((4 - size) << 2) | 0x03);
  PutU16(&f.data[1], index);
  f.data[3] = sub;
  const std::uint32_t mask = size >= 4 ? 0xFFFFFFFFU : (1U << (8 * size)) - 1U;
  PutU32(&f.data[4], value & mask);
  return f;
}

Frame SdoUpload(int node, std::uint16_t index, std::uint8_t sub) {
  Frame f;
  f.id = kSdoClientToServer + static_cast<std::uint32_t>(node);
  f.dlc = 8;
  f.data[0] = 0x40;  // ccs = 2 (initiate upload)
  PutU16(&f.data[1], index);
  f.data[3] = sub;
  return f;
}

bool DecodeSdoReply(int node, const Frame& frame, SdoReply& out) {
  if (!IsData(frame, kSdoServerToClient + static_cast<std::uint32_t>(node)) || frame.dlc != 8) return false;
  out = SdoReply{};
  out.index = GetU16(&frame.data[1]);
  out.sub = frame.data[3];
  const std::uint8_t command = frame.data[0];
  switch (command >> 5) {
    case 3:  // scs = 3: initiate download response
      out.kind = SdoReplyKind::kDownloaded;
      return true;
    case 2:  // scs = 2: initiate upload response
      if ((command & 0x02) == 0) return out.kind = SdoReplyKind::kUnsupported, true;  // segmented
      out.kind = SdoReplyKind::kUploaded;
      out.size = (command & 0x01) != 0 ? 4 - ((command >> 2) & 0x03) : 0;
      out.value = GetU32(&frame.data[4]);
      if (out.size > 0 && out.size < 4) out.value &= (1U << (8 * out.size)) - 1U;
      return true;
    case 4:  // cs = 4: abort transfer
      out.kind = SdoReplyKind::kAborted;
      out.value = GetU32(&frame.data[4]);
      return true;
    default:
      out.kind = SdoReplyKind::kUnsupported;
      return true;
  }
}

const char* SdoAbortText(std::uint32_t code) {
  const char* text = Find(kAbortCodes, code);
  return text != nullptr ? text : "unknown abort code";
}

bool DecodeEmcy(int node, const Frame& frame, Emcy& out) {
  if (!IsData(frame, kEmcy + static_cast<std::uint32_t>(node)) || frame.dlc != 8) return false;
  out.code = GetU16(&frame.data[0]);
  out.error_register = frame.data[2];
  return true;
}

const char* EmcyText(std::uint16_t code) {
  if (const char* text = Find(kEmcyCodes, code)) return text;
  if (const char* text = Find(kEmcyCodes, code & 0xFFF0U)) return text;
  if (const char* text = Find(kEmcyCodes, code & 0xFF00U)) return text;
  if (const char* text = Find(kEmcyCodes, code & 0xF000U)) return text;
  return "unknown error code";
}

DriveState StateOf(std::uint16_t sw) {
  // CiA 402-2 table "Statusword": bits 6 (switch on disabled), 5 (quick stop), 3 (fault), 2 (operation enabled),
  // 1 (switched on), 0 (ready to switch on).
  if ((sw & 0x4F) == 0x00) return DriveState::kNotReadyToSwitchOn;
  if ((sw & 0x4F) == 0x40) return DriveState::kSwitchOnDisabled;
  if ((sw & 0x6F) == 0x21) return DriveState::kReadyToSwitchOn;
  if ((sw & 0x6F) == 0x23) return DriveState::kSwitchedOn;
  if ((sw & 0x6F) == 0x27) return DriveState::kOperationEnabled;
  if ((sw & 0x6F) == 0x07) return DriveState::kQuickStopActive;
  if ((sw & 0x4F) == 0x0F) return DriveState::kFaultReactionActive;
  if ((sw & 0x4F) == 0x08) return DriveState::kFault;
  return DriveState::kNotReadyToSwitchOn;  // a combination the profile does not define: treat as not ready
}

const char* ToString(DriveState state) {
  switch (state) {
    case DriveState::kNotReadyToSwitchOn:
      return "NOT READY TO SWITCH ON";
    case DriveState::kSwitchOnDisabled:
      return "SWITCH ON DISABLED";
    case DriveState::kReadyToSwitchOn:
      return "READY TO SWITCH ON";
    case DriveState::kSwitchedOn:
      return "SWITCHED ON";
    case DriveState::kOperationEnabled:
      return "OPERATION ENABLED";
    case DriveState::kQuickStopActive:
      return "QUICK STOP ACTIVE";
    case DriveState::kFaultReactionActive:
      return "FAULT REACTION ACTIVE";
    case DriveState::kFault:
      return "FAULT";
  }
  return "?";
}

std::uint16_t ControlwordToward(DriveState state, Want want, std::uint16_t previous) {
  switch (want) {
    case Want::kDisabled:
      return kCwDisableVoltage;  // transitions 7, 9, 10, 12: to SWITCH ON DISABLED
    case Want::kQuickStop:
      // From OPERATION ENABLED transition 11 (QUICK STOP ACTIVE); from READY/SWITCHED ON transitions 7/10 (SWITCH
      // ON DISABLED); in QUICK STOP ACTIVE the drive stays (option codes 5..8) or goes on to SWITCH ON DISABLED.
      return kCwQuickStop;
    case Want::kSwitchedOn:
      switch (state) {
        case DriveState::kSwitchOnDisabled:
          return kCwShutdown;  // transition 2
        case DriveState::kReadyToSwitchOn:
        case DriveState::kSwitchedOn:
        case DriveState::kOperationEnabled:
          return kCwSwitchOn;  // transitions 3 and 5 (disable operation)
        default:
          return kCwDisableVoltage;  // QUICK STOP ACTIVE: transition 12; FAULT is left to a reset
      }
    case Want::kEnabled:
      switch (state) {
        case DriveState::kSwitchOnDisabled:
          return kCwShutdown;  // transition 2
        case DriveState::kReadyToSwitchOn:
          return kCwSwitchOn;  // transition 3
        case DriveState::kSwitchedOn:
        case DriveState::kOperationEnabled:
        case DriveState::kQuickStopActive:
          return kCwEnableOperation;  // transitions 4 and 16
        case DriveState::kFault:
          return (previous & kCwFaultReset) != 0 ? kCwDisableVoltage : kCwFaultReset;  // transition 15: the edge
        case DriveState::kNotReadyToSwitchOn:
        case DriveState::kFaultReactionActive:
          return kCwDisableVoltage;  // the drive moves on by itself
      }
  }
  return kCwDisableVoltage;
}

Frame Rpdo1(int node, std::uint16_t controlword, std::int32_t target_velocity) {
  Frame f;
  f.id = kRpdo1 + static_cast<std::uint32_t>(node);
  f.dlc = 6;
  PutU16(&f.data[0], controlword);
  PutU32(&f.data[2], static_cast<std::uint32_t>(target_velocity));
  return f;
}

bool DecodeTpdo1(int node, const Frame& frame, std::uint16_t& statusword, std::int32_t& velocity) {
  if (!IsData(frame, kTpdo1 + static_cast<std::uint32_t>(node)) || frame.dlc != 6) return false;
  statusword = GetU16(&frame.data[0]);
  velocity = static_cast<std::int32_t>(GetU32(&frame.data[2]));
  return true;
}

bool DecodeTpdo2(int node, const Frame& frame, std::int32_t& position) {
  if (!IsData(frame, kTpdo2 + static_cast<std::uint32_t>(node)) || frame.dlc != 4) return false;
  position = static_cast<std::int32_t>(GetU32(&frame.data[0]));
  return true;
}

}  // namespace visco::drivers::cia402
