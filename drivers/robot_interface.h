#pragma once
// What the driver drives: a robot that takes a reference-point velocity and reports its state. The backends: the
// simulated robot (drivers/simulated_robot.h, the default), CiA 402 drives over CAN (drivers/cia402_robot.h) and
// plugins (drivers/robot_plugin.h: a shared library of the user's, loaded at start-up); the control side plugs in the
// motion model of docs/semantics.md (planning/motion_model.h) the same way.
//
// The lifecycle (as ros2_control's hardware components have it), outside the driver's loop:
//   Configure()  communication up, Read() valid (a CiA 402 drive: booted, configured by SDO, PDOs flowing);
//   Activate()   power, commands accepted (a drive: switched on, enabled by the driver's reset);
//   Deactivate() power off (at the end of a run, or when Activate() failed: never a half-started robot).
// Errors while running are RobotFeedback::fault: the driver stops the robot and reports it; its reset calls Reset().
// In the loop, SetVelocity(), QuickStop(), Reset(), Step() and Read() never allocate or block.

#include <cstdint>

namespace visco::drivers {

/// The robot's measured state.
struct RobotFeedback {
  double position[2] = {0.0, 0.0};  // metres, reference point, world frame
  double velocity[2] = {0.0, 0.0};  // m/s, world frame
  bool contact = false;
  double contact_force[2] = {0.0, 0.0};  // newtons on the robot, world frame
  bool out_of_bounds = false;            // the reference point is outside the robot's workspace
  /// The robot itself failed (a drive's fault or EMCY, a drive lost, its bus down): the driver stops it (STOPPED)
  /// and reports `fault_message` with EMCY `fault_code`; the driver's reset calls Reset(). Set until Reset().
  bool fault = false;
  bool fault_bus = false;        // the fault is a communication one (the driver's bus fault bit)
  std::uint16_t fault_code = 0;  // CANopen EMCY error code (CiA 301 / CiA 402), e.g. 0x8130 heartbeat lost
  char fault_message[96] = {};
};

class RobotInterface {
 public:
  virtual ~RobotInterface() = default;

  /// Lifecycle, not real-time (see above). Each throws visco::InputError (bad configuration: naming the file, the
  /// object and what is wrong) or visco::JobFailed (the robot refused or did not answer) with a clear message.
  virtual void Configure() {}
  virtual void Activate() {}
  /// Never throws; safe to call in any state, more than once.
  virtual void Deactivate() {}

  /// Sets the commanded reference-point velocity (m/s, world frame); zero stops the robot (with its own
  /// deceleration). Real-time safe.
  virtual void SetVelocity(const double velocity[2]) = 0;
  /// Stops the robot as fast as it safely can (its quick-stop deceleration); a later SetVelocity() moves it
  /// again. Real-time safe.
  virtual void QuickStop() = 0;
  /// The driver's reset (READY): clear the robot's fault if it can (a CiA 402 fault reset) and enable it. The
  /// robot takes zero velocity. Real-time safe; a robot that needs several cycles goes on in Step().
  virtual void Reset() {}
  /// Advances the robot by `dt` seconds (a simulated robot integrates; a real one exchanges its cyclic frames).
  /// Real-time safe.
  virtual void Step(double dt) = 0;
  /// The current state. Real-time safe.
  virtual RobotFeedback Read() const = 0;
};

}  // namespace visco::drivers
