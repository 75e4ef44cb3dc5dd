#pragma once
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
//
// This header is internal to the directional backprojection (namespace internal; in a header so that it can be unit
// tested). The sweep's parts, one file each: the overlay of the static geometry (overlay.cc), the event loop
// (plane_sweep.cc), the local rule (local_rule.cc), region assembly (region_assembly.cc); the tracking-error geometry
// (tracking_error.h), the ray choice over many sweeps (ray_choice.h).

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <queue>
#include <set>
#include <string>
#include <vector>

#include "planning/backprojection.h"
#include "planning/backprojection/exact.h"
#include "planning/backprojection/sweep_frame.h"

namespace visco::planning::internal {

// Region labels. Static labels use kOutside, kObstacle, kGoal and kGood (meaning "free", refined by the sweep).
enum class Label : std::uint8_t { kOutside, kObstacle, kGoal, kGood, kBad };
inline bool IsGood(Label l) { return l == Label::kGoal || l == Label::kGood; }
inline bool IsFree(Label l) { return l == Label::kGood || l == Label::kBad; }
inline Label Status(bool good) { return good ? Label::kGood : Label::kBad; }

// An input edge in the sweep frame, directed with its polygon's interior on the left (bounds: the inside).
struct Source {
  P2 a, b;
  EdgeKind kind = EdgeKind::kObstacle;
  int name = -1;
  bool sticking = false;
  Vector2d sweep_normal{0, 0};  // outward unit normal in the sweep frame (obstacles), inward (bounds)
  int ray = -1;                 // active rays: index into BackprojectionProblem::rays
};

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

// The overlay of a sweep's static sources as the sweep reads it: its vertices, and its edges that separate two
// static labels or carry an active ray, each with the labels on either side and the source it stands for.
struct OverlayEdge {
  int s = -1, t = -1;                             // vertex indices
  Label left = Label::kBad, right = Label::kBad;  // static labels on the left and the right of s -> t
  EdgeKind kind = EdgeKind::kObstacle;
  int src = -1;
};
struct OverlayGraph {
  std::vector<P2> vertices;
  std::vector<OverlayEdge> edges;
  // For each vertex, the sources of its edges (filled only when asked: PrepareStaticOverlay).
  std::vector<std::vector<int>> vertex_sources;
};

// The overlay of a problem's statics (C-obstacles, goal, bounds, forbidden regions), computed once in the world frame
// for every sweep at any θ (BackprojectionProblem::static_overlay). The sweep frame is an exact similarity of the
// world, so the overlay of the mapped statics is the mapped overlay: the same vertices, edges and labels. Kept without
// exact numbers (each vertex as an input point or as the crossing of two sources' lines, the sweep maps it in its own
// frame), so threads share it read-only.
struct StaticOverlay {
  struct Vertex {
    Vector2d point{0, 0};  // an input point (a < 0) ...
    int a = -1, b = -1;    // ... or where the lines of sources a and b cross
  };
  std::vector<Vertex> vertices;
  std::vector<OverlayEdge> edges;  // as OverlayGraph::edges
  size_t sources = 0;              // the static sources the sweep makes of these statics
  // The statics it was made from (vertices; holes), to tell whether a problem has the same.
  std::vector<std::pair<std::vector<Vector2d>, bool>> obstacles, goal, forbidden;
  Vector2d bounds_min{0, 0}, bounds_max{0, 0};
  bool Matches(const BackprojectionProblem& problem) const;
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
  // The overlay of `problem`'s statics, for BackprojectionProblem::static_overlay.
  static StaticOverlay PrepareOverlay(const BackprojectionProblem& problem);
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
      // A curve ending at p is the common case at an event, and a tie the interval filter cannot decide: the
      // orientation would be computed in exact rationals (a sixth of a sweep's time), the point comparison is cheap.
      if (Same(c->hi, *p) || Same(c->lo, *p)) return 0;
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

  struct StaticsOnly {};
  Sweep(const BackprojectionProblem& problem, SweepFrame& frame, StaticsOnly);  // the static sources, no overlay
  void AddStaticSources(SweepFrame& frame);
  void AddRayParts(const std::vector<int>& active_rays, SweepFrame& frame);
  // The sweep's static events from an overlay of sources_ (vertices in the sweep frame).
  void SetStaticEvents(const std::vector<P2>& vertices, const std::vector<OverlayEdge>& edges);
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

// The result of one sweep: its rings in the sweep frame, its region in the world frame, and the active rays with a
// piece of bad track.
struct SweepResult {
  std::vector<ExactRing> rings;
  Region region;
  std::set<int> bad_track_rays;
};

// Sweeps `problem` with the rays `active` (indices into problem.rays) in `frame` (the frame of problem.theta).
SweepResult RunSweep(const BackprojectionProblem& problem, const std::vector<int>& active, SweepFrame& frame);

}  // namespace visco::planning::internal
