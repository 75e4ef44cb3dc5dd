#pragma once
// The one simulated robot of visco: what `visco-rt driver` drives when there is no hardware, what `visco sim` and the
// demo run, and the plant of the controller's tests. It is docs/semantics.md's motion model (common/motion_model.h,
// the same physics the planner's adversarial checker runs) behind the driver's RobotInterface:
//   * the commanded velocity is followed within an acceleration limit (on the vector's norm, so the direction of a
//     change is kept), or the quick-stop deceleration after QuickStop();
//   * its direction is turned by an offset inside the control-uncertainty cone ±ε_v, chosen by a seeded random
//     adversary (a new offset after exponentially distributed distances and at every contact change), or fixed;
//   * contacts with the C-obstacles slide or stick by Coulomb friction (the generalised damper), and the contact
//     force is the damping times the velocity the contact blocks;
//   * the bounds are the robot's workspace: a motion that would leave them stops on the border and sets
//     RobotFeedback::out_of_bounds, on which the driver stops the robot with the bounds fault.
// Every parameter has one default, here; `AddSimulatedRobotOptions` (drivers/commands.h) exposes them all to every
// command that runs the simulated robot.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "common/latest_value.h"
#include "common/motion_model.h"
#include "drivers/robot_interface.h"

namespace visco::drivers {

/// Half-width of the plane a robot moves in when its configuration gives no bounds (metres).
inline constexpr double kFreePlaneHalfWidth = 1000.0;

struct SimulatedRobotConfig {
  Eigen::Vector2d start{0.0, 0.0};  // metres, initial reference-point position
  /// The C-space the reference point moves in: C-obstacles, bounds and friction (goal and rays are ignored: visual
  /// compliance is the controller's job, not physics). Empty bounds (min == max on an axis): the free plane
  /// ±kFreePlaneHalfWidth.
  MotionWorld world;
  double velocity_cone = 0.0;  // ε_v, radians: the adversary's offsets lie in [−ε_v, ε_v]
  std::uint64_t seed = 1;      // the random adversary's seed
  double mean_hold_m = 0.05;   // metres of travel between the random adversary's direction changes (mean)
  /// Set: no random adversary, the direction is always turned by this offset (radians, |offset| < π/2): a known
  /// disturbance for tests.
  std::optional<double> fixed_offset;
  double max_acceleration = 4.0;          // m/s^2, how fast the velocity follows the command
  double quick_stop_deceleration = 50.0;  // m/s^2, after QuickStop()
  double contact_damping = 200.0;         // N per (m/s) of velocity a contact blocks
};

/// The true state, published on every Step for a simulated camera on another thread.
struct RobotTruth {
  std::int64_t time_ns = 0;  // CLOCK_MONOTONIC
  double position[2] = {0.0, 0.0};
  double velocity[2] = {0.0, 0.0};
  bool contact = false;
  std::uint8_t mode = 0;  // MotionMode
};

/// Walls around a rectangle: four C-obstacles `thickness` thick outside [min, max] (for a robot in a box).
std::vector<std::vector<Eigen::Vector2d>> WallsAround(const Eigen::Vector2d& min, const Eigen::Vector2d& max,
                                                      double thickness = 1.0);

/// Threads: one thread owns it (SetVelocity, QuickStop, Step, Read: the driver's). Other threads see the robot only
/// through truth() (one consumer) or the driver's Snapshot().
class SimulatedRobot final : public RobotInterface {
 public:
  /// A robot at the origin of the free plane.
  SimulatedRobot() : SimulatedRobot(SimulatedRobotConfig{}) {}
  /// Not real-time safe (builds the motion model).
  /// @throws visco::InputError if a rate is not positive, the bounds are empty, an obstacle is degenerate, the fixed
  ///         offset is not below π/2, or the start is outside the bounds or inside a C-obstacle.
  explicit SimulatedRobot(const SimulatedRobotConfig& config);
  void SetVelocity(const double velocity[2]) override;
  void QuickStop() override;
  /// Does not allocate; O(obstacle edges) per step.
  void Step(double dt) override;
  RobotFeedback Read() const override { return feedback_; }

  /// Latest true state (consumer: one thread).
  LatestValue<RobotTruth>& truth() { return truth_; }
  const MotionState& state() const { return state_; }
  const MotionModel& model() const { return model_; }

 private:
  SimulatedRobotConfig config_;
  MotionModel model_;
  RandomAdversary random_;
  FixedAdversary fixed_;
  Adversary* adversary_;  // fixed_ with a fixed offset, else random_
  MotionState state_;
  Eigen::Vector2d command_{0.0, 0.0};
  Eigen::Vector2d velocity_cmd_{0.0, 0.0};  // the command after the acceleration limit
  bool quick_stop_ = false;
  double offset_ = 0.0;
  double hold_left_m_ = 0.0;
  MotionMode last_mode_ = MotionMode::kFree;
  RobotFeedback feedback_;
  LatestValue<RobotTruth> truth_;
};

}  // namespace visco::drivers
