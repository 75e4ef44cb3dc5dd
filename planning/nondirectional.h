#pragma once
// The nondirectional backprojection (Donald; Fox & Hutchinson §VI–VII): B(G) and B_vc(G) over every commanded
// direction θ, as slices: one at each critical orientation and one for each open interval between two, each with its
// regions, active rays and structure. Between two consecutive orientations the structure does not change, so a
// slice's region stands for its whole interval combinatorially (its geometry moves with θ).
//
// Two ways to find which candidate orientations (critical.h) really change the structure:
//   * baseline (Donald's critical-slice method): a backprojection at every candidate and inside every interval
//     between two consecutive candidates;
//   * kinetic (default): walk the candidates in θ order with the current slice's structure, and sweep again only at
//     a candidate whose sources are vertices of the current regions (an event elsewhere cannot change them), at a
//     sliding event whose edge or vertex meets the current regions, or at a vc event (it acts on the whole region).
//     Every interval is then checked at two more orientations, and a change found there is located by bisection: a
//     change of the chosen active rays alone is a `selection` orientation (the choice compares areas, which no
//     geometric event bounds); any other is counted as `unexplained` (the tests require none).
// docs/planning_nondirectional.md explains the design and gives the figures.

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "planning/backprojection.h"
#include "planning/critical.h"

namespace visco::planning {

/// The combinatorial structure of a region: for every ring, holes included, the cyclic sequence of (kind, ref) of
/// its edges, canonically rotated, holes sorted inside their polygon, polygons sorted.
std::vector<std::string> RegionStructure(const Region& region);

struct SliceStructure {
  std::vector<std::string> classic;
  std::vector<std::string> vc;
  std::vector<std::string> active_rays;
  friend bool operator==(const SliceStructure&, const SliceStructure&) = default;
};

/// The backprojections at one θ and their structure.
struct Slice {
  double theta = 0.0;  ///< where it was computed (radians)
  /// The orientations it stands for: lo == hi == theta for a critical slice, else the open interval (lo, hi) (hi may
  /// exceed π: the interval wraps).
  double lo = 0.0, hi = 0.0;
  bool critical = false;
  VcBackprojection vc;  ///< vc.classic is B_θ(G)
  SliceStructure structure;
};

/// Why the nondirectional computation swept (NondirectionalStats::sweeps is indexed by it): after a relevant event
/// (the kinetic walk) or in every interval (the baseline), to locate a change the walk found, the interval checks, a
/// bisection for where a change lies (the checks' and switches of the chosen rays), and the final slices (critical
/// ones, open ones the checks had not swept).
enum SweepPurpose : std::uint8_t { kSweepWalk, kSweepLocate, kSweepChecks, kSweepBisect, kSweepSlices, kSweepPurposes };
/// "walk", "locate", "checks", "bisect", "slices" (the keys of `visco critical`'s stats.sweeps, docs/formats.md).
const char* SweepPurposeName(SweepPurpose purpose);

struct NondirectionalStats {
  CriticalCounts counts;             ///< candidates by kind
  std::int64_t candidates = 0;       ///< candidate orientations (R-critical ones of the start region included)
  std::int64_t events = 0;           ///< distinct orientations of the structural candidates (the baseline sweeps each)
  std::int64_t checked = 0;          ///< events after which the structure was swept again
  std::int64_t backprojections = 0;  ///< VC-enlarged backprojections computed (each several sweeps): sum of `sweeps`
  std::array<std::int64_t, kSweepPurposes> sweeps{};   ///< the backprojections by SweepPurpose
  std::array<double, kSweepPurposes> sweep_seconds{};  ///< their time (wall clock, summed over the threads)
  std::int64_t changes = 0;      ///< orientations where the structure changes (reported, R-critical aside)
  std::int64_t selection = 0;    ///< of which the chosen active rays alone change
  std::int64_t unexplained = 0;  ///< changes found by the interval checks at no candidate (a bug if not 0)
  /// Changes at a candidate that the kinetic walk skipped and the interval checks found (the walk's rule missed
  /// them; the result is still complete, the tests require none).
  std::int64_t found_by_probes = 0;
  /// Changes with the same chosen rays on both sides that the kinetic walk found at an event its rule does not take
  /// for the structure just before it (a later sweep differed and the change was located): 0 where the rule is exact,
  /// as docs/planning_nondirectional.md argues. (Switches of the chosen rays can follow from events the rule does not
  /// see; they are found the same way and not counted.)
  std::int64_t rule_missed = 0;
  /// Of those, the ones at events with a sliding candidate: the sliding rule's argument has a known gap (a motion
  /// leaving an edge into free space at an interior point, docs/planning_nondirectional.md), the others' has none.
  std::int64_t rule_missed_sliding = 0;
  /// Changes the kinetic walk found at the event it swept and that are that event's local edit (a static edge or a
  /// free edge coming or going where the event's free vertex or free edge is, `NondirectionalOptions::local_edits`):
  /// located without a sweep.
  std::int64_t explained = 0;
  /// Slices after a relevant event the kinetic walk computed from the one before it instead of sweeping
  /// (`NondirectionalOptions::computed_updates`; with `check_updates`, the ones it would have computed).
  std::int64_t updated = 0;
  /// With `check_updates`: computed slices whose structure or areas differ from the sweep's (the tests require 0).
  std::int64_t update_mismatches = 0;
  std::int64_t r_critical = 0;  ///< R-critical orientations reported (they bound where R fits)
  /// With `ray_events_on_demand`: the walks (one more each time slices had ray points whose events were not listed),
  /// the ray points whose events were listed in the end, and the backprojections the later walks reused.
  std::int64_t walks = 1;
  std::int64_t ray_points_listed = 0;
  std::int64_t reused = 0;
  std::vector<double> unexplained_at;  ///< where those were found (radians)
};

struct NondirectionalBackprojection {
  /// Sorted by θ in [−π, π): every orientation where the structure changes, and the R-critical ones of the start
  /// region (which bound the intervals where it fits; the structure need not change there).
  std::vector<CriticalOrientation> orientations;
  /// A critical slice at each orientation, then the open slice up to the next one (wrapping): 2 × orientations, or
  /// one open slice for the whole circle when there is no orientation.
  std::vector<Slice> slices;
  NondirectionalStats stats;
  double velocity_cone = 0.0;  ///< the problem's ε_v (RegionAt turns the free edges with it)
};

enum class SliceMethod : std::uint8_t { kKinetic, kBaseline };

struct NondirectionalOptions {
  SliceMethod method = SliceMethod::kKinetic;
  VcSelectionOptions selection;
  int threads = 1;  ///< worker threads for the slices (each runs whole backprojections)
  /// Kinetic walk: sweep again at a sliding event only when its edge or vertex meets the closure of the last swept
  /// slice's regions (classic or VC), and never where no velocity's contact changes (SlidingCauseChangesNothing);
  /// false sweeps at every sliding event (the rule before; kept to compare).
  bool local_sliding = true;
  /// Kinetic walk: sweep at least every this many events even where none is relevant (then bisect the skipped ones
  /// if the structure differs); 0 (default) = only at relevant events and the ends of each thread's chunk. A safety
  /// net for changes the relevance rules could miss; on the test scenes there are none (with 0 the walk finds every
  /// change and the interval checks find none it skipped), and a period p caps the gain over the baseline at p and
  /// costs a fifth of the sweeps at p = 64 on 644 vertices.
  int resweep_period = 0;
  /// Kinetic walk: an event counts where its sources are any vertex of the last swept slice's regions (the broad
  /// rule, kept to compare), instead of only where they are the sources or ends of its free edges, plus the `along`
  /// vgraph events whose static segment meets a region (default; docs/planning_nondirectional.md says why).
  bool vertex_events = false;
  /// Kinetic walk: an event of a free edge passing a point, or of a free vertex crossing an edge, counts only where
  /// that point lies on the boundary of the last swept slice's regions carried to the event (besides its sources
  /// being the regions'); false: wherever its sources are (the rule before, kept to compare).
  bool boundary_events = true;
  /// Kinetic walk: where a sweep after a relevant event differs from the last one by exactly the local edit that event
  /// makes (one static or free edge coming or going at its point), the change is put there without sweeping just
  /// before the event to confirm it; false: always confirmed by a sweep (kept to compare).
  bool local_edits = true;
  /// Kinetic walk: at a relevant event that is one free vertex crossing a static edge, or one free edge passing a
  /// C-obstacle vertex, compute the slice after it from the last one instead of sweeping, where the change there is
  /// one of the local edits that bring no new chain (an edge coming or going, a run cut off; the rest is carried:
  /// docs/planning_nondirectional.md, "Computing the slice after a change"); false: always sweep (kept to compare).
  bool computed_updates = true;
  /// With computed_updates: sweep as well, count the computed slices that differ (stats.update_mismatches), and go on
  /// with the sweep. For the tests.
  bool check_updates = false;
  /// Kinetic walk: list the events of ray points (CandidateScope, critical.h) only for the ray points the walk's
  /// slices have as event points: walk with the others' events, and where a slice had ray points not listed, list
  /// their events too and walk again (the backprojections already swept are reused). false: list every candidate
  /// (the full listing, kept to compare; docs/planning_nondirectional.md, "Ray points' events on demand").
  bool ray_events_on_demand = true;
  /// With ray_events_on_demand: only where the ray points times the points come to this many or more; a smaller
  /// scene lists every candidate (its listing costs less than a second walk would).
  double ray_events_min_pairs = 1e4;
  /// The candidates the problem's C-obstacles and bounds make among themselves, listed once for problems that share
  /// them (ListStaticCandidates, critical.h; the multi-step search's children): taken instead of listed again where
  /// they fit the problem. Null: every candidate is listed.
  std::shared_ptr<const StaticCandidates> static_candidates;
  /// Called now and then with the fraction done (0..1), from the calling thread.
  std::function<void(double)> progress;
  /// When it points to true the computation ends at its next backprojection, throwing NondirectionalStopped (the
  /// planner's memory limit sets it from another thread).
  const std::atomic<bool>* stop = nullptr;
};

/// Computes the nondirectional backprojection of `problem` (problem.theta ignored). `start` (may be null) adds its
/// R-critical orientations. @throws std::invalid_argument like ClassicBackprojection.
NondirectionalBackprojection ComputeNondirectional(const BackprojectionProblem& problem, const NamedPolygon* start,
                                                   const NondirectionalOptions& options = {});

/// The slice that stands for θ (a critical slice when θ is within 1e-12 of its orientation).
const Slice& SliceAt(const NondirectionalBackprojection& nd, double theta);

/// `region`, a backprojection computed at some θ₀, carried to θ = `theta` without a sweep (Briggs's
/// rotating free vertices): every free edge turns about its source (RegionEdge::source) to direction θ + π ± ε_v, the
/// other edges stay on their lines, and each vertex is recomputed as the meeting point of its two edges' lines (a
/// vertex between two non-free edges stays). Between two consecutive critical orientations the structure does not
/// change, so for θ₀ and θ inside one open slice's interval this is the region a sweep at `theta` gives, up to
/// rounding (`NondirectionalProperty.StructureIsConstantBetweenOrientations*` check it); across a critical orientation
/// it is not. The area is recomputed from the new vertices (in double precision).
Region CarryRegion(const Region& region, double theta, double velocity_cone);

/// B_θ(G) (`vc` false) or B_vcθ(G) with the slice's active rays at any θ: the critical slice's region at a critical
/// orientation, else the open slice's region carried to θ (no sweep).
Region RegionAt(const NondirectionalBackprojection& nd, double theta, bool vc);

/// A θ-interval [lo, hi] (radians; hi may exceed π when it wraps) on which R lies inside the region.
struct ThetaInterval {
  double lo = 0.0, hi = 0.0;
  double margin = 0.0;      ///< the largest, over the interval's sampled orientations, of R's distance to the boundary
  double best_theta = 0.0;  ///< where that margin was found
};

struct IntervalQueryStats {
  int pieces = 0;   ///< intervals decided (each at its midpoint)
  int carried = 0;  ///< of which by the slice's region carried there (RegionAt), without a sweep
};

/// Every θ-interval for which the closed polygon R lies inside B_vcθ(G) (`vc`) or B_θ(G): the slices' boundaries and
/// R's own R-critical orientations cut the circle into intervals on which containment does not change; each is
/// decided at its midpoint with the slice's active rays: by the slice's region carried there (RegionAt) where R is
/// clearly inside or outside (1e-6 of the scene's size from every edge that moves), else by a sweep. Endpoints are
/// exact up to the orientations' rounding.
std::vector<ThetaInterval> IntervalsContaining(const NondirectionalBackprojection& nd,
                                               const BackprojectionProblem& problem, const NamedPolygon& region,
                                               bool vc, IntervalQueryStats* stats = nullptr);

/// Whether the feature (one point, or the segment between two) meets the closure of the region: a point inside or
/// within `tolerance` of its boundary, or a segment crossing or within `tolerance` of a ring.
bool FeatureMeetsRegion(const std::vector<Eigen::Vector2d>& feature, const Region& region, double tolerance);

/// Whether the closed polygon R lies inside the region (every vertex inside or on the boundary within `tolerance`,
/// no edge crossing the boundary properly) and its clearance (the least distance of R's boundary to the region's
/// boundary other than C-obstacle edges: being near a wall is no risk, being near a free or bounds edge is).
bool RegionContainsPolygon(const Region& region, const std::vector<Eigen::Vector2d>& polygon, double tolerance,
                           double* clearance = nullptr);

}  // namespace visco::planning
