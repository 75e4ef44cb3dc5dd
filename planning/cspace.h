#pragma once
// Configuration space of a translating robot (Fox & Hutchinson §III, docs/semantics.md "Frames and units"):
// C-obstacles CB_i = B_i (+) (-A) (Minkowski sums, robot and obstacles possibly non-convex), their union CB, and the
// free space (the bounds rectangle minus the interior of CB).
//
// Computed exactly (CGAL, exact constructions) and kept exact inside (PIMPL); the double polygons below are the
// exact ones rounded to the nearest double, for drawing and for consumers that need coordinates. Queries
// (Locate, region tests) are answered on the exact representation. Every boundary edge of the C-obstacles and of
// their union carries its provenance (EdgeSource: the Minkowski feature it lies on), computed exactly.

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "planning/geometry.h"
#include "planning/scene.h"

namespace visco::planning {

/// The Minkowski feature a boundary edge of a C-obstacle lies on (docs/planning_cspace.md "Edge provenance").
/// CB_i = B_i (+) (-A) is bounded by pieces of two kinds of segments (b: obstacle i's vertices, a: the robot's):
///   kObstacleEdge: obstacle edge [b_k, b_k+1] translated by -a_j:   [b_k - a_j, b_k+1 - a_j],
///                  ref "obstacle[ID].e[k]-robot.v[j]";
///   kRobotEdge:    reflected robot edge [-a_j, -a_j+1] translated by b_k: [b_k - a_j, b_k - a_j+1],
///                  ref "obstacle[ID].v[k]-robot.e[j]".
/// k and j are file positions (docs/formats.md "Indices in outputs"; edge k runs from file vertex k to k + 1).
/// Generators are ordered by (obstacle, kind with kObstacleEdge first, obstacle_feature, robot_feature); every
/// boundary point gets the first generator whose segment contains it (collinear, coincident generators are
/// resolved that way), and boundary edges are split where that generator changes, so each edge has exactly one.
struct EdgeSource {
  enum class Kind : std::uint8_t { kObstacleEdge, kRobotEdge };
  Kind kind = Kind::kObstacleEdge;
  std::size_t obstacle = 0;  ///< index in Scene::obstacles
  int obstacle_feature = 0;  ///< file index of the obstacle's edge (kObstacleEdge) or vertex (kRobotEdge)
  int robot_feature = 0;     ///< file index of the robot's vertex (kObstacleEdge) or edge (kRobotEdge)
  std::string ref;           ///< as above; a deterministic function of the scene
};

/// Provenance of a ring's edges and vertices: edges[k] for the edge from vertex k to k + 1 (wrapping);
/// vertex_refs[k] names vertex k: "obstacle[ID].v[k]-robot.v[j]" when it is that Minkowski sum of vertices (the
/// first such (obstacle, k, j)), else "x(<ref>,<ref>)" with the refs of the two edges meeting there, sorted.
struct RingSources {
  std::vector<EdgeSource> edges;
  std::vector<std::string> vertex_refs;
};

/// Provenance of a polygon with holes (same order as its rings).
struct PolygonSources {
  RingSources outer;
  std::vector<RingSources> holes;
};

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
  /// on_cb[i][k]: whether the source and the target of parts[i][k] lie on CB's boundary (exact, before rounding).
  /// An end that does not was clipped by the bounds or is the input's own end in free space.
  std::vector<std::vector<std::array<bool, 2>>> on_cb;
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
  /// obstacle can enclose holes). Edges are split where their EdgeSource changes (so a side that is the sum of
  /// parallel obstacle and robot edges has a vertex inside it), and collinear vertices inside one generator's
  /// segment are dropped.
  const std::vector<PolygonWithHoles>& c_obstacle(std::size_t i) const;
  std::size_t num_c_obstacles() const;
  /// CB, the union of all C-obstacles (counter-clockwise outer boundaries, clockwise holes); edges split as for
  /// c_obstacle.
  const std::vector<PolygonWithHoles>& obstacle_union() const;
  /// The bounds rectangle minus the interior of CB (closed free space).
  const std::vector<PolygonWithHoles>& free_space() const;
  /// Provenance of c_obstacle(i)'s edges and vertices (from obstacle i's generators), ring for ring.
  const std::vector<PolygonSources>& c_obstacle_sources(std::size_t i) const;
  /// Provenance of obstacle_union()'s edges and vertices (from all obstacles' generators), ring for ring.
  const std::vector<PolygonSources>& obstacle_union_sources() const;

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
