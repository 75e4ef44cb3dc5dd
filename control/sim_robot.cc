#include "control/sim_robot.h"

#include <algorithm>
#include <cmath>

#include "common/error.h"
#include "control/control_loop.h"
#include "planning/cspace.h"
#include "planning/scene.h"

namespace visco::control {

planning::MotionWorld MakeMotionWorld(const planning::Scene& scene) {
  planning::MotionWorld world;
  const planning::CSpace cspace(scene);
  for (std::size_t i = 0; i < cspace.num_c_obstacles(); ++i) {
    for (const planning::PolygonWithHoles& part : cspace.c_obstacle(i)) {
      // Holes of a C-obstacle are pockets enclosed by it: unreachable from outside, so the outer boundary suffices.
      world.obstacles.push_back(part.outer.vertices);
    }
  }
  world.bounds_min = scene.bounds.min;
  world.bounds_max = scene.bounds.max;
  world.friction_cone = scene.friction_cone_rad;
  return world;
}

SimRobot::SimRobot(const planning::MotionModel& model, const SimRobotConfig& config)
    : model_(model), config_(config), adversary_(config.seed, config.mean_hold_m) {
  const Eigen::Vector2d start(config.start.x, config.start.y);
  if (!model_.InBounds(start)) throw InputError("command line", "--start", "outside the scene's bounds");
  if (model_.InObstacleInterior(start)) throw InputError("command line", "--start", "inside a C-obstacle");
  state_.position = start;
  feedback_.position[0] = start.x();
  feedback_.position[1] = start.y();
}

void SimRobot::SetVelocity(const double velocity[2]) {
  command_ = Eigen::Vector2d(velocity[0], velocity[1]);
  quick_stop_ = false;
}

void SimRobot::QuickStop() {
  command_.setZero();
  quick_stop_ = true;
}

void SimRobot::Step(double dt) {
  if (!(dt > 0)) return;
  // The speed follows the command with the acceleration (or quick-stop deceleration) limit.
  const double limit = (quick_stop_ ? config_.quick_stop_deceleration : config_.max_acceleration) * dt;
  const Eigen::Vector2d change = command_ - velocity_cmd_;
  velocity_cmd_ += change.norm() > limit ? (limit / change.norm()) * change : change;
  const double speed = velocity_cmd_.norm();
  const Eigen::Vector2d before = state_.position;
  Eigen::Vector2d actual = Eigen::Vector2d::Zero();
  if (speed > 1e-12) {
    const double theta = std::atan2(velocity_cmd_.y(), velocity_cmd_.x());
    if (hold_left_m_ <= 0.0 || state_.mode != last_mode_) {
      const planning::AdversaryChoice choice = adversary_.Choose(model_, state_, theta, config_.velocity_cone);
      offset_ = std::clamp(choice.offset, -config_.velocity_cone, config_.velocity_cone);
      hold_left_m_ = choice.hold;
    }
    last_mode_ = state_.mode;
    actual = speed * Eigen::Vector2d(std::cos(theta + offset_), std::sin(theta + offset_));
    const planning::StepResult result = model_.Advance(state_, actual, dt);
    feedback_.out_of_bounds = result.event == planning::MotionEvent::kLeftBounds;
    hold_left_m_ -= speed * dt;
  }
  const Eigen::Vector2d velocity = (state_.position - before) / dt;
  if (speed > 1e-12) {
    feedback_.contact = state_.mode == planning::MotionMode::kSliding || state_.mode == planning::MotionMode::kStopped;
  }
  const Eigen::Vector2d force =
      feedback_.contact ? Eigen::Vector2d(config_.contact_damping * (velocity - actual)) : Eigen::Vector2d::Zero();
  for (int i = 0; i < 2; ++i) {
    feedback_.position[i] = state_.position[i];
    feedback_.velocity[i] = velocity[i];
    feedback_.contact_force[i] = force[i];
  }
  SimTruth truth;
  truth.time_ns = MonotonicNs();
  truth.position = {state_.position.x(), state_.position.y()};
  truth.velocity = {velocity.x(), velocity.y()};
  truth.contact = feedback_.contact;
  truth.mode = static_cast<std::int8_t>(state_.mode);
  truth_.Publish(truth);
}

}  // namespace visco::control
