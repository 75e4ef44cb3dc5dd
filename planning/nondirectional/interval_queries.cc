// Interval queries on a nondirectional backprojection (nondirectional.h): IntervalsContaining, and the containment
// tests it and the strategy use (FeatureMeetsRegion, RegionContainsPolygon).

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
#include "planning/nondirectional/event_points.h"
#include "planning/nondirectional/ring_geometry.h"

namespace visco::planning {

using Eigen::Vector2d;
using internal::AddEventPoints;
using internal::Cross;
using internal::EventPoint;
using internal::ForEachRing;
using internal::IsEventPoint;
using internal::kSameTheta;
using internal::SegmentsDistance;

bool FeatureMeetsRegion(const std::vector<Vector2d>& feature, const Region& region, double tolerance) {
  if (feature.empty() || region.polygons.empty()) return false;
  for (const auto& p : feature) {
    if (region.Contains(p)) return true;
  }
  // Otherwise the feature meets the closure only by touching or crossing a ring (a point as a segment of length 0).
  const Vector2d &a = feature.front(), &b = feature.back();
  bool meets = false;
  ForEachRing(region, [&](const RegionRing& r) {
    const size_t n = r.vertices.size();
    for (size_t i = 0; i < n && !meets; ++i) {
      meets = SegmentsDistance(a, b, r.vertices[i], r.vertices[(i + 1) % n]) <= tolerance;
    }
  });
  return meets;
}

bool RegionContainsPolygon(const Region& region, const std::vector<Vector2d>& polygon, double tolerance,
                           double* clearance) {
  std::vector<std::array<Vector2d, 2>> edges;
  std::vector<bool> obstacle;  // C-obstacle edges: walls, not a risk to be near (they do not count in the clearance)
  ForEachRing(region, [&](const RegionRing& r) {
    for (size_t i = 0; i < r.vertices.size(); ++i) {
      edges.push_back({r.vertices[i], r.vertices[(i + 1) % r.vertices.size()]});
      obstacle.push_back(i < r.edges.size() && r.edges[i].kind == EdgeKind::kObstacle);
    }
  });
  auto inside = [&](const Vector2d& p) { return region.Contains(p) || region.BoundaryDistance(p) <= tolerance; };
  const size_t n = polygon.size();
  double clear = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < n; ++i) {
    const Vector2d a = polygon[i], b = polygon[(i + 1) % n];
    if (!inside(a)) return false;
    // Split the edge where it meets the region's boundary; every piece must be inside.
    std::vector<double> cuts = {0.0, 1.0};
    const Vector2d d = b - a;
    for (size_t k = 0; k < edges.size(); ++k) {
      const auto& e = edges[k];
      const Vector2d f = e[1] - e[0];
      const double den = Cross(d, f);
      if (!obstacle[k]) clear = std::min(clear, SegmentsDistance(a, b, e[0], e[1]));
      if (std::abs(den) < 1e-300) continue;
      const double t = Cross(e[0] - a, f) / den, u = Cross(e[0] - a, d) / den;
      if (t > 0 && t < 1 && u >= 0 && u <= 1) cuts.push_back(t);
    }
    std::sort(cuts.begin(), cuts.end());
    for (size_t k = 0; k + 1 < cuts.size(); ++k) {
      if (!inside(a + 0.5 * (cuts[k] + cuts[k + 1]) * d)) return false;
    }
  }
  if (clearance) *clearance = clear;
  return true;
}

namespace {

// How far (relative to the scene's size) R must be from a carried region's moving edges for the carried region to
// decide containment: the carrying's error is about 1e-12 on the test scenes (NondirectionalProperty).
constexpr double kCarryMargin = 1e-6;

// Whether a point of the polygon's boundary (a vertex, or one of 16 points along each edge) lies outside the region
// farther than `margin` from its boundary.
bool ClearlyOutside(const Region& region, const std::vector<Vector2d>& polygon, double margin) {
  const size_t n = polygon.size();
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 16; ++k) {
      const Vector2d p = polygon[i] + (k / 16.0) * (polygon[(i + 1) % n] - polygon[i]);
      if (!region.Contains(p) && region.BoundaryDistance(p) > margin) return true;
    }
  }
  return false;
}

}  // namespace

std::vector<ThetaInterval> IntervalsContaining(const NondirectionalBackprojection& nd,
                                               const BackprojectionProblem& problem, const NamedPolygon& region,
                                               bool vc, IntervalQueryStats* stats) {
  const double size = (problem.bounds_max - problem.bounds_min).norm();
  // Breakpoints: the slices' orientations and R's own R-critical orientations where their sources are vertices of
  // the region there.
  std::vector<double> cuts;
  for (size_t s = 0; s < nd.slices.size(); s += 2) {
    if (nd.slices[s].critical) cuts.push_back(nd.slices[s].theta);
  }
  for (const auto& c : RCriticalCandidates(problem, region)) {
    const Slice& s = SliceAt(nd, c.theta);
    bool relevant = c.sources.empty();
    std::vector<EventPoint> points;
    AddEventPoints(vc ? s.vc.region : s.vc.classic, points);
    for (const auto& src : c.sources) relevant = relevant || IsEventPoint(points, src, 0, 1e-9 * size);
    if (relevant) cuts.push_back(c.theta);
  }
  std::sort(cuts.begin(), cuts.end());
  cuts.erase(std::unique(cuts.begin(), cuts.end(), [](double x, double y) { return y - x <= kSameTheta; }), cuts.end());
  if (cuts.empty()) cuts.push_back(-M_PI);
  std::vector<ThetaInterval> out;
  const size_t n = cuts.size();
  std::vector<bool> in(n, false);
  std::vector<double> margin(n, 0.0), mids(n, 0.0);
  int carried_decisions = 0;
  for (size_t k = 0; k < n; ++k) {
    const double lo = cuts[k], hi = k + 1 < n ? cuts[k + 1] : cuts[0] + 2 * M_PI;
    const double mid = WrapAngle(0.5 * (lo + hi));
    mids[k] = mid;
    // The slice's region carried to the midpoint decides without a sweep where R is clearly in (its clearance from
    // every edge that moves exceeds the carrying's error many times) or clearly out (a point of R's boundary that
    // far outside); a sweep decides the rest.
    double clear = 0;
    const Region carried = RegionAt(nd, mid, vc);
    const bool carried_in = RegionContainsPolygon(carried, region.vertices, 1e-9 * size, &clear);
    if (carried_in ? clear > kCarryMargin * size : ClearlyOutside(carried, region.vertices, kCarryMargin * size)) {
      in[k] = carried_in;
      margin[k] = carried_in ? clear : 0.0;
      ++carried_decisions;
      continue;
    }
    BackprojectionProblem p = problem;
    p.theta = mid;
    const Slice& s = SliceAt(nd, mid);
    const Region reg = vc ? BackprojectionWithActiveRays(p, s.vc.active_rays) : ClassicBackprojection(p);
    clear = 0;
    in[k] = RegionContainsPolygon(reg, region.vertices, 1e-9 * size, &clear);
    margin[k] = clear;
  }
  if (stats) *stats = {static_cast<int>(n), carried_decisions};
  // Merge runs of containing intervals (wrapping).
  size_t first = 0;
  while (first < n && in[first]) ++first;
  if (first == n) {
    ThetaInterval all{-M_PI, M_PI, 0.0, 0.0};
    for (size_t k = 0; k < n; ++k) {
      if (margin[k] > all.margin) all.margin = margin[k], all.best_theta = mids[k];
    }
    return {all};
  }
  bool open = false;
  for (size_t step = 1; step <= n; ++step) {
    const size_t k = (first + step) % n;
    if (!in[k]) {
      open = false;
      continue;
    }
    if (!open) out.push_back({cuts[k], cuts[k], -1.0, mids[k]});
    open = true;
    ThetaInterval& cur = out.back();
    double hi = k + 1 < n ? cuts[k + 1] : cuts[0] + 2 * M_PI;
    while (hi < cur.lo) hi += 2 * M_PI;
    cur.hi = hi;
    if (margin[k] > cur.margin) cur.margin = margin[k], cur.best_theta = mids[k];
  }
  return out;
}

}  // namespace visco::planning
