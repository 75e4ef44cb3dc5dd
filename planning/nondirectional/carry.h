#pragma once
// Carrying a region to another θ without a sweep (CarryRegion, RegionAt, nondirectional.h: Briggs's rotating free
// vertices): the line each edge lies on at θ and the vertices recomputed where consecutive lines meet (internal to the
// nondirectional backprojection; in a header so that it can be unit tested).

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "planning/backprojection.h"

namespace visco::planning::internal {

using Eigen::Vector2d;

// The line an edge of a ring lies on at θ: a free edge's through its source, direction θ + π ± ε_v by its ref's
// suffix; any other edge's is the line of the static segment it lies on (it does not move).
struct EdgeLine {
  Vector2d point, dir;
  bool free = false;
};

EdgeLine LineOf(const RegionRing& ring, size_t i, double theta, double eps);

double RingArea2(const std::vector<Vector2d>& v);

RegionRing CarryRing(const RegionRing& ring, double theta, double eps);

// Where the lines of two edges meet at θ, unless they are (nearly) parallel.
std::optional<Vector2d> MeetAt(const RegionEdge& u, const RegionEdge& w, double theta, double eps);
}  // namespace visco::planning::internal
