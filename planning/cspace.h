#pragma once
// Configuration space of a translating robot (Fox & Hutchinson §III, SEMANTICS.md "Frames and units"):
// C-obstacles CB_i = B_i (+) (-A) (Minkowski sums, robot and obstacles possibly non-convex), their union CB, and the
// free space (the bounds rectangle minus the interior of CB).
//
// Computed exactly (CGAL, exact constructions) and kept exact inside (PIMPL); the double polygons below are the
// exact ones rounded to the nearest double, for drawing and for consumers that need coordinates. Queries
// (Locate, region tests) are answered on the exact representation.

#include <cstddef>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "planning/geometry.h"
#include "planning/scene.h"

namespace visco::planning {

/// A segment given by double endpoints and a double offset, standing exactly for
/// [source + offset, target + offset] (the sum is formed exactly, never rounded).
struct OffsetSegment {
  Point source;
  Point target;
  Vector offset = Vector::Zero();
};

/// Result of CSpace::CutSegments.
struct CutResult {
  /// parts[i]: the maximal parts of positive length of input i that stay outside the interior of CB and inside the
  /// closed bounds, ordered from source to target (endpoints rounded to doubles).
  std::vector<std::vector<Segment>> parts;
  /// A point shared by the parts of two different inputs.
  struct Crossing {
    std::size_t first = 0;   // input index, first < second
    std::size_t second = 0;  // input index
    Point point;             // rounded to doubles
    bool overlap = false;    // the two are collinear and overlap; point is an end of the overlap
  };
  /// Sorted by (first, second), then along the line for overlaps. Empty unless asked for.
  std::vector<Crossing> crossings;
};

class CSpace {
 public:
  /// Computes the C-obstacles, their union and the free space of a scene. O(N log N) in the size N of the
  /// arrangement of the Minkowski sums. Not real-time safe.
  explicit CSpace(const Scene& scene);
  ~CSpace();
  CSpace(CSpace&&) noexcept;
  CSpace& operator=(CSpace&&) noexcept;
  CSpace(const CSpace&) = delete;
  CSpace& operator=(const CSpace&) = delete;

  /// CB_i for obstacle i (same order as Scene::obstacles): one or more polygons with holes (a non-convex robot and
  /// obstacle can enclose holes).
  const std::vector<PolygonWithHoles>& c_obstacle(std::size_t i) const;
  std::size_t num_c_obstacles() const;
  /// CB, the union of all C-obstacles (counter-clockwise outer boundaries, clockwise holes).
  const std::vector<PolygonWithHoles>& obstacle_union() const;
  /// The bounds rectangle minus the interior of CB (closed free space).
  const std::vector<PolygonWithHoles>& free_space() const;

  /// Where q lies relative to CB: kInside (interior of CB), kBoundary, kOutside. Exact.
  Location Locate(const Point& q) const;
  /// Whether a simple polygon keeps a part of positive area outside CB (false if it lies entirely inside CB). Exact.
  bool HasFreePart(const Polygon& region) const;

  /// Cuts segments where they enter the interior of CB and clips them to the bounds (Fox & Hutchinson §III-C-1);
  /// with `crossings`, also finds where the remaining parts of different inputs meet (§III-C-2). Exact throughout;
  /// O((k + c + x) log(k + n)) with k inputs, n edges of CB, c segment/edge meetings and x crossings
  /// (bounding-box sweep, CGAL box_intersection_d). Not real-time safe.
  CutResult CutSegments(const std::vector<OffsetSegment>& segments, const Bounds& bounds, bool crossings) const;

  /// The exact representation, for the planner's other exact algorithms (opaque outside planning/*.cc).
  struct Exact;
  const Exact& exact() const { return *exact_; }

 private:
  std::unique_ptr<Exact> exact_;
};

/// The first pair (i, j), i < j, of obstacles whose interiors overlap (touching is allowed), if any. Exact.
std::optional<std::pair<std::size_t, std::size_t>> FindOverlappingObstacles(const std::vector<Obstacle>& obstacles);

}  // namespace visco::planning
