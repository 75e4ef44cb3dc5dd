#pragma once
// A scalable backprojection problem for the planning benchmarks: m convex pentagons on a jittered grid (cells 2 x 2,
// radius 0.6: no overlaps) above a floor, a goal strip along the floor. Seeded: the same m gives the same problem.

#include <cmath>
#include <random>

#include "planning/backprojection.h"

namespace visco::planning::bench {

inline BackprojectionProblem PentagonGrid(int m, double theta_deg = -80) {
  std::mt19937_64 rng(12345);
  auto u = [&]() { return static_cast<double>(rng() >> 11) * (1.0 / 9007199254740992.0); };
  const int side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(m))));
  BackprojectionProblem pr;
  const double w = 2.0 * side;
  pr.bounds_min = {0, 0};
  pr.bounds_max = {w, w + 2};
  for (int i = 0; i < m; ++i) {
    const double cx = 2.0 * (i % side) + 1 + 0.3 * (u() - 0.5), cy = 2.0 * (i / side) + 3 + 0.3 * (u() - 0.5);
    NamedPolygon p;
    const double a0 = 2 * M_PI * u();
    for (int k = 0; k < 5; ++k) {
      const double a = a0 + 2 * M_PI * (k + 0.3 * u()) / 5;
      p.vertices.emplace_back(cx + 0.6 * std::cos(a), cy + 0.6 * std::sin(a));
    }
    pr.obstacles.push_back(p);
  }
  NamedPolygon floor;
  floor.vertices = {{-1, -1}, {w + 1, -1}, {w + 1, 1}, {-1, 1}};
  pr.obstacles.push_back(floor);
  NamedPolygon goal;
  goal.vertices = {{0.2 * w, 1}, {0.8 * w, 1}, {0.8 * w, 1.5}, {0.2 * w, 1.5}};
  pr.goal.push_back(goal);
  pr.theta = theta_deg * M_PI / 180;
  pr.velocity_cone = 5 * M_PI / 180;
  pr.friction_cone = 20 * M_PI / 180;
  return pr;
}

inline int Vertices(const BackprojectionProblem& pr) {
  int n = 0;
  for (const auto& o : pr.obstacles) n += static_cast<int>(o.vertices.size());
  return n;
}

}  // namespace visco::planning::bench
