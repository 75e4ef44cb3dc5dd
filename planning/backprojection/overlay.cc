// The sweep's static part: the input mapped to the sweep frame, the active rays clipped and cut where the tracking
// error makes them fail, the static geometry overlaid with CGAL's arrangement (which merges overlapping C-obstacles
// and splits crossing edges), every face labelled (outside the bounds, inside CB, goal, free), and the static curves
// grouped by their lower end as the sweep's static events.

#include <CGAL/Arr_consolidated_curve_data_traits_2.h>
#include <CGAL/Arr_extended_dcel.h>
#include <CGAL/Arr_segment_traits_2.h>
#include <CGAL/Arrangement_2.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "common/motion_model.h"
#include "planning/backprojection/plane_sweep.h"
#include "planning/backprojection/tracking_error.h"
#include "planning/geometry.h"

namespace visco::planning::internal {

namespace {

using SegTraits = CGAL::Arr_segment_traits_2<K>;
using Traits = CGAL::Arr_consolidated_curve_data_traits_2<SegTraits, int>;
using Dcel = CGAL::Arr_extended_dcel<Traits, int, int, int>;  // vertex: index, face: label counts
using Arr = CGAL::Arrangement_2<Traits, Dcel>;

// Where the lines through a, b and through c, d cross (they are not parallel).
P2 LinesMeet(const P2& a, const P2& b, const P2& c, const P2& d) {
  const auto hit = CGAL::intersection(K::Line_2(a, b), K::Line_2(c, d));
  const P2* x = hit ? boost::get<P2>(&*hit) : nullptr;
  if (x == nullptr) throw std::logic_error("backprojection: the prepared overlay's crossing is not one point");
  return *x;
}

// The overlay of `sources` (in one frame): CGAL's arrangement of their segments (merging overlapping C-obstacles,
// splitting crossing edges), every face labelled by a traversal from the unbounded face that counts how many bounds,
// obstacle and goal polygons contain it, and the edges the sweep sees with the source each stands for. Every
// decision here is an exact predicate that a similarity with positive determinant does not change (orientations,
// signs of dot products): the overlay of rotated sources is the rotated overlay.
OverlayGraph BuildOverlay(const std::vector<Source>& sources, bool vertex_sources) {
  Arr arr;
  {
    std::vector<Traits::Curve_2> cv;
    cv.reserve(sources.size());
    for (size_t i = 0; i < sources.size(); ++i) cv.emplace_back(Seg(sources[i].a, sources[i].b), static_cast<int>(i));
    CGAL::insert(arr, cv.begin(), cv.end());
  }
  OverlayGraph out;
  for (auto v = arr.vertices_begin(); v != arr.vertices_end(); ++v) {
    v->set_data(static_cast<int>(out.vertices.size()));
    out.vertices.push_back(v->point());
  }
  if (vertex_sources) out.vertex_sources.resize(out.vertices.size());
  // Face labels by a traversal from the unbounded face, counting how many bounds/obstacle/goal polygons contain
  // each face.
  struct Counts {
    int bounds = 0, obstacle = 0, goal = 0;
  };
  std::vector<Counts> counts;
  for (auto f = arr.faces_begin(); f != arr.faces_end(); ++f) f->set_data(-1);
  auto label_of = [&](int idx) {
    const Counts& c = counts[idx];
    if (c.bounds <= 0) return Label::kOutside;
    if (c.obstacle > 0) return Label::kObstacle;
    if (c.goal > 0) return Label::kGoal;
    return Label::kGood;
  };
  {
    std::vector<Arr::Face_handle> queue;
    Arr::Face_handle uf = arr.unbounded_face();
    uf->set_data(0);
    counts.push_back({});
    queue.push_back(uf);
    auto visit = [&](Arr::Halfedge_handle he, Arr::Face_handle f) {
      Arr::Face_handle g = he->twin()->face();
      if (g->data() != -1) return;
      Counts c = counts[f->data()];
      const V2 hd = he->target()->point() - he->source()->point();
      for (auto it = he->curve().data().begin(); it != he->curve().data().end(); ++it) {
        const Source& s = sources[*it];
        const bool same = CGAL::sign(hd * (s.b - s.a)) == CGAL::POSITIVE;
        const int delta = same ? -1 : 1;  // leaving the polygon whose interior is on the left of s
        if (s.kind == EdgeKind::kBounds) c.bounds += delta;
        if (s.kind == EdgeKind::kObstacle) c.obstacle += delta;
        if (s.kind == EdgeKind::kGoal) c.goal += delta;
      }
      g->set_data(static_cast<int>(counts.size()));
      counts.push_back(c);
      queue.push_back(g);
    };
    for (size_t qi = 0; qi < queue.size(); ++qi) {
      Arr::Face_handle f = queue[qi];
      if (!f->is_unbounded()) {
        auto circ = f->outer_ccb();
        auto start = circ;
        do {
          visit(circ, f);
        } while (++circ != start);
      }
      for (auto hole = f->holes_begin(); hole != f->holes_end(); ++hole) {
        auto circ = *hole;
        auto start = circ;
        do {
          visit(circ, f);
        } while (++circ != start);
      }
    }
  }
  for (auto e = arr.edges_begin(); e != arr.edges_end(); ++e) {
    Arr::Halfedge_handle he = e;
    const P2& s = he->source()->point();
    const P2& t = he->target()->point();
    // The face of a halfedge lies on its left.
    const Label left = label_of(he->face()->data());
    const Label right = label_of(he->twin()->face()->data());
    int vc = -1, bounds = -1, goal = -1, obstacle = -1;
    for (auto it = he->curve().data().begin(); it != he->curve().data().end(); ++it) {
      const int i = *it;
      const Source& src = sources[i];
      if (vertex_sources) {
        out.vertex_sources[he->source()->data()].push_back(i);
        out.vertex_sources[he->target()->data()].push_back(i);
      }
      if (src.kind == EdgeKind::kVc && (vc < 0 || i < vc)) vc = i;
      if (src.kind == EdgeKind::kBounds && (bounds < 0 || i < bounds)) bounds = i;
      if (src.kind == EdgeKind::kGoal && (goal < 0 || i < goal)) goal = i;
      if (src.kind == EdgeKind::kObstacle) {
        // Prefer the obstacle edge whose interior is the obstacle side.
        const bool same = CGAL::sign((t - s) * (src.b - src.a)) == CGAL::POSITIVE;
        const bool interior_left = same;  // the source's interior is on the left of s->t
        const Label inside = interior_left ? left : right;
        if (inside == Label::kObstacle && (obstacle < 0 || i < obstacle)) obstacle = i;
        if (obstacle < 0) obstacle = i;
      }
    }
    OverlayEdge c{he->source()->data(), he->target()->data(), left, right, EdgeKind::kObstacle, -1};
    if (left == right) {
      if (!(IsFree(left) && vc >= 0)) continue;
      c.kind = EdgeKind::kVc;
      c.src = vc;
    } else if (left == Label::kOutside || right == Label::kOutside) {
      c.kind = EdgeKind::kBounds;
      c.src = bounds >= 0 ? bounds : (obstacle >= 0 ? obstacle : goal);
    } else if (left == Label::kObstacle || right == Label::kObstacle) {
      const Label other = left == Label::kObstacle ? right : left;
      if (other == Label::kGoal && goal >= 0) {
        c.kind = EdgeKind::kGoal;
        c.src = goal;
      } else {
        c.kind = EdgeKind::kObstacle;
        c.src = obstacle >= 0 ? obstacle : goal;
      }
    } else {
      c.kind = EdgeKind::kGoal;
      c.src = goal >= 0 ? goal : (vc >= 0 ? vc : obstacle);
    }
    if (c.src < 0) continue;
    out.edges.push_back(c);
  }
  return out;
}

}  // namespace

// True if the ray part from `lower` up to `upper` runs along a C-obstacle edge at `lower`: the edge lies on the
// part's line and goes on from `lower` towards `upper` (exact, in the sweep frame).
bool Sweep::RunsAlongCB(const P2& lower, const P2& upper, SweepFrame& frame) const {
  for (const auto& poly : problem_.obstacles) {
    const size_t n = poly.vertices.size();
    for (size_t k = 0; k < n; ++k) {
      if (poly.vertices[k] == poly.vertices[(k + 1) % n]) continue;
      const P2 a = frame.Map(poly.vertices[k]), b = frame.Map(poly.vertices[(k + 1) % n]);
      if (!CGAL::collinear(a, b, lower) || !CGAL::collinear(a, b, upper)) continue;
      if (!CGAL::collinear_are_ordered_along_line(a, lower, b)) continue;
      const V2 up = upper - lower;
      if (CGAL::is_positive((a - lower) * up) || CGAL::is_positive((b - lower) * up)) return true;
    }
  }
  return false;
}

Sweep::Sweep(const BackprojectionProblem& pr, SweepFrame& frame, StaticsOnly) : problem_(pr), rot_(frame.rotation()) {
  if (!(pr.bounds_max.x() > pr.bounds_min.x() && pr.bounds_max.y() > pr.bounds_min.y())) {
    throw std::invalid_argument("backprojection: bounds are empty");
  }
  if (!(pr.velocity_cone >= 0.0 && pr.velocity_cone < M_PI / 2)) {
    throw std::invalid_argument("backprojection: the velocity cone must be in [0, 90) degrees");
  }
  if (!(pr.friction_cone >= 0.0 && pr.friction_cone < M_PI / 2)) {
    throw std::invalid_argument("backprojection: the friction cone must be in [0, 90) degrees");
  }
  if (!(pr.ray_tracking_error >= 0.0) || !std::isfinite(pr.ray_tracking_error)) {
    throw std::invalid_argument("backprojection: the ray tracking error must be finite and not negative");
  }
  eps_ = std::max(pr.velocity_cone, 1e-9);  // a cone of zero width is planned as a hair wider: a subset
  phi_ = pr.friction_cone;
  free_right_ = V2(std::sin(eps_), std::cos(eps_));
  free_left_ = V2(-std::sin(eps_), std::cos(eps_));
  cone_cw_ = -free_right_;
  cone_ccw_ = -free_left_;
  less_.p = &current_;
  status_ = std::set<Curve*, StatusLess>(less_);
  AddStaticSources(frame);
}

Sweep::Sweep(const BackprojectionProblem& pr, const std::vector<int>& active_rays, SweepFrame& frame)
    : Sweep(pr, frame, StaticsOnly{}) {
  const size_t statics = sources_.size();
  AddRayParts(active_rays, frame);
  const StaticOverlay* prepared = pr.static_overlay.get();
  if (prepared != nullptr && sources_.size() == statics && statics == prepared->sources && prepared->Matches(pr)) {
    // The prepared overlay, mapped: its input points through the frame (the same exact points as the sources'), its
    // crossings as the crossings of the mapped sources' lines (the rotation of the world's crossing, exactly).
    std::vector<P2> vertices;
    vertices.reserve(prepared->vertices.size());
    for (const StaticOverlay::Vertex& v : prepared->vertices) {
      vertices.push_back(v.a < 0 ? frame.Map(v.point)
                                 : LinesMeet(sources_[v.a].a, sources_[v.a].b, sources_[v.b].a, sources_[v.b].b));
    }
    SetStaticEvents(vertices, prepared->edges);
  } else {
    const OverlayGraph overlay = BuildOverlay(sources_, false);
    SetStaticEvents(overlay.vertices, overlay.edges);
  }
}

void Sweep::AddStaticSources(SweepFrame& frame) {
  const BackprojectionProblem& pr = problem_;
  auto to_exact = [&](const Vector2d& w) { return frame.Map(w); };
  auto add_polygon = [&](const NamedPolygon& poly, EdgeKind kind, const std::string& prefix, size_t index) {
    std::vector<Vector2d> v = poly.vertices;
    std::vector<std::string> vref = poly.vertex_refs, eref = poly.edge_refs;
    const size_t n = v.size();
    if (n < 3) {
      throw std::invalid_argument("backprojection: " + prefix + "[" + std::to_string(index) +
                                  "] has fewer than 3 vertices");
    }
    vref.resize(n);
    eref.resize(n);
    for (size_t k = 0; k < n; ++k) {
      if (vref[k].empty()) vref[k] = prefix + "[" + std::to_string(index) + "].v[" + std::to_string(k) + "]";
      if (eref[k].empty()) eref[k] = prefix + "[" + std::to_string(index) + "].e[" + std::to_string(k) + "]";
    }
    const bool ccw = (SignedAreaD(v) > 0.0) != poly.hole;  // holes run clockwise: CB's interior on the left
    for (size_t k = 0; k < n; ++k) {
      const Vector2d& wa = v[k];
      const Vector2d& wb = v[(k + 1) % n];
      if (wa == wb) continue;
      Source s;
      s.a = to_exact(ccw ? wa : wb);
      s.b = to_exact(ccw ? wb : wa);
      s.kind = kind;
      s.name = AddName(eref[k]);
      const Vector2d d = (ccw ? (wb - wa) : (wa - wb)).normalized();
      const Vector2d n_world(d.y(), -d.x());  // outward
      s.sticking =
          kind == EdgeKind::kObstacle && MotionModel::IsStickingEdge(n_world, pr.theta, eps_, pr.friction_cone);
      s.sweep_normal = rot_.Apply(n_world);
      sources_.push_back(s);
      vertex_names_.emplace(to_exact(v[k]), AddName(vref[k]));
    }
  };
  for (size_t i = 0; i < pr.obstacles.size(); ++i) add_polygon(pr.obstacles[i], EdgeKind::kObstacle, "cobstacle", i);
  for (size_t i = 0; i < pr.goal.size(); ++i) add_polygon(pr.goal[i], EdgeKind::kGoal, "goal", i);
  {
    const Vector2d lo = pr.bounds_min, hi = pr.bounds_max;
    const Vector2d corners[4] = {{lo.x(), lo.y()}, {hi.x(), lo.y()}, {hi.x(), hi.y()}, {lo.x(), hi.y()}};
    const char* sides[4] = {"ymin", "xmax", "ymax", "xmin"};
    const char* corner_names[4] = {"bounds.corner[xmin,ymin]", "bounds.corner[xmax,ymin]", "bounds.corner[xmax,ymax]",
                                   "bounds.corner[xmin,ymax]"};
    for (int k = 0; k < 4; ++k) bounds_sweep_[k] = to_exact(corners[k]);
    for (int k = 0; k < 4; ++k) {
      Source s;
      s.a = to_exact(corners[k]);
      s.b = to_exact(corners[(k + 1) % 4]);
      s.kind = EdgeKind::kBounds;
      s.name = AddName(sides[k]);
      const Vector2d d = (corners[(k + 1) % 4] - corners[k]).normalized();
      s.sweep_normal = rot_.Apply(Vector2d(-d.y(), d.x()));  // inward
      sources_.push_back(s);
      vertex_names_.emplace(to_exact(corners[k]), AddName(corner_names[k]));
    }
    // Forbidden regions: their insides count as outside the bounds (edges clockwise: the allowed side on the left).
    for (size_t i = 0; i < pr.forbidden.size(); ++i) {
      const NamedPolygon& poly = pr.forbidden[i];
      std::vector<Vector2d> v = poly.vertices;
      const size_t n = v.size();
      if (n < 3) {
        throw std::invalid_argument("backprojection: forbidden[" + std::to_string(i) + "] has fewer than 3 vertices");
      }
      const bool ccw = SignedAreaD(v) > 0.0;
      for (size_t k = 0; k < n; ++k) {
        const Vector2d& wa = ccw ? v[(k + 1) % n] : v[k];
        const Vector2d& wb = ccw ? v[k] : v[(k + 1) % n];
        if (wa == wb) continue;
        Source s;
        s.a = to_exact(wa);
        s.b = to_exact(wb);
        s.kind = EdgeKind::kBounds;
        s.name = AddName(k < poly.edge_refs.size() && !poly.edge_refs[k].empty()
                             ? poly.edge_refs[k]
                             : "forbidden[" + std::to_string(i) + "].e[" + std::to_string(k) + "]");
        const Vector2d d = (wb - wa).normalized();
        s.sweep_normal = rot_.Apply(Vector2d(-d.y(), d.x()));  // into the allowed side
        sources_.push_back(s);
        vertex_names_.emplace(to_exact(v[k]),
                              AddName(k < poly.vertex_refs.size() && !poly.vertex_refs[k].empty()
                                          ? poly.vertex_refs[k]
                                          : "forbidden[" + std::to_string(i) + "].v[" + std::to_string(k) + "]"));
      }
    }
    double top = -1e300;
    for (const auto& c : corners) top = std::max(top, rot_.Apply(c).y());
    top_ = FT(top + 1.0 + std::abs(top));
  }
}

void Sweep::AddRayParts(const std::vector<int>& active_rays, SweepFrame& frame) {
  const BackprojectionProblem& pr = problem_;
  auto to_exact = [&](const Vector2d& w) { return frame.Map(w); };
  // Active rays, clipped to the bounds exactly in the sweep frame (their rounded ends may lie a hair outside). An
  // end that is open (clipped here or by the C-space cut, or the camera end) fails when complied to: docs/semantics.md,
  // "the bounds are no end of a ray". Compliance runs down a reliable ray, so only lower ends matter.
  // A closed end lies on CB, but as a rounded point it can lie a few ulps beside the C-obstacle edge it ends on:
  // outside, a motion sliding down that edge would pass it by, where the real ray stops it. It is moved exactly onto
  // the edge (onto the edge's vertex when that close to one, else where the ray's line meets the edge's line). So is
  // an open end that lies on CB (where the camera stops seeing the CM vertex): a motion sliding down the edge meets
  // the ray there and complies to its other end (VISCO_SEED_OFFSET=16255459, seed 50 with heights, goal on CB).
  const double snap = 1e-9 * (pr.bounds_max - pr.bounds_min).norm();
  auto onto_cb = [&](const Vector2d& end, const P2& exact_end, const P2& other) -> P2 {
    double best = snap;
    const Vector2d* a = nullptr;
    const Vector2d* b = nullptr;
    for (const auto& poly : pr.obstacles) {
      const size_t n = poly.vertices.size();
      for (size_t k = 0; k < n; ++k) {
        const Vector2d& wa = poly.vertices[k];
        const Vector2d& wb = poly.vertices[(k + 1) % n];
        const double d = PointSegmentDistance(end, wa, wb);
        if (d <= best && wa != wb) best = d, a = &wa, b = &wb;
      }
    }
    if (a == nullptr) return exact_end;
    if ((end - *a).norm() <= snap) return to_exact(*a);
    if ((end - *b).norm() <= snap) return to_exact(*b);
    const P2& ea = to_exact(*a);
    const V2 edge = to_exact(*b) - ea, ray = exact_end - other;
    const FT denom = ray.x() * edge.y() - ray.y() * edge.x();
    if (CGAL::is_zero(denom)) return exact_end;  // along the edge: nothing to meet
    const V2 w = ea - other;
    const P2 meet = other + ray * ((w.x() * edge.y() - w.y() * edge.x()) / denom);
    return ToD(meet - exact_end).norm() <= snap ? meet : exact_end;
  };
  for (int r : active_rays) {
    const CvcRayInput& ray = pr.rays.at(r);
    // A part of the ray from a to b as a sweep source; its index.
    auto add_part = [&](const P2& a, const P2& b) {
      Source part;
      part.a = a;
      part.b = b;
      part.kind = EdgeKind::kVc;
      part.name = AddName(ray.id);
      part.ray = r;
      sources_.push_back(part);
      return static_cast<int>(sources_.size()) - 1;
    };
    for (size_t k = 0; k < ray.segments.size(); ++k) {
      const auto& seg = ray.segments[k];
      if (seg[0] == seg[1]) continue;
      P2 ends[2] = {to_exact(seg[0]), to_exact(seg[1])};
      bool open[2] = {false, false};
      if (k < ray.open_ends.size()) open[0] = ray.open_ends[k][0], open[1] = ray.open_ends[k][1];
      const P2 unsnapped[2] = {ends[0], ends[1]};
      for (int e = 0; e < 2; ++e) {
        ends[e] = onto_cb(seg[e], unsnapped[e], unsnapped[1 - e]);
      }
      if (!ClipToBounds(ends, open)) continue;
      if (ends[0] == ends[1]) continue;
      const int lower = CGAL::compare_yx(ends[0], ends[1]) == CGAL::SMALLER ? 0 : 1;
      // The servo runs up to δ beside the line all along, so CB within δ of the line (a corner, or an edge leaving
      // one) can stop a motion complying past it, and the bounds or a forbidden region that close can let it leave
      // the allowed configurations. The ray is cut where such a piece begins and ends: each part before
      // the last cut ends at its lower cut, open (complying into it fails, even where the goal lies further down: the
      // robot meets CB first). The edges the ray's ends lie on are the start's and the landing's (above); where CB
      // comes within δ right up to the lower end, the whole ray ends open.
      bool cut_to_the_end = false, last_part_beside_cb = false;
      if (pr.ray_tracking_error > 0.0) {
        const Vector2d up = rot_.InvertExact(ends[1 - lower]), down = rot_.InvertExact(ends[lower]);
        const P2 top = ends[1 - lower], bottom = ends[lower];
        std::vector<std::pair<double, double>> pieces;
        // A part beside such a piece of CB: a motion complying along it can meet CB anywhere on it, before the goal
        // too where the goal lies on it (VISCO_SEED_OFFSET=5261327, seed 51 of the soundness test: the goal's corner
        // on a C-obstacle face 1 cm from the ray), so complying along it fails throughout, not only at its end.
        auto beside_cb = [&](double t0, double t1) {
          const double mid = 0.5 * (t0 + t1);
          return std::any_of(pieces.begin(), pieces.end(),
                             [&](const auto& piece) { return piece.first <= mid && mid <= piece.second; });
        };
        double from = 0.0;
        for (const double cut : PointsWithinTrackingError(pr, up, down, snap, cut_to_the_end, pieces)) {
          const P2 corner = top + (bottom - top) * FT(cut);
          if (corner == ends[1 - lower]) continue;
          const int part = add_part(ends[1 - lower], corner);
          if (beside_cb(from, cut)) failing_parts_.insert(part);
          open_lower_ends_.insert(corner);
          ends[1 - lower] = corner;  // strictly between the ends: the lower end stays the lower one
          from = cut;
        }
        last_part_beside_cb = beside_cb(from, 1.0);
      }
      const int whole = add_part(ends[0], ends[1]);
      if (last_part_beside_cb ||
          (pr.ray_tracking_error > 0.0 && !open[lower] &&
           GoalAfterTheLanding(pr, rot_.InvertExact(ends[1 - lower]), rot_.InvertExact(ends[lower]), snap))) {
        failing_parts_.insert(whole);
      }
      if (open[lower] || cut_to_the_end ||
          (pr.ray_tracking_error > 0.0 && RunsAlongCB(ends[lower], ends[1 - lower], frame))) {
        // Along a C-obstacle edge down to its lower end, the servo holds the robot up to δ off the edge on the free
        // side, and past the end of the edge on the line beyond it: whatever CB does there, the motion never lands
        // where the planner could vouch for it (complying into such an end counts as failing, like an open end).
        // The overlay merges the ray into the edge, so without this the sweep would see only a sliding motion.
        // Found on random scenes with the goal on CB (VISCO_SEED_OFFSET=6995588, seed 31 of the soundness test).
        open_lower_ends_.insert(ends[lower]);
      }
      if (open[lower] || cut_to_the_end) {
        open_lower_ends_.insert(ends[lower]);
      } else if (pr.ray_tracking_error > 0.0) {
        closed_lower_ends_[ends[lower]].push_back(whole);
      }
    }
  }
}

void Sweep::SetStaticEvents(const std::vector<P2>& vertices, const std::vector<OverlayEdge>& edges) {
  // Static curves grouped by lower endpoint (the overlay's vertices are distinct points: one event each).
  std::vector<std::vector<StaticCurve>> uppers(vertices.size());
  std::vector<char> is_event(vertices.size(), 0);
  for (const OverlayEdge& e : edges) {
    const P2& s = vertices[e.s];
    const P2& t = vertices[e.t];
    const bool up = CGAL::compare_yx(s, t) == CGAL::SMALLER;
    const P2& lo = up ? s : t;
    const P2& hi = up ? t : s;
    const Label left = up ? e.left : e.right;
    const Label right = up ? e.right : e.left;
    StaticCurve c{lo, hi, e.kind, e.src, left, right, Vector2d::Zero(), false};
    const Source& src = sources_[c.src];
    if (c.kind == EdgeKind::kObstacle && src.kind == EdgeKind::kObstacle) {
      c.sticking = src.sticking;
      c.n_free = src.sweep_normal;
    } else if (c.kind == EdgeKind::kBounds && src.kind == EdgeKind::kBounds) {
      c.n_free = src.sweep_normal;
    }
    // Where the normal must point into the free side, make sure it does.
    if (c.kind == EdgeKind::kObstacle || c.kind == EdgeKind::kBounds) {
      const Vector2d d = ToD(hi - lo);
      const Vector2d left_normal(-d.y(), d.x());
      const bool free_left = IsFree(left) || left == Label::kGoal;
      if ((left_normal.dot(c.n_free) > 0) != free_left) c.n_free = -c.n_free;
      if (c.n_free.norm() == 0.0) c.n_free = (free_left ? left_normal : Vector2d(-left_normal)).normalized();
    }
    // A C-obstacle edge on the bounds' line: the motion model slides along it like any other (the robot stays on
    // the closed bounds), so the vertex rule at its ends must see it; its normal points out of the C-obstacle.
    if (c.kind == EdgeKind::kBounds && (left == Label::kObstacle || right == Label::kObstacle)) {
      const Vector2d d = ToD(hi - lo);
      const Vector2d left_normal = Vector2d(-d.y(), d.x()).normalized();
      c.obstacle_face = true;
      c.n_free = left == Label::kObstacle ? Vector2d(-left_normal) : left_normal;
    }
    uppers[up ? e.s : e.t].push_back(c);
    is_event[e.s] = is_event[e.t] = 1;
  }
  std::vector<int> order;
  for (size_t v = 0; v < vertices.size(); ++v) {
    if (is_event[v]) order.push_back(static_cast<int>(v));
  }
  std::sort(order.begin(), order.end(), [&](int a, int b) { return LessYX()(vertices[a], vertices[b]); });
  static_events_.reserve(order.size());
  for (const int v : order) static_events_.emplace_back(vertices[v], std::move(uppers[v]));
}

namespace {
std::vector<std::pair<std::vector<Vector2d>, bool>> Outlines(const std::vector<NamedPolygon>& polygons) {
  std::vector<std::pair<std::vector<Vector2d>, bool>> out;
  out.reserve(polygons.size());
  for (const NamedPolygon& p : polygons) out.emplace_back(p.vertices, p.hole);
  return out;
}
bool SameOutlines(const std::vector<std::pair<std::vector<Vector2d>, bool>>& a, const std::vector<NamedPolygon>& b,
                  bool holes) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].first != b[i].vertices || (holes && a[i].second != b[i].hole)) return false;
  }
  return true;
}
}  // namespace

bool StaticOverlay::Matches(const BackprojectionProblem& pr) const {
  return bounds_min == pr.bounds_min && bounds_max == pr.bounds_max && SameOutlines(obstacles, pr.obstacles, true) &&
         SameOutlines(goal, pr.goal, true) && SameOutlines(forbidden, pr.forbidden, false);
}

StaticOverlay Sweep::PrepareOverlay(const BackprojectionProblem& problem) {
  // θ = −90° is the commanded velocity straight down: the sweep frame is the world frame, exactly (c = 1, s = 0).
  SweepFrame frame(-M_PI / 2);
  const Sweep statics(problem, frame, StaticsOnly{});
  const OverlayGraph graph = BuildOverlay(statics.sources_, true);
  // The input points, by their exact value: a vertex of the overlay is one of them or a crossing of two sources.
  std::map<P2, Vector2d, LessYX> inputs;
  for (const Source& s : statics.sources_) {
    for (const P2* p : {&s.a, &s.b})
      inputs.emplace(*p, Vector2d(CGAL::to_double(p->exact().x()), CGAL::to_double(p->exact().y())));
  }
  StaticOverlay out;
  out.sources = statics.sources_.size();
  out.edges = graph.edges;
  out.vertices.resize(graph.vertices.size());
  for (size_t v = 0; v < graph.vertices.size(); ++v) {
    const auto input = inputs.find(graph.vertices[v]);
    if (input != inputs.end()) {
      out.vertices[v].point = input->second;
      continue;
    }
    // Inside two sources' segments that cross (not an end of either): two of its sources are not parallel.
    const std::vector<int>& through = graph.vertex_sources[v];
    for (size_t i = 0; i < through.size() && out.vertices[v].a < 0; ++i) {
      for (size_t j = i + 1; j < through.size(); ++j) {
        const Source& a = statics.sources_[through[i]];
        const Source& b = statics.sources_[through[j]];
        if (CGAL::orientation(a.b - a.a, b.b - b.a) != CGAL::COLLINEAR) {
          out.vertices[v].a = through[i];
          out.vertices[v].b = through[j];
          break;
        }
      }
    }
    if (out.vertices[v].a < 0)
      throw std::logic_error("backprojection: an overlay vertex is neither an input point nor a crossing");
    // The crossing is the vertex (the lines of two sources through it meet only there).
  }
  out.obstacles = Outlines(problem.obstacles);
  out.goal = Outlines(problem.goal);
  out.forbidden = Outlines(problem.forbidden);
  out.bounds_min = problem.bounds_min;
  out.bounds_max = problem.bounds_max;
  return out;
}

}  // namespace visco::planning::internal

namespace visco::planning {

void PrepareStaticOverlay(BackprojectionProblem& problem) {
  problem.static_overlay.reset();
  problem.static_overlay = std::make_shared<const internal::StaticOverlay>(internal::Sweep::PrepareOverlay(problem));
}

}  // namespace visco::planning

namespace visco::planning::internal {

// Clips a segment to the closed bounds rectangle (exact, in the sweep frame); a clipped end becomes open. False if
// nothing of positive length remains.
bool Sweep::ClipToBounds(P2 (&ends)[2], bool (&open)[2]) const {
  for (int k = 0; k < 4; ++k) {
    const P2& c0 = bounds_sweep_[k];
    const P2& c1 = bounds_sweep_[(k + 1) % 4];
    const bool out0 = CGAL::orientation(c0, c1, ends[0]) == CGAL::RIGHT_TURN;
    const bool out1 = CGAL::orientation(c0, c1, ends[1]) == CGAL::RIGHT_TURN;
    if (out0 && out1) return false;
    if (!out0 && !out1) continue;
    const auto hit = CGAL::intersection(K::Line_2(c0, c1), Seg(ends[0], ends[1]));
    const P2* x = hit ? boost::get<P2>(&*hit) : nullptr;
    if (!x) return false;  // not reached: the ends lie strictly on either side of the line
    const int outside = out0 ? 0 : 1;
    ends[outside] = *x;
    open[outside] = true;
  }
  return CGAL::compare_yx(ends[0], ends[1]) != CGAL::EQUAL;
}

}  // namespace visco::planning::internal
