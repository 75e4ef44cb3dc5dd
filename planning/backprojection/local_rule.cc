// rules below say so.
//
// Local rule at an event point p (a vertex of the overlay or a point where a free edge meets another curve). Curves
// through p are rays from p: lower rays (already swept, with known labels on both sides) and upper rays. For a point
// q just above p in a free upper sector S, its forward cone can reach (docs/semantics.md's motion model):
//   * S's clockwise side iff q's direction from p is below 90° + ε (sweep frame angles),
//   * S's counter-clockwise side iff it is above 90° − ε,
//   * p itself iff it is within [90° − ε, 90° + ε].
// A side is good if it is a goal edge, a non-sticking C-obstacle edge (the motion slides down it to p) or an active
// ray (it complies down it to p) and p is good, or the swept region below when S straddles the sweep line. p is
// good if it is in the closed goal or, for every velocity the adversary may pick there, the motion model's contact,
// vertex and ray rules lead into a good region (evaluated at every critical direction and between them). So every
// free upper sector splits into at most three zones at 90° ∓ ε, whose labels differ only across free edges, which
// are erected there. Points on free edges count as bad (a trajectory can run down a free edge to its bad origin).
// Between events a region's label does not change (Donald's locality argument), so the sweep is O((n + k) log n)
// with k the free-edge events.

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "common/motion_model.h"
#include "planning/backprojection/plane_sweep.h"

namespace visco::planning::internal {

// Is the motion arriving at p (by free motion, sliding or complying) good when the adversary picks direction w?
// Directions are exact vectors: which ray w runs along and which sector it points into are decided exactly. The
// contact rules (pushing, sticking, the larger tangential component) are the motion model's own double-precision
// predicates, so the planner and the simulator agree on them.
bool Sweep::OutcomeAt(const V2& w, const std::vector<LRay>& rays, Label below) const {
  // Active rays going down from p are engaged (their projection points down for a reliable ray).
  bool any_vc = false;
  for (const LRay& r : rays) {
    if (!r.upper && r.kind == EdgeKind::kVc) {
      any_vc = true;
      if (!IsGood(r.track)) return false;
    }
  }
  if (any_vc) return true;
  const Vector2d wd = ToD(w).normalized();
  // Along a ray?
  for (const LRay& r : rays) {
    if (CGAL::orientation(w, r.edir) != CGAL::COLLINEAR || CGAL::sign(w * r.edir) != CGAL::POSITIVE) continue;
    if (r.kind == EdgeKind::kFree) return false;
    if (r.kind == EdgeKind::kGoal) return true;
    // Tangent to an edge: moves along it; good only if every free region beside it is good.
    bool any_free = false;
    for (Label l : {r.ccw, r.cw}) {
      if (IsFree(l)) {
        any_free = true;
        if (!IsGood(l)) return false;
      }
      if (l == Label::kGoal) return true;
    }
    if (any_free) return true;
    break;  // blocked on both sides: contact rules below
  }
  // The sector containing w: bounded by the nearest ray clockwise of w and the nearest counter-clockwise (exact; no
  // ray runs along w here, except one blocked on both sides, which bounds no free sector).
  Label sector = below;
  {
    const LRay* cw_ray = nullptr;   // first ray turning clockwise from w
    const LRay* ccw_ray = nullptr;  // last ray turning clockwise from w (first counter-clockwise)
    for (const LRay& r : rays) {
      if (ClockwiseHalf(w, r.edir) == 3) continue;
      if (!cw_ray || ClockwiseBefore(w, r.edir, cw_ray->edir)) cw_ray = &r;
      if (!ccw_ray || ClockwiseBefore(w, ccw_ray->edir, r.edir)) ccw_ray = &r;
    }
    if (cw_ray && !cw_ray->upper) {
      sector = cw_ray->ccw;
    } else if (ccw_ray && !ccw_ray->upper) {
      sector = ccw_ray->cw;
    } else if (cw_ray) {
      sector = cw_ray->ccw;  // no lower ray: a static upper label (the region below p)
      if (IsFree(sector)) sector = below;
    }
  }
  if (IsGood(sector)) return true;
  if (sector == Label::kBad || sector == Label::kOutside) return false;
  // Pushing into CB: contact rules (docs/semantics.md vertex rule). The edge with the larger tangential component wins;
  // where two tie (w on the bisector of their directions, one of the critical directions sampled below) either may be
  // taken, so both must lead somewhere good (decided with a tolerance: rounding must not pick one side at random).
  constexpr double kTie = 1e-12;
  std::vector<std::pair<double, const LRay*>> pushed;
  for (const LRay& r : rays) {
    if (r.kind != EdgeKind::kObstacle && !r.obstacle_face) continue;
    if (!(wd.dot(r.n_free) < -1e-14)) continue;
    if (MotionModel::Sticks(wd, r.n_free, phi_)) continue;
    const double comp = wd.dot(r.dir);
    if (comp <= 1e-14) continue;
    pushed.push_back({comp, &r});
  }
  if (pushed.empty()) return false;  // stops
  double best_comp = 0.0;
  for (const auto& [comp, r] : pushed) best_comp = std::max(best_comp, comp);
  for (const auto& [comp, best] : pushed) {
    if (comp < best_comp - kTie) continue;
    // Sliding along a C-obstacle edge on the bounds' line runs along the bounds: counted as failing (conservative;
    // found on random scenes with the goal on CB, VISCO_SEED_OFFSET=5340517, seed 33 of the soundness test).
    if (best->upper || best->sticking || best->obstacle_face) return false;
    bool good = false;
    for (Label l : {best->ccw, best->cw}) {
      if (l == Label::kGoal) {
        good = true;
        break;
      }
      if (IsFree(l)) {
        good = IsGood(l);
        break;
      }
    }
    if (!good) return false;
  }
  return true;
}

// p is good iff OutcomeAt holds for every direction of the cone. OutcomeAt is constant between consecutive
// critical directions, so the cone's extremes, the critical directions inside it and one direction strictly between
// each consecutive pair are enough (docs/planning_backprojection.md, "Why sampled directions are enough"). Critical:
//   * the direction of every ray at p (moving along an edge or a ray, and the sector boundaries),
//   * the friction-cone boundaries of every obstacle edge at p (sticking starts or stops),
//   * the directions perpendicular to an edge (pushing starts or stops) and the bisectors of every pair of edges at p
//     (where the vertex rule's larger tangential component switches from one edge to the other).
Label Sweep::StatusAtPoint(const std::vector<LRay>& rays, Label below) const {
  for (const LRay& r : rays) {
    if (r.kind == EdgeKind::kGoal || r.ccw == Label::kGoal || r.cw == Label::kGoal) return Label::kGood;
  }
  if (below == Label::kGoal) return Label::kGood;
  // The open lower end of an active ray: whoever gets here is complying down the ray, past its end (out of the
  // bounds, or onto the camera), whatever the adversary does.
  if (open_lower_ends_.count(current_) != 0) return Label::kBad;
  std::vector<V2> crit = {cone_cw_, cone_ccw_};
  auto in_cone = [&](const V2& d) {
    return CGAL::orientation(cone_cw_, d) == CGAL::LEFT_TURN && CGAL::orientation(d, cone_ccw_) == CGAL::LEFT_TURN;
  };
  auto add = [&](const Vector2d& d) {
    const V2 e(d.x(), d.y());
    if (in_cone(e)) crit.push_back(e);
  };
  const double cphi = std::cos(phi_), sphi = std::sin(phi_);
  for (const LRay& r : rays) {
    if (in_cone(r.edir)) crit.push_back(r.edir);
    if (r.kind != EdgeKind::kObstacle && !r.obstacle_face) continue;
    const Vector2d in = -r.n_free;
    add({cphi * in.x() - sphi * in.y(), sphi * in.x() + cphi * in.y()});  // friction-cone boundaries
    add({cphi * in.x() + sphi * in.y(), -sphi * in.x() + cphi * in.y()});
    // Along the edge's line (pushing starts or stops), exactly: a rounded tangent could fall a hair inside CB, where
    // it neither pushes (the tolerance below) nor moves freely, and would be taken for a stop.
    if (in_cone(-r.edir)) crit.push_back(-r.edir);
    for (const LRay& q : rays) {
      if (&q == &r || (q.kind != EdgeKind::kObstacle && !q.obstacle_face)) continue;
      const Vector2d diff = r.dir - q.dir;  // w · r.dir = w · q.dir on the perpendicular of the difference
      add({-diff.y(), diff.x()});
      add({diff.y(), -diff.x()});
    }
  }
  // Counter-clockwise order inside the cone (less than a half turn wide: orientation is a strict weak order).
  std::sort(crit.begin(), crit.end(),
            [](const V2& a, const V2& b) { return CGAL::orientation(a, b) == CGAL::LEFT_TURN; });
  crit.erase(std::unique(crit.begin(), crit.end(),
                         [](const V2& a, const V2& b) { return CGAL::orientation(a, b) == CGAL::COLLINEAR; }),
             crit.end());
  const size_t n = crit.size();
  for (size_t i = 0; i + 1 < n; ++i) {
    // A positive combination lies strictly between the two (exact), whatever the rounding of the weights.
    const V2& a = crit[i];
    const V2& b = crit[i + 1];
    crit.push_back(a * FT(std::sqrt(CGAL::to_double(b.squared_length()))) +
                   b * FT(std::sqrt(CGAL::to_double(a.squared_length()))));
  }
  for (const V2& w : crit) {
    if (!OutcomeAt(w, rays, below)) return Label::kBad;
  }
  return Label::kGood;
}

// The servo runs the robot up to δ beside an active ray's line, so complying down to the ray's lower end p on CB
// meets CB anywhere on the two C-obstacle edges that bound the free wedge around the ray at p (the first obstacle ray
// turning clockwise from the ray's direction, and the first counter-clockwise), up to L = δ / sin(angle to the ray)
// from p; from there it moves with the commanded cone under the contact rules (compliance has ended). Good when, on
// both sides:
//   * nothing else lies in the wedge that the offset motion would cross first (the bounds, a forbidden region,
//     another active ray) and the continuation of the ray beyond p points into CB;
//   * a lower edge (below p in the sweep frame): the free sector beside it is good (a motion that meets the edge
//     there behaves as one arriving from that sector: sticking or sliding on to somewhere bad makes it bad), and the
//     edge piece reaches at least L below p (its label is the same along the piece);
//   * an upper edge: every direction of the cone pushes into it and slides down it towards p without sticking (both
//     extremes decide: the good directions form one arc), and the edge runs on for at least L; p's own status covers
//     the rest.
bool Sweep::LandingIsGood(const StaticCurve& ray, const std::vector<LRay>& rays,
                          const std::vector<StaticCurve>& uppers) const {
  const double delta = problem_.ray_tracking_error;
  const V2 up = ray.hi - ray.lo;
  const Vector2d upd = ToD(up).normalized();
  // Rays at p other than along `up`, in clockwise order from it.
  std::vector<const LRay*> order;
  for (const LRay& r : rays) {
    if (ClockwiseHalf(up, r.edir) == 3) continue;  // the ray itself (and anything running along it)
    order.push_back(&r);
  }
  std::sort(order.begin(), order.end(),
            [&](const LRay* a, const LRay* b) { return ClockwiseBefore(up, a->edir, b->edir); });
  auto side_ok = [&](bool clockwise) {
    const size_t n = order.size();
    for (size_t i = 0; i < n; ++i) {
      const LRay& r = *order[clockwise ? i : n - 1 - i];
      const int half = ClockwiseHalf(up, r.edir);
      if (half == 1 || (clockwise ? half != 0 : half != 2)) return false;  // the continuation is free
      if (r.kind == EdgeKind::kGoal || r.kind == EdgeKind::kFree) continue;
      if (r.kind != EdgeKind::kObstacle) return false;  // bounds, forbidden or another active ray in the way
      const double sin_angle = std::abs(upd.x() * r.dir.y() - upd.y() * r.dir.x());
      if (!(sin_angle > 1e-9)) return false;
      const double reach = delta / sin_angle;
      const Label beside = clockwise ? r.ccw : r.cw;  // the wedge's side of the edge
      if (!r.upper) {
        if (!IsGood(beside)) return false;
        return ToD(r.curve->lo - r.curve->hi).norm() >= reach;
      }
      const StaticCurve& u = uppers[r.upper_index];
      if (u.sticking || ToD(u.hi - u.lo).norm() < reach) return false;
      for (const V2& w : {cone_cw_, cone_ccw_}) {
        const Vector2d wd = ToD(w).normalized();
        if (!(wd.dot(u.n_free) < -1e-14) || MotionModel::Sticks(wd, u.n_free, phi_) || !(wd.dot(r.dir) < -1e-14))
          return false;
      }
      return true;
    }
    return false;  // no C-obstacle edge on this side
  };
  return side_ok(true) && side_ok(false);
}

void Sweep::Process(const P2& p, const std::vector<StaticCurve>& static_uppers) {
  current_ = p;
  auto [first, last] = status_.equal_range(Probe{});
  std::vector<Curve*> through(first, last);
  if (through.empty() && static_uppers.empty()) return;
  if (static_uppers.empty()) {
    int ending = 0;
    for (const Curve* c : through) ending += Same(c->hi, p);
    if (ending == 0 && through.size() < 2) return;  // a stale intersection event
  }
  Curve* left_neighbour = first == status_.begin() ? nullptr : *std::prev(first);
  Curve* right_neighbour = last == status_.end() ? nullptr : *last;
  const Label l_left = left_neighbour ? left_neighbour->right : Label::kOutside;
  const Label l_right = through.empty() ? l_left : through.back()->right;

  // Upper static rays: new ones and continuations of static curves passing through p.
  std::vector<StaticCurve> uppers = static_uppers;
  for (const Curve* c : through) {
    if (Same(c->hi, p) || c->kind == EdgeKind::kFree) continue;
    const Label sl = IsFree(c->left) ? Label::kGood : c->left;
    const Label sr = IsFree(c->right) ? Label::kGood : c->right;
    uppers.push_back({p, c->hi, c->kind, c->src, sl, sr, c->n_free, c->sticking});
  }
  // Left to right: counter-clockwise directions first.
  std::sort(uppers.begin(), uppers.end(), [](const StaticCurve& a, const StaticCurve& b) {
    return CGAL::orientation(b.hi - b.lo, a.hi - a.lo) == CGAL::LEFT_TURN;
  });

  // Rays in counter-clockwise order from angle 0: upper rays right to left, then lower rays left to right.
  std::vector<LRay> rays;
  for (size_t i = uppers.size(); i-- > 0;) {
    LRay r;
    r.upper = true;
    r.upper_index = static_cast<int>(i);
    r.edir = uppers[i].hi - p;
    r.dir = ToD(r.edir).normalized();
    r.kind = uppers[i].kind;
    r.ccw = uppers[i].left;
    r.cw = uppers[i].right;
    r.sticking = uppers[i].sticking;
    r.obstacle_face = uppers[i].obstacle_face;
    r.n_free = uppers[i].n_free;
    rays.push_back(r);
  }
  for (const Curve* c : through) {
    LRay r;
    r.curve = c;
    r.edir = c->lo - p;
    r.dir = ToD(r.edir).normalized();
    r.kind = c->kind;
    r.ccw = c->right;
    r.cw = c->left;
    r.track = c->track;
    r.sticking = c->sticking;
    r.obstacle_face = c->obstacle_face;
    r.n_free = c->n_free;
    rays.push_back(r);
  }
  const Label below = l_left;
  const auto closed_end = closed_lower_ends_.find(p);
  bool status_p_known = false;
  Label status_p = Label::kBad;
  auto point_status = [&]() {
    if (!status_p_known) {
      status_p = StatusAtPoint(rays, below);
      status_p_known = true;
    }
    return status_p;
  };

  // Upper sectors S_0 .. S_k and their zones.
  const size_t k = uppers.size();
  struct NewCurve {
    bool is_static;
    size_t index;  // into uppers
    V2 dir;        // free curves
    Label left, right;
    bool right_free;  // free curve at 90° - ε
  };
  std::vector<std::vector<NewCurve>> per_sector(k + 1);
  std::vector<Label> sector_low(k + 1), sector_high(k + 1);
  // Where complying down the upper ray `u` from p leads: p's status, unless u ends here on CB and the servo's tracking
  // error can make the motion meet CB beside p somewhere bad. u ends on CB at its registered lower end, or where the
  // overlay stops it at a C-obstacle edge: a rounded end a few ulps inside CB leaves the piece beyond the edge in CB,
  // and the overlay drops it, so the ray really ends where it enters CB.
  auto ray_status = [&](const StaticCurve& u) -> Label {
    if (failing_parts_.count(u.src) != 0) return Label::kBad;
    const Label at_p = point_status();
    if (!IsGood(at_p) || !(problem_.ray_tracking_error > 0.0)) return at_p;
    const bool registered =
        closed_end != closed_lower_ends_.end() &&
        std::find(closed_end->second.begin(), closed_end->second.end(), u.src) != closed_end->second.end();
    const bool continues = std::any_of(rays.begin(), rays.end(), [&](const LRay& r) {
      return !r.upper && r.kind == EdgeKind::kVc && r.curve->src == u.src;
    });
    const bool on_cb =
        std::any_of(rays.begin(), rays.end(), [](const LRay& r) { return r.kind == EdgeKind::kObstacle; });
    if (!registered && (continues || !on_cb)) return at_p;
    return LandingIsGood(u, rays, uppers) ? at_p : Label::kBad;
  };
  auto side_status = [&](int upper_index, Label lower) -> bool {
    if (upper_index < 0) return IsGood(lower);
    const StaticCurve& u = uppers[upper_index];
    switch (u.kind) {
      case EdgeKind::kGoal:
        return true;
      case EdgeKind::kBounds:
        return false;
      case EdgeKind::kObstacle:
        return !u.sticking && IsGood(point_status());
      case EdgeKind::kVc:
        return IsGood(ray_status(u));
      case EdgeKind::kFree:
        return false;
    }
    return false;
  };
  for (size_t i = 0; i <= k; ++i) {
    const int ccw_upper = i == 0 ? -1 : static_cast<int>(i) - 1;
    const int cw_upper = i == k ? -1 : static_cast<int>(i);
    Label stat;
    if (i == 0) {
      stat = k > 0 ? uppers[0].left : (IsFree(l_left) ? Label::kGood : l_left);
    } else {
      stat = uppers[i - 1].right;
    }
    if (!IsFree(stat)) {
      sector_low[i] = sector_high[i] = stat;
      continue;
    }
    const bool cw_good = side_status(cw_upper, l_right);
    const bool ccw_good = side_status(ccw_upper, l_left);
    const Label zr = Status(cw_good);
    const Label zl = Status(ccw_good);
    Label zm = Label::kBad;
    if (cw_good && ccw_good) zm = point_status();
    // Position of the free directions relative to the sector's bounding rays.
    auto strictly_inside = [&](const V2& f) {
      if (cw_upper >= 0 && CGAL::orientation(uppers[cw_upper].hi - p, f) != CGAL::LEFT_TURN) return false;
      if (ccw_upper >= 0 && CGAL::orientation(f, uppers[ccw_upper].hi - p) != CGAL::LEFT_TURN) return false;
      return true;
    };
    // Label just counter-clockwise of the clockwise ray, and just clockwise of the counter-clockwise ray.
    if (cw_upper < 0) {
      sector_low[i] = zr;
    } else {
      const V2 d = uppers[cw_upper].hi - p;
      if (CGAL::orientation(d, free_right_) == CGAL::LEFT_TURN) {
        sector_low[i] = zr;
      } else if (CGAL::orientation(d, free_left_) == CGAL::LEFT_TURN) {
        sector_low[i] = zm;
      } else {
        sector_low[i] = zl;
      }
    }
    if (ccw_upper < 0) {
      sector_high[i] = zl;
    } else {
      const V2 d = uppers[ccw_upper].hi - p;
      if (CGAL::orientation(free_left_, d) == CGAL::LEFT_TURN) {
        sector_high[i] = zl;
      } else if (CGAL::orientation(free_right_, d) == CGAL::LEFT_TURN) {
        sector_high[i] = zm;
      } else {
        sector_high[i] = zr;
      }
    }
    // Free edges inside this sector, left to right (90° + ε first).
    if (strictly_inside(free_left_) && zm != zl) per_sector[i].push_back({false, 0, free_left_, zl, zm, false});
    if (strictly_inside(free_right_) && zr != zm) per_sector[i].push_back({false, 0, free_right_, zm, zr, true});
  }
  std::vector<NewCurve> out;
  for (size_t i = 0; i <= k; ++i) {
    for (const NewCurve& c : per_sector[i]) out.push_back(c);
    if (i < k) out.push_back({true, i, V2(), sector_low[i], sector_high[i + 1], false});
  }

  // Output pieces of the curves ending (or split) at p, then replace them.
  for (Curve* c : through) {
    if (IsGood(c->left) != IsGood(c->right)) {
      if (IsGood(c->left)) {
        pieces_.push_back({c->lo, p, c->kind, c->name});
      } else {
        pieces_.push_back({p, c->lo, c->kind, c->name});
      }
    }
  }
  status_.erase(first, last);

  std::vector<Curve*> inserted;
  int point_name = -1;
  for (const NewCurve& nc : out) {
    auto c = std::make_unique<Curve>();
    c->id = static_cast<int>(curves_.size());
    c->lo = p;
    c->left = nc.left;
    c->right = nc.right;
    if (nc.is_static) {
      const StaticCurve& u = uppers[nc.index];
      c->hi = u.hi;
      c->kind = u.kind;
      c->src = u.src;
      c->name = sources_[u.src].name;
      c->sticking = u.sticking;
      c->obstacle_face = u.obstacle_face;
      c->n_free = u.n_free;
      if (u.kind == EdgeKind::kVc) {
        c->track = ray_status(u);
        // Blame the ray only where its failure starts: below p no active ray arrives (a bad track inherited from a
        // crossing ray is that ray's fault, and that ray is blamed at its own start).
        const bool inherited =
            std::any_of(rays.begin(), rays.end(), [](const LRay& r) { return !r.upper && r.kind == EdgeKind::kVc; });
        if (!IsGood(c->track) && !inherited) bad_track_rays_.insert(sources_[u.src].ray);
      }
      // Static labels of non-free sides stay as they are.
      if (!IsFree(u.left)) c->left = u.left;
      if (!IsFree(u.right)) c->right = u.right;
    } else {
      c->kind = EdgeKind::kFree;
      c->hi = p + nc.dir * ((top_ - p.y()) / nc.dir.y());
      // Keep the ref of a free edge that continues through p.
      int name = -1;
      for (const Curve* t : through) {
        if (t->kind == EdgeKind::kFree && CGAL::orientation(t->dir, nc.dir) == CGAL::COLLINEAR &&
            CGAL::sign(t->dir * nc.dir) == CGAL::POSITIVE) {
          name = t->name;
        }
      }
      if (name < 0) {
        if (point_name < 0) point_name = VertexName(p, through);
        name = AddName(names_[point_name] + (nc.right_free ? "/-eps" : "/+eps"));
        free_sources_.emplace(name, FreeSource{p, static_cast<std::int8_t>(nc.right_free ? -1 : 1)});
      }
      c->name = name;
    }
    c->dir = c->hi - c->lo;
    Curve* raw = c.get();
    curves_.push_back(std::move(c));
    status_.insert(raw);
    inserted.push_back(raw);
  }
  if (inserted.empty()) {
    CheckIntersection(left_neighbour, right_neighbour, p);
  } else {
    CheckIntersection(left_neighbour, inserted.front(), p);
    CheckIntersection(inserted.back(), right_neighbour, p);
  }
}

}  // namespace visco::planning::internal
