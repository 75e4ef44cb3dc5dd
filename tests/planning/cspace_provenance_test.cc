// Provenance of the C-obstacles' boundary edges (cspace.h EdgeSource) against an independent reference on seeded
// random scenes (tests/planning/random_vc_scenes.h: non-convex robots and obstacles, touching obstacles, lattice
// coordinates so that parallel and collinear features are common). The scenes go through the scene file loader with
// polygons written in either orientation, from a random first vertex and with repeated vertices, and the reference
// works on the file's vertex lists only: for every boundary edge of CB and of each CB_i, the segment its ref names
// (obstacle edge i shifted by minus robot vertex j, or obstacle vertex i minus robot edge j) must contain it, and it
// must be the first such generator in the documented order; vertex refs likewise. Then B_θ(G) at several θ: every
// `obstacle` edge of the output lies on the segment its ref names and has the ref of the CB edge it lies on, so
// the same edge has the same ref at every θ.

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <random>
#include <regex>
#include <string>
#include <tuple>
#include <vector>

#include "common/error.h"
#include "planning/backprojection.h"
#include "planning/cspace.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "planning/scene_problem.h"
#include "tests/planning/random_vc_scenes.h"

namespace visco::planning {
namespace {

using FilePolygon = std::vector<Point>;  // vertices as written in the scene file

struct FileScene {
  std::string json;
  FilePolygon robot;
  std::vector<std::pair<std::string, FilePolygon>> obstacles;  // file order
};

// Writes a polygon as a file would: from a random first vertex, in a random orientation, sometimes with a vertex
// repeated (consecutively, or the first one again at the end).
FilePolygon Scramble(const Polygon& polygon, std::mt19937_64& rng) {
  FilePolygon out(polygon.vertices.begin(), polygon.vertices.end());
  std::rotate(out.begin(), out.begin() + static_cast<long>(rng() % out.size()), out.end());
  if (rng() % 2) std::reverse(out.begin(), out.end());
  if (rng() % 4 == 0) {
    const std::size_t at = rng() % out.size();
    out.insert(out.begin() + static_cast<long>(at), out[at]);
  }
  if (rng() % 5 == 0) out.push_back(out.front());
  return out;
}

std::string PolygonJson(const FilePolygon& p) {
  std::string s = "[";
  for (std::size_t i = 0; i < p.size(); ++i)
    s += fmt::format("{}[{:.17g}, {:.17g}]", i ? ", " : "", p[i].x(), p[i].y());
  return s + "]";
}

std::optional<FileScene> RandomFileScene(std::uint64_t seed) {
  testing::RandomSceneOptions options;
  options.cells_x = 3;
  options.cells_y = 3;
  options.lattice = seed % 3 == 2 ? 0.0 : 0.5;  // a third with continuous coordinates
  const Scene random = testing::RandomScene(seed, options);
  std::mt19937_64 rng(seed * 7919 + 3);
  FileScene f;
  f.robot = Scramble(random.robot.polygon, rng);
  std::string obstacles;
  for (const Obstacle& o : random.obstacles) {
    f.obstacles.emplace_back(o.id, Scramble(o.shape.polygon, rng));
    obstacles += fmt::format("{}{{\"id\": \"{}\", \"polygon\": {}}}", obstacles.empty() ? "" : ", ", o.id,
                             PolygonJson(f.obstacles.back().second));
  }
  const Point hi = random.bounds.max;
  f.json = fmt::format(
      R"({{"bounds": {{"min": [0, 0], "max": [{}, {}]}}, "robot": {{"polygon": {}}}, "obstacles": [{}],
          "goal": {{"polygon": [[0, 0], [{}, 0], [{}, 1], [0, 1]]}},
          "uncertainty": {{"velocity_cone_deg": 6, "position": 0.02}}, "friction_cone_deg": 20}})",
      hi.x(), hi.y(), PolygonJson(f.robot), obstacles, hi.x(), hi.x());
  return f;
}

// The reference: generators from the file's vertex lists, in the documented order.
struct RefGenerator {
  std::string ref;
  Point a, b;
  std::size_t obstacle;
};

std::vector<RefGenerator> ReferenceGenerators(const FileScene& f, std::optional<std::size_t> only) {
  std::vector<RefGenerator> out;
  const FilePolygon& r = f.robot;
  const std::size_t m = r.size();
  for (std::size_t o = 0; o < f.obstacles.size(); ++o) {
    if (only && o != *only) continue;
    const auto& [id, b] = f.obstacles[o];
    const std::size_t n = b.size();
    for (std::size_t i = 0; i < n; ++i) {  // obstacle edges (non-degenerate ones only) minus robot vertices
      if (b[i] == b[(i + 1) % n]) continue;
      for (std::size_t j = 0; j < m; ++j) {
        // A repeated vertex is named by its first position (the loader's source_index).
        if ((j > 0 && r[j] == r[j - 1]) || (j == m - 1 && r[j] == r[0])) continue;
        out.push_back({fmt::format("obstacle[{}].e[{}]-robot.v[{}]", id, i, j), b[i] - r[j], b[(i + 1) % n] - r[j], o});
      }
    }
    for (std::size_t i = 0; i < n; ++i) {  // obstacle vertices minus robot edges
      if ((i > 0 && b[i] == b[i - 1]) || (i == n - 1 && b[i] == b[0])) continue;
      for (std::size_t j = 0; j < m; ++j) {
        if (r[j] == r[(j + 1) % m]) continue;
        out.push_back({fmt::format("obstacle[{}].v[{}]-robot.e[{}]", id, i, j), b[i] - r[j], b[i] - r[(j + 1) % m], o});
      }
    }
  }
  return out;
}

double SegmentDistance(const Point& p, const Point& a, const Point& b) {
  const Vector d = b - a;
  const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
  return (p - (a + t * d)).norm();
}

constexpr double kTolerance = 1e-9;

// The first generator (documented order) containing [p, q].
const RefGenerator* FirstContaining(const std::vector<RefGenerator>& generators, const Point& p, const Point& q) {
  for (const RefGenerator& g : generators) {
    if (SegmentDistance(p, g.a, g.b) <= kTolerance && SegmentDistance(q, g.a, g.b) <= kTolerance) return &g;
  }
  return nullptr;
}

// The name of a vertex by the reference: the first sum of vertices equal to it, else the two edge refs.
std::string ReferenceVertexRef(const FileScene& f, std::optional<std::size_t> only, const Point& p,
                               const std::string& in, const std::string& out) {
  for (std::size_t o = 0; o < f.obstacles.size(); ++o) {
    if (only && o != *only) continue;
    const auto& [id, b] = f.obstacles[o];
    std::optional<std::pair<std::size_t, std::size_t>> first;
    for (std::size_t i = 0; i < b.size(); ++i) {
      for (std::size_t j = 0; j < f.robot.size(); ++j) {
        if ((b[i] - f.robot[j] - p).norm() <= kTolerance && !first) first = {i, j};
      }
    }
    // Lexicographically first (i, j): a repeated vertex's first position comes first, as the loader names it.
    if (first) return fmt::format("obstacle[{}].v[{}]-robot.v[{}]", id, first->first, first->second);
  }
  return "x(" + std::min(in, out) + "," + std::max(in, out) + ")";
}

struct Counts {
  int scenes = 0, rings = 0, edges = 0, split_edges = 0, robot_edge_refs = 0, sum_vertices = 0, crossing_vertices = 0;
};

void CheckRings(const FileScene& f, const std::vector<PolygonWithHoles>& polygons,
                const std::vector<PolygonSources>& sources, std::optional<std::size_t> only, Counts& counts) {
  const std::vector<RefGenerator> generators = ReferenceGenerators(f, only);
  ASSERT_EQ(polygons.size(), sources.size());
  for (std::size_t p = 0; p < polygons.size(); ++p) {
    std::vector<std::pair<const Polygon*, const RingSources*>> rings = {{&polygons[p].outer, &sources[p].outer}};
    ASSERT_EQ(polygons[p].holes.size(), sources[p].holes.size());
    for (std::size_t h = 0; h < polygons[p].holes.size(); ++h)
      rings.emplace_back(&polygons[p].holes[h], &sources[p].holes[h]);
    for (const auto& [ring, src] : rings) {
      ++counts.rings;
      const std::size_t n = ring->size();
      ASSERT_EQ(src->edges.size(), n);
      ASSERT_EQ(src->vertex_refs.size(), n);
      for (std::size_t k = 0; k < n; ++k) {
        const Point& a = (*ring)[k];
        const Point& b = (*ring)[(k + 1) % n];
        const EdgeSource& e = src->edges[k];
        ++counts.edges;
        counts.robot_edge_refs += e.kind == EdgeSource::Kind::kRobotEdge;
        if (only) {
          EXPECT_EQ(e.obstacle, *only);
        }
        const RefGenerator* named = nullptr;
        for (const RefGenerator& g : generators) named = g.ref == e.ref ? &g : named;
        ASSERT_NE(named, nullptr) << e.ref << " names no generator of the file";
        EXPECT_LE(SegmentDistance(a, named->a, named->b), kTolerance) << e.ref;
        EXPECT_LE(SegmentDistance(b, named->a, named->b), kTolerance) << e.ref;
        EXPECT_EQ(named->obstacle, e.obstacle);
        const RefGenerator* first = FirstContaining(generators, a, b);
        ASSERT_NE(first, nullptr);
        EXPECT_EQ(e.ref, first->ref) << "edge " << a.transpose() << " -> " << b.transpose();
        const std::string& before = src->edges[(k + n - 1) % n].ref;
        counts.split_edges += before == e.ref;  // consecutive pieces of one generator (a pinch between them)
        const std::string vertex = ReferenceVertexRef(f, only, a, before, e.ref);
        EXPECT_EQ(src->vertex_refs[k], vertex) << "vertex " << a.transpose();
        (vertex[0] == 'x' ? counts.crossing_vertices : counts.sum_vertices)++;
      }
    }
  }
}

TEST(CSpaceProvenance, EveryBoundaryEdgeLiesOnTheGeneratorItsRefNames) {
  Counts counts;
  for (std::uint64_t seed = 1; seed <= 100; ++seed) {
    const std::optional<FileScene> f = RandomFileScene(seed);
    Scene scene;
    try {
      scene = ParseScene(f->json, fmt::format("random{}.json", seed));
    } catch (const InputError&) {
      continue;  // e.g. the goal strip entirely inside CB
    }
    ++counts.scenes;
    const CSpace cspace(scene);
    SCOPED_TRACE(seed);
    CheckRings(*f, cspace.obstacle_union(), cspace.obstacle_union_sources(), std::nullopt, counts);
    for (std::size_t i = 0; i < cspace.num_c_obstacles(); ++i) {
      CheckRings(*f, cspace.c_obstacle(i), cspace.c_obstacle_sources(i), i, counts);
    }
    if (::testing::Test::HasFailure()) break;
  }
  std::printf(
      "%d scenes, %d rings, %d edges (%d robot-edge refs, %d next to a piece of the same generator), %d sum "
      "and %d crossing vertices\n",
      counts.scenes, counts.rings, counts.edges, counts.robot_edge_refs, counts.split_edges, counts.sum_vertices,
      counts.crossing_vertices);
  EXPECT_GE(counts.scenes, 80);
  EXPECT_GT(counts.robot_edge_refs, 0);
  EXPECT_GT(counts.crossing_vertices, 0);
}

TEST(CSpaceProvenance, BackprojectionEdgesKeepTheirRefsAtEveryTheta) {
  int checked = 0, scenes = 0;
  std::map<std::string, int> thetas_per_ref;
  for (std::uint64_t seed = 1; seed <= 16; ++seed) {
    const std::optional<FileScene> f = RandomFileScene(seed);
    Scene scene;
    try {
      scene = ParseScene(f->json, fmt::format("random{}.json", seed));
    } catch (const InputError&) {
      continue;
    }
    ++scenes;
    SCOPED_TRACE(seed);
    const CSpace cspace(scene);
    const std::vector<RefGenerator> generators = ReferenceGenerators(*f, std::nullopt);
    std::map<std::string, int> seen;  // ref -> the number of θ it appeared at
    for (const double theta_deg : {-90.0, -70.0, -120.0, -45.0}) {
      const BackprojectionProblem pr = ProblemFromScene(scene, cspace, nullptr, theta_deg * M_PI / 180, false);
      const Region region = ClassicBackprojection(pr);
      std::map<std::string, bool> here;
      for (const RegionPolygon& poly : region.polygons) {
        std::vector<const RegionRing*> rings = {&poly.outer};
        for (const RegionRing& h : poly.holes) rings.push_back(&h);
        for (const RegionRing* ring : rings) {
          const std::size_t n = ring->vertices.size();
          for (std::size_t k = 0; k < n; ++k) {
            if (ring->edges[k].kind != EdgeKind::kObstacle) continue;
            const Point a = ring->vertices[k], b = ring->vertices[(k + 1) % n];
            const std::string& ref = ring->edges[k].ref;
            const RefGenerator* named = nullptr;
            for (const RefGenerator& g : generators) named = g.ref == ref ? &g : named;
            ASSERT_NE(named, nullptr) << ref;
            // Rotated into the sweep frame and back in double precision: a looser tolerance.
            EXPECT_LE(SegmentDistance(a, named->a, named->b), 1e-7) << ref << " at " << theta_deg;
            EXPECT_LE(SegmentDistance(b, named->a, named->b), 1e-7) << ref << " at " << theta_deg;
            // The CB edge under the middle of this edge carries the same ref.
            const Point mid = 0.5 * (a + b);
            std::string cb_ref;
            double best = 1e-7;
            const auto& polygons = cspace.obstacle_union();
            const auto& sources = cspace.obstacle_union_sources();
            for (std::size_t p = 0; p < polygons.size(); ++p) {
              std::vector<std::pair<const Polygon*, const RingSources*>> cb = {{&polygons[p].outer, &sources[p].outer}};
              for (std::size_t h = 0; h < polygons[p].holes.size(); ++h)
                cb.emplace_back(&polygons[p].holes[h], &sources[p].holes[h]);
              for (const auto& [cb_ring, src] : cb) {
                for (std::size_t e = 0; e < cb_ring->size(); ++e) {
                  const double d = SegmentDistance(mid, (*cb_ring)[e], (*cb_ring)[(e + 1) % cb_ring->size()]);
                  if (d <= best) {
                    best = d;
                    cb_ref = src->edges[e].ref;
                  }
                }
              }
            }
            EXPECT_EQ(ref, cb_ref) << "at " << theta_deg;
            ++checked;
            here[ref] = true;
          }
        }
      }
      for (const auto& [ref, unused] : here) ++seen[ref];
    }
    for (const auto& [ref, count] : seen) ++thetas_per_ref[std::to_string(count)];
  }
  std::printf("%d scenes, %d obstacle edges of B_θ(G) checked; refs seen at 1/2/3/4 of the 4 θ: %d/%d/%d/%d\n", scenes,
              checked, thetas_per_ref["1"], thetas_per_ref["2"], thetas_per_ref["3"], thetas_per_ref["4"]);
  EXPECT_GE(scenes, 12);
  EXPECT_GT(checked, 50);
  EXPECT_GT(thetas_per_ref["4"], 0);  // edges seen at every θ, with one ref
}

}  // namespace
}  // namespace visco::planning
