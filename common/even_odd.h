#pragma once
// The even-odd point-in-polygon test, rounded (not exact): shared by the motion model (common/) and the planner.

#include <Eigen/Core>
#include <cstddef>
#include <vector>

namespace visco {

/// Even-odd rule on one ring (either orientation), rounded: true if p is inside. Points on the boundary may go
/// either way; callers that care test the boundary first.
inline bool InsideEvenOdd(const std::vector<Eigen::Vector2d>& ring, const Eigen::Vector2d& p) {
  bool inside = false;
  for (std::size_t i = 0, j = ring.size() - 1; i < ring.size(); j = i++) {
    const Eigen::Vector2d& a = ring[i];
    const Eigen::Vector2d& b = ring[j];
    if ((a.y() > p.y()) != (b.y() > p.y())) {
      const double x = a.x() + (p.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
      if (p.x() < x) inside = !inside;
    }
  }
  return inside;
}

}  // namespace visco
