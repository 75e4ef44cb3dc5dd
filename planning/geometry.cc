#include "planning/geometry.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Exact_rational.h>
#include <CGAL/Interval_nt.h>
#include <CGAL/Polygon_2_algorithms.h>

#include <algorithm>

namespace visco::planning {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using KPoint = Kernel::Point_2;

KPoint ToCgal(const Point& p) { return {p.x(), p.y()}; }

std::vector<KPoint> ToCgal(const Polygon& polygon) {
  std::vector<KPoint> points;
  points.reserve(polygon.size());
  for (const Point& p : polygon.vertices) points.push_back(ToCgal(p));
  return points;
}

int SignOf(const CGAL::Exact_rational& value) { return CGAL::sign(value); }

// Sign of (b - a) x (d - c) or (b - a) . (d - c): interval filter first, exact rationals when the interval
// straddles zero.
int ProductSign(const Point& a, const Point& b, const Point& c, const Point& d, bool cross) {
  {
    CGAL::Protect_FPU_rounding<true> protect;
    using I = CGAL::Interval_nt<false>;
    const I ux = I(b.x()) - I(a.x()), uy = I(b.y()) - I(a.y());
    const I vx = I(d.x()) - I(c.x()), vy = I(d.y()) - I(c.y());
    const I value = cross ? ux * vy - uy * vx : ux * vx + uy * vy;
    if (value.inf() > 0) return 1;
    if (value.sup() < 0) return -1;
    if (value.inf() == 0 && value.sup() == 0) return 0;
  }
  using Q = CGAL::Exact_rational;
  const Q ux = Q(b.x()) - Q(a.x()), uy = Q(b.y()) - Q(a.y());
  const Q vx = Q(d.x()) - Q(c.x()), vy = Q(d.y()) - Q(c.y());
  return SignOf(cross ? Q(ux * vy - uy * vx) : Q(ux * vx + uy * vy));
}

}  // namespace

int Orientation(const Point& a, const Point& b, const Point& c) {
  return static_cast<int>(CGAL::orientation(ToCgal(a), ToCgal(b), ToCgal(c)));
}

int CrossSign(const Point& a, const Point& b, const Point& c, const Point& d) {
  return ProductSign(a, b, c, d, /*cross=*/true);
}

int DotSign(const Point& a, const Point& b, const Point& c, const Point& d) {
  return ProductSign(a, b, c, d, /*cross=*/false);
}

int CompareDistance(const Point& p, const Point& q, const Point& r) {
  return static_cast<int>(CGAL::compare_distance_to_point(ToCgal(p), ToCgal(q), ToCgal(r)));
}

bool OnSegment(const Segment& s, const Point& p) {
  if (Orientation(s.source, s.target, p) != 0) return false;
  return CGAL::collinear_are_ordered_along_line(ToCgal(s.source), ToCgal(p), ToCgal(s.target));
}

bool InSegmentInterior(const Segment& s, const Point& p) {
  if (Orientation(s.source, s.target, p) != 0) return false;
  return CGAL::collinear_are_strictly_ordered_along_line(ToCgal(s.source), ToCgal(p), ToCgal(s.target));
}

bool SegmentsIntersect(const Segment& s, const Segment& t) {
  return CGAL::do_intersect(Kernel::Segment_2(ToCgal(s.source), ToCgal(s.target)),
                            Kernel::Segment_2(ToCgal(t.source), ToCgal(t.target)));
}

bool SegmentsCrossProperly(const Segment& s, const Segment& t) {
  const int o1 = Orientation(s.source, s.target, t.source);
  const int o2 = Orientation(s.source, s.target, t.target);
  const int o3 = Orientation(t.source, t.target, s.source);
  const int o4 = Orientation(t.source, t.target, s.target);
  return o1 * o2 < 0 && o3 * o4 < 0;
}

double PointSegmentDistance(const Point& p, const Point& a, const Point& b) {
  const Vector d = b - a;
  const double len2 = d.squaredNorm();
  const double t = len2 > 0 ? std::clamp((p - a).dot(d) / len2, 0.0, 1.0) : 0.0;
  return (a + t * d - p).norm();
}

double SignedArea(const Polygon& polygon) {
  double area = 0;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Point& p = polygon.Vertex(i);
    const Point& q = polygon.Vertex(i + 1);
    area += p.x() * q.y() - p.y() * q.x();
  }
  return area;
}

int PolygonOrientation(const Polygon& polygon) {
  if (polygon.size() < 3) return 0;
  {
    CGAL::Protect_FPU_rounding<true> protect;
    using I = CGAL::Interval_nt<false>;
    I area(0);
    for (std::size_t i = 0; i < polygon.size(); ++i) {
      const Point& p = polygon.Vertex(i);
      const Point& q = polygon.Vertex(i + 1);
      area += I(p.x()) * I(q.y()) - I(p.y()) * I(q.x());
    }
    if (area.inf() > 0) return 1;
    if (area.sup() < 0) return -1;
  }
  using Q = CGAL::Exact_rational;
  Q area(0);
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Point& p = polygon.Vertex(i);
    const Point& q = polygon.Vertex(i + 1);
    area += Q(p.x()) * Q(q.y()) - Q(p.y()) * Q(q.x());
  }
  return SignOf(area);
}

bool IsSimple(const Polygon& polygon) {
  if (polygon.size() < 3) return false;
  const std::vector<KPoint> points = ToCgal(polygon);
  if (!CGAL::is_simple_2(points.begin(), points.end(), Kernel())) return false;
  return PolygonOrientation(polygon) != 0;
}

Location Locate(const Polygon& polygon, const Point& p) {
  const std::vector<KPoint> points = ToCgal(polygon);
  switch (CGAL::bounded_side_2(points.begin(), points.end(), ToCgal(p), Kernel())) {
    case CGAL::ON_BOUNDED_SIDE:
      return Location::kInside;
    case CGAL::ON_BOUNDARY:
      return Location::kBoundary;
    case CGAL::ON_UNBOUNDED_SIDE:
      break;
  }
  return Location::kOutside;
}

bool InOpenSector(const Point& apex, const Point& first, const Point& second, const Point& towards, bool reverse) {
  const int s = reverse ? -1 : 1;
  const int first_second = Orientation(apex, first, second);
  if (first_second > 0) {  // convex sector (< 180 degrees)
    return s * Orientation(apex, first, towards) > 0 && s * Orientation(apex, towards, second) > 0;
  }
  if (first_second < 0) {  // reflex sector: inside unless in the closed convex complement
    return !(s * Orientation(apex, second, towards) >= 0 && s * Orientation(apex, towards, first) >= 0);
  }
  if (DotSign(apex, first, apex, second) < 0) {  // straight angle: the open half-plane left of apex->first
    return s * Orientation(apex, first, towards) > 0;
  }
  return false;  // zero-angle spike (not a simple polygon's vertex)
}

}  // namespace visco::planning
