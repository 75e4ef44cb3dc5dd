#pragma once
// The exact arithmetic of the plane sweep (internal to the directional backprojection; in a header so that it can be
// unit tested): CGAL's lazy exact kernel, point order and equality decided on the interval approximations first,
// and the clockwise order of directions.

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>

#include <Eigen/Core>
#include <vector>

namespace visco::planning::internal {

using K = CGAL::Exact_predicates_exact_constructions_kernel;
using FT = K::FT;
using P2 = K::Point_2;
using V2 = K::Vector_2;
using Seg = K::Segment_2;

using Eigen::Vector2d;

// Point equality and (y, x) order, decided on the interval approximations when they are apart and otherwise on the
// exact values directly (one shared point, the common case in the sweep, is equal at once). The same answers as
// CGAL's filtered `==` and compare_yx, without their cost on ties: there
// the interval predicate cannot decide and CGAL throws and catches an exception before it computes exactly (12 % of
// `visco plan` went to throwing and unwinding, mostly for points that are equal).
inline CGAL::Comparison_result CompareApprox(const CGAL::Interval_nt<false>& a, const CGAL::Interval_nt<false>& b) {
  if (a.sup() < b.inf()) return CGAL::SMALLER;
  if (a.inf() > b.sup()) return CGAL::LARGER;
  return CGAL::EQUAL;  // undecided
}
inline bool Same(const P2& a, const P2& b) {
  if (CGAL::identical(a, b)) return true;
  const auto &ia = a.approx(), &ib = b.approx();
  if (CompareApprox(ia.x(), ib.x()) != CGAL::EQUAL || CompareApprox(ia.y(), ib.y()) != CGAL::EQUAL) return false;
  return a.exact() == b.exact();
}
inline CGAL::Comparison_result CompareYX(const P2& a, const P2& b) {
  if (CGAL::identical(a, b)) return CGAL::EQUAL;
  const auto &ia = a.approx(), &ib = b.approx();
  const CGAL::Comparison_result y = CompareApprox(ia.y(), ib.y());
  if (y != CGAL::EQUAL) return y;
  const auto &ea = a.exact(), &eb = b.exact();
  const CGAL::Comparison_result ey = CGAL::compare(ea.y(), eb.y());
  if (ey != CGAL::EQUAL) return ey;
  const CGAL::Comparison_result x = CompareApprox(ia.x(), ib.x());
  if (x != CGAL::EQUAL) return x;
  return CGAL::compare(ea.x(), eb.x());
}

struct LessYX {
  bool operator()(const P2& a, const P2& b) const { return CompareYX(a, b) == CGAL::SMALLER; }
};

// Where direction d lies going clockwise from reference r, as a key ordered like the clockwise angle in (0, 2π]:
// 0 strictly clockwise of r within a half turn, 1 opposite to r, 2 the other half turn, 3 along r (a full turn).
inline int ClockwiseHalf(const V2& r, const V2& d) {
  switch (CGAL::orientation(r, d)) {
    case CGAL::RIGHT_TURN:
      return 0;
    case CGAL::LEFT_TURN:
      return 2;
    default:
      return CGAL::sign(r * d) == CGAL::NEGATIVE ? 1 : 3;
  }
}

// True if d1 comes strictly before d2 turning clockwise from r (exact).
inline bool ClockwiseBefore(const V2& r, const V2& d1, const V2& d2) {
  const int h1 = ClockwiseHalf(r, d1), h2 = ClockwiseHalf(r, d2);
  if (h1 != h2) return h1 < h2;
  if (h1 == 1 || h1 == 3) return false;  // the same direction
  return CGAL::orientation(d1, d2) == CGAL::RIGHT_TURN;
}

inline Vector2d ToD(const V2& v) { return {CGAL::to_double(v.x()), CGAL::to_double(v.y())}; }

inline double SignedAreaD(const std::vector<Vector2d>& poly) {
  double a = 0.0;
  for (size_t i = 0; i < poly.size(); ++i) {
    const Vector2d& p = poly[i];
    const Vector2d& q = poly[(i + 1) % poly.size()];
    a += p.x() * q.y() - p.y() * q.x();
  }
  return 0.5 * a;
}

}  // namespace visco::planning::internal
