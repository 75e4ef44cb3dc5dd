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

#include <algorithm>
#include <map>
#include <stdexcept>

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
  std::vector<PolygonWithHoles> union_double;
  std::vector<PolygonWithHoles> free_double;
};

CSpace::CSpace(const Scene& scene) : exact_(std::make_unique<Exact>()) {
  Exact& e = *exact_;
  const KPolygon minus_robot = ToExact(scene.robot.polygon, -1.0);  // a point reflection keeps the orientation
  for (const Obstacle& obstacle : scene.obstacles) {
    e.c_obstacles.push_back(CGAL::minkowski_sum_2(ToExact(obstacle.shape.polygon), minus_robot));
    e.c_obstacles_double.push_back({ToDouble(e.c_obstacles.back())});
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
    e.union_double.push_back(ToDouble(pwh));
    add_cycle(pwh.outer_boundary());
    for (auto it = pwh.holes_begin(); it != pwh.holes_end(); ++it) add_cycle(*it);
  }
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
  std::vector<std::vector<KSegment>> exact_parts(n);
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
