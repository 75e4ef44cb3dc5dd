#include "planning/vc_rays.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <sstream>
#include <string>

#include "planning/cspace.h"
#include "planning/scene_file.h"
#include "tests/planning/random_vc_scenes.h"

namespace visco::planning {
namespace {

Scene Make(const std::string& obstacles, const std::string& camera, const std::string& robot = "") {
  const std::string text = R"({"bounds": {"min": [-10, -10], "max": [10, 10]},
    "robot": {"polygon": )" +
                           (robot.empty() ? "[[0, 0], [1, 0], [1, 1], [0, 1]]" : robot) + R"(}, "obstacles": )" +
                           obstacles + R"(,
    "goal": {"polygon": [[-10, -10], [-9, -10], [-9, -9], [-10, -9]]},
    "camera": )" + camera + R"(, "uncertainty": {"velocity_cone_deg": 5, "position": 0.01}, "friction_cone_deg": 10})";
  return ParseScene(text, "hand.json");
}

// (obstacle id, vertex as written in the file) of the unoccluded vertices.
std::set<std::pair<std::string, int>> Visible(const Scene& s) {
  std::set<std::pair<std::string, int>> out;
  for (const UnoccludedVertex& u : FindUnoccludedVertices(s)) {
    out.insert({s.obstacles[u.obstacle].id, s.obstacles[u.obstacle].shape.source_index[u.vertex]});
  }
  EXPECT_EQ(FindUnoccludedVertices(s), FindUnoccludedVerticesReference(s));
  return out;
}

using V = std::set<std::pair<std::string, int>>;

TEST(VcRays, SquareSeenFromTheSide) {
  // Camera to the right looking left: the two right corners and the top-right... (0,0)-(1,1) square, P = (3, 0.5).
  const Scene s = Make(R"([{"id": "a", "polygon": [[0, 0], [1, 0], [1, 1], [0, 1]]}])",
                       R"({"center": [3, 0.5], "fov_deg": [100, 260]})");
  EXPECT_EQ(Visible(s), (V{{"a", 1}, {"a", 2}}));
}

TEST(VcRays, CameraOnAnEdgesSupportingLine) {
  // P on the line y = 1 of the top edge: the segment from (0, 1) to P runs along that edge (boundary only).
  const Scene s = Make(R"([{"id": "a", "polygon": [[0, 0], [1, 0], [1, 1], [0, 1]]}])",
                       R"({"center": [3, 1], "fov_deg": [100, 260]})");
  EXPECT_EQ(Visible(s), (V{{"a", 1}, {"a", 2}, {"a", 3}}));
}

TEST(VcRays, VertexOnAnothersProjectionRay) {
  // P = (0, 0). Square a = [1, 2]^2; b's corner (3, 3) lies on the ray through a's corners (1, 1) and (2, 2) (the
  // diagonal of a, through its interior): occluded. c's corner (4, 2) is on the ray through a's corner (2, 1),
  // which it only grazes: visible.
  const Scene s = Make(R"([{"id": "a", "polygon": [[1, 1], [2, 1], [2, 2], [1, 2]]},
                           {"id": "b", "polygon": [[3, 3], [3.5, 3], [3.5, 3.5], [3, 3.5]]},
                           {"id": "c", "polygon": [[4, 2], [5, 2], [5, 2.5], [4, 2.5]]}])",
                       R"({"center": [0, 0], "fov_deg": [0, 89]})");
  const V visible = Visible(s);
  EXPECT_TRUE(visible.count({"a", 0}));
  EXPECT_FALSE(visible.count({"a", 2}));  // (2, 2): the diagonal runs through a's interior
  EXPECT_FALSE(visible.count({"b", 0}));  // (3, 3)
  EXPECT_TRUE(visible.count({"a", 1}));   // (2, 1)
  EXPECT_TRUE(visible.count({"c", 0}));   // (4, 2), grazing (2, 1)
  EXPECT_TRUE(visible.count({"a", 3}));   // (1, 2)
}

TEST(VcRays, CollinearVertices) {
  // A polygon with a straight-angle vertex at (1, 0.5) facing the camera, and one on the far side at (0, 0.5).
  const Scene s = Make(R"([{"id": "a", "polygon": [[0, 0], [1, 0], [1, 0.5], [1, 1], [0, 1], [0, 0.5]]}])",
                       R"({"center": [3, 0.5], "fov_deg": [100, 260]})");
  EXPECT_EQ(Visible(s), (V{{"a", 1}, {"a", 2}, {"a", 3}}));
}

TEST(VcRays, TouchingObstaclesSeenAlongTheirSeam) {
  // a and b share the edge x = 1; the camera looks down the seam: (1, 0) is seen along the boundary of both.
  const Scene s = Make(R"([{"id": "a", "polygon": [[0, 0], [1, 0], [1, 1], [0, 1]]},
                           {"id": "b", "polygon": [[1, 0], [2, 0], [2, 1], [1, 1]]}])",
                       R"({"center": [1, 5], "fov_deg": [240, 300]})");
  EXPECT_EQ(Visible(s), (V{{"a", 1}, {"a", 2}, {"a", 3}, {"b", 0}, {"b", 2}, {"b", 3}}));
  // A vertex of b in the middle of a's edge, seen from the side of a: the segment to P enters a at once.
  const Scene t = Make(R"([{"id": "a", "polygon": [[0, 0], [1, 0], [1, 2], [0, 2]]},
                           {"id": "b", "polygon": [[1, 0.5], [2, 0.5], [2, 1.5], [1, 1.5]]}])",
                       R"({"center": [-3, 1], "fov_deg": [-60, 60]})");
  EXPECT_EQ(Visible(t), (V{{"a", 0}, {"a", 3}}));
}

TEST(VcRays, CameraOnAnObstacleBoundary) {
  // P at the middle of a's top edge looking up: vertices above are visible, nothing through a.
  const Scene s = Make(R"([{"id": "a", "polygon": [[0, 0], [2, 0], [2, 1], [0, 1]]},
                           {"id": "b", "polygon": [[0, 3], [2, 3], [2, 4], [0, 4]]}])",
                       R"({"center": [1, 1], "fov_deg": [0, 179]})");
  EXPECT_EQ(Visible(s), (V{{"a", 2}, {"b", 0}, {"b", 1}}));
}

TEST(VcRays, CmVerticesWithARobotEdgeParallelToTheRay) {
  // The camera straight above the vertex: the ray is vertical, parallel to the square robot's vertical edges.
  // Left of "down" is +x: a1 = (1, 0) and a2 = (1, 1) tie, the lower index wins; right: a0 and a3 tie -> a0.
  const Scene s =
      Make(R"([{"id": "a", "polygon": [[4, 1], [6, 1], [5, 2]]}])", R"({"center": [5, 8], "fov_deg": [265, 275]})");
  const auto u = FindUnoccludedVertices(s);
  ASSERT_EQ(u.size(), 1u);
  EXPECT_EQ(u[0].cm, (std::array<int, 2>{1, 0}));
  EXPECT_EQ(FindUnoccludedVerticesReference(s), u);
}

TEST(VcRays, CvcRaysOfTheSlot) {
  const Scene s = LoadScene("data/scenes/slot.json");
  const CSpace cspace(s);
  const VcRays rays = ComputeVcRays(s, cspace);
  // The slot's left lip (4, 2) is vertex 2 of obstacle "left": k = 2.
  const VcRay* lip = nullptr;
  for (const VcRay& r : rays.vc_rays) {
    if (r.id == "vc2") lip = &r;
  }
  ASSERT_NE(lip, nullptr);
  EXPECT_EQ(lip->from, Point(4, 2));
  EXPECT_EQ(lip->to, Point(9.5, 7.5));
  // Ray direction (5.5, 5.5)/|.|: the unit square's CM vertices are a1 = (1, 0) (right of the ray) and a3 = (0, 1).
  EXPECT_EQ(lip->cm_vertices, (std::array<int, 2>{1, 3}));
  for (const CvcRay& c : rays.cvc_rays) {
    if (c.vc_ray != lip - rays.vc_rays.data()) continue;
    EXPECT_TRUE(c.id == "vc2.cm1" || c.id == "vc2.cm3") << c.id;
    ASSERT_FALSE(c.segments.empty());
    // Free parts never enter CB's interior; the a1 ray starts at (3, 2), a corner of CB_left's top edge... it runs
    // from (3, 2) up-right in free space and is clipped by the bounds' top y = 8 at x = 9.
    if (c.id == "vc2.cm1") {
      EXPECT_EQ(c.segments.front().source, Point(3, 2));
      EXPECT_EQ(c.segments.back().target, Point(8.5, 7.5));
    }
  }
  EXPECT_EQ(rays.cvc_rays.size(), 2 * rays.vc_rays.size());
}

TEST(VcRays, OverlappingObstaclesOccludeVerticesInsideEachOther) {
  // A floor and a wall overlapping it: the wall's lower corners (4, 0) and (6, 0) lie inside the floor, and the
  // floor's top edge vertices are outside the wall. P = (5, 8) looks down.
  const Scene s = Make(R"([{"id": "floor", "polygon": [[-9, -2], [9, -2], [9, 1], [-9, 1]]},
                           {"id": "wall", "polygon": [[4, 0], [6, 0], [6, 4], [4, 4]]}])",
                       R"({"center": [5, 8], "fov_deg": [181, 359]})");
  const V visible = Visible(s);
  EXPECT_TRUE(visible.count({"wall", 2}));   // (6, 4)
  EXPECT_TRUE(visible.count({"wall", 3}));   // (4, 4)
  EXPECT_FALSE(visible.count({"wall", 0}));  // (4, 0): inside the floor
  EXPECT_FALSE(visible.count({"wall", 1}));  // (6, 0): inside the floor
  EXPECT_TRUE(visible.count({"floor", 2}));  // (9, 1)
  EXPECT_TRUE(visible.count({"floor", 3}));  // (-9, 1)
  // The C-space cut uses the union: no CVC part runs through either obstacle.
  const CSpace cspace(s);
  const VcRays rays = ComputeVcRays(s, cspace);
  for (const CvcRay& c : rays.cvc_rays) {
    for (const Segment& seg : c.segments) {
      EXPECT_NE(cspace.Locate(0.5 * (seg.source + seg.target)), Location::kInside) << c.id;
    }
  }
}

// Property (overlapping parts, against sampling): on random scenes of overlapping rectangles and stars, no reported
// unoccluded vertex has a point of its segment to P (sampled) strictly inside an obstacle, and every vertex strictly
// inside another obstacle is occluded.
TEST(VcRaysProperty, OverlappingObstaclesAgainstSampling) {
  int visible = 0, buried = 0;
  for (std::uint64_t seed = 1; seed <= 150; ++seed) {
    testing::RandomSceneOptions o;
    o.lattice = seed % 2 == 0 ? 0.5 : 0.0;
    o.overlap = 0.6;
    const Scene s = testing::RandomScene(seed, o);
    const auto found = FindUnoccludedVertices(s);
    const Point p = s.camera->center;
    std::set<std::pair<int, int>> unoccluded;
    for (const UnoccludedVertex& u : found) unoccluded.insert({u.obstacle, u.vertex});
    for (std::size_t oi = 0; oi < s.obstacles.size(); ++oi) {
      const Polygon& poly = s.obstacles[oi].shape.polygon;
      for (std::size_t vi = 0; vi < poly.size(); ++vi) {
        const Point b = poly[vi];
        bool inside_other = false;
        for (std::size_t k = 0; k < s.obstacles.size(); ++k) {
          inside_other |= k != oi && Locate(s.obstacles[k].shape.polygon, b) == Location::kInside;
        }
        const bool reported = unoccluded.count({static_cast<int>(oi), static_cast<int>(vi)}) > 0;
        if (inside_other) {
          ++buried;
          EXPECT_FALSE(reported) << "seed " << seed << ": vertex inside another obstacle reported unoccluded";
        }
        if (!reported) continue;
        ++visible;
        for (int k = 1; k < 400; ++k) {
          const Point q = b + (p - b) * (k / 400.0);
          for (const Obstacle& ob : s.obstacles) {
            if (Locate(ob.shape.polygon, q) != Location::kInside) continue;
            // Strictly inside by a margin (sampling near a grazed boundary is not evidence).
            double dist = 1e300;
            for (std::size_t e = 0; e < ob.shape.polygon.size(); ++e) {
              const Segment edge = ob.shape.polygon.Edge(e);
              const Vector d = edge.target - edge.source;
              const double t = std::clamp((q - edge.source).dot(d) / d.squaredNorm(), 0.0, 1.0);
              dist = std::min(dist, (q - (edge.source + t * d)).norm());
            }
            EXPECT_LT(dist, 1e-9) << "seed " << seed << ": the segment of a reported vertex enters " << ob.id;
          }
        }
      }
    }
  }
  EXPECT_GT(visible, 300);
  EXPECT_GT(buried, 50);
}

// Property: the sweep equals the O(n^2) reference on hundreds of seeded random scenes full of degeneracies.
TEST(VcRaysProperty, SweepEqualsReference) {
  int total_visible = 0;
  for (std::uint64_t seed = 1; seed <= 400; ++seed) {
    testing::RandomSceneOptions o;
    o.lattice = seed % 4 == 0 ? 0.0 : (seed % 4 == 1 ? 1.0 : 0.5);
    o.touching = seed % 3 == 0 ? 0.5 : 0.15;
    const Scene s = testing::RandomScene(seed, o);
    const auto fast = FindUnoccludedVertices(s);
    const auto slow = FindUnoccludedVerticesReference(s);
    ASSERT_EQ(fast, slow) << "seed " << seed;
    total_visible += static_cast<int>(fast.size());
  }
  EXPECT_GT(total_visible, 1000);
}

// Distance from q to the boundary of CB (the union of the C-obstacles), in doubles.
double DistanceToBoundary(const CSpace& cspace, const Point& q) {
  double dist = 1e300;
  for (const PolygonWithHoles& part : cspace.obstacle_union()) {
    std::vector<const Polygon*> rings = {&part.outer};
    for (const Polygon& hole : part.holes) rings.push_back(&hole);
    for (const Polygon* ring : rings) {
      for (std::size_t e = 0; e < ring->size(); ++e) {
        const Segment edge = ring->Edge(e);
        dist = std::min(dist, PointSegmentDistance(q, edge.source, edge.target));
      }
    }
  }
  return dist;
}

// A gap between two parts of a CVC ray is cut: no point of it is free inside the bounds, and some point of it is
// inside CB or outside the bounds (its midpoint alone can be a vertex of CB's boundary, in lattice scenes:
// VISCO_SEED_OFFSET=5000, seed 118).
bool GapIsCut(const Scene& s, const CSpace& cspace, const CvcRay& c, double t0, double t1) {
  const Point a = c.full.source, b = c.full.target;
  bool cut = false;
  for (const double f : {0.25, 0.5, 0.75}) {
    const Point q = a + (t0 + f * (t1 - t0)) * (b - a);
    const bool out_of_bounds = !s.bounds.Contains(q);
    const Location where = cspace.Locate(q);
    if (where == Location::kOutside && !out_of_bounds) return false;
    cut = cut || where == Location::kInside || out_of_bounds;
  }
  return cut;
}

std::string DescribeGap(const CSpace& cspace, const CvcRay& c, double t0, double t1) {
  const Point a = c.full.source, b = c.full.target;
  const Point p0 = a + t0 * (b - a), p1 = a + t1 * (b - a), mid = 0.5 * (p0 + p1);
  std::ostringstream out;
  out << "ray (" << a.x() << ", " << a.y() << ")-(" << b.x() << ", " << b.y() << "), " << c.segments.size()
      << " parts; gap (" << p0.x() << ", " << p0.y() << ")-(" << p1.x() << ", " << p1.y() << "), its midpoint "
      << (cspace.Locate(mid) == Location::kBoundary ? "on" : "outside") << " CB, " << DistanceToBoundary(cspace, mid)
      << " from its boundary";
  return out.str();
}

// Property: every CVC free part lies outside CB's interior and inside the bounds, the cut parts between them lie
// inside CB (or outside the bounds), and parts begin and end on CB's boundary, the bounds or the ray's ends.
TEST(VcRaysProperty, CvcPartsAreExactlyTheFreeParts) {
  int checked = 0;
  for (std::uint64_t seed = 1; seed <= 120; ++seed) {
    testing::RandomSceneOptions o;
    o.cells_x = 3;
    o.cells_y = 3;
    o.lattice = seed % 2 == 0 ? 0.5 : 0.0;
    const Scene s = testing::RandomScene(seed, o);
    const CSpace cspace(s);
    const VcRays rays = ComputeVcRays(s, cspace);
    ASSERT_EQ(rays.cvc_rays.size(), 2 * rays.vc_rays.size());
    for (const CvcRay& c : rays.cvc_rays) {
      const Point a = c.full.source, b = c.full.target;
      const Vector d = b - a;
      const double len2 = d.squaredNorm();
      double t_prev = 0;
      for (const Segment& seg : c.segments) {
        const Point mid = 0.5 * (seg.source + seg.target);
        // A part may run along CB's boundary (a ray along a C-obstacle edge); its rounded points then fall a hair
        // to either side of it (VISCO_SEED_OFFSET=210000, seed 10).
        for (const double t : {0.25, 0.5, 0.75}) {
          const Point q = seg.source + t * (seg.target - seg.source);
          EXPECT_TRUE(cspace.Locate(q) != Location::kInside || DistanceToBoundary(cspace, q) < 1e-9)
              << c.id << " seed " << seed << ": part (" << seg.source.x() << ", " << seg.source.y() << ")-("
              << seg.target.x() << ", " << seg.target.y() << "), length " << (seg.target - seg.source).norm() << ", at "
              << t << " inside CB, " << DistanceToBoundary(cspace, q) << " from its boundary";
        }
        EXPECT_TRUE(s.bounds.Contains(mid));
        const double t0 = (seg.source - a).dot(d) / len2, t1 = (seg.target - a).dot(d) / len2;
        EXPECT_LT(t0, t1);
        EXPECT_GE(t0, t_prev - 1e-12);
        if (t0 - t_prev > 1e-6) {  // a gap: inside CB or outside the bounds
          EXPECT_TRUE(GapIsCut(s, cspace, c, t_prev, t0))
              << c.id << " seed " << seed << ": " << DescribeGap(cspace, c, t_prev, t0);
        }
        // Each end is on CB's boundary, on the bounds, or an end of the ray.
        for (const Point& e : {seg.source, seg.target}) {
          const bool on_ray_end = (e - a).norm() < 1e-9 || (e - b).norm() < 1e-9;
          const bool on_bounds = std::abs(e.x() - s.bounds.min.x()) < 1e-9 ||
                                 std::abs(e.x() - s.bounds.max.x()) < 1e-9 ||
                                 std::abs(e.y() - s.bounds.min.y()) < 1e-9 || std::abs(e.y() - s.bounds.max.y()) < 1e-9;
          bool on_cb = false;
          for (const PolygonWithHoles& cb : cspace.obstacle_union()) {
            for (const Polygon* ring = &cb.outer; ring && !on_cb; ring = nullptr) {
              for (std::size_t i = 0; i < ring->size() && !on_cb; ++i) {
                const Segment edge = ring->Edge(i);
                const Vector ev = edge.target - edge.source;
                const double t = std::clamp((e - edge.source).dot(ev) / ev.squaredNorm(), 0.0, 1.0);
                on_cb = (edge.source + t * ev - e).norm() < 1e-9;
              }
            }
            for (const Polygon& h : cb.holes) {
              for (std::size_t i = 0; i < h.size() && !on_cb; ++i) {
                const Segment edge = h.Edge(i);
                const Vector ev = edge.target - edge.source;
                const double t = std::clamp((e - edge.source).dot(ev) / ev.squaredNorm(), 0.0, 1.0);
                on_cb = (edge.source + t * ev - e).norm() < 1e-9;
              }
            }
          }
          EXPECT_TRUE(on_ray_end || on_bounds || on_cb) << c.id << " seed " << seed << " end " << e.transpose();
        }
        t_prev = t1;
        ++checked;
      }
      if (1 - t_prev > 1e-6) {
        EXPECT_TRUE(GapIsCut(s, cspace, c, t_prev, 1.0))
            << c.id << " seed " << seed << ": " << DescribeGap(cspace, c, t_prev, 1.0);
      }
    }
    // Crossings: each point lies on both rays' parts.
    for (const CvcCrossing& x : rays.crossings) {
      ASSERT_LT(x.first, x.second);
      for (int r : {x.first, x.second}) {
        bool on = false;
        for (const Segment& seg : rays.cvc_rays[r].segments) {
          const Vector ev = seg.target - seg.source;
          const double t = std::clamp((x.point - seg.source).dot(ev) / ev.squaredNorm(), 0.0, 1.0);
          on = on || (seg.source + t * ev - x.point).norm() < 1e-9;
        }
        EXPECT_TRUE(on);
      }
    }
  }
  EXPECT_GT(checked, 500);
}

// Property: crossings are exactly the pairs of CVC parts that meet (checked by brute force over all pairs).
TEST(VcRaysProperty, CrossingsEqualBruteForcePairs) {
  for (std::uint64_t seed = 1; seed <= 60; ++seed) {
    testing::RandomSceneOptions o;
    o.cells_x = 3;
    o.cells_y = 3;
    const Scene s = testing::RandomScene(seed * 7919, o);
    const CSpace cspace(s);
    const VcRays rays = ComputeVcRays(s, cspace);
    std::set<std::pair<int, int>> expected, got;
    for (std::size_t i = 0; i < rays.cvc_rays.size(); ++i) {
      for (std::size_t j = i + 1; j < rays.cvc_rays.size(); ++j) {
        if (rays.cvc_rays[i].vc_ray == rays.cvc_rays[j].vc_ray) continue;  // parallel siblings
        for (const Segment& a : rays.cvc_rays[i].segments) {
          for (const Segment& b : rays.cvc_rays[j].segments) {
            if (SegmentsIntersect(a, b)) expected.insert({static_cast<int>(i), static_cast<int>(j)});
          }
        }
      }
    }
    for (const CvcCrossing& x : rays.crossings) got.insert({x.first, x.second});
    // Rounded endpoints can make a touching pair differ; require agreement on all pairs that cross properly.
    for (const auto& pair : expected) {
      bool proper = false;
      for (const Segment& a : rays.cvc_rays[pair.first].segments) {
        for (const Segment& b : rays.cvc_rays[pair.second].segments) proper = proper || SegmentsCrossProperly(a, b);
      }
      if (proper) {
        EXPECT_TRUE(got.count(pair)) << "seed " << seed;
      }
    }
  }
}

}  // namespace
}  // namespace visco::planning
