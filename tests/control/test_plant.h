#pragma once
// A small kinematic plant for controller tests: the reference point integrates the commanded velocity, optionally
// rotated by a fixed disturbance angle (inside the control cone), and stops or slides on straight walls with
// Coulomb friction (sticking when the push is within the friction cone of the wall normal, docs/semantics.md).

#include <cmath>
#include <vector>

#include "control/types.h"

namespace visco::control::testing {

struct Wall {
  Vec2 point;   // a point on the wall line
  Vec2 normal;  // unit outward normal (free side)
};

class TestPlant {
 public:
  Vec2 position;
  Vec2 velocity;
  bool contact = false;
  double disturbance = 0.0;  // radians, rotation of the actual velocity w.r.t. the command
  double friction = 0.0;     // radians, friction cone half-angle
  std::vector<Wall> walls;

  void Step(Vec2 command, double dt) {
    const double c = std::cos(disturbance), s = std::sin(disturbance);
    Vec2 v{c * command.x - s * command.y, s * command.x + c * command.y};
    contact = false;
    for (const Wall& wall : walls) {
      const double gap = Dot(position - wall.point, wall.normal);
      const double push = Dot(v, wall.normal);
      if (gap <= 1e-9 && push < 0) {
        contact = true;
        const Vec2 tangential = v - push * wall.normal;
        const double angle = std::atan2(Norm(tangential), -push);
        v = angle <= friction ? Vec2{} : tangential;
      }
    }
    Vec2 next = position + dt * v;
    for (const Wall& wall : walls) {
      const double gap = Dot(next - wall.point, wall.normal);
      if (gap < 0) {
        next = next - gap * wall.normal;
        contact = true;
      }
    }
    velocity = (1.0 / dt) * (next - position);
    position = next;
  }
};

}  // namespace visco::control::testing
