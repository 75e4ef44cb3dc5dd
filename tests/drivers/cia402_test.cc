// The CiA 402 backend's protocol against frames computed by hand from CiA 301 (NMT, SYNC, heartbeat, expedited SDO,
// EMCY, abort codes) and CiA 402 (statusword states, controlword transitions, the mapped PDOs), and its configuration
// file's checks. The backend against a drive on a bus is the HIL test (tests/drivers/hil/cia402_hil_test.py).

#include "drivers/cia402.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "common/error.h"
#include "drivers/cia402_robot.h"

namespace visco::drivers::cia402 {
namespace {

std::vector<int> Bytes(const Frame& f) { return std::vector<int>(f.data, f.data + f.dlc); }
Frame Make(std::uint32_t id, std::vector<int> bytes) {
  Frame f;
  f.id = id;
  f.dlc = static_cast<std::uint8_t>(bytes.size());
  for (std::size_t i = 0; i < bytes.size(); ++i) f.data[i] = static_cast<std::uint8_t>(bytes[i]);
  return f;
}

TEST(Cia402Frames, NmtSyncAndHeartbeat) {
  const Frame start = Nmt(kNmtStart, 3);
  EXPECT_EQ(start.id, 0x000U);
  EXPECT_EQ(Bytes(start), (std::vector<int>{0x01, 0x03}));
  EXPECT_EQ(Bytes(Nmt(kNmtResetCommunication, 2)), (std::vector<int>{0x82, 0x02}));
  EXPECT_EQ(Bytes(Nmt(kNmtEnterPreOperational, 127)), (std::vector<int>{0x80, 0x7F}));
  EXPECT_EQ(Sync().id, 0x080U);
  EXPECT_EQ(Sync().dlc, 0);
  const Frame hb = Heartbeat(127, kStateOperational);
  EXPECT_EQ(hb.id, 0x77FU);
  EXPECT_EQ(Bytes(hb), (std::vector<int>{0x05}));
}

TEST(Cia402Frames, ExpeditedSdoRequests) {
  // Download: ccs=1, n = 4 - size, e=1, s=1 -> 0x2F (1 byte), 0x2B (2), 0x23 (4); index little-endian, sub, data.
  Frame f = SdoDownload(2, kModesOfOperation, 0, 9, 1);
  EXPECT_EQ(f.id, 0x602U);
  EXPECT_EQ(Bytes(f), (std::vector<int>{0x2F, 0x60, 0x60, 0x00, 0x09, 0, 0, 0}));
  EXPECT_EQ(Bytes(SdoDownload(2, kProducerHeartbeatTime, 0, 100, 2)),
            (std::vector<int>{0x2B, 0x17, 0x10, 0x00, 0x64, 0x00, 0, 0}));
  EXPECT_EQ(Bytes(SdoDownload(5, kRpdo1Communication, 1, kPdoInvalid | 0x205, 4)),
            (std::vector<int>{0x23, 0x00, 0x14, 0x01, 0x05, 0x02, 0x00, 0x80}));
  // The consumer heartbeat entry: node 127 at 300 ms = 0x007F012C.
  EXPECT_EQ(Bytes(SdoDownload(2, kConsumerHeartbeatTime, 1, 127U << 16 | 300U, 4)),
            (std::vector<int>{0x23, 0x16, 0x10, 0x01, 0x2C, 0x01, 0x7F, 0x00}));
  EXPECT_EQ(Bytes(SdoDownload(2, kRpdo1Mapping, 1, MappingEntry(kControlword, 0, 16), 4)),
            (std::vector<int>{0x23, 0x00, 0x16, 0x01, 0x10, 0x00, 0x40, 0x60}));
  EXPECT_EQ(MappingEntry(kTargetVelocity, 0, 32), 0x60FF0020U);
  // Upload: ccs=2.
  f = SdoUpload(3, kDeviceType, 0);
  EXPECT_EQ(f.id, 0x603U);
  EXPECT_EQ(Bytes(f), (std::vector<int>{0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}));
}

TEST(Cia402Frames, SdoAnswersAndAbortCodes) {
  SdoReply r;
  ASSERT_TRUE(DecodeSdoReply(2, Make(0x582, {0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00}), r));
  EXPECT_EQ(r.kind, SdoReplyKind::kUploaded);
  EXPECT_EQ(r.index, 0x1000);
  EXPECT_EQ(r.size, 4);
  EXPECT_EQ(r.value, 0x00020192U);
  ASSERT_TRUE(DecodeSdoReply(2, Make(0x582, {0x4B, 0x41, 0x60, 0x00, 0x37, 0x02, 0xAA, 0xBB}), r));
  EXPECT_EQ(r.size, 2);
  EXPECT_EQ(r.value, 0x0237U);  // the unused bytes are not part of the value
  ASSERT_TRUE(DecodeSdoReply(2, Make(0x582, {0x4F, 0x60, 0x60, 0x00, 0x09, 0xFF, 0xFF, 0xFF}), r));
  EXPECT_EQ(r.size, 1);
  EXPECT_EQ(r.value, 9U);
  ASSERT_TRUE(DecodeSdoReply(2, Make(0x582, {0x60, 0x60, 0x60, 0x00, 0, 0, 0, 0}), r));
  EXPECT_EQ(r.kind, SdoReplyKind::kDownloaded);
  EXPECT_EQ(r.index, 0x6060);
  ASSERT_TRUE(DecodeSdoReply(2, Make(0x582, {0x80, 0x60, 0x60, 0x00, 0x30, 0x00, 0x09, 0x06}), r));
  EXPECT_EQ(r.kind, SdoReplyKind::kAborted);
  EXPECT_EQ(r.value, 0x06090030U);
  EXPECT_STREQ(SdoAbortText(r.value), "invalid value for parameter");
  EXPECT_STREQ(SdoAbortText(0x06020000), "object does not exist in the object dictionary");
  EXPECT_STREQ(SdoAbortText(0x12345678), "unknown abort code");
  ASSERT_TRUE(DecodeSdoReply(2, Make(0x582, {0x41, 0x08, 0x10, 0x00, 0x20, 0, 0, 0}), r));  // segmented
  EXPECT_EQ(r.kind, SdoReplyKind::kUnsupported);
  EXPECT_FALSE(DecodeSdoReply(3, Make(0x582, {0x60, 0, 0, 0, 0, 0, 0, 0}), r));  // another node's
  EXPECT_FALSE(DecodeSdoReply(2, Make(0x582, {0x60, 0, 0}), r));
}

TEST(Cia402Frames, EmcyAndItsMeaning) {
  Emcy e;
  ASSERT_TRUE(DecodeEmcy(2, Make(0x082, {0x10, 0x23, 0x02, 0, 0, 0, 0, 0}), e));
  EXPECT_EQ(e.code, 0x2310);
  EXPECT_EQ(e.error_register, 0x02);
  EXPECT_STREQ(EmcyText(0x2310), "continuous over-current");
  EXPECT_STREQ(EmcyText(0x8130), "life guard or heartbeat error");
  EXPECT_STREQ(EmcyText(0x2311), "continuous over-current");  // the class of a vendor's refinement
  EXPECT_STREQ(EmcyText(0x5123), "device hardware");
  EXPECT_FALSE(DecodeEmcy(2, Make(0x083, {0x10, 0x23, 0x02, 0, 0, 0, 0, 0}), e));
}

TEST(Cia402StateMachine, StatuswordStates) {
  // CiA 402-2, statusword bits 6,5,3,2,1,0 (bit 4 voltage enabled and bit 9 remote do not matter).
  EXPECT_EQ(StateOf(0x0000), DriveState::kNotReadyToSwitchOn);
  EXPECT_EQ(StateOf(0x0250), DriveState::kSwitchOnDisabled);
  EXPECT_EQ(StateOf(0x0231), DriveState::kReadyToSwitchOn);
  EXPECT_EQ(StateOf(0x0233), DriveState::kSwitchedOn);
  EXPECT_EQ(StateOf(0x0237), DriveState::kOperationEnabled);
  EXPECT_EQ(StateOf(0x0217), DriveState::kQuickStopActive);
  EXPECT_EQ(StateOf(0x021F), DriveState::kFaultReactionActive);
  EXPECT_EQ(StateOf(0x0218), DriveState::kFault);
  EXPECT_EQ(StateOf(0x0238), DriveState::kFault);
}

TEST(Cia402StateMachine, ControlwordsWalkTheTransitions) {
  // Enable: 2 shutdown, 3 switch on, 4 enable operation; 16 from QUICK STOP ACTIVE; 15 fault reset on an edge.
  EXPECT_EQ(ControlwordToward(DriveState::kSwitchOnDisabled, Want::kEnabled, 0), 0x0006);
  EXPECT_EQ(ControlwordToward(DriveState::kReadyToSwitchOn, Want::kEnabled, 0x06), 0x0007);
  EXPECT_EQ(ControlwordToward(DriveState::kSwitchedOn, Want::kEnabled, 0x07), 0x000F);
  EXPECT_EQ(ControlwordToward(DriveState::kOperationEnabled, Want::kEnabled, 0x0F), 0x000F);
  EXPECT_EQ(ControlwordToward(DriveState::kQuickStopActive, Want::kEnabled, 0x02), 0x000F);
  EXPECT_EQ(ControlwordToward(DriveState::kFault, Want::kEnabled, 0x02), 0x0080);
  EXPECT_EQ(ControlwordToward(DriveState::kFault, Want::kEnabled, 0x80), 0x0000);  // the next edge after this
  EXPECT_EQ(ControlwordToward(DriveState::kFaultReactionActive, Want::kEnabled, 0x0F), 0x0000);
  // Switched on (the driver DISABLED): 5 disable operation from OPERATION ENABLED.
  EXPECT_EQ(ControlwordToward(DriveState::kSwitchOnDisabled, Want::kSwitchedOn, 0), 0x0006);
  EXPECT_EQ(ControlwordToward(DriveState::kReadyToSwitchOn, Want::kSwitchedOn, 0x06), 0x0007);
  EXPECT_EQ(ControlwordToward(DriveState::kOperationEnabled, Want::kSwitchedOn, 0x0F), 0x0007);
  EXPECT_EQ(ControlwordToward(DriveState::kFault, Want::kSwitchedOn, 0), 0x0000);  // no reset without the driver's
  // Every stop: 11 quick stop; off: disable voltage.
  EXPECT_EQ(ControlwordToward(DriveState::kOperationEnabled, Want::kQuickStop, 0x0F), 0x0002);
  EXPECT_EQ(ControlwordToward(DriveState::kOperationEnabled, Want::kDisabled, 0x0F), 0x0000);
}

TEST(Cia402Frames, MappedPdos) {
  const Frame rpdo = Rpdo1(2, kCwEnableOperation, -1000);
  EXPECT_EQ(rpdo.id, 0x202U);
  EXPECT_EQ(Bytes(rpdo), (std::vector<int>{0x0F, 0x00, 0x18, 0xFC, 0xFF, 0xFF}));
  std::uint16_t sw = 0;
  std::int32_t v = 0, p = 0;
  ASSERT_TRUE(DecodeTpdo1(2, Make(0x182, {0x37, 0x02, 0xE8, 0x03, 0x00, 0x00}), sw, v));
  EXPECT_EQ(sw, 0x0237);
  EXPECT_EQ(v, 1000);
  ASSERT_TRUE(DecodeTpdo2(3, Make(0x283, {0x00, 0x00, 0xFF, 0xFF}), p));
  EXPECT_EQ(p, -65536);
  EXPECT_FALSE(DecodeTpdo1(2, Make(0x182, {0x37, 0x02, 0xE8, 0x03}), sw, v));  // wrong length: not our mapping
}

std::string ConfigError(const std::string& json) {
  try {
    ParseCia402Config(json, "drives.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(Cia402Config, ReadsAndRejectsWithTheKeyNamed) {
  const std::string axes = R"("axes": [{"node": 2, "counts_per_metre": 100000}, {"node": 3, "counts_per_metre": -1e5,
                              "velocity_units_per_mps": 1000, "acceleration": 2}])";
  const Cia402Config c = ParseCia402Config(
      R"({"format": "visco-cia402-1", "interface": "vcan1", "mode": "cyclic_synchronous_velocity", )" + axes + "}",
      "drives.json");
  EXPECT_EQ(c.interface, "vcan1");
  EXPECT_EQ(c.mode, kModeCyclicSynchronousVelocity);
  EXPECT_EQ(c.axes[0].velocity_units_per_mps, 100000);  // counts per second by default
  EXPECT_EQ(c.axes[1].counts_per_metre, -1e5);
  EXPECT_EQ(c.axes[1].velocity_units_per_mps, 1000);
  EXPECT_EQ(c.axes[1].acceleration, 2);
  const std::string head = R"({"format": "visco-cia402-1", "interface": "vcan1", )";
  EXPECT_EQ(ConfigError(R"({"interface": "vcan1", )" + axes + "}"), "drives.json: format: must be \"visco-cia402-1\"");
  EXPECT_NE(ConfigError(R"({"format": "visco-cia402-1", )" + axes + "}").find("drives.json: interface:"),
            std::string::npos);
  EXPECT_NE(ConfigError(head + R"("mode": 7, )" + axes + "}").find("drives.json: mode: must be"), std::string::npos);
  EXPECT_NE(ConfigError(head + R"("speed": 7, )" + axes + "}").find("drives.json: speed: unknown key"),
            std::string::npos);
  EXPECT_NE(ConfigError(head + R"("axes": [{"node": 2, "counts_per_metre": 1}, {"node": 2, "counts_per_metre": 1}]})")
                .find("drives.json: axes[1].node: node 2 twice"),
            std::string::npos);
  EXPECT_NE(ConfigError(head + R"("axes": [{"node": 2, "counts_per_metre": 0}, {"node": 3, "counts_per_metre": 1}]})")
                .find("axes[0].counts_per_metre: missing or zero"),
            std::string::npos);
  EXPECT_NE(ConfigError(head + R"("axes": [{"node": 127, "counts_per_metre": 1}, {"node": 3, "counts_per_metre": 1}]})")
                .find("axes[0].node: node 127 is the master's own"),
            std::string::npos);
  EXPECT_NE(ConfigError(head + R"("axes": [{"node": 2, "counts_per_metre": 1}]})").find("axes: must be two drives"),
            std::string::npos);
  EXPECT_NE(ConfigError(head + R"("heartbeat_ms": 100, "heartbeat_timeout_ms": 150, )" + axes + "}")
                .find("heartbeat_timeout_ms: must be at least twice heartbeat_ms"),
            std::string::npos);
  EXPECT_NE(
      ConfigError(head +
                  R"("axes": [{"node": 2, "counts_per_metre": 1, "gain": 3}, {"node": 3, "counts_per_metre": 1}]})")
          .find("axes[0].gain: unknown key"),
      std::string::npos);
  EXPECT_EQ(ConfigError("{nope"), "drives.json: not valid JSON");
  // On the driver's own bus, the drives must not take its node id.
  Cia402DriverContext context;
  context.driver_node = 2;
  context.driver_interface = "vcan1";
  try {
    Cia402Robot robot(c, context);
    ADD_FAILURE() << "node 2 on the driver's bus accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("axes[0].node: node 2 is the driver's own on vcan1"), std::string::npos)
        << e.what();
  }
  context.driver_interface = "vcan0";
  EXPECT_NO_THROW(Cia402Robot(c, context));  // another bus: no conflict (and nothing happens before Configure)
}

}  // namespace
}  // namespace visco::drivers::cia402
