#pragma once
// What the driver drives: a robot that takes a reference-point velocity and reports its state. The default is the
// simulated robot (drivers/simulated_robot.h); a hardware robot or the motion model of docs/semantics.md
// (planning/motion_model.h, plugged in by the control side) implements the same interface.

namespace visco::drivers {

/// The robot's measured state.
struct RobotFeedback {
  double position[2] = {0.0, 0.0};  // metres, reference point, world frame
  double velocity[2] = {0.0, 0.0};  // m/s, world frame
  bool contact = false;
  double contact_force[2] = {0.0, 0.0};  // newtons on the robot, world frame
  bool out_of_bounds = false;            // the reference point is outside the robot's workspace
};

class RobotInterface {
 public:
  virtual ~RobotInterface() = default;
  /// Sets the commanded reference-point velocity (m/s, world frame); zero stops the robot (with its own
  /// deceleration). Real-time safe.
  virtual void SetVelocity(const double velocity[2]) = 0;
  /// Stops the robot as fast as it safely can (its quick-stop deceleration); a later SetVelocity() moves it
  /// again. Real-time safe.
  virtual void QuickStop() = 0;
  /// Advances the robot by `dt` seconds (a simulated robot integrates; a real one may ignore it). Real-time safe.
  virtual void Step(double dt) = 0;
  /// The current state. Real-time safe.
  virtual RobotFeedback Read() const = 0;
};

}  // namespace visco::drivers
