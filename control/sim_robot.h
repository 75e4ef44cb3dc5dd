#pragma once
// The simulated robot of `visco sim`: docs/semantics.md's motion model (planning/motion_model.h) behind the driver's
// RobotInterface. The commanded velocity is followed with an acceleration limit; its direction is turned by an
// offset inside the control-uncertainty cone chosen by a seeded random adversary (planning::RandomAdversary: a new
// offset after exponentially distributed distances and at every contact change); contacts with the C-obstacles
// slide or stick by Coulomb friction; the bounds are walls. Part of visco::control_sim (not the real-time library).

#include <Eigen/Core>
#include <cstdint>
#include <memory>

#include "common/latest_value.h"
#include "control/types.h"
#include "drivers/robot_interface.h"
#include "planning/motion_model.h"

namespace visco::planning {
struct Scene;
}

namespace visco::control {

struct SimRobotConfig {
  Vec2 start;                             // metres, initial reference point
  double velocity_cone = 0.0;             // radians, ε_v (from the scene)
  std::uint64_t seed = 1;                 // adversary seed
  double mean_hold_m = 0.05;              // metres of travel between the adversary's direction changes (mean)
  double max_acceleration = 4.0;          // m/s^2, how fast the speed follows the command
  double quick_stop_deceleration = 50.0;  // m/s^2
  double contact_damping = 200.0;         // N per (m/s) of commanded velocity the contact blocks
};

/// The true state, published on every Step for the simulated camera (another thread).
struct SimTruth {
  std::int64_t time_ns = 0;  // monotonic
  Vec2 position;
  Vec2 velocity;
  bool contact = false;
  std::int8_t mode = 0;  // planning::MotionMode
};

/// The motion world of a scene: C-obstacles (outer boundaries of CB_i), bounds, friction; no goal, no rays (visual
/// compliance is the controller's job, not physics). Not real-time safe.
planning::MotionWorld MakeMotionWorld(const planning::Scene& scene);

/// Threads: the driver's thread owns it (SetVelocity, QuickStop, Step, Read through drivers::Driver). Other threads
/// see the robot through truth() (one consumer: the simulated camera) or the driver's Snapshot(), never Read().
class SimRobot final : public drivers::RobotInterface {
 public:
  /// @throws InputError if the start is outside the bounds or inside a C-obstacle.
  SimRobot(const planning::MotionModel& model, const SimRobotConfig& config);
  void SetVelocity(const double velocity[2]) override;
  void QuickStop() override;
  void Step(double dt) override;
  drivers::RobotFeedback Read() const override { return feedback_; }

  /// Latest true state (consumer: one thread).
  LatestValue<SimTruth>& truth() { return truth_; }
  const planning::MotionState& state() const { return state_; }

 private:
  const planning::MotionModel& model_;
  SimRobotConfig config_;
  planning::RandomAdversary adversary_;
  planning::MotionState state_;
  Eigen::Vector2d command_{0.0, 0.0};
  Eigen::Vector2d velocity_cmd_{0.0, 0.0};  // the command after the acceleration limit
  bool quick_stop_ = false;
  double offset_ = 0.0;
  double hold_left_m_ = 0.0;
  planning::MotionMode last_mode_ = planning::MotionMode::kFree;
  drivers::RobotFeedback feedback_;
  LatestValue<SimTruth> truth_;
};

}  // namespace visco::control
