#pragma once
// The CiA 402 backend: two CANopen drives in velocity mode, one per axis (x, y), behind the driver's RobotInterface
// (`visco driver --robot cia402 --robot-config drives.json`). The driver is their NMT master, hand-written (no
// CANopen stack is packaged for Debian; the protocol is drivers/cia402.h):
//   Configure()  NMT reset communication of each drive (never a broadcast), its boot-up awaited; SDO configuration
//                (device type checked, modes of operation 0x6060, quick stop option 0x605A, heartbeat producer 0x1017
//                and consumer 0x1016 of the master's heartbeat, RPDO1/TPDO1/TPDO2 mapped, the drive's limits 0x607F,
//                0x6083, 0x6084, 0x6085 read and checked against the driver's); NMT start of each drive; TPDOs awaited.
//   Activate()   each drive to SWITCHED ON (power, operation disabled): the driver's reset enables operation.
//   Deactivate() disable voltage, NMT pre-operational.
// In the loop, Step() reads the drives' frames (TPDOs, heartbeats, EMCY) and every SYNC period sends each drive its
// RPDO (controlword, target velocity) and the SYNC; it produces the master's heartbeat, which the drives consume (a
// dead driver stops them). A drive's fault, EMCY, lost heartbeat, unexpected NMT state or leaving OPERATION ENABLED,
// and the drives' interface going down, are RobotFeedback::fault: the driver stops (every stop is a quick stop of
// every drive) and reports; its reset is the drives' fault reset. docs/your_own_robot.md.

#include <memory>
#include <string>

#include "drivers/cia402.h"
#include "drivers/robot_interface.h"

namespace visco::drivers {

class CanSocket;

struct Cia402Axis {
  int node = 0;
  double counts_per_metre = 0.0;         // 0x6064 position actual value per metre of the axis
  double velocity_units_per_mps = 0.0;   // 0x60FF / 0x606C units per m/s (default: counts_per_metre, counts/s)
  double acceleration = 0.0;             // m/s^2 written to 0x6083 and 0x6084 when > 0 (else the drive's are read)
  double quick_stop_deceleration = 0.0;  // m/s^2 written to 0x6085 when > 0
};

struct Cia402Config {
  std::string source = "cia402";                    // the configuration file (for error messages)
  std::string interface;                            // the drives' CAN interface
  std::int8_t mode = cia402::kModeProfileVelocity;  // 3 or 9
  int master_node = 127;                            // the master's heartbeat id on the drives' bus
  double sync_period_ms = 10.0;                     // SYNC producer period (also the RPDO period)
  double heartbeat_ms = 100.0;                      // the drives' heartbeat producer time (0x1017), and the master's
  double heartbeat_timeout_ms =
      300.0;                        // consumer time both ways: the master of the drives', the drives of the master's
  double boot_timeout_ms = 5000.0;  // boot-up awaited after the NMT reset
  double sdo_timeout_ms = 500.0;
  double state_timeout_ms = 1000.0;     // a drive reaching the wanted state (Activate, a fault reset)
  std::uint16_t quick_stop_option = 6;  // 0x605A: 6 = stop on the quick stop ramp and stay in QUICK STOP ACTIVE
  bool have_workspace = false;
  double workspace[4] = {0, 0, 0, 0};  // xmin ymin xmax ymax: beyond it RobotFeedback::out_of_bounds
  Cia402Axis axes[2];                  // x, y
};

/// Reads the configuration file (docs/your_own_robot.md "CiA 402 configuration").
/// @throws visco::InputError naming the file, the key and what is wrong.
Cia402Config LoadCia402Config(const std::string& path);
Cia402Config ParseCia402Config(const std::string& json_text, const std::string& source);

/// What the driver's options impose on the drives: its speed limit, and, on its own bus, its node id.
struct Cia402DriverContext {
  double max_speed = 1.0;
  int driver_node = 0;
  std::string driver_interface;
};

class Cia402Robot final : public RobotInterface {
 public:
  /// Checks the configuration against the driver's (node ids distinct, not the driver's own on a shared bus).
  /// @throws visco::InputError.
  Cia402Robot(const Cia402Config& config, const Cia402DriverContext& context);
  ~Cia402Robot() override;

  /// @throws visco::JobFailed naming the node and object (an SDO abort with its code decoded), or visco::InputError
  ///         where the drive's limits contradict the driver's.
  void Configure() override;
  void Activate() override;
  void Deactivate() override;

  void SetVelocity(const double velocity[2]) override;
  void QuickStop() override;
  void Reset() override;
  void Step(double dt) override;
  RobotFeedback Read() const override { return feedback_; }

  /// What the drives report (tests, logs).
  cia402::DriveState drive_state(int axis) const { return drives_[axis].state; }

 private:
  struct Drive {
    int node = 0;
    bool booted = false;
    std::uint8_t nmt = 0xFF;  // last heartbeat's NMT state (0xFF: none yet)
    std::int64_t last_heartbeat_us = -1;
    bool have_tpdo1 = false, have_tpdo2 = false;
    std::uint16_t statusword = 0;
    cia402::DriveState state = cia402::DriveState::kNotReadyToSwitchOn;
    std::int32_t velocity = 0, position = 0;
    std::uint16_t controlword = 0;
    std::int32_t target = 0;
    bool enabled_seen = false;  // OPERATION ENABLED reached since the last Reset()
    std::uint16_t emcy = 0;     // last EMCY error code (0: none)
  };

  void Dispatch(const can::Frame& frame, std::int64_t now_us);
  void Cycle(std::int64_t now_us);  // the SYNC period's frames
  void Write(const can::Frame& frame);
  void Watch(std::int64_t now_us);
  void UpdateFeedback();  // feedback_ from the drives' last TPDOs, in metres and m/s
  void Fault(bool bus, std::uint16_t code, const char* format, ...) __attribute__((format(printf, 4, 5)));
  // Configuration helpers (outside the loop: they wait).
  void Pump(std::int64_t until_us);
  std::uint32_t SdoRead(int axis, std::uint16_t index, std::uint8_t sub, const char* what);
  bool SdoReadOptional(int axis, std::uint16_t index, std::uint8_t sub, std::uint32_t& value, const char* what);
  void SdoWrite(int axis, std::uint16_t index, std::uint8_t sub, std::uint32_t value, int size, const char* what);
  bool Sdo(int axis, const can::Frame& request, cia402::SdoReply& reply, const char* what);
  template <typename Done>
  void Await(double timeout_ms, Done done, bool cyclic);
  [[noreturn]] void Refuse(int axis, const std::string& what);

  Cia402Config config_;
  Cia402DriverContext context_;
  std::unique_ptr<CanSocket> socket_;
  Drive drives_[2];
  cia402::Want want_ = cia402::Want::kDisabled;
  bool produce_heartbeat_ = true;
  bool configured_ = false;
  bool interface_down_ = false;
  bool sdo_pending_ = false;
  int sdo_node_ = 0;
  cia402::SdoReply sdo_reply_;
  bool sdo_replied_ = false;
  std::int64_t next_sync_us_ = 0;
  std::int64_t next_heartbeat_us_ = 0;
  std::int64_t reset_us_ = -1;  // when the last Reset() asked for a fault reset (the drives' grace period)
  double command_[2] = {0.0, 0.0};
  RobotFeedback feedback_;
};

}  // namespace visco::drivers
