#pragma once
// The nondirectional backprojection's computation (ComputeNondirectional, nondirectional.h): the kinetic walk over the
// candidate orientations in θ order, sweeping again only after the events that can change the last slice's regions
// (relevant_events.cc) or computing the slice after one (computed_updates.h); with SliceMethod::kBaseline a sweep in
// every interval instead. Then the interval checks (interval_checks.cc) and the final slices. Internal; in a header
// so that it can be unit tested.

#include <Eigen/Core>
#include <array>
#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "planning/nondirectional.h"
#include "planning/nondirectional/event_points.h"

namespace visco::planning::internal {

using Eigen::Vector2d;

class KineticWalk {
 public:
  KineticWalk(const BackprojectionProblem& problem, const NamedPolygon* start, const NondirectionalOptions& options)
      : pr_(problem), start_(start), options_(options) {
    size_ = (problem.bounds_max - problem.bounds_min).norm();
  }

  NondirectionalBackprojection Run();

 private:
  struct Event {
    std::uint32_t begin, end;  // candidates [begin, end)
  };

  double EventTheta(size_t k) const { return structural_.theta(events_[k].begin); }

  Slice Evaluate(double theta, SweepPurpose purpose);

  // One walk over the listed candidates: the changes it finds (θ, and the candidate reported or −1 for a switch of
  // the chosen rays), checked (Verify).
  void Walk(std::vector<double>& changes, std::vector<int>& change_candidate);

  // Records the ray points (CandidateScope) that are event points of `points` (within the walk's match of a source).
  void NoteRayPoints(const std::vector<EventPoint>& points) const;

  // Where events can change the slice's regions (both of them).
  std::vector<EventPoint> EventPointsOf(const Slice& s) const;

  // The points the kinetic walk's rule looks at (every vertex of the regions with the broad rule).
  std::vector<EventPoint> WalkPointsOf(const Slice& s) const;

  // An event matters only where every free edge it involves can be one of the regions' (a free vertex needs both):
  // each source is a vertex of the regions, or the source of one of their free edges with the same sign.
  bool Relevant(const CriticalOrientation& c, const std::vector<EventPoint>& ends) const;

  // A slice's regions carried to an event's orientation, computed when first asked for (most events are decided by
  // their sources alone).
  class CarriedAt {
   public:
    CarriedAt(const Slice& s, double theta, double eps) : s_(s), theta_(theta), eps_(eps) {}
    const std::array<Region, 2>& Get() {
      if (!regions_) {
        regions_ = {CarryRegion(s_.vc.classic, theta_, eps_), CarryRegion(s_.vc.region, theta_, eps_)};
      }
      return *regions_;
    }

   private:
    const Slice& s_;
    double theta_, eps_;
    std::optional<std::array<Region, 2>> regions_;
  };

  // Whether candidate c can change the structure of slice s (whose event points are `ends`; `carried` is s carried to
  // the event): a sliding event only where its edge or vertex meets the closure of a region, the others where their
  // sources are event points and, with `boundary_events`, their point lies on the boundary of a carried region.
  bool CanChange(const CriticalOrientation& c, const std::vector<EventPoint>& ends, const Slice& s,
                 CarriedAt& carried) const;

  // Whether event k can change the structure of `current` (the last swept slice, whose event points are `ends`).
  bool EventRelevant(size_t k, const std::vector<EventPoint>& ends, const Slice& current) const;

  // The slice after event k computed from `last` (the last slice before it, swept or computed) without a sweep, where
  // the event is one candidate whose local edit the updater knows and that edit is confirmed; nullopt otherwise.
  // `ends`: last's walk points (the walk has them already).
  std::optional<Slice> Updated(size_t k, const Slice& last, const std::vector<EventPoint>& ends) const;

  // Whether the change between `before` and `after` (swept with no event but k between them that the rule takes) is
  // a local edit event k makes (MakesEdit), in each region that changes, with the same active rays: then it happened
  // at k, and no sweep just before k needs to say so. A change at a skipped event would add an edit of its own.
  bool ExplainedAt(size_t k, const Slice& before, const Slice& after) const;

  // The interval after event k: from its θ to event k + 1's (the last one wraps to the first, a turn on).
  std::pair<double, double> EventInterval(size_t k) const;

  // The representative θ of the interval after event k.
  double IntervalTheta(size_t k) const;

  // The swept intervals' slices, by event index (a large scene has millions of events and sweeps a few hundred).
  using SweptSlices = std::unordered_map<size_t, Slice>;

  // One slice per interval between consecutive events: every one swept (baseline) or only after relevant events
  // (kinetic; the others inherit the previous interval's slice: source[k] is the swept interval whose slice interval
  // k has).
  SweptSlices IntervalSlices(std::vector<std::uint32_t>& source);

  // The candidate of event k to report: the first whose sources are vertices on either side.
  int PickCandidate(size_t k, const Slice& before, const Slice& after) const;

  // θ (radians) moved by whole turns to the first value not below `from`.
  static double Unwrap(double theta, double from);

  // A change located between two sweeps: where (θ, wrapped) and the structures on its two sides.
  struct Switch {
    double theta = 0.0;
    SliceStructure before, after;
  };

  // Bisects x < y (radians, unwrapped; the structure is `sx` at x and differs at y) to 1e-12 rad for where it changes.
  Switch Bisect(double x, double y, const SliceStructure& sx);

  // The chosen rays can switch between two events (the choice compares areas; no event bounds it): the walk's slices
  // on the two sides of event k then differ although nothing happens at k. Where the rays differ and nothing changes
  // just beside k, the gap is bisected for the switch (after k, towards the gap's midpoint where `after` was swept, or
  // before it); a change there that is not the rays' stays with event k.
  std::optional<Switch> RaySwitchInGap(size_t k, const Slice& before, const Slice& after);
  /// The step from event k to the orientations just beside it: 1e-9 rad, or a quarter of the smaller gap to its
  /// neighbouring events (0 when two events coincide).
  double StepBeside(size_t k) const;

  // Event k changes the structure and the chosen rays differ between the slices on its two sides: where the rays
  // just beside k are not those of the slice on that side, they switch again within the gap (between two sweeps, so
  // with the event's own change the walk would take the two for one), and each switch is bisected and reported.
  void RaySwitchesBeside(size_t k, const Slice& before, const Slice& after, std::vector<double>& changes,
                         std::vector<int>& change_candidate);

  // Reports a switch of the chosen rays as a `selection` orientation, naming the rays that come or go.
  void AddSelection(const Switch& s, std::vector<double>& changes, std::vector<int>& change_candidate);

  // The candidate within `tolerance` of θ, or −1.
  int NearestCandidate(double theta, double tolerance) const;

  // The event interval containing θ (radians, any turn): k such that θ lies between events k and k + 1 (wrapping).
  size_t EventIntervalAt(double theta) const;

  // Records the change located between two sweeps (a switch of the chosen rays, or a change at the nearest
  // candidate, which the walk had skipped, or at none).
  void AddFound(const Switch& s, std::vector<double>& changes, std::vector<int>& change_candidate);

  // Checks every interval between consecutive changes at three orientations and locates any change found there.
  void Verify(std::vector<double>& changes, std::vector<int>& change_candidate, const SweptSlices& intervals,
              const std::vector<std::uint32_t>& source);

  const BackprojectionProblem& pr_;
  const NamedPolygon* start_;
  NondirectionalOptions options_;
  double size_ = 1.0;
  CandidateList structural_;  // the candidates but the R-critical ones, compact (critical.h)
  std::vector<Event> events_;
  std::array<std::atomic<std::int64_t>, kSweepPurposes> sweeps_{};
  std::array<std::atomic<std::int64_t>, kSweepPurposes> sweep_ns_{};
  std::int64_t checked_ = 0;
  std::int64_t unexplained_ = 0;
  std::int64_t found_by_probes_ = 0;
  std::int64_t rule_missed_ = 0;
  std::int64_t explained_ = 0;
  std::int64_t rule_missed_sliding_ = 0;
  std::vector<double> unexplained_at_;
  std::map<double, std::vector<std::string>> selection_refs_;
  std::map<std::pair<double, double>, Slice> midpoints_;  // the last interval checks' midpoint slices, by (lo, hi)
  std::vector<RegionEdge> statics_;                       // the static edges events can bring (computed_updates)
  std::set<std::string> crossed_;                         // of those, the ones another meets (RegionUpdater::Crossed)
  std::vector<std::array<Vector2d, 2>> ray_segments_;     // every candidate ray's segments (computed_updates)
  std::atomic<std::int64_t> updated_{0}, update_mismatches_{0};
  // Ray events on demand: every ray point of the arrangement (sorted by x), the ones the walk's slices had as event
  // points (indices into it), and the backprojections swept so far by θ (a later walk sweeps mostly where the one
  // before did).
  std::vector<Vector2d> ray_points_;
  mutable std::mutex ray_points_mutex_;
  mutable std::set<size_t> needed_ray_points_;
  std::mutex swept_mutex_;
  std::map<double, Slice> swept_by_theta_;
  std::atomic<std::int64_t> reused_{0};
};

}  // namespace visco::planning::internal
