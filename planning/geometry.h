#pragma once
// Planar geometry shared by the planner: points, segments, polygons, and exact predicates.
//
// Coordinates are doubles in the world frame (metres, x right, y up). Every predicate here is *exact* for the
// doubles it is given (it decides the sign of the exact real expression, never a rounded one): rays from one camera
// centre are near-degenerate by construction, and rounded predicates give inconsistent answers on them. The
// implementation uses CGAL's filtered predicates (interval arithmetic, exact rational fallback) inside
// geometry.cc; this header stays free of CGAL.
//
// All functions are pure and thread-safe. None is real-time safe unless stated (they do not allocate, but the
// exact fallback may).

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "common/even_odd.h"

namespace visco::planning {

/// A point of the plane (world frame, metres).
using Point = Eigen::Vector2d;
/// A free vector of the plane (metres or unitless direction).
using Vector = Eigen::Vector2d;

/// A closed line segment from `source` to `target`.
struct Segment {
  Point source;
  Point target;
};

/// A polygon as a cyclic list of vertices (the edge i runs from vertices[i] to vertices[(i + 1) % size]).
/// Polygons that the scene loader produces are simple, counter-clockwise and free of repeated consecutive
/// vertices; other producers say what they guarantee.
struct Polygon {
  std::vector<Point> vertices;

  std::size_t size() const { return vertices.size(); }
  const Point& operator[](std::size_t i) const { return vertices[i]; }
  /// Vertex i modulo size (also for i == size).
  const Point& Vertex(std::size_t i) const { return vertices[i % vertices.size()]; }
  /// Edge i, from vertex i to vertex i + 1 (wrapping).
  Segment Edge(std::size_t i) const { return {Vertex(i), Vertex(i + 1)}; }
};

/// A polygonal region: a counter-clockwise outer boundary and clockwise holes.
struct PolygonWithHoles {
  Polygon outer;
  std::vector<Polygon> holes;
};

/// Orientation of the triple (a, b, c): +1 if c lies to the left of the directed line a->b (counter-clockwise
/// turn), -1 to the right, 0 if the three points are collinear (or two coincide). Exact.
int Orientation(const Point& a, const Point& b, const Point& c);

/// Sign of the cross product (b - a) x (d - c): +1 if direction c->d turns counter-clockwise from a->b, -1
/// clockwise, 0 if parallel (or either vector is zero). Exact.
int CrossSign(const Point& a, const Point& b, const Point& c, const Point& d);

/// Sign of the dot product (b - a) . (d - c). Exact.
int DotSign(const Point& a, const Point& b, const Point& c, const Point& d);

/// Compares the distances |p - q| and |p - r|: -1 if q is closer to p, 0 if equal, +1 if r is closer. Exact.
int CompareDistance(const Point& p, const Point& q, const Point& r);

/// Euclidean distance from p to the closed segment ab (a point if a == b). Rounded, not a predicate: for tolerances.
double PointSegmentDistance(const Point& p, const Point& a, const Point& b);

/// Whether p lies on the closed segment s. Exact.
bool OnSegment(const Segment& s, const Point& p);

/// Whether p lies on the segment s strictly between its endpoints. Exact.
bool InSegmentInterior(const Segment& s, const Point& p);

/// Whether the closed segments s and t share at least one point. Exact.
bool SegmentsIntersect(const Segment& s, const Segment& t);

/// Whether s and t cross properly: they meet in exactly one point, interior to both, and are not collinear. Exact.
bool SegmentsCrossProperly(const Segment& s, const Segment& t);

/// Twice the signed area (positive for counter-clockwise polygons). Rounded (not exact); use
/// PolygonOrientation for the sign.
double SignedArea(const Polygon& polygon);

/// Orientation of a simple polygon: +1 counter-clockwise, -1 clockwise, 0 degenerate (fewer than 3 vertices or
/// all collinear). Exact.
int PolygonOrientation(const Polygon& polygon);

/// Whether the polygon is simple: at least 3 vertices, no repeated vertex, edges meet only at shared endpoints of
/// consecutive edges, nonzero area. Exact.
bool IsSimple(const Polygon& polygon);

/// Where a point lies relative to a polygon.
enum class Location { kOutside, kBoundary, kInside };

/// Locates p relative to a simple polygon (either orientation). Exact. O(n).
Location Locate(const Polygon& polygon, const Point& p);

/// Even-odd (crossing-number) test of p against a closed ring of vertices, in rounded arithmetic: for sampling and
/// simulation, where a point within rounding of an edge may go either way (use Locate when it must not). O(n).
/// (common/even_odd.h: the motion model uses it too.)
using visco::InsideEvenOdd;

/// Whether the direction from `apex` towards `towards` points strictly into the open angular sector that is swept
/// counter-clockwise from the direction apex->first to the direction apex->second (the interior angle at a vertex of
/// a counter-clockwise polygon is the sector from apex->next to apex->previous). A straight sector (first and second
/// opposite) is the open half-plane to the left of apex->first. Set `reverse` to test the opposite direction
/// (from `towards` through `apex` and beyond). Exact.
bool InOpenSector(const Point& apex, const Point& first, const Point& second, const Point& towards,
                  bool reverse = false);

}  // namespace visco::planning
