#pragma once
// The controller tests' plant: the one simulated robot (drivers/simulated_robot.h, docs/semantics.md's motion model)
// behind the knobs these tests set: straight walls (half-planes with Coulomb friction), a fixed disturbance angle
// inside the control cone, and a velocity that follows the command at once (no acceleration limit to speak of, so
// that a test's timing is the controller's alone). It adds no physics of its own.

#include <cmath>
#include <memory>
#include <vector>

#include "control/types.h"
#include "drivers/simulated_robot.h"

namespace visco::control::testing {

struct Wall {
  Vec2 point;   // a point on the wall line
  Vec2 normal;  // unit outward normal (free side)
};

class TestPlant {
 public:
  // Knobs, read when the plant first moves (and again whenever one of them or the position was changed since).
  Vec2 position;
  double disturbance = 0.0;  // radians, rotation of the actual velocity w.r.t. the command
  double friction = 0.0;     // radians, friction cone half-angle
  std::vector<Wall> walls;
  // The robot's state after the last Step.
  Vec2 velocity;
  bool contact = false;

  void Step(Vec2 command, double dt) {
    if (!robot_ || Changed()) Build();
    const double v[2] = {command.x, command.y};
    robot_->SetVelocity(v);
    robot_->Step(dt);
    const drivers::RobotFeedback f = robot_->Read();
    position = {f.position[0], f.position[1]};
    velocity = {f.velocity[0], f.velocity[1]};
    contact = f.contact && Norm(command) > 0;  // touching without pushing is no contact for these tests
    built_position_ = position;
  }

 private:
  bool Changed() const {
    return position.x != built_position_.x || position.y != built_position_.y || disturbance != built_disturbance_ ||
           friction != built_friction_ || walls.size() != built_walls_;
  }
  void Build() {
    drivers::SimulatedRobotConfig config;
    config.start = {position.x, position.y};
    config.fixed_offset = disturbance;
    config.velocity_cone = std::abs(disturbance);
    config.max_acceleration = 1e9;
    config.world.bounds_min = {-kHalfWidth, -kHalfWidth};
    config.world.bounds_max = {kHalfWidth, kHalfWidth};
    config.world.friction_cone = friction;
    for (const Wall& w : walls) {
      // The half-plane behind the wall, as a large rectangle: its edge on the wall line, counter-clockwise.
      const Eigen::Vector2d p(w.point.x, w.point.y), n(w.normal.x, w.normal.y), t(-n.y(), n.x());
      const double l = 2 * kHalfWidth;
      config.world.obstacles.push_back({p - l * t - l * n, p - l * t, p + l * t, p + l * t - l * n});
    }
    robot_ = std::make_unique<drivers::SimulatedRobot>(config);
    built_position_ = position;
    built_disturbance_ = disturbance;
    built_friction_ = friction;
    built_walls_ = walls.size();
  }
  static constexpr double kHalfWidth = 50.0;  // metres: far beyond every test's motion
  std::unique_ptr<drivers::SimulatedRobot> robot_;
  Vec2 built_position_;
  double built_disturbance_ = 0.0;
  double built_friction_ = 0.0;
  std::size_t built_walls_ = 0;
};

}  // namespace visco::control::testing
