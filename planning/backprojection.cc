// Directional backprojections by a plane sweep against the commanded velocity (Donald–Canny, Fox & Hutchinson
// §IV-C and §V), in exact arithmetic.
//
// Frame: the input is mapped exactly by a similarity (a rotation with rounded cosine and sine, applied in exact
// arithmetic, so collinear edges stay collinear) so that the commanded velocity points straight down (−y); the sweep
// goes up, events in (y, x) lexicographic order. The static geometry (C-obstacle, goal and bounds edges, active CVC ray
// segments) is overlaid first with CGAL's arrangement (which merges overlapping C-obstacles and splits crossing edges);
// every face gets a static label (outside the bounds, inside CB, goal, free). The sweep then refines free regions into
// good (in the backprojection) and bad, erecting free edges (rays of the inverted velocity cone) where the local
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

#include "planning/backprojection.h"

#include <CGAL/Arr_consolidated_curve_data_traits_2.h>
#include <CGAL/Arr_extended_dcel.h>
#include <CGAL/Arr_segment_traits_2.h>
#include <CGAL/Arrangement_2.h>
#include <CGAL/Boolean_set_operations_2.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Polygon_set_2.h>
#include <CGAL/Polygon_with_holes_2.h>
#include <CGAL/convex_hull_2.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <queue>
#include <set>
#include <stdexcept>
#include <unordered_map>
#include <utility>

#include "common/motion_model.h"
#include "planning/geometry.h"

namespace visco::planning {
namespace {

using K = CGAL::Exact_predicates_exact_constructions_kernel;
using FT = K::FT;
using P2 = K::Point_2;
using V2 = K::Vector_2;
using Seg = K::Segment_2;
using SegTraits = CGAL::Arr_segment_traits_2<K>;
using Traits = CGAL::Arr_consolidated_curve_data_traits_2<SegTraits, int>;
using Dcel = CGAL::Arr_face_extended_dcel<Traits, int>;
using Arr = CGAL::Arrangement_2<Traits, Dcel>;
using ExactPolygon = CGAL::Polygon_2<K>;
using ExactPolygonWithHoles = CGAL::Polygon_with_holes_2<K>;
using PolygonSet = CGAL::Polygon_set_2<K>;

using Eigen::Vector2d;

// Region labels. Static labels use kOutside, kObstacle, kGoal and kGood (meaning "free", refined by the sweep).
enum class Label : std::uint8_t { kOutside, kObstacle, kGoal, kGood, kBad };
bool IsGood(Label l) { return l == Label::kGoal || l == Label::kGood; }
bool IsFree(Label l) { return l == Label::kGood || l == Label::kBad; }
Label Status(bool good) { return good ? Label::kGood : Label::kBad; }

// Point equality and (y, x) order, decided on the interval approximations when they are apart and otherwise on the
// exact values directly (one shared point, the common case in the sweep, is equal at once). The same answers as
// CGAL's filtered `==` and compare_yx, without their cost on ties: there
// the interval predicate cannot decide and CGAL throws and catches an exception before it computes exactly (12 % of
// `visco plan` went to throwing and unwinding, mostly for points that are equal).
CGAL::Comparison_result CompareApprox(const CGAL::Interval_nt<false>& a, const CGAL::Interval_nt<false>& b) {
  if (a.sup() < b.inf()) return CGAL::SMALLER;
  if (a.inf() > b.sup()) return CGAL::LARGER;
  return CGAL::EQUAL;  // undecided
}
bool Same(const P2& a, const P2& b) {
  if (CGAL::identical(a, b)) return true;
  const auto &ia = a.approx(), &ib = b.approx();
  if (CompareApprox(ia.x(), ib.x()) != CGAL::EQUAL || CompareApprox(ia.y(), ib.y()) != CGAL::EQUAL) return false;
  return a.exact() == b.exact();
}
CGAL::Comparison_result CompareYX(const P2& a, const P2& b) {
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

// An input edge in the sweep frame, directed with its polygon's interior on the left (bounds: the inside).
struct Source {
  P2 a, b;
  EdgeKind kind = EdgeKind::kObstacle;
  int name = -1;
  bool sticking = false;
  Vector2d sweep_normal{0, 0};  // outward unit normal in the sweep frame (obstacles), inward (bounds)
  int ray = -1;                 // active rays: index into BackprojectionProblem::rays
};

struct Rotation {
  using ET = FT::ET;  // the exact rational type behind the lazy kernel
  double c = 1, s = 0;
  ET ec = 1, es = 0, det = 1;  // c, s and c² + s² exactly
  Rotation() = default;
  Rotation(double c_in, double s_in) : c(c_in), s(s_in), ec(c_in), es(s_in), det(ec * ec + es * es) {}
  Vector2d Apply(const Vector2d& p) const { return {c * p.x() - s * p.y(), s * p.x() + c * p.y()}; }
  // The sweep frame is the similarity [[c, -s], [s, c]] applied exactly (not rounded): collinear and touching input
  // edges stay collinear and touching. Computed in plain rationals, so the lazy point carries its exact value from
  // the start (no construction DAG for each predicate that the interval filter cannot decide to re-evaluate).
  P2 ApplyExact(const Vector2d& p) const {
    const ET x(p.x()), y(p.y());
    return P2(FT(ET(ec * x - es * y)), FT(ET(es * x + ec * y)));
  }
  // The exact inverse, converted to double once (CGAL::to_double of the exact value).
  Vector2d InvertExact(const P2& p) const {
    const FT px = p.x(), py = p.y();  // kept alive: exact() refers into them
    const ET& x = CGAL::exact(px);
    const ET& y = CGAL::exact(py);
    return {CGAL::to_double(ET((ec * x + es * y) / det)), CGAL::to_double(ET((ec * y - es * x) / det))};
  }
  FT Scale2() const { return FT(det); }  // the similarity's area factor
};

// The sweep frame of one θ, shared by every sweep at that θ (the ray choice runs up to 3k + 1 of them): each world
// point is mapped once, so equal world points are one exact point in every sweep and their comparisons, which the
// interval filter cannot decide, reuse one exact value instead of rebuilding it.
class SweepFrame {
 public:
  explicit SweepFrame(double theta) : rot_(std::cos(-M_PI / 2 - theta), std::sin(-M_PI / 2 - theta)) {}
  const Rotation& rotation() const { return rot_; }
  const P2& Map(const Vector2d& w) {
    auto [it, inserted] = points_.try_emplace({w.x(), w.y()});
    if (inserted) it->second = rot_.ApplyExact(w);
    return it->second;
  }

 private:
  Rotation rot_;
  std::map<std::pair<double, double>, P2> points_;
};

// Where direction d lies going clockwise from reference r, as a key ordered like the clockwise angle in (0, 2π]:
// 0 strictly clockwise of r within a half turn, 1 opposite to r, 2 the other half turn, 3 along r (a full turn).
int ClockwiseHalf(const V2& r, const V2& d) {
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
bool ClockwiseBefore(const V2& r, const V2& d1, const V2& d2) {
  const int h1 = ClockwiseHalf(r, d1), h2 = ClockwiseHalf(r, d2);
  if (h1 != h2) return h1 < h2;
  if (h1 == 1 || h1 == 3) return false;  // the same direction
  return CGAL::orientation(d1, d2) == CGAL::RIGHT_TURN;
}

Vector2d ToD(const V2& v) { return {CGAL::to_double(v.x()), CGAL::to_double(v.y())}; }

double SignedAreaD(const std::vector<Vector2d>& poly) {
  double a = 0.0;
  for (size_t i = 0; i < poly.size(); ++i) {
    const Vector2d& p = poly[i];
    const Vector2d& q = poly[(i + 1) % poly.size()];
    a += p.x() * q.y() - p.y() * q.x();
  }
  return 0.5 * a;
}

// A curve on the sweep line.
struct Curve {
  P2 lo, hi;
  V2 dir;  // hi - lo
  EdgeKind kind = EdgeKind::kFree;
  int src = -1;   // source index (static curves)
  int name = -1;  // ref index
  Label left = Label::kBad, right = Label::kBad;
  Label track = Label::kBad;  // active rays: where complying down the ray leads
  bool sticking = false;
  bool obstacle_face = false;  // bounds: a C-obstacle edge on the bounds' line (n_free: out of the C-obstacle)
  Vector2d n_free{0, 0};       // obstacle/bounds: unit normal into the free side (sweep frame)
  int id = 0;
};

// A static curve waiting for its lower endpoint's event.
struct StaticCurve {
  P2 lo, hi;
  EdgeKind kind;
  int src;
  Label left, right;  // static labels
  Vector2d n_free;
  bool sticking;
  bool obstacle_face = false;  // as Curve::obstacle_face
};

struct Piece {
  P2 a, b;
  EdgeKind kind;
  int name;
};

// The result of one sweep in the sweep frame: rings (outer counter-clockwise, holes clockwise) with provenance.
struct ExactRing {
  std::vector<P2> vertices;
  std::vector<std::pair<EdgeKind, int>> edges;
  FT area2;  // twice the signed area
};

class Sweep {
 public:
  Sweep(const BackprojectionProblem& problem, const std::vector<int>& active_rays, SweepFrame& frame);
  void Run();
  std::vector<ExactRing> Assemble() const;
  Region ToRegion(const std::vector<ExactRing>& rings) const;
  std::vector<RegionEdge> StaticEdges() const;
  // A static source's segment in the world frame (RegionEdge::line).
  std::array<Vector2d, 2> WorldLine(const Source& src) const {
    return {rot_.InvertExact(src.a) + Vector2d::Zero(), rot_.InvertExact(src.b) + Vector2d::Zero()};
  }
  // Active rays (indices into the problem's rays) with a piece whose track is bad: complying down from there fails.
  const std::set<int>& bad_track_rays() const { return bad_track_rays_; }

 private:
  struct Probe {};
  struct StatusLess {
    using is_transparent = void;
    const P2* p = nullptr;
    int Side(const Curve* c) const {  // -1: the curve passes left of p, 0: through p, +1: right of p
      switch (CGAL::orientation(c->lo, c->hi, *p)) {
        case CGAL::RIGHT_TURN:
          return -1;
        case CGAL::LEFT_TURN:
          return 1;
        default:
          return 0;
      }
    }
    bool operator()(const Curve* a, const Curve* b) const {
      const bool as = Same(a->lo, *p);
      const bool bs = Same(b->lo, *p);
      if (as && bs) {
        const auto o = CGAL::orientation(b->dir, a->dir);
        if (o != CGAL::COLLINEAR) return o == CGAL::LEFT_TURN;  // a counter-clockwise of b: a is left
        return a->id < b->id;
      }
      if (bs) return Side(a) < 0;
      if (as) return Side(b) > 0;
      return a->id < b->id;  // not reached: the set only compares a new curve with existing ones
    }
    bool operator()(const Curve* a, Probe) const { return Side(a) < 0; }
    bool operator()(Probe, const Curve* a) const { return Side(a) > 0; }
  };

  struct LRay {
    const Curve* curve = nullptr;  // lower rays
    int upper_index = -1;          // upper rays: index into the upper list
    bool upper = false;
    V2 edir;  // exact direction from p
    EdgeKind kind = EdgeKind::kFree;
    Label ccw = Label::kBad, cw = Label::kBad;  // labels of the sectors on either side (upper: static)
    Label track = Label::kBad;
    bool sticking = false;
    bool obstacle_face = false;
    Vector2d n_free{0, 0};
    Vector2d dir{0, 0};
  };

  void Process(const P2& p, const std::vector<StaticCurve>& uppers);
  Label StatusAtPoint(const std::vector<LRay>& rays, Label below) const;
  bool LandingIsGood(const StaticCurve& ray, const std::vector<LRay>& rays,
                     const std::vector<StaticCurve>& uppers) const;
  bool OutcomeAt(const V2& w, const std::vector<LRay>& rays, Label below) const;
  void CheckIntersection(const Curve* a, const Curve* b, const P2& p);
  int VertexName(const P2& p, const std::vector<Curve*>& through);
  bool ClipToBounds(P2 (&ends)[2], bool (&open)[2]) const;
  bool RunsAlongCB(const P2& lower, const P2& upper, SweepFrame& frame) const;
  int AddName(std::string name);

  const BackprojectionProblem& problem_;
  const Rotation& rot_;  // the frame's (it outlives the sweep)
  double eps_ = 0, phi_ = 0;
  V2 free_right_, free_left_;  // directions 90° − ε and 90° + ε
  V2 cone_cw_, cone_ccw_;  // the velocity cone's extremes −90° − ε and −90° + ε (= −free_right_, −free_left_)
  FT top_;
  std::vector<Source> sources_;
  std::vector<std::string> names_;
  struct FreeSource {
    P2 point;          // the point it is erected at (RegionEdge::source)
    std::int8_t sign;  // RegionEdge::sign
  };
  std::map<int, FreeSource> free_sources_;  // by the free edge's name
  std::map<P2, int, LessYX> vertex_names_;
  P2 bounds_sweep_[4];                    // the bounds' corners in the sweep frame, counter-clockwise
  std::set<P2, LessYX> open_lower_ends_;  // lower ends of active ray segments that fail when complied to
  std::set<int> failing_parts_;           // ray parts (sources) beside CB within δ: complying along them fails
  // Lower ends on CB of active ray segments (sources_ indices), when the tracking error is positive: complying to the
  // end is good only if meeting CB beside it is (LandingIsGood).
  std::map<P2, std::vector<int>, LessYX> closed_lower_ends_;
  std::set<int> bad_track_rays_;
  std::vector<std::pair<P2, std::vector<StaticCurve>>> static_events_;
  std::priority_queue<P2, std::vector<P2>, std::function<bool(const P2&, const P2&)>> dynamic_{
      [](const P2& a, const P2& b) { return CompareYX(a, b) == CGAL::LARGER; }};
  StatusLess less_;
  std::set<Curve*, StatusLess> status_{less_};
  std::vector<std::unique_ptr<Curve>> curves_;
  std::vector<Piece> pieces_;
  P2 current_;
};

// The points of segment [a, b] within δ of the line through `up` and `down` form one piece (the distance is affine
// along the segment): false if there are none, else the piece's ends as parameters along the line (0 at up, 1 at
// down), in any order.
bool PieceWithinTrackingError(const Vector2d& a, const Vector2d& b, const Vector2d& up, const Vector2d& down,
                              double delta, double& t0, double& t1) {
  const Vector2d d = down - up;
  const Vector2d n = Vector2d(-d.y(), d.x()).normalized();
  // Signed distance from the line: da + s (db − da) for s in [0, 1]; keep |·| <= δ.
  const double da = (a - up).dot(n), db = (b - up).dot(n);
  double s0 = 0.0, s1 = 1.0;
  if (da != db) {
    const double lo = (-delta - da) / (db - da), hi = (delta - da) / (db - da);
    s0 = std::max(s0, std::min(lo, hi));
    s1 = std::min(s1, std::max(lo, hi));
  } else if (std::abs(da) > delta) {
    return false;
  }
  if (s0 > s1) return false;
  t0 = (a + s0 * (b - a) - up).dot(d) / d.squaredNorm();
  t1 = (a + s1 * (b - a) - up).dot(d) / d.squaredNorm();
  return true;
}

// Where along the ray from `up` to `down` (0 at up, 1 at down) the C-obstacles (their edges that neither end lies on,
// within `snap`), the bounds and the forbidden regions come within the tracking error δ of its line beside the ray:
// each edge's points within δ of the line form one piece of it (PieceWithinTrackingError); returns the parameters in
// (0, 1) where such pieces begin and end, ascending, and sets `to_the_end` where one runs on to the lower end or past
// it; `pieces` gets each piece's parameter range.
std::vector<double> PointsWithinTrackingError(const BackprojectionProblem& pr, const Vector2d& up, const Vector2d& down,
                                              double snap, bool& to_the_end,
                                              std::vector<std::pair<double, double>>& pieces) {
  const double delta = pr.ray_tracking_error;
  std::vector<double> breaks;
  to_the_end = false;
  auto consider = [&](const Vector2d& a, const Vector2d& b) {
    double t0, t1;
    if (!PieceWithinTrackingError(a, b, up, down, delta, t0, t1)) return;
    if (std::max(t0, t1) <= 0.0 || std::min(t0, t1) >= 1.0) return;  // beside the line beyond the ray's ends
    to_the_end = to_the_end || std::max(t0, t1) >= 1.0;
    pieces.emplace_back(std::min(t0, t1), std::max(t0, t1));
    for (const double t : {t0, t1}) {
      if (t > 0.0 && t < 1.0) breaks.push_back(t);
    }
  };
  for (const auto& poly : pr.obstacles) {
    const size_t nv = poly.vertices.size();
    for (size_t i = 0; i < nv; ++i) {
      const Vector2d& a = poly.vertices[i];
      const Vector2d& b = poly.vertices[(i + 1) % nv];
      if (PointSegmentDistance(up, a, b) <= snap || PointSegmentDistance(down, a, b) <= snap) continue;
      consider(a, b);
    }
  }
  // The bounds and the forbidden regions too, ends or not: the robot beside the line can leave the allowed
  // configurations there (VISCO_SEED_OFFSET=8636742, seed 14 of the goal-on-CB soundness scenes: a ray starting on
  // the bounds, the robot joining it 1 cm inside them with δ = 2.3 cm).
  const Vector2d lo = pr.bounds_min, hi = pr.bounds_max;
  const Vector2d corners[4] = {{lo.x(), lo.y()}, {hi.x(), lo.y()}, {hi.x(), hi.y()}, {lo.x(), hi.y()}};
  for (int k = 0; k < 4; ++k) consider(corners[k], corners[(k + 1) % 4]);
  for (const auto& poly : pr.forbidden) {
    const size_t nv = poly.vertices.size();
    for (size_t i = 0; i < nv; ++i) consider(poly.vertices[i], poly.vertices[(i + 1) % nv]);
  }
  std::sort(breaks.begin(), breaks.end());
  breaks.erase(std::unique(breaks.begin(), breaks.end(), [](double x, double y) { return y - x <= 1e-12; }),
               breaks.end());
  return breaks;
}

// With the servo's tracking error the robot can meet the edges a closed lower end `down` lies on (its landing) up to
// δ / sin(angle) before the end. The sweep checks the landing at the end (LandingIsGood), but where the ray enters
// the goal on the way there it stops at the goal and never looks. True if the part from `up` enters the goal only
// after a landing edge has come within δ of its line: the robot may meet the edge first (seed 29 of the soundness
// test's goal-on-CB scenes, once the simulator met landing edges where the robot joins a ray).
bool GoalAfterTheLanding(const BackprojectionProblem& pr, const Vector2d& up, const Vector2d& down, double snap) {
  const Vector2d d = down - up;
  const double len2 = d.squaredNorm();
  if (!(len2 > 0.0)) return false;
  const double delta = pr.ray_tracking_error;
  double landing = 1.0;  // the ray parameter where a landing edge first comes within δ
  for (const auto& poly : pr.obstacles) {
    const size_t nv = poly.vertices.size();
    for (size_t i = 0; i < nv; ++i) {
      const Vector2d& a = poly.vertices[i];
      const Vector2d& b = poly.vertices[(i + 1) % nv];
      double t0, t1;
      if (PointSegmentDistance(down, a, b) > snap || !PieceWithinTrackingError(a, b, up, down, delta, t0, t1)) continue;
      landing = std::min({landing, t0, t1});
    }
  }
  if (!(landing < 1.0)) return false;
  double goal = 1.0;  // the ray parameter where the part first meets the goal's boundary
  for (const auto& poly : pr.goal) {
    const size_t nv = poly.vertices.size();
    for (size_t i = 0; i < nv; ++i) {
      const Vector2d& a = poly.vertices[i];
      const Vector2d e = poly.vertices[(i + 1) % nv] - a;
      const double denom = d.x() * e.y() - d.y() * e.x();
      if (denom == 0.0) continue;
      const Vector2d w = a - up;
      const double t = (w.x() * e.y() - w.y() * e.x()) / denom, u = (w.x() * d.y() - w.y() * d.x()) / denom;
      if (t >= 0.0 && t < goal && u >= 0.0 && u <= 1.0) goal = t;
    }
  }
  return goal < 1.0 && goal > landing;
}

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

int Sweep::AddName(std::string name) {
  names_.push_back(std::move(name));
  return static_cast<int>(names_.size()) - 1;
}

Sweep::Sweep(const BackprojectionProblem& pr, const std::vector<int>& active_rays, SweepFrame& frame)
    : problem_(pr), rot_(frame.rotation()) {
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

  // Overlay.
  Arr arr;
  {
    std::vector<Traits::Curve_2> cv;
    cv.reserve(sources_.size());
    for (size_t i = 0; i < sources_.size(); ++i)
      cv.emplace_back(Seg(sources_[i].a, sources_[i].b), static_cast<int>(i));
    CGAL::insert(arr, cv.begin(), cv.end());
  }
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
        const Source& s = sources_[*it];
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

  // Static curves grouped by lower endpoint.
  std::map<P2, std::vector<StaticCurve>, LessYX> events;
  for (auto e = arr.edges_begin(); e != arr.edges_end(); ++e) {
    Arr::Halfedge_handle he = e;
    P2 s = he->source()->point(), t = he->target()->point();
    const bool up = CGAL::compare_yx(s, t) == CGAL::SMALLER;
    const P2 lo = up ? s : t;
    const P2 hi = up ? t : s;
    // The face of a halfedge lies on its left.
    const Label left = label_of(up ? he->face()->data() : he->twin()->face()->data());
    const Label right = label_of(up ? he->twin()->face()->data() : he->face()->data());
    int vc = -1, bounds = -1, goal = -1, obstacle = -1;
    for (auto it = he->curve().data().begin(); it != he->curve().data().end(); ++it) {
      const int i = *it;
      const Source& src = sources_[i];
      if (src.kind == EdgeKind::kVc && (vc < 0 || i < vc)) vc = i;
      if (src.kind == EdgeKind::kBounds && (bounds < 0 || i < bounds)) bounds = i;
      if (src.kind == EdgeKind::kGoal && (goal < 0 || i < goal)) goal = i;
      if (src.kind == EdgeKind::kObstacle) {
        // Prefer the obstacle edge whose interior is the obstacle side.
        const bool same = CGAL::sign((hi - lo) * (src.b - src.a)) == CGAL::POSITIVE;
        const bool interior_left = same;  // the source's interior is on the left of lo->hi
        const Label inside = interior_left ? left : right;
        if (inside == Label::kObstacle && (obstacle < 0 || i < obstacle)) obstacle = i;
        if (obstacle < 0) obstacle = i;
      }
    }
    StaticCurve c{lo, hi, EdgeKind::kObstacle, -1, left, right, Vector2d::Zero(), false};
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
    events[lo].push_back(c);
    events.try_emplace(hi);
  }
  static_events_.assign(events.begin(), events.end());
}

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

int Sweep::VertexName(const P2& p, const std::vector<Curve*>& through) {
  auto it = vertex_names_.find(p);
  if (it != vertex_names_.end()) return it->second;
  std::vector<std::string> parts;
  for (const Curve* c : through) parts.push_back(names_[c->name]);
  // Every static segment through p, whatever the sweep holds there: where segments coincide (a goal strip and the
  // forbidden strip abutting it share an edge) the curves through p depend on θ, and so did the name, a change of
  // structure where nothing changed (found by
  // NondirectionalProperty.StructureIsConstantWithStripGoalsAndForbiddenStrips).
  for (const Source& src : sources_) {
    if (src.name >= 0 && src.kind != EdgeKind::kFree && Seg(src.a, src.b).has_on(p)) parts.push_back(names_[src.name]);
  }
  std::sort(parts.begin(), parts.end());
  parts.erase(std::unique(parts.begin(), parts.end()), parts.end());
  std::string s = "x(";
  for (size_t i = 0; i < parts.size(); ++i) s += (i ? "," : "") + parts[i];
  s += ")";
  const int id = AddName(s);
  vertex_names_.emplace(p, id);
  return id;
}

void Sweep::Run() {
  size_t si = 0;
  const std::vector<StaticCurve> none;
  while (si < static_events_.size() || !dynamic_.empty()) {
    bool from_static;
    if (si >= static_events_.size()) {
      from_static = false;
    } else if (dynamic_.empty()) {
      from_static = true;
    } else {
      from_static = CompareYX(static_events_[si].first, dynamic_.top()) != CGAL::LARGER;
    }
    const P2 p = from_static ? static_events_[si].first : dynamic_.top();
    while (!dynamic_.empty() && Same(dynamic_.top(), p)) dynamic_.pop();
    if (from_static) {
      Process(p, static_events_[si].second);
      ++si;
    } else {
      Process(p, none);
    }
  }
}

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

void Sweep::CheckIntersection(const Curve* a, const Curve* b, const P2& p) {
  if (!a || !b) return;
  if (a->kind != EdgeKind::kFree && b->kind != EdgeKind::kFree) return;
  const auto res = CGAL::intersection(Seg(a->lo, a->hi), Seg(b->lo, b->hi));
  if (!res) return;
  if (const P2* q = boost::get<P2>(&*res)) {
    if (CGAL::compare_yx(*q, p) == CGAL::LARGER) dynamic_.push(*q);
  } else if (const Seg* s = boost::get<Seg>(&*res)) {
    const P2 low = CGAL::compare_yx(s->source(), s->target()) == CGAL::SMALLER ? s->source() : s->target();
    if (CGAL::compare_yx(low, p) == CGAL::LARGER) dynamic_.push(low);
  }
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

std::vector<ExactRing> Sweep::Assemble() const {
  // Pieces are directed with the region on their left. At a vertex, a ring leaves by the first piece clockwise from
  // the reverse of the arriving one (the sharpest left turn), so rings that touch at a vertex stay separate. All
  // decisions are exact; a chain that does not close is an inconsistency of the sweep, never a smaller region.
  std::map<P2, std::vector<int>, LessYX> starts;
  for (size_t i = 0; i < pieces_.size(); ++i) starts[pieces_[i].a].push_back(static_cast<int>(i));
  std::vector<char> used(pieces_.size(), 0);
  std::vector<ExactRing> rings;
  auto fail = [&](const char* what, const P2& at) {
    const Vector2d w = rot_.InvertExact(at);
    throw std::logic_error(std::string("backprojection: ") + what + " at (" + std::to_string(w.x()) + ", " +
                           std::to_string(w.y()) + ") (a bug: please report the scene and θ)");
  };
  for (size_t i0 = 0; i0 < pieces_.size(); ++i0) {
    if (used[i0]) continue;
    std::vector<int> ring;
    int cur = static_cast<int>(i0);
    while (true) {
      used[cur] = 1;
      ring.push_back(cur);
      const Piece& pc = pieces_[cur];
      auto it = starts.find(pc.b);
      if (it == starts.end()) fail("open boundary chain", pc.b);
      const V2 back = pc.a - pc.b;
      int next = -1;
      // The pairing of arriving and leaving pieces is decided among all pieces at the vertex (in and out alternate
      // around it when the labels are consistent), so it is a bijection; meeting a used piece is an inconsistency.
      for (int cand : it->second) {
        const V2 d = pieces_[cand].b - pieces_[cand].a;
        if (next < 0 || ClockwiseBefore(back, d, pieces_[next].b - pieces_[next].a)) next = cand;
      }
      if (next == static_cast<int>(i0)) break;
      if (used[next]) fail("boundary chains meet inconsistently", pc.b);
      cur = next;
    }
    // Merge collinear consecutive pieces with the same provenance.
    ExactRing r;
    for (int idx : ring) {
      const Piece& pc = pieces_[idx];
      if (!r.vertices.empty() && r.edges.back() == std::make_pair(pc.kind, pc.name) &&
          CGAL::orientation(r.vertices.back(), pc.a, pc.b) == CGAL::COLLINEAR) {
        continue;  // extends the previous edge: its start stays
      }
      r.vertices.push_back(pc.a);
      r.edges.emplace_back(pc.kind, pc.name);
    }
    if (r.vertices.size() >= 2 && r.edges.back() == r.edges.front() &&
        CGAL::orientation(r.vertices.back(), r.vertices.front(), r.vertices[1]) == CGAL::COLLINEAR) {
      r.vertices.erase(r.vertices.begin());
      r.edges.erase(r.edges.begin());
    }
    if (r.vertices.size() < 3) continue;
    FT a2 = 0;
    for (size_t i = 0; i < r.vertices.size(); ++i) {
      const P2& p = r.vertices[i];
      const P2& q = r.vertices[(i + 1) % r.vertices.size()];
      a2 += p.x() * q.y() - p.y() * q.x();
    }
    r.area2 = a2;
    if (CGAL::sign(a2) == CGAL::ZERO) continue;
    rings.push_back(std::move(r));
  }
  return rings;
}

// Where p lies relative to a counter-clockwise ring, exactly, by its winding number. The sweep's rings may touch
// themselves at a vertex (weakly simple, where CGAL's Polygon_2::bounded_side requires a simple polygon).
CGAL::Bounded_side RingSide(const std::vector<P2>& ring, const P2& p) {
  int winding = 0;
  for (size_t i = 0; i < ring.size(); ++i) {
    const P2& a = ring[i];
    const P2& b = ring[(i + 1) % ring.size()];
    const CGAL::Orientation o = CGAL::orientation(a, b, p);
    if (o == CGAL::COLLINEAR && CGAL::collinear_are_ordered_along_line(a, p, b)) return CGAL::ON_BOUNDARY;
    const bool a_below = CGAL::compare_y(a, p) != CGAL::LARGER;
    const bool b_below = CGAL::compare_y(b, p) != CGAL::LARGER;
    if (a_below && !b_below && o == CGAL::LEFT_TURN) ++winding;   // upward, p on its left
    if (!a_below && b_below && o == CGAL::RIGHT_TURN) --winding;  // downward, p on its right
  }
  return winding != 0 ? CGAL::ON_BOUNDED_SIDE : CGAL::ON_UNBOUNDED_SIDE;
}

Region Sweep::ToRegion(const std::vector<ExactRing>& rings) const {
  Region region;
  FT total = 0;
  std::vector<const ExactRing*> outers, holes;
  for (const auto& r : rings) {
    total += r.area2;
    (CGAL::sign(r.area2) == CGAL::POSITIVE ? outers : holes).push_back(&r);
  }
  region.area = CGAL::to_double(total / (2 * rot_.Scale2()));
  std::map<int, const Source*> static_lines;  // a static edge's name -> the segment it comes from (RegionEdge::line)
  for (const Source& src : sources_) static_lines.emplace(src.name, &src);
  auto convert = [&](const ExactRing& r) {
    RegionRing out;
    for (size_t i = 0; i < r.vertices.size(); ++i) {
      out.vertices.push_back(rot_.InvertExact(r.vertices[i]) + Vector2d::Zero());  // + 0: no negative zeros
      RegionEdge edge{r.edges[i].first, names_[r.edges[i].second], Vector2d::Zero(), {}};
      if (const auto it = free_sources_.find(r.edges[i].second); it != free_sources_.end()) {
        edge.source = rot_.InvertExact(it->second.point) + Vector2d::Zero();
        edge.sign = it->second.sign;
      } else if (const auto st = static_lines.find(r.edges[i].second); st != static_lines.end()) {
        edge.line = WorldLine(*st->second);
      }
      out.edges.push_back(std::move(edge));
    }
    return out;
  };
  // Deterministic order: outer rings by their lowest-leftmost vertex in the sweep frame.
  auto lowest = [](const ExactRing* r) { return *std::min_element(r->vertices.begin(), r->vertices.end(), LessYX()); };
  std::sort(outers.begin(), outers.end(),
            [&](const ExactRing* a, const ExactRing* b) { return LessYX()(lowest(a), lowest(b)); });
  for (const ExactRing* o : outers) region.polygons.push_back({convert(*o), {}});
  for (const ExactRing* h : holes) {
    // The smallest outer ring that contains the hole. Rings do not cross, so any point of the hole's boundary that
    // is not on an outer ring decides, exactly: the midpoints of its edges are tried in turn.
    int best = -1;
    for (size_t e = 0; e < h->vertices.size() && best < 0; ++e) {
      const P2 mid = CGAL::midpoint(h->vertices[e], h->vertices[(e + 1) % h->vertices.size()]);
      bool on_some_boundary = false;
      for (size_t i = 0; i < outers.size(); ++i) {
        const auto side = RingSide(outers[i]->vertices, mid);
        if (side == CGAL::ON_BOUNDARY) on_some_boundary = true;
        if (side != CGAL::ON_BOUNDED_SIDE) continue;
        if (best < 0 || CGAL::abs(outers[i]->area2) < CGAL::abs(outers[best]->area2)) best = static_cast<int>(i);
      }
      if (on_some_boundary) best = -1;  // try another edge: this midpoint cannot tell touching from inside
    }
    if (best < 0) {
      const Vector2d w = rot_.InvertExact(h->vertices[0]);
      throw std::logic_error("backprojection: a hole at (" + std::to_string(w.x()) + ", " + std::to_string(w.y()) +
                             ") lies in no outer ring (a bug: please report the scene and θ)");
    }
    region.polygons[best].holes.push_back(convert(*h));
  }
  return region;
}

struct SweepResult {
  std::vector<ExactRing> rings;
  Region region;
  std::set<int> bad_track_rays;
};

SweepResult RunSweep(const BackprojectionProblem& problem, const std::vector<int>& active, SweepFrame& frame) {
  Sweep sweep(problem, active, frame);
  sweep.Run();
  SweepResult r;
  r.rings = sweep.Assemble();
  r.region = sweep.ToRegion(r.rings);
  r.bad_track_rays = sweep.bad_track_rays();
  return r;
}

// The simple loops of a ring. A ring may touch itself at a vertex (two parts of the region meeting at a point, or a
// hole touching the outer boundary), which CGAL's polygon sets reject as a precondition (and which a release build
// would take silently and wrongly): the ring is cut at each repeated vertex into loops that are each simple. A loop
// that encloses nothing (an edge walked out and back) is dropped.
std::vector<ExactPolygon> SimpleLoops(const std::vector<P2>& ring) {
  std::vector<ExactPolygon> loops;
  std::vector<P2> path;
  std::map<P2, size_t, K::Less_xy_2> at;  // index in `path` of each vertex on it
  auto close = [&](std::vector<P2>::iterator from) {
    ExactPolygon loop(from, path.end());
    if (loop.size() >= 3 && CGAL::sign(loop.area()) != CGAL::ZERO) {
      loops.push_back(std::move(loop));
    }
  };
  for (const P2& p : ring) {
    auto it = at.find(p);
    if (it == at.end()) {
      at.emplace(p, path.size());
      path.push_back(p);
      continue;
    }
    // p closes the loop from its first visit: cut it off, p stays on the path once.
    const size_t first = it->second;
    close(path.begin() + static_cast<std::ptrdiff_t>(first));
    for (size_t k = first + 1; k < path.size(); ++k) at.erase(path[k]);
    path.resize(first + 1);
  }
  close(path.begin());
  return loops;
}

// The region of `rings` as an exact polygon set: the points inside an odd number of the rings' loops (outer
// boundaries, holes, and islands inside holes alike).
PolygonSet ToPolygonSet(const std::vector<ExactRing>& rings) {
  PolygonSet set;
  for (const auto& r : rings) {
    for (auto& loop : SimpleLoops(r.vertices)) {
      if (loop.is_clockwise_oriented()) loop.reverse_orientation();
      set.symmetric_difference(loop);
    }
  }
  return set;
}

}  // namespace

const char* EdgeKindName(EdgeKind kind) {
  switch (kind) {
    case EdgeKind::kObstacle:
      return "obstacle";
    case EdgeKind::kGoal:
      return "goal";
    case EdgeKind::kFree:
      return "free";
    case EdgeKind::kVc:
      return "vc";
    case EdgeKind::kBounds:
      return "bounds";
  }
  return "?";
}

bool Region::Contains(const Vector2d& p) const {
  for (const auto& poly : polygons) {
    if (!InsideEvenOdd(poly.outer.vertices, p)) continue;
    bool in_hole = false;
    for (const auto& h : poly.holes) in_hole |= InsideEvenOdd(h.vertices, p);
    if (!in_hole) return true;
  }
  return false;
}

double Region::BoundaryDistance(const Vector2d& p) const {
  double best = std::numeric_limits<double>::infinity();
  auto ring_distance = [&](const RegionRing& r) {
    for (size_t i = 0; i < r.vertices.size(); ++i) {
      const Vector2d& a = r.vertices[i];
      const Vector2d& b = r.vertices[(i + 1) % r.vertices.size()];
      const Vector2d ab = b - a;
      const double s = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
      best = std::min(best, (p - (a + s * ab)).norm());
    }
  };
  for (const auto& poly : polygons) {
    ring_distance(poly.outer);
    for (const auto& h : poly.holes) ring_distance(h);
  }
  return best;
}

std::vector<Vector2d> TrackingErrorCuts(const BackprojectionProblem& problem, const Vector2d& a, const Vector2d& b) {
  std::vector<Vector2d> cuts;
  if (!(problem.ray_tracking_error > 0.0) || a == b) return cuts;
  const double snap = 1e-9 * (problem.bounds_max - problem.bounds_min).norm();
  bool to_the_end = false;
  std::vector<std::pair<double, double>> pieces;
  for (const double t : PointsWithinTrackingError(problem, a, b, snap, to_the_end, pieces))
    cuts.push_back(a + t * (b - a));
  return cuts;
}

bool IsReliableRay(const Vector2d& a, const Vector2d& b, double theta, double velocity_cone) {
  const double line = std::atan2(b.y() - a.y(), b.x() - a.x());
  const double delta = std::abs(std::remainder(line - theta, M_PI));  // angle between the line and v*, [0, π/2]
  return delta + velocity_cone < M_PI / 2 - 1e-9;
}

bool IsReliableRay(const CvcRayInput& ray, double theta, double velocity_cone) {
  return !ray.segments.empty() && std::all_of(ray.segments.begin(), ray.segments.end(), [&](const auto& s) {
    return IsReliableRay(s[0], s[1], theta, velocity_cone);
  });
}

Region ClassicBackprojection(const BackprojectionProblem& problem) {
  SweepFrame frame(problem.theta);
  return RunSweep(problem, {}, frame).region;
}

Region BackprojectionWithActiveRays(const BackprojectionProblem& problem, const std::vector<std::string>& active) {
  std::vector<int> idx;
  for (const auto& id : active) {
    auto it = std::find_if(problem.rays.begin(), problem.rays.end(), [&](const CvcRayInput& r) { return r.id == id; });
    if (it == problem.rays.end()) throw std::invalid_argument("backprojection: unknown CVC ray '" + id + "'");
    idx.push_back(static_cast<int>(it - problem.rays.begin()));
  }
  SweepFrame frame(problem.theta);
  return RunSweep(problem, idx, frame).region;
}

std::vector<RegionEdge> Sweep::StaticEdges() const {
  std::vector<RegionEdge> out;
  for (const Source& src : sources_) {
    if (src.kind == EdgeKind::kVc) continue;
    // As ToRegion labels them.
    out.push_back({src.kind, names_[src.name], Vector2d::Zero(), WorldLine(src), 0});
  }
  return out;
}

std::vector<RegionEdge> StaticRegionEdges(const BackprojectionProblem& problem) {
  SweepFrame frame(problem.theta);
  return Sweep(problem, {}, frame).StaticEdges();
}

const char* RaySelectionName(RaySelection selection) {
  switch (selection) {
    case RaySelection::kNone:
      return "none";
    case RaySelection::kExact:
      return "exact";
    case RaySelection::kGreedy:
      return "greedy";
    case RaySelection::kTrack:
      return "track";
  }
  return "?";
}

namespace {

bool LargerArea(const SweepResult& a, const SweepResult& b) {
  return a.region.area > b.region.area * (1 + 1e-12) + 1e-15;
}

// True if the region of `rings` contains `set` (exact polygon difference).
bool ContainsSet(const PolygonSet& set, const std::vector<ExactRing>& rings) {
  PolygonSet diff = set;
  diff.difference(ToPolygonSet(rings));
  return diff.is_empty();
}

// Sweeps `set`; adopts its region as the current one if it is strictly larger and contains the current one (B_θ ⊆
// B_vcθ, and every earlier claim stays valid). True if adopted.
bool AdoptIfLarger(const BackprojectionProblem& problem, SweepFrame& frame, const std::vector<int>& set,
                   SweepResult& current, PolygonSet& current_set, int& sweeps) {
  SweepResult trial = RunSweep(problem, set, frame);
  ++sweeps;
  if (!LargerArea(trial, current) || !ContainsSet(current_set, trial.rings)) return false;
  current = std::move(trial);
  current_set = ToPolygonSet(current.rings);
  return true;
}

// Greedy choice: single candidates in order, then pairs of rejected ones; a set is kept only if its region contains
// the current region and is strictly larger.
std::vector<int> GreedySelection(const BackprojectionProblem& problem, SweepFrame& frame,
                                 const std::vector<int>& candidates, SweepResult& current, int& sweeps) {
  std::vector<int> active;
  PolygonSet current_set = ToPolygonSet(current.rings);
  auto try_add = [&](const std::vector<int>& add) {
    std::vector<int> trial_set = active;
    trial_set.insert(trial_set.end(), add.begin(), add.end());
    if (!AdoptIfLarger(problem, frame, trial_set, current, current_set, sweeps)) return false;
    active = std::move(trial_set);
    return true;
  };
  std::vector<int> rejected;
  for (int c : candidates) {
    if (!try_add({c})) rejected.push_back(c);
  }
  // Some enlargements need two rays together (e.g. a ray and its sibling): try pairs of rejected rays.
  if (rejected.size() <= 12) {
    for (size_t i = 0; i < rejected.size(); ++i) {
      for (size_t j = i + 1; j < rejected.size(); ++j) {
        if (rejected[i] < 0 || rejected[j] < 0) continue;
        if (try_add({rejected[i], rejected[j]})) rejected[i] = rejected[j] = -1;
      }
    }
  }
  return active;
}

// Whether adding ray c to `active` cannot enlarge the region, decided without a sweep: every piece of c complies to
// an open end (the bounds, the camera end, where the camera loses the vertex) and meets neither the goal nor an active
// ray on the way. A trajectory that reaches such a piece, however it reaches it, complies to that end (a reliable ray:
// every velocity in the cone projects onto it the same way) and fails; so with c active every point keeps or loses
// its place in the region, none is added. Conservative: a piece whose box meets a goal's box counts as meeting it.
bool LeadsOnlyToOpenEnds(const BackprojectionProblem& problem, int c, const std::vector<int>& active) {
  const CvcRayInput& ray = problem.rays[c];
  const Vector2d dir(std::cos(problem.theta), std::sin(problem.theta));
  for (size_t k = 0; k < ray.segments.size(); ++k) {
    const auto& s = ray.segments[k];
    const int destination = (s[1] - s[0]).dot(dir) > 0 ? 1 : 0;
    if (k >= ray.open_ends.size() || !ray.open_ends[k][destination]) return false;
    const Vector2d lo = s[0].cwiseMin(s[1]), hi = s[0].cwiseMax(s[1]);
    for (const NamedPolygon& g : problem.goal) {
      Vector2d glo = g.vertices.front(), ghi = g.vertices.front();
      for (const Vector2d& v : g.vertices) glo = glo.cwiseMin(v), ghi = ghi.cwiseMax(v);
      if (!(hi.x() < glo.x() || ghi.x() < lo.x() || hi.y() < glo.y() || ghi.y() < lo.y())) return false;
    }
    const Seg piece(P2(s[0].x(), s[0].y()), P2(s[1].x(), s[1].y()));
    for (int a : active) {
      for (const auto& t : problem.rays[a].segments) {
        if (CGAL::do_intersect(piece, Seg(P2(t[0].x(), t[0].y()), P2(t[1].x(), t[1].y())))) return false;
      }
    }
  }
  return true;
}

// Track-pruned choice (the default): start with every reliable candidate active and drop, sweep after sweep, the rays
// with a piece of bad track (complying down from there fails: it ends on a sticking edge, an open end, or switches
// to a ray that fails), until every active ray leads to good places along its whole length (at most k + 1 sweeps;
// rays that only help together stay, since their tracks are computed with each other active). That set's region is
// kept if it contains B_θ(G) (exact polygon difference; otherwise the start is the empty set). Then each dropped ray
// is tried once more on its own, in id order, and kept if the region grows and still contains the current one (a ray
// that only leads to open ends is not tried: LeadsOnlyToOpenEnds).
// Last, every active ray the region does not need is dropped. At most 3k + 1 sweeps in all, against 2^k for the exact
// search.
std::vector<int> TrackSelection(const BackprojectionProblem& problem, SweepFrame& frame,
                                const std::vector<int>& candidates, SweepResult& current, int& sweeps,
                                bool skip_open_ended) {
  const PolygonSet base_set = ToPolygonSet(current.rings);
  std::vector<int> active = candidates;
  SweepResult trial;
  while (!active.empty()) {
    trial = RunSweep(problem, active, frame);
    ++sweeps;
    if (trial.bad_track_rays.empty()) break;
    std::vector<int> kept;
    for (int c : active) {
      if (trial.bad_track_rays.count(c) == 0) kept.push_back(c);
    }
    active = std::move(kept);
  }
  if (!active.empty() && LargerArea(trial, current) && ContainsSet(base_set, trial.rings)) {
    current = std::move(trial);
  } else {
    active.clear();
  }
  PolygonSet current_set = ToPolygonSet(current.rings);
  for (int c : candidates) {
    if (std::find(active.begin(), active.end(), c) != active.end()) continue;
    if (skip_open_ended && LeadsOnlyToOpenEnds(problem, c, active)) continue;  // its sweep could not be adopted
    std::vector<int> with = active;
    with.push_back(c);
    if (AdoptIfLarger(problem, frame, with, current, current_set, sweeps)) active = std::move(with);
  }
  // Fewest rays: every ray the region does not need is dropped (each one is a servo the robot must run and a line the
  // camera must see); a ray goes if the region without it still contains the current one.
  std::sort(active.begin(), active.end());
  for (size_t i = 0; i < active.size();) {
    std::vector<int> without = active;
    without.erase(without.begin() + static_cast<std::ptrdiff_t>(i));
    SweepResult t = RunSweep(problem, without, frame);
    ++sweeps;
    if (ContainsSet(current_set, t.rings)) {
      active = std::move(without);
      current = std::move(t);
      current_set = ToPolygonSet(current.rings);
    } else {
      ++i;
    }
  }
  return active;
}

// Exact choice: every subset of the candidates, by size, then lexicographically (so that the first set reaching the
// best area is the smallest, then the first by id). A subset's region is checked for containing B_θ(G) only when
// its area beats the best so far (the check is a polygon difference; the sweep is the unavoidable cost).
std::vector<int> ExactSelection(const BackprojectionProblem& problem, SweepFrame& frame,
                                const std::vector<int>& candidates, SweepResult& best, int& sweeps) {
  const int n = static_cast<int>(candidates.size());
  const PolygonSet base_set = ToPolygonSet(best.rings);
  std::vector<int> best_set;
  for (int k = 1; k <= n; ++k) {
    // Subsets of size k in lexicographic order of candidate positions.
    std::vector<int> pos(k);
    for (int i = 0; i < k; ++i) pos[i] = i;
    while (true) {
      std::vector<int> trial_set;
      for (int i : pos) trial_set.push_back(candidates[i]);
      SweepResult trial = RunSweep(problem, trial_set, frame);
      ++sweeps;
      if (LargerArea(trial, best) && ContainsSet(base_set, trial.rings)) {
        best = std::move(trial);
        best_set = trial_set;
      }
      int i = k - 1;
      while (i >= 0 && pos[i] == n - k + i) --i;
      if (i < 0) break;
      ++pos[i];
      for (int j = i + 1; j < k; ++j) pos[j] = pos[j - 1] + 1;
    }
  }
  return best_set;
}

}  // namespace

VcBackprojection VcEnlargedBackprojection(const BackprojectionProblem& problem, const VcSelectionOptions& options) {
  VcBackprojection out;
  std::vector<int> candidates;
  for (size_t i = 0; i < problem.rays.size(); ++i) {
    if (IsReliableRay(problem.rays[i], problem.theta, problem.velocity_cone)) {
      candidates.push_back(static_cast<int>(i));
    } else {
      out.unreliable_rays.push_back(problem.rays[i].id);
    }
  }
  std::sort(candidates.begin(), candidates.end(),
            [&](int a, int b) { return problem.rays[a].id < problem.rays[b].id; });
  out.candidates = static_cast<int>(candidates.size());
  SweepFrame frame(problem.theta);
  SweepResult result = RunSweep(problem, {}, frame);
  out.classic = result.region;
  out.sweeps = 1;
  std::vector<int> active;
  if (candidates.empty()) {
    out.selection = RaySelection::kNone;
  } else if (options.method == RaySelection::kTrack) {
    out.selection = RaySelection::kTrack;
    active = TrackSelection(problem, frame, candidates, result, out.sweeps, options.skip_open_ended);
  } else if (options.method == RaySelection::kExact && out.candidates <= options.exact_limit) {
    out.selection = RaySelection::kExact;
    active = ExactSelection(problem, frame, candidates, result, out.sweeps);
  } else {
    out.selection = RaySelection::kGreedy;
    active = GreedySelection(problem, frame, candidates, result, out.sweeps);
  }
  for (int c : candidates) {
    if (std::find(active.begin(), active.end(), c) == active.end()) out.rejected_rays.push_back(problem.rays[c].id);
  }
  out.region = result.region;
  for (int a : active) out.active_rays.push_back(problem.rays[a].id);
  std::sort(out.active_rays.begin(), out.active_rays.end());
  std::sort(out.rejected_rays.begin(), out.rejected_rays.end());
  return out;
}

std::vector<NamedPolygon> GoalKernel(const std::vector<NamedPolygon>& goal, double position_uncertainty, int sides) {
  std::vector<NamedPolygon> out;
  if (position_uncertainty <= 0.0) return goal;
  const double r = position_uncertainty / std::cos(M_PI / sides);  // circumscribes the disc
  for (size_t gi = 0; gi < goal.size(); ++gi) {
    const auto& g = goal[gi];
    ExactPolygon poly;
    for (const auto& v : g.vertices) poly.push_back(P2(v.x(), v.y()));
    if (poly.is_clockwise_oriented()) poly.reverse_orientation();
    PolygonSet kernel(poly);
    for (size_t i = 0; i < g.vertices.size(); ++i) {
      const Vector2d& a = g.vertices[i];
      const Vector2d& b = g.vertices[(i + 1) % g.vertices.size()];
      std::vector<P2> pts;
      for (int k = 0; k < sides; ++k) {
        const double ang = 2 * M_PI * k / sides;
        const Vector2d d(r * std::cos(ang), r * std::sin(ang));
        pts.emplace_back(a.x() + d.x(), a.y() + d.y());
        pts.emplace_back(b.x() + d.x(), b.y() + d.y());
      }
      std::vector<P2> hull;
      CGAL::convex_hull_2(pts.begin(), pts.end(), std::back_inserter(hull));
      kernel.difference(ExactPolygon(hull.begin(), hull.end()));
    }
    std::vector<ExactPolygonWithHoles> parts;
    kernel.polygons_with_holes(std::back_inserter(parts));
    for (size_t pi = 0; pi < parts.size(); ++pi) {
      NamedPolygon np;
      const ExactPolygon& ob = parts[pi].outer_boundary();
      size_t k = 0;
      for (auto v = ob.vertices_begin(); v != ob.vertices_end(); ++v, ++k) {
        np.vertices.emplace_back(CGAL::to_double(v->x()), CGAL::to_double(v->y()));
        const std::string base = "kernel(goal[" + std::to_string(gi) + "])[" + std::to_string(pi) + "]";
        np.vertex_refs.push_back(base + ".v[" + std::to_string(k) + "]");
        np.edge_refs.push_back(base + ".e[" + std::to_string(k) + "]");
      }
      out.push_back(std::move(np));
    }
  }
  return out;
}

}  // namespace visco::planning
