#pragma once
// Directional backprojections in C = R² (Fox & Hutchinson §IV–V, docs/semantics.md "Backprojections"):
//   * B_θ(G): the classic one (Erdmann; Donald–Canny plane sweep against the commanded velocity);
//   * B_vcθ(G): the same with a set of active CVC rays (frictionless two-sided walls), and the choice of that set
//     so that the region stays sound and contains B_θ(G).
//
// The sweep runs in exact arithmetic (CGAL's lazy exact kernel, hidden in planning/backprojection/) in a frame rotated
// so that the commanded velocity points straight down; sticking and sliding are decided with the motion model's own
// predicates (common/motion_model.h), so planner and simulator agree on ties. Rings are assembled and holes placed
// with exact predicates; output coordinates are rotated back to the world frame exactly, then converted to double. An
// inconsistency of the sweep is a std::logic_error (`visco` exits 1 with "internal error"), never a smaller or
// larger region.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace visco::planning {

namespace internal {
struct StaticOverlay;  // planning/backprojection/plane_sweep.h
}

/// A polygon with names for its vertices and edges (edge i runs from vertex i to vertex i + 1, wrapping). Names are
/// the provenance refs of the output (docs/formats.md); empty names are filled in as "<prefix>[i].v[k]"/"…e[k]".
struct NamedPolygon {
  std::vector<Eigen::Vector2d> vertices;
  std::vector<std::string> vertex_refs;  ///< optional, one per vertex
  std::vector<std::string> edge_refs;    ///< optional, one per edge
  /// A hole of the preceding polygon (a C-obstacle can enclose free space): the region inside is removed.
  bool hole = false;
};

/// A candidate CVC ray for B_vcθ(G): its free-space segments and its id (docs/formats.md `cvc_rays[].id`).
struct CvcRayInput {
  std::string id;
  std::string group;  ///< the workspace VC ray it comes from (siblings share it); may be empty
  std::vector<std::array<Eigen::Vector2d, 2>> segments;
  /// Per segment, per end: true where the end is open (not on a C-obstacle: the bounds clip the ray or it is the
  /// camera end); complying to an open end fails. Empty: every end is on a C-obstacle. The sweep also treats an end
  /// outside the bounds as open (it clips the segment to the bounds exactly).
  std::vector<std::array<bool, 2>> open_ends;
};

/// Everything a directional backprojection depends on, in C-space (metres, radians).
struct BackprojectionProblem {
  std::vector<NamedPolygon> obstacles;  ///< C-obstacles (may overlap; either orientation)
  std::vector<NamedPolygon> goal;       ///< goal regions (either orientation)
  Eigen::Vector2d bounds_min{0.0, 0.0};
  Eigen::Vector2d bounds_max{0.0, 0.0};
  double theta = 0.0;             ///< commanded direction, counter-clockwise from +x
  double velocity_cone = 0.0;     ///< ε_v, half-angle, in [0, π/2); 0 is planned as 1e-9 rad (more cautious)
  double friction_cone = 0.0;     ///< φ, in [0, π/2)
  std::vector<CvcRayInput> rays;  ///< candidate CVC rays (ignored by the classic backprojection)
  /// How far (metres) a motion complying to an active ray may run beside its line (the servo's tracking error). 0:
  /// compliance is exact (the papers' model). > 0: where a ray's lower end lies on CB, complying down the ray is good
  /// only if the motion is good wherever it can meet CB this close to the line: on each of the two C-obstacle edges
  /// that bound the free wedge around the ray at its end, up to δ / sin(angle between the ray and the edge) from the
  /// end (docs/semantics.md "Compliance ends").
  double ray_tracking_error = 0.0;
  /// Regions where arriving fails, treated like the outside of the bounds (their edges appear as `bounds` edges):
  /// e.g. the parts of a visual guarded step's ray outside the next preimage, where the step would end too early.
  std::vector<NamedPolygon> forbidden;
  /// The overlay of the static geometry (C-obstacles, goal, bounds, forbidden regions), computed once for every sweep
  /// of these statics at any θ (PrepareStaticOverlay); empty: each sweep overlays them itself. A sweep uses it only
  /// if it was made from the same statics (it keeps a copy of them and compares), so changing them is safe.
  std::shared_ptr<const internal::StaticOverlay> static_overlay;
};

/// Computes `problem.static_overlay`: the arrangement of its static geometry, the same at every θ up to the sweep
/// frame's exact rotation, so that each later sweep maps it instead of building it (planning_strategy.md, "Where a
/// sweep's time went"). The regions are the same with it as without.
void PrepareStaticOverlay(BackprojectionProblem& problem);

enum class EdgeKind : std::uint8_t { kObstacle, kGoal, kFree, kVc, kBounds };
const char* EdgeKindName(EdgeKind kind);

/// Provenance of one output edge (docs/formats.md region JSON).
struct RegionEdge {
  EdgeKind kind = EdgeKind::kFree;
  std::string ref;
  /// A free edge's source: the static point it is erected at (world frame, exact up to one rounding). The edge lies
  /// on the line through it of direction θ + π ± ε_v for every θ of its slice's interval, which is how a slice's
  /// region is carried to another θ without a sweep (nondirectional.h, CarryRegion). Zero for the other kinds.
  Eigen::Vector2d source{0.0, 0.0};
  /// Any other edge: the static segment it lies on (a C-obstacle, goal or bounds edge, a CVC ray's free segment; world
  /// frame), whose line does not move with θ. Both zero for a free edge.
  std::array<Eigen::Vector2d, 2> line{Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()};
  /// A free edge: which of its source's two free edges it is, +1 direction θ + π + ε_v (ref `…/+eps`), −1 θ + π − ε_v
  /// (`…/-eps`). 0 for the other kinds.
  std::int8_t sign = 0;
};

/// A closed ring: edge i runs from vertices[i] to vertices[i + 1] (wrapping). Outer rings are counter-clockwise,
/// holes clockwise.
struct RegionRing {
  std::vector<Eigen::Vector2d> vertices;
  std::vector<RegionEdge> edges;
};

struct RegionPolygon {
  RegionRing outer;
  std::vector<RegionRing> holes;
};

/// A polygonal region with edge provenance.
struct Region {
  std::vector<RegionPolygon> polygons;
  double area = 0.0;  ///< computed exactly in the sweep frame, then rounded
  /// True if p is inside (interior or within `tolerance` of the boundary counts as inside when `closed`).
  bool Contains(const Eigen::Vector2d& p) const;
  /// Distance from p to the region's boundary.
  double BoundaryDistance(const Eigen::Vector2d& p) const;
};

/// How VcEnlargedBackprojection chose the active rays.
enum class RaySelection : std::uint8_t {
  kNone,    ///< no reliable candidate: nothing to choose
  kExact,   ///< every subset of the reliable candidates was swept: the result is a maximum (see below)
  kGreedy,  ///< single rays in id order, then pairs of rejected rays
  kTrack,   ///< the default: every candidate, minus those whose track is bad, then the dropped ones one by one
};
const char* RaySelectionName(RaySelection selection);

/// The VC-enlarged backprojection with the active rays it relies on.
struct VcBackprojection {
  Region region;
  Region classic;  ///< B_θ(G), the region with no ray active (swept first; callers need not sweep it again)
  std::vector<std::string> active_rays;      ///< ids of the CVC rays the motion complies to (sorted)
  std::vector<std::string> rejected_rays;    ///< reliable candidates that are not active
  std::vector<std::string> unreliable_rays;  ///< candidates within 90° ± ε_v of θ (never active, docs/semantics.md)
  RaySelection selection = RaySelection::kNone;
  int candidates = 0;  ///< reliable candidates (the exact search sweeps 2^candidates active sets)
  int sweeps = 0;      ///< plane sweeps run to choose the set (the no-ray sweep included)
};

/// Candidate counts up to this are searched exactly by default: 2^8 = 256 sweeps, about 0.3 s on fig13 (a sweep of
/// a figure-sized scene takes 1-3 ms; 12 candidates, as fig5 has, take 4096 sweeps, about 4.5 s; BM_RaySelection).
constexpr int kExactRaySelectionLimit = 8;

struct VcSelectionOptions {
  /// How to choose: kTrack (default, at most 3k + 1 sweeps for k reliable candidates), kExact (every subset: 2^k
  /// sweeps; the reference the tests measure the others against) or kGreedy.
  RaySelection method = RaySelection::kTrack;
  /// kExact only: search all subsets when there are at most this many reliable candidates, otherwise fall back to
  /// the greedy choice.
  int exact_limit = kExactRaySelectionLimit;
  /// kTrack only: do not sweep again a dropped ray whose every piece complies to an open end without meeting the goal
  /// or an active ray (its sweep could not be adopted: the region it gives has no point the current one lacks). The
  /// same choice either way, fewer sweeps; false is the reference the tests compare with.
  bool skip_open_ended = true;
  /// kTrack only: do not sweep again a dropped ray whose every piece complies to an open end or to a point of CB
  /// outside the current region's closure, without meeting the goal or an active ray (its sweep could not be adopted
  /// either). The same choice either way, fewer sweeps; false is the reference the tests compare with.
  bool skip_outside_landings = true;
};

/// B_θ(G) by the plane sweep. @throws std::invalid_argument on malformed input (empty bounds, ε_v outside [0, π/2),
/// φ outside [0, π/2), degenerate polygons).
Region ClassicBackprojection(const BackprojectionProblem& problem);

/// B_θ(G) with exactly the given rays active (ids from problem.rays); used by VcBackprojection and by tests.
Region BackprojectionWithActiveRays(const BackprojectionProblem& problem, const std::vector<std::string>& active);

/// The static edges a region's rings can have besides CVC rays (C-obstacle, goal, bounds and forbidden edges), each
/// with the kind, ref and RegionEdge::line a sweep gives it: where an event brings one into a region, the
/// nondirectional walk takes it from here instead of sweeping (nondirectional/computed_updates.h). @throws as
/// ClassicBackprojection.
std::vector<RegionEdge> StaticRegionEdges(const BackprojectionProblem& problem);

/// B_vcθ(G). A region swept with an active set S is exactly what S guarantees (the rays are walls for the whole
/// motion, from every start point), and the sweep's region is not monotone in S (a ray can divert trajectories away
/// from the goal). The admissible sets are those whose region contains B_θ(G) (the region with no ray, exact
/// polygon containment); the result is an admissible set, chosen by `options.method`:
///   * track (default): every reliable candidate active, then, sweep after sweep, the rays with a piece of bad track
///     (complying down from it fails) dropped until none is left; kept if admissible; then each dropped ray tried
///     alone, kept if the region grows and contains the current one; last, every ray the region does not need is
///     dropped (fewest rays to comply to). At most 3k + 1 sweeps for k candidates;
///   * exact (at most `exact_limit` reliable candidates): every subset is swept; ties in area (1e-12 relative) go to
///     the smaller set, then to the lexicographically first one by candidate id; only sets that would improve the
///     best area so far are checked for containment: an admissible set of largest area;
///   * greedy (or exact above the limit): each reliable candidate in id order, then pairs of rejected candidates
///     (≤ 12 rejected), keeping a set only if its region contains the current one and is strictly larger.
/// Every way B_θ(G) ⊆ B_vcθ(G) and the region is sound for the reported active rays.
VcBackprojection VcEnlargedBackprojection(const BackprojectionProblem& problem, const VcSelectionOptions& options = {});

/// True if a CVC ray segment from a to b can be relied on for commanded direction θ (its line is not within
/// 90° ± ε_v of θ).
bool IsReliableRay(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double theta, double velocity_cone);

/// True if the CVC ray can ever be active for commanded direction θ: it has a free-space segment and every segment
/// is reliable (IsReliableRay).
bool IsReliableRay(const CvcRayInput& ray, double theta, double velocity_cone);

/// Where the servo's tracking error δ (`problem.ray_tracking_error`) makes the sweep cut an active ray segment
/// [a, b]: the points where CB (edges neither end lies on), the bounds or a forbidden region come within δ of its
/// line beside it or stop doing so (docs/semantics.md, "Compliance ends"). They do not depend on θ; the critical
/// orientations take them as static points. Empty when δ = 0.
std::vector<Eigen::Vector2d> TrackingErrorCuts(const BackprojectionProblem& problem, const Eigen::Vector2d& a,
                                               const Eigen::Vector2d& b);

/// The goal kernel: each goal polygon eroded by the disc of radius ε_p, approximated from inside (the disc is
/// replaced by a circumscribed regular polygon with `sides` sides, so the result is a subset of the true kernel).
std::vector<NamedPolygon> GoalKernel(const std::vector<NamedPolygon>& goal, double position_uncertainty,
                                     int sides = 64);

}  // namespace visco::planning
