#include "drivers/simulated_robot.h"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "common/error.h"

namespace visco::drivers {
namespace {

std::int64_t MonotonicNanos() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// The configuration's world with its bounds filled in, checked before the motion model sees it.
MotionWorld CheckedWorld(const SimulatedRobotConfig& config) {
  auto positive = [](double value, const char* option) {
    if (!(value > 0.0) || !std::isfinite(value)) {
      throw InputError("command line", option, "must be a positive number, not " + std::to_string(value));
    }
  };
  positive(config.max_acceleration, "--max-acceleration");
  positive(config.quick_stop_deceleration, "--quick-stop-deceleration");
  positive(config.mean_hold_m, "--mean-hold");
  if (!(config.contact_damping >= 0.0)) throw InputError("command line", "--contact-damping", "must be >= 0");
  if (!(config.velocity_cone >= 0.0 && config.velocity_cone < M_PI / 2)) {
    throw InputError("command line", "--velocity-cone", "must be in [0, 90) degrees");
  }
  if (config.fixed_offset && !(std::abs(*config.fixed_offset) < M_PI / 2)) {
    throw InputError("command line", "--fixed-offset", "must be below 90 degrees in magnitude");
  }
  MotionWorld world = config.world;
  world.goal.clear();
  world.active_rays.clear();
  world.active_ray_open_ends.clear();
  world.ray_landing_offset = 0.0;
  const bool no_bounds = world.bounds_min == world.bounds_max;
  if (no_bounds) {
    world.bounds_min = Eigen::Vector2d::Constant(-kFreePlaneHalfWidth);
    world.bounds_max = Eigen::Vector2d::Constant(kFreePlaneHalfWidth);
  }
  if (!(world.bounds_min.array() < world.bounds_max.array()).all()) {
    throw InputError("command line", "--workspace", "the workspace is empty (min must be below max on both axes)");
  }
  return world;
}

MotionModel BuildModel(const SimulatedRobotConfig& config) {
  try {
    return MotionModel(CheckedWorld(config));
  } catch (const std::invalid_argument& e) {
    throw InputError("simulated robot", "world", e.what());
  }
}

}  // namespace

std::vector<std::vector<Eigen::Vector2d>> WallsAround(const Eigen::Vector2d& min, const Eigen::Vector2d& max,
                                                      double thickness) {
  const double t = thickness;
  auto box = [](double x0, double y0, double x1, double y1) {
    return std::vector<Eigen::Vector2d>{{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
  };
  return {box(min.x() - t, min.y() - t, max.x() + t, min.y()),  // floor
          box(min.x() - t, max.y(), max.x() + t, max.y() + t),  // ceiling
          box(min.x() - t, min.y(), min.x(), max.y()),          // left
          box(max.x(), min.y(), max.x() + t, max.y())};         // right
}

SimulatedRobot::SimulatedRobot(const SimulatedRobotConfig& config)
    : config_(config),
      model_(BuildModel(config)),
      random_(config.seed, config.mean_hold_m),
      fixed_(config.fixed_offset.value_or(0.0)),
      adversary_(config.fixed_offset ? static_cast<Adversary*>(&fixed_) : &random_) {
  if (!config.start.allFinite() || !model_.InBounds(config.start)) {
    throw InputError("command line", "--start", "the start position lies outside the workspace bounds");
  }
  if (model_.InObstacleInterior(config.start)) {
    throw InputError("command line", "--start", "the start position lies inside a C-obstacle");
  }
  state_.position = config.start;
  feedback_.position[0] = config.start.x();
  feedback_.position[1] = config.start.y();
}

void SimulatedRobot::SetVelocity(const double velocity[2]) {
  command_ =
      Eigen::Vector2d(std::isfinite(velocity[0]) ? velocity[0] : 0.0, std::isfinite(velocity[1]) ? velocity[1] : 0.0);
  quick_stop_ = false;
}

void SimulatedRobot::QuickStop() {
  command_.setZero();
  quick_stop_ = true;
}

void SimulatedRobot::Step(double dt) {
  if (!(dt > 0.0)) return;
  // The velocity follows the command within the acceleration (or quick-stop deceleration) limit, by norm.
  const double limit = (quick_stop_ ? config_.quick_stop_deceleration : config_.max_acceleration) * dt;
  const Eigen::Vector2d change = command_ - velocity_cmd_;
  velocity_cmd_ += change.norm() > limit ? Eigen::Vector2d((limit / change.norm()) * change) : change;
  const double speed = velocity_cmd_.norm();
  const Eigen::Vector2d before = state_.position;
  Eigen::Vector2d actual = Eigen::Vector2d::Zero();
  if (speed > 1e-12) {
    const double theta = std::atan2(velocity_cmd_.y(), velocity_cmd_.x());
    if (hold_left_m_ <= 0.0 || state_.mode != last_mode_) {
      const AdversaryChoice choice = adversary_->Choose(model_, state_, theta, config_.velocity_cone);
      // A fixed offset is the test's disturbance as given; the random one stays inside the cone.
      offset_ = config_.fixed_offset ? choice.offset
                                     : std::clamp(choice.offset, -config_.velocity_cone, config_.velocity_cone);
      hold_left_m_ = choice.hold;
    }
    last_mode_ = state_.mode;
    actual = speed * Eigen::Vector2d(std::cos(theta + offset_), std::sin(theta + offset_));
    const StepResult result = model_.Advance(state_, actual, dt);
    feedback_.out_of_bounds = result.event == MotionEvent::kLeftBounds;
    hold_left_m_ -= speed * dt;
    feedback_.contact = state_.mode == MotionMode::kSliding || state_.mode == MotionMode::kStopped;
  }
  const Eigen::Vector2d velocity = (state_.position - before) / dt;
  // At rest the contact is kept as it was (the robot still touches what it touched).
  const Eigen::Vector2d force =
      feedback_.contact ? Eigen::Vector2d(config_.contact_damping * (velocity - actual)) : Eigen::Vector2d::Zero();
  RobotTruth truth;
  truth.time_ns = MonotonicNanos();
  for (int i = 0; i < 2; ++i) {
    feedback_.position[i] = truth.position[i] = state_.position[i];
    feedback_.velocity[i] = truth.velocity[i] = velocity[i];
    feedback_.contact_force[i] = force[i];
  }
  truth.contact = feedback_.contact;
  truth.mode = static_cast<std::uint8_t>(state_.mode);
  truth_.Publish(truth);
}

}  // namespace visco::drivers
