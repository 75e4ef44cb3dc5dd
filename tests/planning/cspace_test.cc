#include "planning/cspace.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>

#include "planning/scene_file.h"

namespace visco::planning {
namespace {

double Area(const std::vector<PolygonWithHoles>& regions) {
  double area = 0;
  for (const PolygonWithHoles& r : regions) {
    area += SignedArea(r.outer) / 2;
    for (const Polygon& h : r.holes) area += SignedArea(h) / 2;  // holes are clockwise: negative
  }
  return area;
}

Scene TwoBlocks() {
  return ParseScene(R"({
    "bounds": {"min": [-2, -2], "max": [10, 8]},
    "robot": {"polygon": [[0, 0], [1, 0], [1, 1], [0, 1]]},
    "obstacles": [{"id": "left", "polygon": [[0, 0], [4, 0], [4, 2], [0, 2]]},
                  {"id": "right", "polygon": [[5.5, 0], [10, 0], [10, 2], [5.5, 2]]}],
    "goal": {"polygon": [[4, 0], [4.5, 0], [4.5, 0.5], [4, 0.5]]},
    "uncertainty": {"velocity_cone_deg": 8, "position": 0.05},
    "friction_cone_deg": 15
  })",
                    "two_blocks.json");
}

TEST(CSpace, MinkowskiSumsOfRectangles) {
  const CSpace cspace(TwoBlocks());
  ASSERT_EQ(cspace.num_c_obstacles(), 2u);
  // CB_left = [0, 4] x [0, 2] (+) -[0, 1]^2 = [-1, 4] x [-1, 2].
  EXPECT_DOUBLE_EQ(Area(cspace.c_obstacle(0)), 15.0);
  EXPECT_DOUBLE_EQ(Area(cspace.c_obstacle(1)), 5.5 * 3);
  EXPECT_DOUBLE_EQ(Area(cspace.obstacle_union()), 15.0 + 16.5);  // disjoint: the slot x in (4, 4.5) stays free
  EXPECT_DOUBLE_EQ(Area(cspace.free_space()), 12 * 10 - 15.0 - (10 - 4.5) * (2 + 1));
  EXPECT_EQ(cspace.Locate({2, 1}), Location::kInside);
  EXPECT_EQ(cspace.Locate({4, 1}), Location::kBoundary);
  EXPECT_EQ(cspace.Locate({4.2, 1}), Location::kOutside);
  EXPECT_EQ(cspace.Locate({4, 2}), Location::kBoundary);
}

TEST(CSpace, NonConvexRobotAndObstacle) {
  // An L-shaped robot against an L-shaped obstacle; the exact sum's area is checked against a fine sampling of
  // the definition q in CB  <=>  (A + q) meets B.
  const Scene scene = ParseScene(R"({
    "bounds": {"min": [-5, -5], "max": [10, 10]},
    "robot": {"polygon": [[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]]},
    "obstacles": [{"id": "l", "polygon": [[3, 3], [6, 3], [6, 4], [4, 4], [4, 6], [3, 6]]}],
    "goal": {"polygon": [[7, 7], [8, 7], [8, 8], [7, 8]]},
    "uncertainty": {"velocity_cone_deg": 8, "position": 0.05},
    "friction_cone_deg": 15
  })",
                                 "l.json");
  const CSpace cspace(scene);
  ASSERT_EQ(cspace.c_obstacle(0).size(), 1u);
  // Sample on a grid offset from all vertices; membership by the definition, with exact predicates.
  const auto overlaps = [&](const Point& q) {
    Polygon moved = scene.robot.polygon;
    for (Point& p : moved.vertices) p += q;
    const Polygon& b = scene.obstacles[0].shape.polygon;
    for (std::size_t i = 0; i < moved.size(); ++i) {
      for (std::size_t j = 0; j < b.size(); ++j) {
        if (SegmentsIntersect(moved.Edge(i), b.Edge(j))) return true;
      }
    }
    return Locate(b, moved[0]) != Location::kOutside || Locate(moved, b[0]) != Location::kOutside;
  };
  int mismatches = 0, inside = 0;
  const double step = 0.0937;
  for (double x = -1.0 + step / 3; x < 7; x += step) {
    for (double y = -1.0 + step / 7; y < 7; y += step) {
      const bool expected = overlaps({x, y});
      const Location got = cspace.Locate({x, y});
      if (got == Location::kBoundary) continue;
      inside += expected;
      mismatches += expected != (got == Location::kInside);
    }
  }
  EXPECT_GT(inside, 100);
  EXPECT_EQ(mismatches, 0);
}

TEST(CSpace, CutSegmentsKeepsFreePartsOnly) {
  const CSpace cspace(TwoBlocks());
  const Bounds bounds{{-2, -2}, {10, 8}};
  // A horizontal segment at y = 1 through both C-obstacles: only the slot [4, 4.5] and the ends stay.
  // A segment along the top edge of CB_left (y = 2) runs on the boundary: kept whole.
  // A segment displaced by an exact offset.
  const std::vector<OffsetSegment> input = {
      {{-3, 1}, {12, 1}, {0, 0}},
      {{-1, 2}, {4, 2}, {0, 0}},
      {{5, 6}, {5, 1}, {-0.75, 0}},
      {{3, 5}, {4.25, -0.5}, {0, 0}},
  };
  const CutResult result = cspace.CutSegments(input, bounds, /*crossings=*/true);
  ASSERT_EQ(result.parts.size(), 4u);
  ASSERT_EQ(result.parts[0].size(), 2u);
  EXPECT_EQ(result.parts[0][0].source, Point(-2, 1));
  EXPECT_EQ(result.parts[0][0].target, Point(-1, 1));
  EXPECT_EQ(result.parts[0][1].source, Point(4, 1));
  EXPECT_EQ(result.parts[0][1].target, Point(4.5, 1));
  ASSERT_EQ(result.parts[1].size(), 1u);
  EXPECT_EQ(result.parts[1][0].source, Point(-1, 2));
  EXPECT_EQ(result.parts[1][0].target, Point(4, 2));
  ASSERT_EQ(result.parts[2].size(), 1u);  // x = 4.25, from y = 6 down to y = 1 (free slot all the way)
  EXPECT_EQ(result.parts[2][0].source, Point(4.25, 6));
  EXPECT_EQ(result.parts[2][0].target, Point(4.25, 1));
  // The slanted segment enters CB_left at y = 2 (x = 3 + 1.25 * 3 / 5.5), leaves it into the slot at x = 4
  // (y = 0.6) and ends there.
  ASSERT_EQ(result.parts[3].size(), 2u);
  EXPECT_EQ(result.parts[3][0].source, Point(3, 5));
  EXPECT_NEAR(result.parts[3][0].target.x(), 3 + 1.25 * 3 / 5.5, 1e-12);
  EXPECT_NEAR(result.parts[3][0].target.y(), 2, 1e-12);
  EXPECT_NEAR(result.parts[3][1].source.x(), 4, 1e-12);
  EXPECT_NEAR(result.parts[3][1].source.y(), 0.6, 1e-12);
  EXPECT_EQ(result.parts[3][1].target, Point(4.25, -0.5));
  // Crossings between parts of different inputs: 0 and 2 at (4.25, 1); 1 and 3 at the point where 3 enters.
  bool found_02 = false, found_13 = false;
  for (const CutResult::Crossing& c : result.crossings) {
    if (c.first == 0 && c.second == 2) found_02 = c.point == Point(4.25, 1);
    if (c.first == 1 && c.second == 3) found_13 = std::abs(c.point.y() - 2) < 1e-12;
  }
  EXPECT_TRUE(found_02);
  EXPECT_TRUE(found_13);
}

TEST(CSpace, FindOverlappingObstacles) {
  std::vector<Obstacle> obstacles = {
      {"a", {Polygon{{{0, 0}, {2, 0}, {2, 2}, {0, 2}}}, {0, 1, 2, 3}}},
      {"b", {Polygon{{{2, 0}, {4, 0}, {4, 2}, {2, 2}}}, {0, 1, 2, 3}}},  // touches a along an edge
      {"c", {Polygon{{{4, 2}, {5, 2}, {5, 3}, {4, 3}}}, {0, 1, 2, 3}}},  // touches b at a corner
  };
  EXPECT_FALSE(FindOverlappingObstacles(obstacles).has_value());
  obstacles.push_back({"d", {Polygon{{{0, 0}, {2, 0}, {2, 2}, {0, 2}}}, {0, 1, 2, 3}}, std::nullopt});  // equals a
  const auto overlap = FindOverlappingObstacles(obstacles);
  ASSERT_TRUE(overlap.has_value());
  EXPECT_EQ(overlap->first, 0u);
  EXPECT_EQ(overlap->second, 3u);
}

// Provenance of CB's edges, checked by hand (cspace.h EdgeSource). Robot A = [0, 1]^2 (reference point at its vertex
// 0), obstacle "box" = [2, 4]^2 written clockwise from (2, 2): file vertices v0 (2,2), v1 (2,4), v2 (4,4), v3 (4,2);
// file edges e0 left, e1 top, e2 right, e3 bottom. CB = [1, 4]^2. Each side is the sum of a box edge and a parallel
// robot edge; every point gets the first generator containing it (obstacle edges before robot edges, then by file
// index), e.g. the bottom y = 1: e3 - a2 covers x in [1, 3], e3 - a3 covers [2, 4], so [1, 3] is e3 - a2 and
// [3, 4] is e3 - a3.
TEST(CSpace, EdgeProvenanceOfTwoSquares) {
  const Scene scene = ParseScene(R"({
    "bounds": {"min": [-2, -2], "max": [8, 8]},
    "robot": {"polygon": [[0, 0], [1, 0], [1, 1], [0, 1]]},
    "obstacles": [{"id": "box", "polygon": [[2, 2], [2, 4], [4, 4], [4, 2]]}],
    "goal": {"polygon": [[6, 6], [7, 6], [7, 7], [6, 7]]},
    "uncertainty": {"velocity_cone_deg": 8, "position": 0.05},
    "friction_cone_deg": 15
  })",
                                 "squares.json");
  const CSpace cspace(scene);
  const std::map<std::pair<std::pair<double, double>, std::pair<double, double>>, std::string> expected_edges = {
      {{{1, 1}, {3, 1}}, "obstacle[box].e[3]-robot.v[2]"}, {{{3, 1}, {4, 1}}, "obstacle[box].e[3]-robot.v[3]"},
      {{{4, 1}, {4, 2}}, "obstacle[box].e[2]-robot.v[3]"}, {{{4, 2}, {4, 4}}, "obstacle[box].e[2]-robot.v[0]"},
      {{{4, 4}, {2, 4}}, "obstacle[box].e[1]-robot.v[0]"}, {{{2, 4}, {1, 4}}, "obstacle[box].e[1]-robot.v[1]"},
      {{{1, 4}, {1, 2}}, "obstacle[box].e[0]-robot.v[1]"}, {{{1, 2}, {1, 1}}, "obstacle[box].e[0]-robot.v[2]"}};
  const std::map<std::pair<double, double>, std::string> expected_vertices = {
      {{1, 1}, "obstacle[box].v[0]-robot.v[2]"}, {{3, 1}, "obstacle[box].v[3]-robot.v[2]"},
      {{4, 1}, "obstacle[box].v[3]-robot.v[3]"}, {{4, 2}, "obstacle[box].v[3]-robot.v[0]"},
      {{4, 4}, "obstacle[box].v[2]-robot.v[0]"}, {{2, 4}, "obstacle[box].v[1]-robot.v[0]"},
      {{1, 4}, "obstacle[box].v[1]-robot.v[1]"}, {{1, 2}, "obstacle[box].v[0]-robot.v[1]"}};
  for (const bool use_union : {true, false}) {
    const auto& rings = use_union ? cspace.obstacle_union() : cspace.c_obstacle(0);
    const auto& sources = use_union ? cspace.obstacle_union_sources() : cspace.c_obstacle_sources(0);
    ASSERT_EQ(rings.size(), 1u);
    ASSERT_EQ(sources.size(), 1u);
    const Polygon& outer = rings[0].outer;
    ASSERT_EQ(outer.size(), 8u);
    ASSERT_EQ(sources[0].outer.edges.size(), 8u);
    ASSERT_EQ(sources[0].outer.vertex_refs.size(), 8u);
    for (std::size_t k = 0; k < 8; ++k) {
      const Point& a = outer[k];
      const Point& b = outer[(k + 1) % 8];
      const auto edge = expected_edges.find({{a.x(), a.y()}, {b.x(), b.y()}});
      ASSERT_NE(edge, expected_edges.end()) << a.transpose() << " -> " << b.transpose();
      EXPECT_EQ(sources[0].outer.edges[k].ref, edge->second);
      EXPECT_EQ(sources[0].outer.edges[k].obstacle, 0u);
      EXPECT_EQ(sources[0].outer.edges[k].kind, EdgeSource::Kind::kObstacleEdge);
      EXPECT_EQ(sources[0].outer.vertex_refs[k], expected_vertices.at({a.x(), a.y()}));
    }
  }
}

// Where two C-obstacles overlap, CB's edges carry the generator of the first obstacle whose segment contains them;
// a vertex where the two boundaries cross, which is no sum of vertices, is named by the two edges meeting there.
TEST(CSpace, EdgeProvenanceOfTheUnion) {
  const Scene scene = ParseScene(R"({
    "bounds": {"min": [-2, -2], "max": [8, 8]},
    "robot": {"polygon": [[0, 0], [1, 0], [1, 1], [0, 1]]},
    "obstacles": [{"id": "a", "polygon": [[0, 0], [2, 0], [2, 2], [0, 2]]},
                  {"id": "b", "polygon": [[2.5, 0.5], [4, 0.5], [4, 3.3], [2.5, 3.3]]}],
    "goal": {"polygon": [[6, 6], [7, 6], [7, 7], [6, 7]]},
    "uncertainty": {"velocity_cone_deg": 8, "position": 0.05},
    "friction_cone_deg": 15
  })",
                                 "union.json");
  const CSpace cspace(scene);
  // CB_a = [-1, 2] x [-1, 2], CB_b = [1.5, 4] x [-0.5, 3.3]: one piece; the top of CB_a (y = 2) meets the left of
  // CB_b (x = 1.5) at (1.5, 2). CB_b's left side is covered by e3 - a1 (y in [0.5, 3.3]) and e3 - a2 (y in
  // [-0.5, 2.3]): from (1.5, 3.3) down to (1.5, 2) it is one edge of e3 - a1 (no vertex at y = 2.3).
  ASSERT_EQ(cspace.obstacle_union().size(), 1u);
  const Polygon& outer = cspace.obstacle_union()[0].outer;
  const RingSources& sources = cspace.obstacle_union_sources()[0].outer;
  bool found = false;
  for (std::size_t k = 0; k < outer.size(); ++k) {
    if (outer[k] != Point(1.5, 2)) continue;
    found = true;
    // Leaving along the top of CB_a (towards x = -1 on the counter-clockwise ring), arriving down CB_b's left side.
    EXPECT_EQ(sources.edges[k].ref, "obstacle[a].e[2]-robot.v[0]");  // [(2,2)-(0,0), (0,2)-(0,0)] covers x in [0, 2]
    const std::size_t before = (k + outer.size() - 1) % outer.size();
    EXPECT_EQ(sources.edges[before].ref, "obstacle[b].e[3]-robot.v[1]");
    EXPECT_EQ(outer[before], Point(1.5, 3.3));
    EXPECT_EQ(sources.vertex_refs[k], "x(obstacle[a].e[2]-robot.v[0],obstacle[b].e[3]-robot.v[1])");
  }
  EXPECT_TRUE(found);
}

}  // namespace
}  // namespace visco::planning
