#pragma once
// The driver's default robot: a point-mass kinematic integrator of the reference point with a velocity limit, an
// acceleration limit (so a stop takes v / a seconds, as on a real axis) and optional walls at the workspace bounds
// that the robot presses against (contact, with a reaction force proportional to the velocity pushed into the
// wall). The full motion model of SEMANTICS.md (velocity cone chosen by an adversary, friction contacts with
// obstacles, sticking) lives in planning/ and is plugged in by the control side through RobotInterface.

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
};

class SimulatedRobot final : public RobotInterface {
 public:
  /// @throws visco::InputError if the acceleration is not positive or the bounds are empty or exclude the start.
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
