// Carrying a region to another θ (carry.h; CarryRegion, RegionAt and SliceAt of nondirectional.h).

#include "planning/nondirectional/carry.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "planning/geometry.h"
#include "planning/nondirectional.h"
#include "planning/nondirectional/ring_geometry.h"

namespace visco::planning::internal {

EdgeLine LineOf(const RegionRing& ring, size_t i, double theta, double eps) {
  const RegionEdge& e = ring.edges[i];
  if (e.kind == EdgeKind::kFree) {
    const double angle = theta + M_PI + (e.sign > 0 ? eps : -eps);
    return {e.source, Vector2d(std::cos(angle), std::sin(angle)), true};
  }
  // The static segment it lies on as the sweep recorded it (exact up to one rounding), else its own two ends (less
  // precise when the edge is short).
  if (e.line[0] != e.line[1]) return {e.line[0], e.line[1] - e.line[0], false};
  const Vector2d& a = ring.vertices[i];
  const Vector2d& b = ring.vertices[(i + 1) % ring.vertices.size()];
  return {a, b - a, false};
}

double RingArea2(const std::vector<Vector2d>& v) {
  double a = 0;
  for (size_t i = 0; i < v.size(); ++i) a += Cross(v[i], v[(i + 1) % v.size()]);
  return a;
}

RegionRing CarryRing(const RegionRing& ring, double theta, double eps) {
  RegionRing out = ring;
  const size_t n = ring.vertices.size();
  if (n == 0 || ring.edges.size() != n) return out;
  std::vector<EdgeLine> lines(n);
  for (size_t i = 0; i < n; ++i) lines[i] = LineOf(ring, i, theta, eps);
  for (size_t i = 0; i < n; ++i) {
    const EdgeLine& u = lines[(i + n - 1) % n];  // the edge into vertex i
    const EdgeLine& w = lines[i];                // the edge out of it
    if (!u.free && !w.free) continue;            // two edges that do not move meet where they did
    const double den = Cross(u.dir, w.dir);
    // Parallel lines meet nowhere: only at a critical orientation (a vgraph or vc event), where nothing is carried.
    if (std::abs(den) <= 1e-15 * u.dir.norm() * w.dir.norm()) continue;
    out.vertices[i] = u.point + (Cross(w.point - u.point, w.dir) / den) * u.dir;
  }
  return out;
}

std::optional<Vector2d> MeetAt(const RegionEdge& u, const RegionEdge& w, double theta, double eps) {
  const RegionRing pair{{Vector2d::Zero(), Vector2d::Zero()}, {u, w}};
  const EdgeLine a = LineOf(pair, 0, theta, eps), b = LineOf(pair, 1, theta, eps);
  const double den = Cross(a.dir, b.dir);
  if (!(std::abs(den) > 1e-12 * a.dir.norm() * b.dir.norm())) return std::nullopt;
  return a.point + (Cross(b.point - a.point, b.dir) / den) * a.dir;
}

}  // namespace visco::planning::internal

namespace visco::planning {

using internal::CarryRing;
using internal::RingArea2;

const Slice& SliceAt(const NondirectionalBackprojection& nd, double theta) {
  if (nd.slices.size() == 1) return nd.slices[0];
  theta = WrapAngle(theta);
  for (size_t s = 0; s < nd.slices.size(); s += 2) {
    if (std::abs(WrapAngle(theta - nd.slices[s].theta)) <= 1e-12) return nd.slices[s];
  }
  for (size_t s = 1; s < nd.slices.size(); s += 2) {
    const Slice& sl = nd.slices[s];
    for (double t : {theta, theta + 2 * M_PI}) {
      if (t > sl.lo && t < sl.hi) return sl;
    }
  }
  return nd.slices.back();
}

Region CarryRegion(const Region& region, double theta, double velocity_cone) {
  // θ₀ is not needed: the free edges' lines depend on θ only, and the other edges and the sources do not move.
  const double eps = std::max(velocity_cone, 1e-9);  // as the sweep plans a cone of zero width
  Region out;
  double area2 = 0;
  for (const auto& poly : region.polygons) {
    RegionPolygon q{CarryRing(poly.outer, theta, eps), {}};
    area2 += RingArea2(q.outer.vertices);
    for (const auto& h : poly.holes) {
      q.holes.push_back(CarryRing(h, theta, eps));
      area2 += RingArea2(q.holes.back().vertices);
    }
    out.polygons.push_back(std::move(q));
  }
  out.area = 0.5 * area2;
  return out;
}

Region RegionAt(const NondirectionalBackprojection& nd, double theta, bool vc) {
  const Slice& s = SliceAt(nd, theta);
  const Region& r = vc ? s.vc.region : s.vc.classic;
  if (s.critical) return r;
  return CarryRegion(r, theta, nd.velocity_cone);
}

}  // namespace visco::planning
