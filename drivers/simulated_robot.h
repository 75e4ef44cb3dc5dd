#pragma once
// The driver's default robot: a point-mass kinematic integrator of the reference point with a velocity limit, an
// acceleration limit (so a stop takes v / a seconds, as on a real axis) and optional walls at the workspace bounds
// that the robot presses against (contact, with a reaction force proportional to the velocity pushed into the
// wall), and an optional workspace whose exit is reported (RobotFeedback::out_of_bounds). The full motion model of
// docs/semantics.md (velocity cone chosen by an adversary, friction contacts with obstacles, sticking) lives in
// planning/ and is plugged in by the control side through RobotInterface.

#include "drivers/robot_interface.h"

namespace visco::drivers {

struct SimulatedRobotConfig {
  double start[2] = {0.0, 0.0};           // metres, initial reference-point position
  double max_acceleration = 2.0;          // m/s^2, per axis
  double quick_stop_deceleration = 50.0;  // m/s^2, per axis, after QuickStop()
  bool walls = false;                     // true: the bounds below are rigid walls
  double bounds_min[2] = {0.0, 0.0};
  double bounds_max[2] = {0.0, 0.0};
  double wall_damping = 200.0;  // N per (m/s) pushed into a wall
  // The robot's workspace (its soft limits): a reference point outside it sets RobotFeedback::out_of_bounds, on
  // which the driver stops the robot and raises the bounds fault (EMCY 0x8612). Nothing physical stops it there.
  bool workspace = false;
  double workspace_min[2] = {0.0, 0.0};
  double workspace_max[2] = {0.0, 0.0};
};

class SimulatedRobot final : public RobotInterface {
 public:
  /// @throws visco::InputError if the acceleration is not positive or the bounds or workspace are empty or
  /// exclude the start.
  explicit SimulatedRobot(const SimulatedRobotConfig& config);
  void SetVelocity(const double velocity[2]) override;
  void QuickStop() override;
  void Step(double dt) override;
  RobotFeedback Read() const override { return state_; }

 private:
  SimulatedRobotConfig config_;
  double command_[2] = {0.0, 0.0};
  bool quick_stop_ = false;
  RobotFeedback state_;
};

}  // namespace visco::drivers
