#pragma once
// Critical orientations of the directional backprojections (Donald; Fox & Hutchinson §VI-A, §VII-A/B): the
// commanded directions θ at which the combinatorial structure of B_θ(G) or B_vcθ(G) may change. Between two
// consecutive critical orientations the structure (the cyclic sequence of edge provenances of every ring) is the
// same (docs/planning_nondirectional.md says why the list below is complete).
//
// The six kinds of the papers, and what generates them here (all in double precision; every candidate is a closed
// form of the static geometry):
//   * vgraph:    a free edge (a ray of the inverted velocity cone, direction θ + π ± ε_v) from one point of the static
//                arrangement passes through another point it sees (Donald's v-graph critical);
//   * sliding:   an edge of the velocity cone is parallel or antiparallel to an edge of a friction cone (an edge
//                switches between sticking and sliding), the cone reaches an edge's direction or normal, or it
//                reaches the bisector where the vertex rule switches from one edge to the other;
//   * vertex:    a free vertex (where a +ε_v free edge meets a −ε_v one; it moves on a fixed circle through their two
//                sources) crosses a C-obstacle, goal or bounds edge;
//   * R:         a free edge passes through a vertex of the start region R, or a free vertex crosses an edge of R, or
//                a region vertex on an edge crosses R's boundary there (Donald's R-critical);
//   * free-edge: a free vertex crosses a CVC ray (Fox & Hutchinson Prop. 2);
//   * vc:        a free edge is parallel to a CVC ray (Prop. 3), or the ray's reliability changes (its line enters or
//                leaves 90° ± ε_v of θ).
// The points of the static arrangement are the vertices of CB, the goal, the bounds, the ends of the CVC rays' free
// segments, the start region's vertices, and every crossing of two of their edges.

#include <Eigen/Core>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "planning/backprojection.h"

namespace visco::planning {

enum class CriticalKind : std::uint8_t { kVgraph, kSliding, kVertex, kR, kFreeEdge, kVc, kSelection };
/// "vgraph", "sliding", "vertex", "R", "free-edge", "vc", "selection" (docs/formats.md).
const char* CriticalKindName(CriticalKind kind);

/// What a sliding candidate is, by the contact model (docs/semantics.md "The motion model"; n is the edge's
/// outward normal): a cone edge reaching the friction cone's edge −n ± φ, where sticking starts or stops
/// (kSticking; also where the outward side could not be told), or where the cone overlaps the friction cone on both
/// sides of the event so that the edge sticks throughout (kStickingHeld: the cone edge reaches the friction cone's
/// edge on its own side); one reaching n ± φ, the papers' "parallel" case,
/// where the cone points away from the obstacle and no velocity touches the edge (kAway); the cone reaching the edge's
/// direction, where velocities start or stop pushing into it (kContact); θ itself along the edge (kAlong); a cone edge
/// reaching the vertex rule's bisector where it points into CB, so that velocities beside it push into both edges
/// (kVertexRule; also where the side could not be told), or out of CB, where no velocity beside it pushes into
/// either (kVertexAway).
enum class SlidingCause : std::uint8_t {
  kNone,
  kSticking,
  kAway,
  kContact,
  kAlong,
  kVertexRule,
  kVertexAway,
  kStickingHeld
};
/// "", "sticking", "away", "contact", "along", "vertex-rule", "vertex-away", "sticking-held" (the `cause` of a sliding
/// orientation in `visco critical`'s JSON).
const char* SlidingCauseName(SlidingCause cause);
/// Whether a sliding candidate of this cause changes no velocity's contact, so never the structure (kAway, kAlong,
/// kVertexAway, kStickingHeld; docs/planning_nondirectional.md, "Sliding events that matter").
bool SlidingCauseChangesNothing(SlidingCause cause);

/// One critical orientation: θ in [−π, π) and the features that cause it (vertex, edge and ray refs as in the
/// region JSON).
struct CriticalOrientation {
  double theta = 0.0;
  CriticalKind kind = CriticalKind::kVgraph;
  std::vector<std::string> refs;
  /// The static points whose free edges the event involves (one for a free edge through a point, two for a free
  /// vertex); the event can change the structure only where they are vertices of the region. Empty for the kinds that
  /// act on the whole region (sliding, vc, selection).
  std::vector<Eigen::Vector2d> sources;
  /// For each source, which of its two free edges the event involves: +1 the one of direction θ + π + ε_v, −1 the
  /// one of θ + π − ε_v.
  std::vector<std::int8_t> source_signs;
  /// For a sliding event: the obstacle edge (its two ends) or vertex (one point) whose sticking or sliding switches
  /// there. Only motions that touch it behave differently across the event, so it can change the structure only
  /// where the feature meets the closure of a region (docs/planning_nondirectional.md, "Sliding events that matter").
  /// Empty for the other kinds.
  std::vector<Eigen::Vector2d> feature;
  /// Where a free edge's or free vertex's event happens at θ: the point a free edge passes through (vgraph, R) or the
  /// free vertex on the edge it crosses (vertex, free-edge, R). Such an event can change the structure only where
  /// this point lies on the boundary of a region just before or after it (docs/planning_nondirectional.md, "Events on
  /// the boundary"). Empty for the kinds that act on the whole region or on a feature (sliding, vc, and the vgraph
  /// events along a static segment).
  std::vector<Eigen::Vector2d> point;
  /// A sliding candidate's cause (kNone for the other kinds).
  SlidingCause sliding = SlidingCause::kNone;
};

/// Counts of the candidates by kind, before any filtering (indexed by CriticalKind).
struct CriticalCounts {
  std::int64_t by_kind[7] = {0, 0, 0, 0, 0, 0, 0};
  std::int64_t points = 0;         ///< points of the static arrangement
  std::int64_t segments = 0;       ///< edges of the static arrangement
  std::int64_t visible_pairs = 0;  ///< pairs of points that see each other
  std::int64_t total() const;
};

/// How the generator finds the segments near a segment, circle or point: through a uniform grid (the default) or by
/// scanning all of them (the obvious reference the tests compare with; O(n³)). Both give the same candidates.
enum class CandidateSearch : std::uint8_t { kIndexed, kScan };

/// One candidate of a CandidateList: its θ, kind and cause, the free vertex of a free-vertex event, and the indices
/// its refs, sources and features are read from (in the list's tables of strings and points; which is which depends on
/// `form`, planning/critical.cc). 40 bytes and no allocation of its own: a large scene with a camera has tens of
/// millions of candidates (n = 106, seed 2 of BM_MultiStep: 27 million, 24 million of them free-edge), which as
/// CriticalOrientations took 21 GB.
struct CandidateEntry {
  static constexpr std::uint32_t kNoIndex = 0xffffffffu;
  /// kRefs: refs only (vc); kSlidingFeature: ref ids[0], the feature's points ids[1] (and ids[2]); kThroughPoint: a
  /// free edge through a point (vgraph, R): refs ids[0], ids[1], which are also its points (`flags`: 1 the source is
  /// ids[1], else ids[0]; 2 its sign is −1, else +1; 4 along a static segment: the feature is both, else the point is
  /// the one that is not the source); kFreeVertex: refs ids[0..2], sources ids[0] (+1) and ids[1] (−1), point `point`.
  enum Form : std::uint8_t { kRefs, kSlidingFeature, kThroughPoint, kFreeVertex };
  double theta = 0.0;
  double point[2] = {0.0, 0.0};
  std::uint32_t ids[3] = {kNoIndex, kNoIndex, kNoIndex};
  CriticalKind kind = CriticalKind::kVgraph;
  SlidingCause sliding = SlidingCause::kNone;
  Form form = kRefs;
  std::uint8_t flags = 0;
};

/// Which candidates CriticalCandidateList lists. A *ray point* is a static point that only CVC rays make: a ray's end
/// or cut, or a crossing of a ray with another edge or ray, where no C-obstacle, goal, bounds, forbidden or start
/// edge has a vertex or crosses another. It is a vertex of a region only where a ray through it is active, which
/// few are; most candidates of a scene with a camera are events of ray points (BM_MultiStep's n = 106, seed 2: 900 of
/// its 1 158 points). With `all` every candidate is listed (the full listing, the reference); otherwise the events
/// whose sources include a ray point are listed only where every such source is one of `ray_points` (within 10⁻⁹ of
/// the scene's size, as the kinetic walk matches sources). Events along a static segment, those of the start region
/// (R) and those without sources (sliding, vc) are always listed. docs/planning_nondirectional.md, "Ray points'
/// events on demand".
struct CandidateScope {
  bool all = true;
  std::vector<Eigen::Vector2d> ray_points;
  /// Without `all`: every candidate is listed all the same where the ray points times the points are fewer than this
  /// (a small scene's full listing costs less than a second walk would); CandidateList::scoped() says which it was.
  /// Decided from the points before any event is listed, so a small scene is listed once.
  double all_below_pairs = 0.0;
};

/// The candidates of CriticalCandidates, stored compactly (CandidateEntry) and read one at a time.
class CandidateList {
 public:
  CandidateList() = default;
  CandidateList(std::deque<CandidateEntry> entries, std::vector<std::string> strings,
                std::vector<Eigen::Vector2d> points, std::vector<Eigen::Vector2d> ray_points = {})
      : entries_(std::move(entries)),
        strings_(std::move(strings)),
        points_(std::move(points)),
        ray_points_(std::move(ray_points)) {}
  /// Every ray point of the static arrangement (CandidateScope), listed or not, sorted by x.
  const std::vector<Eigen::Vector2d>& ray_points() const { return ray_points_; }
  /// Whether the events of ray points the scope did not name were left out (false: every candidate is listed).
  bool scoped() const { return scoped_; }
  void set_scoped(bool scoped) { scoped_ = scoped; }
  std::size_t size() const { return entries_.size(); }
  bool empty() const { return entries_.empty(); }
  double theta(std::size_t i) const { return entries_[i].theta; }
  CriticalKind kind(std::size_t i) const { return entries_[i].kind; }
  SlidingCause sliding(std::size_t i) const { return entries_[i].sliding; }
  /// Candidate i as a CriticalOrientation, written into `out` (its vectors keep their capacity: no allocation once
  /// warm); without `with_refs` its refs are left empty.
  void Get(std::size_t i, CriticalOrientation& out, bool with_refs = true) const;
  CriticalOrientation Get(std::size_t i) const;
  std::vector<std::string> Refs(std::size_t i) const;
  /// Removes the candidates of one kind (keeping the order of the others) and returns them.
  std::vector<CriticalOrientation> TakeKind(CriticalKind kind);

 private:
  std::deque<CandidateEntry> entries_;  // no huge block: a large scene has tens of millions
  std::vector<std::string> strings_;
  std::vector<Eigen::Vector2d> points_;
  std::vector<Eigen::Vector2d> ray_points_;
  bool scoped_ = false;
};

/// The events of the pairs of static points that a problem's C-obstacles and bounds make among themselves (their
/// vertices, the bounds' corners and the crossings of their edges): free edges through one another, and free vertices
/// crossing their edges. They depend on the C-obstacles, the bounds and the cones only, so the child targets of a
/// multi-step search (each with its own goal and forbidden strips and no rays) share them: listed once
/// (ListStaticCandidates) and given to CriticalCandidateList, which then lists only the events its other points and
/// edges add. Opaque (planning/critical.cc).
class StaticCandidates;

/// The static candidates of `problem`'s C-obstacles and bounds (its goal, rays and forbidden regions are left out).
/// `threads` and `stop` as for CriticalCandidateList.
std::shared_ptr<const StaticCandidates> ListStaticCandidates(const BackprojectionProblem& problem, int threads = 1,
                                                             const std::atomic<bool>* stop = nullptr);

/// Every candidate critical orientation of the problem's B_θ(G) and B_vcθ(G) over all θ (problem.theta is ignored),
/// sorted by θ in [−π, π), exact duplicates (same θ, kind, refs and sources) removed. `start` (may be null) adds the
/// R-critical orientations of that region. A superset: the nondirectional backprojection (nondirectional.h) keeps
/// those where the structure really changes. `threads` list the pairs of points' events side by side (the same list
/// whatever the threads). `scope` (null: every candidate) leaves out the events of ray points it does not name.
/// `statics` (may be null) are taken instead of listing those pairs again where the problem's C-obstacles, bounds and
/// cones are those they were listed from (else, and with CandidateSearch::kScan, they are not used): the same list.
/// Not real-time safe.
CandidateList CriticalCandidateList(const BackprojectionProblem& problem, const NamedPolygon* start,
                                    CriticalCounts* counts = nullptr,
                                    CandidateSearch search = CandidateSearch::kIndexed,
                                    const std::atomic<bool>* stop = nullptr, int threads = 1,
                                    const CandidateScope* scope = nullptr, const StaticCandidates* statics = nullptr);

/// The same candidates as CriticalOrientations (for the command line and the tests; large scenes take gigabytes).
std::vector<CriticalOrientation> CriticalCandidates(const BackprojectionProblem& problem, const NamedPolygon* start,
                                                    CriticalCounts* counts = nullptr,
                                                    CandidateSearch search = CandidateSearch::kIndexed,
                                                    const std::atomic<bool>* stop = nullptr);

/// The listing before CandidateList, kept as the reference the tests compare with: every candidate built as a
/// CriticalOrientation, then sorted and deduplicated.
std::vector<CriticalOrientation> CriticalCandidatesReference(const BackprojectionProblem& problem,
                                                             const NamedPolygon* start,
                                                             CriticalCounts* counts = nullptr);

/// Thrown by CriticalCandidates and ComputeNondirectional (nondirectional.h) when their stop flag is set (the
/// planner's memory limit sets it from another thread).
class NondirectionalStopped : public std::runtime_error {
 public:
  NondirectionalStopped() : std::runtime_error("the nondirectional backprojection was stopped") {}
};

/// Only the R-critical candidates of region `start` (the same as CriticalCandidates's of kind R).
std::vector<CriticalOrientation> RCriticalCandidates(const BackprojectionProblem& problem, const NamedPolygon& start,
                                                     CandidateSearch search = CandidateSearch::kIndexed);

/// θ wrapped to [−π, π).
double WrapAngle(double theta);

}  // namespace visco::planning
