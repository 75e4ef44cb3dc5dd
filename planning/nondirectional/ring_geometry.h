#pragma once
// Small double-precision helpers on the rings of a region, shared by the nondirectional backprojection's parts
// (internal; in a header so that they can be unit tested).

#include <Eigen/Core>
#include <algorithm>
#include <cmath>

#include "planning/backprojection.h"
#include "planning/geometry.h"

namespace visco::planning::internal {

using Eigen::Vector2d;

inline double Cross(const Vector2d& u, const Vector2d& v) { return u.x() * v.y() - u.y() * v.x(); }

inline double SegmentsDistance(const Vector2d& a, const Vector2d& b, const Vector2d& c, const Vector2d& d) {
  const double den = Cross(b - a, d - c);
  if (std::abs(den) > 0) {
    const double t = Cross(c - a, d - c) / den, u = Cross(c - a, b - a) / den;
    if (t >= 0 && t <= 1 && u >= 0 && u <= 1) return 0.0;
  }
  return std::min({PointSegmentDistance(a, c, d), PointSegmentDistance(b, c, d), PointSegmentDistance(c, a, b),
                   PointSegmentDistance(d, a, b)});
}

template <typename F>
void ForEachRing(const Region& region, F&& f) {
  for (const auto& poly : region.polygons) {
    f(poly.outer);
    for (const auto& h : poly.holes) f(h);
  }
}

// Whether p lies within `tolerance` of a ring of `region`.
inline bool PointNearBoundary(const Vector2d& p, const Region& region, double tolerance) {
  bool near = false;
  ForEachRing(region, [&](const RegionRing& r) {
    const size_t n = r.vertices.size();
    for (size_t i = 0; i < n && !near; ++i)
      near = PointSegmentDistance(p, r.vertices[i], r.vertices[(i + 1) % n]) <= tolerance;
  });
  return near;
}

}  // namespace visco::planning::internal
