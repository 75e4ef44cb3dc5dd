// Event points (event_points.h).

#include "planning/nondirectional/event_points.h"

#include <algorithm>

#include "planning/nondirectional/ring_geometry.h"

namespace visco::planning::internal {

void AddEventPoints(const Region& region, std::vector<EventPoint>& out) {
  ForEachRing(region, [&](const RegionRing& ring) {
    for (size_t i = 0; i < ring.vertices.size(); ++i) {
      out.push_back({ring.vertices[i], 0});
      if (ring.edges[i].kind == EdgeKind::kFree) out.push_back({ring.edges[i].source, ring.edges[i].sign});
    }
  });
}

void AddFreeEdgePoints(const Region& region, std::vector<EventPoint>& out) {
  ForEachRing(region, [&](const RegionRing& ring) {
    const size_t n = ring.vertices.size();
    for (size_t i = 0; i < n; ++i) {
      if (ring.edges[i].kind != EdgeKind::kFree) continue;
      const int sign = ring.edges[i].sign;
      out.push_back({ring.edges[i].source, sign});
      out.push_back({ring.vertices[i], sign});
      out.push_back({ring.vertices[(i + 1) % n], sign});
    }
  });
}

bool IsEventPoint(const std::vector<EventPoint>& points, const Vector2d& p, int want, double tolerance) {
  return std::any_of(points.begin(), points.end(), [&](const EventPoint& e) {
    return (e.p - p).norm() <= tolerance && (e.sign == 0 || want == 0 || e.sign == want);
  });
}

}  // namespace visco::planning::internal
