// Regions with provenance (backprojection.h): edge kinds' names, point containment and boundary distance.

#include <algorithm>
#include <cmath>
#include <limits>

#include "planning/backprojection.h"
#include "planning/geometry.h"

namespace visco::planning {

using Eigen::Vector2d;

const char* EdgeKindName(EdgeKind kind) {
  switch (kind) {
    case EdgeKind::kObstacle:
      return "obstacle";
    case EdgeKind::kGoal:
      return "goal";
    case EdgeKind::kFree:
      return "free";
    case EdgeKind::kVc:
      return "vc";
    case EdgeKind::kBounds:
      return "bounds";
  }
  return "?";
}

bool Region::Contains(const Vector2d& p) const {
  for (const auto& poly : polygons) {
    if (!InsideEvenOdd(poly.outer.vertices, p)) continue;
    bool in_hole = false;
    for (const auto& h : poly.holes) in_hole |= InsideEvenOdd(h.vertices, p);
    if (!in_hole) return true;
  }
  return false;
}

double Region::BoundaryDistance(const Vector2d& p) const {
  double best = std::numeric_limits<double>::infinity();
  auto ring_distance = [&](const RegionRing& r) {
    for (size_t i = 0; i < r.vertices.size(); ++i) {
      const Vector2d& a = r.vertices[i];
      const Vector2d& b = r.vertices[(i + 1) % r.vertices.size()];
      const Vector2d ab = b - a;
      const double s = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
      best = std::min(best, (p - (a + s * ab)).norm());
    }
  };
  for (const auto& poly : polygons) {
    ring_distance(poly.outer);
    for (const auto& h : poly.holes) ring_distance(h);
  }
  return best;
}

}  // namespace visco::planning
