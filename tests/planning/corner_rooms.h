#pragma once
// Seeded random corner rooms (a floor and a wall at a random angle, no camera): scenes whose strategies need a contact
// step into the corner, for the planner's tests.

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "planning/scene.h"
#include "planning/scene_file.h"

namespace visco::planning {

// A random corner room: a floor and a wall (overlapping slabs) meeting at a random angle β in [60°, 150°], turned by
// a random α all around, a small goal inside the wedge near the corner, a start region 2 m x 1.5 m far out in it; ε_v
// 2–8°, φ 5–25°, no camera; bounds 14 m x 14 m around the corner, so the regions always fit. Returns false when the
// scene is refused.
inline bool RandomCornerRoom(std::uint64_t seed, Scene& out) {
  std::mt19937_64 rng(seed * 2654435761u + 17);
  std::uniform_real_distribution<double> u(0, 1);
  const double deg = M_PI / 180;
  const double alpha = 2 * M_PI * u(rng), beta = (60 + 90 * u(rng)) * deg;
  const Eigen::Vector2d c(7, 7), u1(std::cos(alpha), std::sin(alpha)),
      u2(std::cos(alpha + beta), std::sin(alpha + beta));
  const Eigen::Vector2d n1(-u1.y(), u1.x()), n2(-u2.y(), u2.x());  // n1 points into the wedge, n2 out of it
  const double L = 9, t = 0.4;
  auto poly = [](std::vector<Eigen::Vector2d> v) {
    double area = 0;
    for (size_t i = 0; i < v.size(); ++i)
      area += v[i].x() * v[(i + 1) % v.size()].y() - v[(i + 1) % v.size()].x() * v[i].y();
    if (area < 0) std::reverse(v.begin(), v.end());
    std::string j = "[";
    for (size_t i = 0; i < v.size(); ++i) j += fmt::format("{}[{:.6f}, {:.6f}]", i ? ", " : "", v[i].x(), v[i].y());
    return j + "]";
  };
  const std::vector<Eigen::Vector2d> floor = {c - t * u1, c + L * u1, c + L * u1 - t * n1, c - t * u1 - t * n1};
  const std::vector<Eigen::Vector2d> wall = {c - t * u2, c + L * u2, c + L * u2 + t * n2, c - t * u2 + t * n2};
  const Eigen::Vector2d bisector = (u1 + u2).normalized();
  const double goal_at = 1.0 + u(rng), start_at = 4.0 + 0.5 * u(rng);
  const Eigen::Vector2d g = c + goal_at * bisector, st = c + start_at * bisector;
  std::vector<Eigen::Vector2d> goal, start;
  for (const auto& [dx, dy] : std::vector<std::pair<double, double>>{{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}) {
    goal.push_back(g + Eigen::Vector2d(0.3 * dx, 0.3 * dy));
    start.push_back(st + Eigen::Vector2d(1.0 * dx, 0.75 * dy));
  }
  const std::string json = fmt::format(
      R"({{"name": "corner_room_{}", "bounds": {{"min": [0, 0], "max": [14, 14]}},
          "robot": {{"polygon": [[0, 0], [0.3, 0], [0.3, 0.3], [0, 0.3]]}},
          "obstacles": [{{"id": "floor", "polygon": {}}}, {{"id": "wall", "polygon": {}}}],
          "goal": {{"polygon": {}}}, "start": {{"polygon": {}}},
          "uncertainty": {{"velocity_cone_deg": {:.3f}, "position": 0.1}}, "friction_cone_deg": {:.3f}}})",
      seed, poly(floor), poly(wall), poly(goal), poly(start), 2 + 6 * u(rng), 5 + 20 * u(rng));
  try {
    out = ParseScene(json, "corner room " + std::to_string(seed));
  } catch (const std::exception& e) {
    std::printf("corner room %llu rejected: %s\n", static_cast<unsigned long long>(seed), e.what());
    return false;
  }
  return true;
}

}  // namespace visco::planning
