#pragma once
// Event points: where an event can change a region (the kinetic walk's relevance rules look there; internal to the
// nondirectional backprojection, in a header so that it can be unit tested).

#include <Eigen/Core>
#include <vector>

#include "planning/backprojection.h"

namespace visco::planning::internal {

using Eigen::Vector2d;

constexpr double kSameTheta = 1e-10;  // candidates closer than this are one event

// How near (relative to the scene's size) an event's point must be to a carried region's boundary to count as on
// it: the carrying's error is about 1e-12 (NondirectionalProperty), and candidates up to 1e-10 rad apart are one
// event.
constexpr double kOnBoundary = 1e-7;

// A point where an event can change a region, and which of the point's two free edges it must involve (+1:
// direction θ + π + ε_v, −1: θ + π − ε_v, 0: either).
struct EventPoint {
  Vector2d p;
  int sign = 0;
};

// Where events can change `region`, broadly (the R-critical cuts, the reported candidate, the walk's broad rule): at
// the static point a free edge of it is erected at (its source), involving that free edge, and at every vertex,
// involving either free edge there. A free edge usually starts at its source, but not
// always: where the part next to the source lies outside the region (in a forbidden region beside a goal strip, or
// beyond the bounds), the region's edge starts where the line leaves it, and events at the source move that edge all
// the same (VISCO_SEED_OFFSET=19507001, strategy seed 11: the free vertex of a goal strip's two free edges crossed
// the bounds unseen, and a slice spanning 133° was carried to a region of area 15 where the sweep gives 0.03). And a
// vertex where a free edge does not start yet is where a part of the region can appear, attached (and go again
// before the next sweep: the strip property).
void AddEventPoints(const Region& region, std::vector<EventPoint>& out);

// The kinetic walk's narrower rule: only the free edges of `region` (their sources, and their two ends, each with
// its sign). A part of the region that appears attached at a vertex where no free edge starts does so where a free
// edge turns across a static segment's line at that vertex (the segment's `along` vgraph events, decided by whether
// the segment meets the region: CanChange) or where an edge starts or stops sticking (sliding events).
void AddFreeEdgePoints(const Region& region, std::vector<EventPoint>& out);

// Whether `p` is one of `points`, for the free edge of sign `want` (0: either).
bool IsEventPoint(const std::vector<EventPoint>& points, const Vector2d& p, int want, double tolerance);
}  // namespace visco::planning::internal
