#include "planning/geometry.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace visco::planning {
namespace {

TEST(Geometry, OrientationSigns) {
  EXPECT_EQ(Orientation({0, 0}, {1, 0}, {0, 1}), 1);
  EXPECT_EQ(Orientation({0, 0}, {1, 0}, {0, -1}), -1);
  EXPECT_EQ(Orientation({0, 0}, {1, 0}, {2, 0}), 0);
  EXPECT_EQ(Orientation({0, 0}, {0, 0}, {2, 3}), 0);
}

// The classic failure of rounded orientation (Kettner et al., "Classroom examples of robustness problems"): points
// near the line through (12, 12) and (24, 24) at spacing 2^-53, where rounded arithmetic returns a noisy pattern.
TEST(Geometry, OrientationIsExactNearDegenerate) {
  const double u = std::ldexp(1.0, -53);
  const Point q(12, 12), r(24, 24);
  int positives = 0, negatives = 0, zeros = 0;
  for (int i = 0; i < 64; ++i) {
    for (int j = 0; j < 64; ++j) {
      const Point p(0.5 + i * u, 0.5 + j * u);
      // Exact algebra: (q - p) x (r - p) = 12 (p.y - p.x), whose sign is sign(j - i).
      const int expected = (j > i) - (j < i);
      const int got = Orientation(p, q, r);
      EXPECT_EQ(got, expected) << i << " " << j;
      positives += got > 0;
      negatives += got < 0;
      zeros += got == 0;
    }
  }
  EXPECT_EQ(zeros, 64);
  EXPECT_EQ(positives, negatives);
}

TEST(Geometry, CrossAndDotSignsAreExact) {
  const double u = std::ldexp(1.0, -52);
  // (b - a) x (d - c) with nearly parallel long vectors.
  EXPECT_EQ(CrossSign({0, 0}, {1e8, 1e8 + 1}, {0, 0}, {1e8, 1e8 + 1}), 0);
  EXPECT_EQ(CrossSign({0, 0}, {1, 1}, {0, 0}, {1, 1 + u}), 1);
  EXPECT_EQ(CrossSign({0, 0}, {1, 1}, {0, 0}, {1, 1 - u / 2}), -1);
  EXPECT_EQ(DotSign({0, 0}, {1, 0}, {0, 0}, {u * u, 5}), 1);
  EXPECT_EQ(DotSign({0, 0}, {1, 0}, {0, 0}, {0, 5}), 0);
  EXPECT_EQ(CompareDistance({0, 0}, {3, 4}, {5, 0}), 0);
  EXPECT_EQ(CompareDistance({0, 0}, {3, 4}, {5, u * 8}), -1);
}

TEST(Geometry, Segments) {
  const Segment s{{0, 0}, {2, 0}};
  EXPECT_TRUE(OnSegment(s, {1, 0}));
  EXPECT_TRUE(OnSegment(s, {2, 0}));
  EXPECT_FALSE(OnSegment(s, {3, 0}));
  EXPECT_TRUE(InSegmentInterior(s, {1, 0}));
  EXPECT_FALSE(InSegmentInterior(s, {0, 0}));
  EXPECT_TRUE(SegmentsIntersect(s, {{1, -1}, {1, 1}}));
  EXPECT_TRUE(SegmentsCrossProperly(s, {{1, -1}, {1, 1}}));
  EXPECT_TRUE(SegmentsIntersect(s, {{2, 0}, {3, 1}}));  // touching at an endpoint
  EXPECT_FALSE(SegmentsCrossProperly(s, {{2, 0}, {3, 1}}));
  EXPECT_TRUE(SegmentsIntersect(s, {{1, 0}, {3, 0}}));  // collinear overlap
  EXPECT_FALSE(SegmentsCrossProperly(s, {{1, 0}, {3, 0}}));
  EXPECT_FALSE(SegmentsIntersect(s, {{0, 1}, {2, 1}}));
  EXPECT_FALSE(SegmentsCrossProperly(s, {{1, 0}, {1, 1}}));  // T-junction
}

TEST(Geometry, PolygonsOrientationSimplicityLocation) {
  const Polygon square{{{0, 0}, {2, 0}, {2, 2}, {0, 2}}};
  Polygon clockwise = square;
  std::reverse(clockwise.vertices.begin(), clockwise.vertices.end());
  EXPECT_EQ(PolygonOrientation(square), 1);
  EXPECT_EQ(PolygonOrientation(clockwise), -1);
  EXPECT_DOUBLE_EQ(SignedArea(square), 8.0);
  EXPECT_TRUE(IsSimple(square));
  EXPECT_TRUE(IsSimple(clockwise));
  EXPECT_FALSE(IsSimple(Polygon{{{0, 0}, {2, 2}, {2, 0}, {0, 2}}}));  // bow tie
  EXPECT_FALSE(IsSimple(Polygon{{{0, 0}, {1, 0}, {2, 0}}}));          // collinear, zero area
  EXPECT_FALSE(IsSimple(Polygon{{{0, 0}, {1, 0}}}));
  EXPECT_TRUE(IsSimple(Polygon{{{0, 0}, {1, 0}, {2, 0}, {2, 1}}}));  // a collinear vertex is fine
  for (const Polygon& p : {square, clockwise}) {
    EXPECT_EQ(Locate(p, {1, 1}), Location::kInside);
    EXPECT_EQ(Locate(p, {2, 1}), Location::kBoundary);
    EXPECT_EQ(Locate(p, {0, 0}), Location::kBoundary);
    EXPECT_EQ(Locate(p, {3, 1}), Location::kOutside);
  }
  // Non-convex: a U shape.
  const Polygon u{{{0, 0}, {3, 0}, {3, 3}, {2, 3}, {2, 1}, {1, 1}, {1, 3}, {0, 3}}};
  EXPECT_EQ(Locate(u, {1.5, 2}), Location::kOutside);
  EXPECT_EQ(Locate(u, {1.5, 0.5}), Location::kInside);
}

TEST(Geometry, OpenSectors) {
  const Point apex(0, 0);
  // Convex 90-degree sector from +x to +y.
  EXPECT_TRUE(InOpenSector(apex, {1, 0}, {0, 1}, {1, 1}));
  EXPECT_FALSE(InOpenSector(apex, {1, 0}, {0, 1}, {1, 0}));  // on the boundary: not strictly inside
  EXPECT_FALSE(InOpenSector(apex, {1, 0}, {0, 1}, {-1, -1}));
  EXPECT_TRUE(InOpenSector(apex, {1, 0}, {0, 1}, {1, 1}, /*reverse=*/false));
  EXPECT_TRUE(InOpenSector(apex, {1, 0}, {0, 1}, {-1, -1}, /*reverse=*/true));
  // Reflex 270-degree sector from +y to +x.
  EXPECT_TRUE(InOpenSector(apex, {0, 1}, {1, 0}, {-1, -1}));
  EXPECT_FALSE(InOpenSector(apex, {0, 1}, {1, 0}, {1, 1}));
  EXPECT_FALSE(InOpenSector(apex, {0, 1}, {1, 0}, {0, 2}));
  // Straight: the left half-plane of +x.
  EXPECT_TRUE(InOpenSector(apex, {1, 0}, {-1, 0}, {0, 1}));
  EXPECT_FALSE(InOpenSector(apex, {1, 0}, {-1, 0}, {5, 0}));
  EXPECT_FALSE(InOpenSector(apex, {1, 0}, {-1, 0}, {0, -1}));
  EXPECT_FALSE(InOpenSector(apex, {1, 0}, {0, 1}, apex));  // the zero direction is in no open sector
}

// Property: the interval-filtered predicates agree with the naive formula wherever the naive one is far from 0.
TEST(Geometry, PredicatesAgreeWithNaiveAwayFromDegeneracy) {
  std::mt19937_64 rng(20261122);
  std::uniform_real_distribution<double> coord(-100, 100);
  for (int trial = 0; trial < 20000; ++trial) {
    const Point a(coord(rng), coord(rng)), b(coord(rng), coord(rng)), c(coord(rng), coord(rng)),
        d(coord(rng), coord(rng));
    const double det = (b - a).x() * (d - c).y() - (b - a).y() * (d - c).x();
    if (std::abs(det) > 1e-6) {
      EXPECT_EQ(CrossSign(a, b, c, d), det > 0 ? 1 : -1);
    }
    const double o = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    if (std::abs(o) > 1e-6) {
      EXPECT_EQ(Orientation(a, b, c), o > 0 ? 1 : -1);
    }
  }
}

// Property: the rounded even-odd test agrees with the exact Locate on random simple polygons (star-shaped around
// the origin, either orientation) for points not within rounding of the boundary.
TEST(Geometry, InsideEvenOddAgreesWithLocate) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int inside = 0;
  int outside = 0;
  for (int shape = 0; shape < 200; ++shape) {
    const int n = 3 + static_cast<int>(unit(rng) * 12);
    Polygon polygon;
    for (int i = 0; i < n; ++i) {
      const double angle = 2.0 * M_PI * (i + 0.8 * unit(rng)) / n;
      const double radius = 0.5 + 2.0 * unit(rng);
      polygon.vertices.emplace_back(radius * std::cos(angle), radius * std::sin(angle));
    }
    if (shape % 2 == 1) std::reverse(polygon.vertices.begin(), polygon.vertices.end());
    for (int k = 0; k < 50; ++k) {
      const Point p(6.0 * unit(rng) - 3.0, 6.0 * unit(rng) - 3.0);
      const Location where = Locate(polygon, p);
      if (where == Location::kBoundary) continue;
      EXPECT_EQ(InsideEvenOdd(polygon.vertices, p), where == Location::kInside)
          << "shape " << shape << " point (" << p.x() << ", " << p.y() << ")";
      ++(where == Location::kInside ? inside : outside);
    }
  }
  EXPECT_GT(inside, 1000);
  EXPECT_GT(outside, 1000);
  EXPECT_FALSE(InsideEvenOdd({}, Point(0, 0)));
}

}  // namespace
}  // namespace visco::planning
