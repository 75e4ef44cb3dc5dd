// C-obstacles, their union, free space, and exact cutting of segments against CB. All CGAL exact-constructions
// code of the planner's C-space lives in this file (it compiles slowly).

#include "planning/cspace.h"

#include <CGAL/Boolean_set_operations_2.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Polygon_2.h>
#include <CGAL/Polygon_set_2.h>
#include <CGAL/Polygon_with_holes_2.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/minkowski_sum_2.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <tuple>

namespace visco::planning {
namespace {

using K = CGAL::Exact_predicates_exact_constructions_kernel;
using FT = K::FT;
using KPoint = K::Point_2;
using KSegment = K::Segment_2;
using KPolygon = CGAL::Polygon_2<K>;
using KPolygonWithHoles = CGAL::Polygon_with_holes_2<K>;
using KPolygonSet = CGAL::Polygon_set_2<K>;
using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 2, std::size_t>;

KPolygon ToExact(const Polygon& polygon, double sign = 1.0) {
  KPolygon result;
  for (const Point& p : polygon.vertices) result.push_back(KPoint(sign * p.x(), sign * p.y()));
  return result;
}

// Rounds an exact number to a double: exactly when it is representable, else to one of its two neighbours.
double ToDouble(const FT& x) {
  if (x.approx().inf() == x.approx().sup()) return x.approx().inf();
  CGAL::exact(x);  // refines the approximation to the tightest interval
  return CGAL::to_double(x);
}

Point ToDouble(const KPoint& p) { return {ToDouble(p.x()), ToDouble(p.y())}; }

Polygon ToDouble(const KPolygon& polygon) {
  Polygon result;
  for (auto it = polygon.vertices_begin(); it != polygon.vertices_end(); ++it) {
    result.vertices.push_back(ToDouble(*it));
  }
  return result;
}

PolygonWithHoles ToDouble(const KPolygonWithHoles& pwh) {
  PolygonWithHoles result;
  result.outer = ToDouble(pwh.outer_boundary());
  for (auto it = pwh.holes_begin(); it != pwh.holes_end(); ++it) result.holes.push_back(ToDouble(*it));
  return result;
}

KPolygon Rectangle(const Bounds& bounds) {
  KPolygon r;
  r.push_back(KPoint(bounds.min.x(), bounds.min.y()));
  r.push_back(KPoint(bounds.max.x(), bounds.min.y()));
  r.push_back(KPoint(bounds.max.x(), bounds.max.y()));
  r.push_back(KPoint(bounds.min.x(), bounds.max.y()));
  return r;
}

// Given the boundary directions leaving a boundary point (each with whether the interior lies just
// counter-clockwise of it, i.e. the edge leaves the point), the state of the open piece leaving in direction d:
// 0 along the boundary, +1 into the interior, -1 into the exterior. Exact.
int StateFromBoundaryDirections(const std::vector<std::pair<K::Vector_2, bool>>& around, const K::Vector_2& d) {
  // Counter-clockwise angle from d to u, as (half, u) with half 0 for (0, pi], 1 for (pi, 2 pi); the nearest
  // direction clockwise of d has the largest angle.
  const auto half = [&](const K::Vector_2& u) {
    const CGAL::Orientation o = CGAL::orientation(d, u);
    if (o == CGAL::LEFT_TURN) return 0;
    if (o == CGAL::COLLINEAR) return CGAL::sign(d * u) < 0 ? 0 : 2;  // 2: the same direction as d
    return 1;
  };
  const std::pair<K::Vector_2, bool>* best = nullptr;
  int best_half = -1;
  for (const auto& entry : around) {
    const int h = half(entry.first);
    if (h == 2) return 0;
    if (best == nullptr || h > best_half ||
        (h == best_half && CGAL::orientation(best->first, entry.first) == CGAL::LEFT_TURN)) {
      best = &entry;
      best_half = h;
    }
  }
  return best->second ? 1 : -1;
}

// A segment whose pieces can bound a C-obstacle (cspace.h EdgeSource). Only indices are stored (there are
// 2 n m of them); the exact segment is formed for the few that a boundary edge's bounding box meets.
struct MinkowskiGenerator {
  std::size_t obstacle = 0;
  EdgeSource::Kind kind = EdgeSource::Kind::kObstacleEdge;
  std::uint32_t obstacle_vertex = 0;  // normalised: the edge from this vertex (kObstacleEdge), or this vertex
  std::uint32_t robot_vertex = 0;     // normalised: this vertex (kObstacleEdge), or the edge from this vertex
  int obstacle_feature = 0;           // file positions (EdgeSource)
  int robot_feature = 0;
  std::tuple<std::size_t, int, int, int> key() const {
    return {obstacle, static_cast<int>(kind), obstacle_feature, robot_feature};
  }
};

KPoint Difference(const Point& b, const Point& a) { return KPoint(FT(b.x()) - FT(a.x()), FT(b.y()) - FT(a.y())); }

// A box certainly containing the exact b - a (the rounded difference is within half an ulp of it).
CGAL::Bbox_2 DifferenceBox(const Point& b, const Point& a) {
  const double x = b.x() - a.x(), y = b.y() - a.y();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  return {std::nextafter(x, -kInf), std::nextafter(y, -kInf), std::nextafter(x, kInf), std::nextafter(y, kInf)};
}

// The generator's segment: its two ends (b - a) as points of the scene's normalised polygons.
std::pair<std::pair<const Point*, const Point*>, std::pair<const Point*, const Point*>> Ends(
    const Scene& scene, const MinkowskiGenerator& g) {
  const Polygon& b = scene.obstacles[g.obstacle].shape.polygon;
  const Polygon& a = scene.robot.polygon;
  if (g.kind == EdgeSource::Kind::kObstacleEdge) {
    return {{&b[g.obstacle_vertex], &a[g.robot_vertex]}, {&b[(g.obstacle_vertex + 1) % b.size()], &a[g.robot_vertex]}};
  }
  return {{&b[g.obstacle_vertex], &a[g.robot_vertex]}, {&b[g.obstacle_vertex], &a[(g.robot_vertex + 1) % a.size()]}};
}

KSegment ExactSegment(const Scene& scene, const MinkowskiGenerator& g) {
  const auto [s, t] = Ends(scene, g);
  return {Difference(*s.first, *s.second), Difference(*t.first, *t.second)};
}

CGAL::Bbox_2 GeneratorBox(const Scene& scene, const MinkowskiGenerator& g) {
  const auto [s, t] = Ends(scene, g);
  return DifferenceBox(*s.first, *s.second) + DifferenceBox(*t.first, *t.second);
}

EdgeSource SourceOf(const Scene& scene, const MinkowskiGenerator& g) {
  EdgeSource source{g.kind, g.obstacle, g.obstacle_feature, g.robot_feature, ""};
  const bool obstacle_edge = g.kind == EdgeSource::Kind::kObstacleEdge;
  source.ref = fmt::format("obstacle[{}].{}[{}]-robot.{}[{}]", scene.obstacles[g.obstacle].id,
                           obstacle_edge ? 'e' : 'v', g.obstacle_feature, obstacle_edge ? 'v' : 'e', g.robot_feature);
  return source;
}

// Obstacle i's generators (cspace.h EdgeSource), sorted by key: obstacle edges translated by minus each robot
// vertex, reflected robot edges translated by each obstacle vertex.
std::vector<MinkowskiGenerator> GeneratorsOf(const Scene& scene, std::size_t i) {
  const ScenePolygon& robot = scene.robot;
  const ScenePolygon& shape = scene.obstacles[i].shape;
  std::vector<MinkowskiGenerator> out;
  for (std::uint32_t k = 0; k < shape.polygon.size(); ++k) {
    for (std::uint32_t j = 0; j < robot.polygon.size(); ++j) {
      out.push_back({i, EdgeSource::Kind::kObstacleEdge, k, j, SourceEdgeIndex(shape, k), robot.source_index[j]});
      out.push_back({i, EdgeSource::Kind::kRobotEdge, k, j, shape.source_index[k], SourceEdgeIndex(robot, j)});
    }
  }
  std::sort(out.begin(), out.end(),
            [](const MinkowskiGenerator& a, const MinkowskiGenerator& b) { return a.key() < b.key(); });
  return out;
}

// A boundary cycle split where its generator changes: points[k] -> points[k + 1] lies on generators[k].
struct SplitRing {
  std::vector<KPoint> points;
  std::vector<std::size_t> generators;  // indices into the (key-sorted) generator list
};

// A segment lying on a generator: the generator's own segment, or a boundary edge of a C-obstacle already split.
struct Carrier {
  KSegment segment;
  std::size_t generator;  // index into the key-sorted generator list
  CGAL::Bbox_2 box;       // contains the segment
};

// Splits the cycles' edges where the first (by key) generator containing them changes, and merges consecutive
// pieces of one generator at points a cycle visits once. Each point takes the smallest generator index among the
// carriers containing it. Exact; candidates by a bounding-box sweep over all cycles at once,
// O((E + C) log(E + C) + pairs) for E edges and C carriers.
std::vector<SplitRing> SplitByGenerators(const std::vector<const KPolygon*>& cycles,
                                         const std::vector<Carrier>& carriers) {
  std::vector<std::pair<std::size_t, std::size_t>> edge_of;  // box info -> (cycle, edge)
  std::vector<Box> edge_boxes, generator_boxes;
  for (std::size_t c = 0; c < cycles.size(); ++c) {
    const KPolygon& cycle = *cycles[c];
    for (std::size_t k = 0; k < cycle.size(); ++k) {
      edge_boxes.emplace_back(cycle[k].bbox() + cycle[(k + 1) % cycle.size()].bbox(), edge_of.size());
      edge_of.emplace_back(c, k);
    }
  }
  for (std::size_t g = 0; g < carriers.size(); ++g) generator_boxes.emplace_back(carriers[g].box, g);
  std::vector<std::vector<std::size_t>> candidates(edge_of.size());
  CGAL::box_intersection_d(edge_boxes.begin(), edge_boxes.end(), generator_boxes.begin(), generator_boxes.end(),
                           [&](const Box& edge, const Box& g) { candidates[edge.info()].push_back(g.info()); });
  std::vector<SplitRing> out;
  std::size_t next_edge = 0;
  for (const KPolygon* cycle_pointer : cycles) {
    const KPolygon& cycle = *cycle_pointer;
    const std::size_t n = cycle.size();
    SplitRing ring;
    for (std::size_t k = 0; k < n; ++k) {
      const KPoint& p = cycle[k];
      const KPoint& q = cycle[(k + 1) % n];
      const K::Vector_2 d = q - p;
      const FT length = d * d;  // positions along the edge: (x - p) . d, from 0 to length
      std::vector<std::pair<FT, KPoint>> cuts = {{FT(0), p}, {length, q}};
      struct Cover {
        FT lo, hi;
        std::size_t generator;
      };
      std::vector<Cover> covers;
      for (std::size_t g : candidates[next_edge + k]) {
        const KSegment& s = carriers[g].segment;
        if (!CGAL::collinear(s.source(), s.target(), p) || !CGAL::collinear(s.source(), s.target(), q)) continue;
        std::pair<FT, KPoint> a = {(s.source() - p) * d, s.source()}, b = {(s.target() - p) * d, s.target()};
        if (b.first < a.first) std::swap(a, b);
        if (b.first <= 0 || a.first >= length) continue;  // no common part of positive length
        if (a.first > 0) cuts.push_back(a);
        if (b.first < length) cuts.push_back(b);
        covers.push_back({CGAL::max(a.first, FT(0)), CGAL::min(b.first, length), carriers[g].generator});
      }
      std::sort(cuts.begin(), cuts.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
      cuts.erase(std::unique(cuts.begin(), cuts.end(), [](const auto& x, const auto& y) { return x.first == y.first; }),
                 cuts.end());
      for (std::size_t c = 0; c + 1 < cuts.size(); ++c) {
        constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
        std::size_t best = kNone;
        for (const Cover& cover : covers) {
          if (cover.lo <= cuts[c].first && cover.hi >= cuts[c + 1].first) best = std::min(best, cover.generator);
        }
        if (best == kNone) {
          throw std::logic_error("CSpace: a C-obstacle boundary edge lies on no Minkowski generator");
        }
        if (c > 0 && ring.generators.back() == best) continue;  // the same generator goes on
        ring.points.push_back(cuts[c].second);
        ring.generators.push_back(best);
      }
    }
    next_edge += n;
    // Merge pieces of one generator across cycle vertices visited once (collinear: both lie on that generator).
    std::map<KPoint, int, K::Less_xy_2> visits;
    for (const KPoint& p : ring.points) ++visits[p];
    SplitRing merged;
    const std::size_t m = ring.points.size();
    for (std::size_t k = 0; k < m; ++k) {
      if (ring.generators[(k + m - 1) % m] == ring.generators[k] && visits[ring.points[k]] == 1) continue;
      merged.points.push_back(ring.points[k]);
      merged.generators.push_back(ring.generators[k]);
    }
    out.push_back(std::move(merged));
  }
  return out;
}

// Edge and vertex provenance of split rings. A vertex is named as a sum of vertices b_k - a_j when it is one (the
// first (obstacle, k, j) by file positions; among `obstacle`'s vertices only, if given), else by its two edges.
std::vector<RingSources> RingSourcesOf(const std::vector<SplitRing>& rings,
                                       const std::vector<MinkowskiGenerator>& generators, const Scene& scene,
                                       std::optional<std::size_t> obstacle) {
  std::vector<RingSources> out(rings.size());
  std::vector<std::pair<std::size_t, std::size_t>> vertex_of;  // box info -> (ring, vertex)
  std::vector<Box> vertex_boxes, sum_boxes;
  for (std::size_t r = 0; r < rings.size(); ++r) {
    for (std::size_t g : rings[r].generators) out[r].edges.push_back(SourceOf(scene, generators[g]));
    out[r].vertex_refs.resize(rings[r].points.size());
    for (std::size_t k = 0; k < rings[r].points.size(); ++k) {
      vertex_boxes.emplace_back(rings[r].points[k].bbox(), vertex_of.size());
      vertex_of.emplace_back(r, k);
    }
  }
  // Sums of vertices: (obstacle, normalised k, normalised j) packed in a box's info.
  std::vector<std::tuple<std::size_t, std::uint32_t, std::uint32_t>> sums;
  const Polygon& a = scene.robot.polygon;
  for (std::size_t i = 0; i < scene.obstacles.size(); ++i) {
    if (obstacle && i != *obstacle) continue;
    const Polygon& b = scene.obstacles[i].shape.polygon;
    for (std::uint32_t k = 0; k < b.size(); ++k) {
      for (std::uint32_t j = 0; j < a.size(); ++j) {
        sum_boxes.emplace_back(DifferenceBox(b[k], a[j]), sums.size());
        sums.emplace_back(i, k, j);
      }
    }
  }
  std::vector<std::optional<std::tuple<std::size_t, int, int>>> first(vertex_of.size());  // (obstacle, file k, j)
  CGAL::box_intersection_d(
      vertex_boxes.begin(), vertex_boxes.end(), sum_boxes.begin(), sum_boxes.end(),
      [&](const Box& vertex, const Box& sum) {
        const auto [r, k] = vertex_of[vertex.info()];
        const auto [i, bk, aj] = sums[sum.info()];
        const ScenePolygon& shape = scene.obstacles[i].shape;
        if (rings[r].points[k] != Difference(shape.polygon[bk], a[aj])) return;
        const std::tuple<std::size_t, int, int> key = {i, shape.source_index[bk], scene.robot.source_index[aj]};
        auto& best = first[vertex.info()];
        if (!best || key < *best) best = key;
      });
  for (std::size_t v = 0; v < vertex_of.size(); ++v) {
    const auto [r, k] = vertex_of[v];
    if (first[v]) {
      const auto [i, bk, aj] = *first[v];
      out[r].vertex_refs[k] = fmt::format("obstacle[{}].v[{}]-robot.v[{}]", scene.obstacles[i].id, bk, aj);
    } else {
      const std::size_t n = rings[r].points.size();
      std::string x = out[r].edges[(k + n - 1) % n].ref, y = out[r].edges[k].ref;
      if (y < x) std::swap(x, y);
      out[r].vertex_refs[k] = "x(" + x + "," + y + ")";
    }
  }
  return out;
}

Polygon ToDouble(const SplitRing& ring) {
  Polygon result;
  for (const KPoint& p : ring.points) result.vertices.push_back(ToDouble(p));
  return result;
}

}  // namespace

// A directed edge of CB's boundary with its neighbours: the interior of CB lies to the left of source->target
// (outer boundaries counter-clockwise, holes clockwise); prev precedes source and next follows target on the cycle.
struct BoundaryEdge {
  KPoint prev, source, target, next;
};

struct CSpace::Exact {
  std::vector<KPolygonWithHoles> c_obstacles;  // CB_i, one per obstacle
  KPolygonSet obstacle_union;
  std::vector<BoundaryEdge> edges;
  std::vector<std::vector<PolygonWithHoles>> c_obstacles_double;
  std::vector<std::vector<PolygonSources>> c_obstacles_sources;
  std::vector<PolygonWithHoles> union_double;
  std::vector<PolygonSources> union_sources;
  std::vector<PolygonWithHoles> free_double;
};

CSpace::CSpace(const Scene& scene) : exact_(std::make_unique<Exact>()) {
  Exact& e = *exact_;
  const KPolygon minus_robot = ToExact(scene.robot.polygon, -1.0);  // a point reflection keeps the orientation
  // Provenance (cspace.h EdgeSource): every boundary edge is split where the first generator containing it
  // changes. Splits polygons with holes (all at once), records their double rings and provenance, returns the split.
  std::vector<MinkowskiGenerator> all_generators;  // key-sorted: obstacles ascend
  const auto split = [&](const std::vector<KPolygonWithHoles>& polygons, const std::vector<Carrier>& carriers,
                         std::optional<std::size_t> obstacle, std::vector<PolygonWithHoles>& rings,
                         std::vector<PolygonSources>& sources) {
    std::vector<const KPolygon*> cycles;
    for (const KPolygonWithHoles& pwh : polygons) {
      cycles.push_back(&pwh.outer_boundary());
      for (auto it = pwh.holes_begin(); it != pwh.holes_end(); ++it) cycles.push_back(&*it);
    }
    std::vector<SplitRing> split_rings = SplitByGenerators(cycles, carriers);
    std::vector<RingSources> ring_sources = RingSourcesOf(split_rings, all_generators, scene, obstacle);
    std::size_t c = 0;
    for (const KPolygonWithHoles& pwh : polygons) {
      PolygonWithHoles& r = rings.emplace_back();
      PolygonSources& s = sources.emplace_back();
      r.outer = ToDouble(split_rings[c]);
      s.outer = std::move(ring_sources[c++]);
      for (auto it = pwh.holes_begin(); it != pwh.holes_end(); ++it) {
        r.holes.push_back(ToDouble(split_rings[c]));
        s.holes.push_back(std::move(ring_sources[c++]));
      }
    }
    return split_rings;
  };
  // CB's boundary lies on the C-obstacles' boundaries, and a point of it on a generator of obstacle j lies on CB_j's
  // boundary (the generator lies in CB_j), where CB_j's own split names the first of j's generators containing it.
  // So the split edges of all CB_j carry CB's first generator too, and are far fewer than the generators.
  std::vector<Carrier> union_carriers;
  for (std::size_t i = 0; i < scene.obstacles.size(); ++i) {
    e.c_obstacles.push_back(CGAL::minkowski_sum_2(ToExact(scene.obstacles[i].shape.polygon), minus_robot));
    const std::size_t offset = all_generators.size();
    const std::vector<MinkowskiGenerator> generators = GeneratorsOf(scene, i);
    all_generators.insert(all_generators.end(), generators.begin(), generators.end());
    std::vector<Carrier> carriers;
    for (std::size_t g = 0; g < generators.size(); ++g) {
      carriers.push_back({ExactSegment(scene, generators[g]), offset + g, GeneratorBox(scene, generators[g])});
    }
    for (const SplitRing& ring : split({e.c_obstacles.back()}, carriers, i, e.c_obstacles_double.emplace_back(),
                                       e.c_obstacles_sources.emplace_back())) {
      const std::size_t n = ring.points.size();
      for (std::size_t k = 0; k < n; ++k) {
        KSegment piece(ring.points[k], ring.points[(k + 1) % n]);
        const CGAL::Bbox_2 box = piece.bbox();
        union_carriers.push_back({std::move(piece), ring.generators[k], box});
      }
    }
  }
  if (!e.c_obstacles.empty()) e.obstacle_union.join(e.c_obstacles.begin(), e.c_obstacles.end());
  std::vector<KPolygonWithHoles> pieces;
  e.obstacle_union.polygons_with_holes(std::back_inserter(pieces));
  const auto add_cycle = [&](const KPolygon& cycle) {
    const std::size_t n = cycle.size();
    for (std::size_t k = 0; k < n; ++k) {
      e.edges.push_back({cycle[(k + n - 1) % n], cycle[k], cycle[(k + 1) % n], cycle[(k + 2) % n]});
    }
  };
  for (const KPolygonWithHoles& pwh : pieces) {
    add_cycle(pwh.outer_boundary());
    for (auto it = pwh.holes_begin(); it != pwh.holes_end(); ++it) add_cycle(*it);
  }
  split(pieces, union_carriers, std::nullopt, e.union_double, e.union_sources);
  KPolygonSet free_set(Rectangle(scene.bounds));
  free_set.difference(e.obstacle_union);
  std::vector<KPolygonWithHoles> free_pieces;
  free_set.polygons_with_holes(std::back_inserter(free_pieces));
  for (const KPolygonWithHoles& pwh : free_pieces) e.free_double.push_back(ToDouble(pwh));
}

CSpace::~CSpace() = default;
CSpace::CSpace(CSpace&&) noexcept = default;
CSpace& CSpace::operator=(CSpace&&) noexcept = default;

const std::vector<PolygonWithHoles>& CSpace::c_obstacle(std::size_t i) const {
  return exact_->c_obstacles_double.at(i);
}
std::size_t CSpace::num_c_obstacles() const { return exact_->c_obstacles_double.size(); }
const std::vector<PolygonWithHoles>& CSpace::obstacle_union() const { return exact_->union_double; }
const std::vector<PolygonWithHoles>& CSpace::free_space() const { return exact_->free_double; }
const std::vector<PolygonSources>& CSpace::c_obstacle_sources(std::size_t i) const {
  return exact_->c_obstacles_sources.at(i);
}
const std::vector<PolygonSources>& CSpace::obstacle_union_sources() const { return exact_->union_sources; }

Location CSpace::Locate(const Point& q) const {
  switch (exact_->obstacle_union.oriented_side(KPoint(q.x(), q.y()))) {
    case CGAL::ON_POSITIVE_SIDE:
      return Location::kInside;
    case CGAL::ON_ORIENTED_BOUNDARY:
      return Location::kBoundary;
    case CGAL::ON_NEGATIVE_SIDE:
      break;
  }
  return Location::kOutside;
}

bool CSpace::HasFreePart(const Polygon& region) const {
  KPolygon polygon = ToExact(region);
  if (polygon.orientation() == CGAL::CLOCKWISE) polygon.reverse_orientation();
  KPolygonSet rest(polygon);
  rest.difference(exact_->obstacle_union);
  return !rest.is_empty();
}

CutResult CSpace::CutSegments(const std::vector<OffsetSegment>& segments, const Bounds& bounds, bool crossings) const {
  const Exact& e = *exact_;
  const std::size_t n = segments.size();
  std::vector<KSegment> exact(n);
  for (std::size_t i = 0; i < n; ++i) {
    const OffsetSegment& s = segments[i];
    exact[i] = KSegment(KPoint(FT(s.source.x()) + FT(s.offset.x()), FT(s.source.y()) + FT(s.offset.y())),
                        KPoint(FT(s.target.x()) + FT(s.offset.x()), FT(s.target.y()) + FT(s.offset.y())));
  }

  // Candidate (segment, boundary edge) pairs whose bounding boxes meet.
  std::vector<Box> segment_boxes, edge_boxes;
  for (std::size_t i = 0; i < n; ++i) {
    if (!exact[i].is_degenerate()) segment_boxes.emplace_back(exact[i].bbox(), i);
  }
  for (std::size_t k = 0; k < e.edges.size(); ++k) {
    edge_boxes.emplace_back(e.edges[k].source.bbox() + e.edges[k].target.bbox(), k);
  }
  std::vector<std::vector<std::size_t>> candidates(n);
  CGAL::box_intersection_d(segment_boxes.begin(), segment_boxes.end(), edge_boxes.begin(), edge_boxes.end(),
                           [&](const Box& s, const Box& edge) { candidates[s.info()].push_back(edge.info()); });

  const K::Iso_rectangle_2 box(KPoint(bounds.min.x(), bounds.min.y()), KPoint(bounds.max.x(), bounds.max.y()));
  CutResult result;
  result.parts.resize(n);
  result.on_cb.resize(n);
  std::vector<std::vector<KSegment>> exact_parts(n);
  const auto on_boundary = [&](const KPoint& x) {
    return e.obstacle_union.oriented_side(x) == CGAL::ON_ORIENTED_BOUNDARY;
  };
  for (std::size_t i = 0; i < n; ++i) {
    const KSegment& seg = exact[i];
    if (seg.is_degenerate()) continue;
    const KPoint& s = seg.source();
    const K::Vector_2 r = seg.to_vector();
    // Order points along the segment by their projection on r (exact).
    const auto before = [&](const KPoint& a, const KPoint& b) { return (b - a) * r > 0; };
    std::vector<KPoint> breaks = {seg.source(), seg.target()};
    std::vector<std::size_t>& cand = candidates[i];
    std::sort(cand.begin(), cand.end());
    for (std::size_t k : cand) {
      const BoundaryEdge& edge = e.edges[k];
      const auto hit = CGAL::intersection(seg, KSegment(edge.source, edge.target));
      if (!hit) continue;
      if (const KPoint* p = boost::get<KPoint>(&*hit)) {
        breaks.push_back(*p);
      } else if (const KSegment* o = boost::get<KSegment>(&*hit)) {
        breaks.push_back(o->source());
        breaks.push_back(o->target());
      }
    }
    std::sort(breaks.begin(), breaks.end(), before);
    breaks.erase(std::unique(breaks.begin(), breaks.end()), breaks.end());

    // State of the open piece that starts at `x` and runs in direction d: +1 interior of CB, 0 on its boundary,
    // -1 outside, 2 unknown (x is on no boundary edge, so the piece continues the state before x).
    const auto state_after = [&](const KPoint& x, const K::Vector_2& d) -> int {
      // The boundary directions leaving x: along outgoing edges (interior on their left, i.e. just
      // counter-clockwise of them) and back along incoming edges (interior just clockwise of them). The state in
      // direction d is decided by the boundary direction nearest to d clockwise. This handles vertices where the
      // boundary passes several times (pinches of the union) as well as plain vertices and edge interiors.
      std::vector<std::pair<K::Vector_2, bool>> around;  // (direction, outgoing)
      for (std::size_t k : cand) {
        const BoundaryEdge& edge = e.edges[k];
        if (x == edge.source) {
          around.emplace_back(edge.target - x, true);
        } else if (x == edge.target) {
          around.emplace_back(edge.source - x, false);
        } else if (KSegment(edge.source, edge.target).has_on(x)) {
          around.emplace_back(edge.target - x, true);
          around.emplace_back(edge.source - x, false);
        }
      }
      if (around.empty()) return 2;
      return StateFromBoundaryDirections(around, d);
    };

    // Classify each piece [breaks[k], breaks[k + 1]].
    const std::size_t pieces = breaks.size() - 1;
    std::vector<int> state(pieces, 2);
    for (std::size_t k = 0; k < pieces; ++k) state[k] = state_after(breaks[k], r);
    if (state[0] == 2) {
      // The source is on no boundary edge: look back from the first breakpoint, or locate the source.
      const int back = state_after(breaks[1], -r);
      state[0] = back != 2 ? back : (e.obstacle_union.oriented_side(s) == CGAL::ON_POSITIVE_SIDE ? 1 : -1);
    }
    for (std::size_t k = 1; k < pieces; ++k) {
      if (state[k] == 2) state[k] = state[k - 1];
    }
    // Merge consecutive kept pieces, clip to the bounds.
    std::vector<KSegment> kept;
    for (std::size_t k = 0; k < pieces; ++k) {
      if (state[k] == 1) continue;
      if (!kept.empty() && kept.back().target() == breaks[k]) {
        kept.back() = KSegment(kept.back().source(), breaks[k + 1]);
      } else {
        kept.emplace_back(breaks[k], breaks[k + 1]);
      }
    }
    for (const KSegment& piece : kept) {
      const auto clipped = CGAL::intersection(piece, box);
      if (!clipped) continue;
      if (const KSegment* c = boost::get<KSegment>(&*clipped)) {
        if (c->is_degenerate()) continue;
        exact_parts[i].push_back(*c);
        result.parts[i].push_back({ToDouble(c->source()), ToDouble(c->target())});
        result.on_cb[i].push_back({on_boundary(c->source()), on_boundary(c->target())});
      }
    }
  }

  if (crossings) {
    std::vector<Box> part_boxes;
    std::vector<std::pair<std::size_t, std::size_t>> owner;  // (input, part)
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t p = 0; p < exact_parts[i].size(); ++p) {
        part_boxes.emplace_back(exact_parts[i][p].bbox(), owner.size());
        owner.emplace_back(i, p);
      }
    }
    std::map<std::pair<std::size_t, std::size_t>, std::vector<std::pair<KPoint, bool>>> found;
    CGAL::box_self_intersection_d(part_boxes.begin(), part_boxes.end(), [&](const Box& a, const Box& b) {
      auto [ia, pa] = owner[a.info()];
      auto [ib, pb] = owner[b.info()];
      if (ia == ib) return;
      if (ia > ib) {
        std::swap(ia, ib);
        std::swap(pa, pb);
      }
      const auto hit = CGAL::intersection(exact_parts[ia][pa], exact_parts[ib][pb]);
      if (!hit) return;
      auto& list = found[{ia, ib}];
      if (const KPoint* p = boost::get<KPoint>(&*hit)) {
        list.emplace_back(*p, false);
      } else if (const KSegment* o = boost::get<KSegment>(&*hit)) {
        list.emplace_back(o->source(), true);
        list.emplace_back(o->target(), true);
      }
    });
    for (auto& [pair, list] : found) {
      std::sort(list.begin(), list.end(), [](const auto& a, const auto& b) {
        return a.first < b.first || (a.first == b.first && a.second < b.second);
      });
      list.erase(std::unique(list.begin(), list.end(), [](const auto& a, const auto& b) { return a.first == b.first; }),
                 list.end());
      for (const auto& [point, overlap] : list) {
        result.crossings.push_back({pair.first, pair.second, ToDouble(point), overlap});
      }
    }
  }
  return result;
}

std::optional<std::pair<std::size_t, std::size_t>> FindOverlappingObstacles(const std::vector<Obstacle>& obstacles) {
  std::vector<KPolygon> polygons;
  std::vector<Box> boxes;
  for (std::size_t i = 0; i < obstacles.size(); ++i) {
    polygons.push_back(ToExact(obstacles[i].shape.polygon));
    boxes.emplace_back(polygons.back().bbox(), i);
  }
  std::optional<std::pair<std::size_t, std::size_t>> first;
  CGAL::box_self_intersection_d(boxes.begin(), boxes.end(), [&](const Box& a, const Box& b) {
    const std::size_t i = std::min(a.info(), b.info()), j = std::max(a.info(), b.info());
    if (first && std::make_pair(i, j) >= *first) return;
    // Regularised: true only if the interiors meet (touching boundaries do not count).
    if (CGAL::do_intersect(polygons[i], polygons[j])) first = std::make_pair(i, j);
  });
  return first;
}

}  // namespace visco::planning
