// The kinetic walk's relevance rules (kinetic_walk.h): which events can change the last swept slice's regions.

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
#include "planning/nondirectional/carry.h"
#include "planning/nondirectional/kinetic_walk.h"
#include "planning/nondirectional/ring_geometry.h"

namespace visco::planning::internal {

std::vector<EventPoint> KineticWalk::EventPointsOf(const Slice& s) const {
  std::vector<EventPoint> v;
  AddEventPoints(s.vc.classic, v);
  AddEventPoints(s.vc.region, v);
  return v;
}

std::vector<EventPoint> KineticWalk::WalkPointsOf(const Slice& s) const {
  if (options_.vertex_events) return EventPointsOf(s);
  std::vector<EventPoint> v;
  AddFreeEdgePoints(s.vc.classic, v);
  AddFreeEdgePoints(s.vc.region, v);
  return v;
}

bool KineticWalk::Relevant(const CriticalOrientation& c, const std::vector<EventPoint>& ends) const {
  for (size_t k = 0; k < c.sources.size(); ++k) {
    const int want = k < c.source_signs.size() ? c.source_signs[k] : 0;
    if (!IsEventPoint(ends, c.sources[k], want, 1e-9 * size_)) return false;
  }
  return true;
}

bool KineticWalk::CanChange(const CriticalOrientation& c, const std::vector<EventPoint>& ends, const Slice& s,
                            CarriedAt& carried) const {
  const auto feature_meets_regions = [&] {
    const double tol = 1e-9 * size_;
    return FeatureMeetsRegion(c.feature, s.vc.classic, tol) || FeatureMeetsRegion(c.feature, s.vc.region, tol);
  };
  if (c.kind == CriticalKind::kSliding && options_.local_sliding && !c.feature.empty()) {
    // The cone pointing away from the obstacle, θ itself along the edge, the vertex rule's bisector pointing out
    // of CB, the edge sticking on both sides: no velocity's contact changes.
    if (SlidingCauseChangesNothing(c.sliding)) return false;
    return feature_meets_regions();
  }
  if (Relevant(c, ends)) {
    if (!options_.boundary_events || options_.vertex_events || c.point.empty()) return true;
    const double tol = kOnBoundary * size_;
    const auto& regions = carried.Get();
    return PointNearBoundary(c.point.front(), regions[0], tol) || PointNearBoundary(c.point.front(), regions[1], tol);
  }
  // A free edge turning across the line of a static segment: a part of the region can appear along the segment.
  return !options_.vertex_events && c.kind == CriticalKind::kVgraph && !c.feature.empty() && feature_meets_regions();
}

bool KineticWalk::EventRelevant(size_t k, const std::vector<EventPoint>& ends, const Slice& current) const {
  CarriedAt carried(current, EventTheta(k), pr_.velocity_cone);
  CriticalOrientation c;
  for (size_t i = events_[k].begin; i < events_[k].end; ++i) {
    structural_.Get(i, c, false);
    if (CanChange(c, ends, current, carried)) return true;
  }
  return false;
}

int KineticWalk::PickCandidate(size_t k, const Slice& before, const Slice& after) const {
  auto vb = EventPointsOf(before), va = EventPointsOf(after);
  CarriedAt cb(before, EventTheta(k), pr_.velocity_cone), ca(after, EventTheta(k), pr_.velocity_cone);
  // Prefer the specific kinds (a free edge parallel to a ray is also parallel to the segment of its two ends).
  static const CriticalKind priority[] = {CriticalKind::kVc, CriticalKind::kFreeEdge, CriticalKind::kVertex,
                                          CriticalKind::kSliding, CriticalKind::kVgraph};
  CriticalOrientation c;
  for (CriticalKind kind : priority) {
    for (size_t i = events_[k].begin; i < events_[k].end; ++i) {
      if (structural_.kind(i) != kind) continue;
      structural_.Get(i, c, false);
      if (CanChange(c, vb, before, cb) || CanChange(c, va, after, ca)) return static_cast<int>(i);
    }
  }
  // No candidate the rules take (a change they missed): the first that can change anything at all.
  for (size_t i = events_[k].begin; i < events_[k].end; ++i) {
    if (!SlidingCauseChangesNothing(structural_.sliding(i))) return static_cast<int>(i);
  }
  return static_cast<int>(events_[k].begin);
}

}  // namespace visco::planning::internal
