// The kinetic walk (kinetic_walk.h) and the entry points of nondirectional.h that run it.

#include "planning/nondirectional/kinetic_walk.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "planning/geometry.h"
#include "planning/nondirectional/carry.h"
#include "planning/nondirectional/computed_updates.h"
#include "planning/nondirectional/local_edit.h"
#include "planning/nondirectional/region_structure.h"
#include "planning/nondirectional/ring_geometry.h"
#include "planning/threads.h"

namespace visco::planning::internal {

NondirectionalBackprojection KineticWalk::Run() {
  NondirectionalBackprojection nd;
  nd.velocity_cone = pr_.velocity_cone;
  if (options_.method == SliceMethod::kKinetic && options_.computed_updates) {
    statics_ = StaticRegionEdges(pr_);
    crossed_ = RegionUpdater::Crossed(statics_, kOnBoundary * size_);
    // Every candidate ray, active or not: an event at a ray's end can also change which rays are chosen.
    for (const auto& ray : pr_.rays)
      ray_segments_.insert(ray_segments_.end(), ray.segments.begin(), ray.segments.end());
  }
  // The events of ray points are listed for the ray points the walk's slices have as event points: walk with what is
  // listed, and where the slices had others, list theirs too and walk again (the sweeps done are reused). The walk
  // takes an event only where its sources are the slice's event points, so the final walk has every event it can take.
  bool on_demand = options_.ray_events_on_demand && options_.method == SliceMethod::kKinetic;
  CandidateScope scope;
  scope.all = !on_demand;
  // Few pairs of a ray point and another point: the full listing costs less than a second walk would (slot, 26 ray
  // points of 52: 165 sweeps with it, 193 on demand). The listing decides it before listing anything.
  scope.all_below_pairs = options_.ray_events_min_pairs;
  std::set<size_t> listed;  // indices into ray_points_ (the same arrangement every time)
  std::vector<CriticalOrientation> r_candidates;
  std::vector<double> changes;
  std::vector<int> change_candidate;
  for (;;) {
    structural_ = CriticalCandidateList(pr_, start_, &nd.stats.counts, CandidateSearch::kIndexed, options_.stop,
                                        std::max(1, options_.threads), &scope, options_.static_candidates.get());
    on_demand = on_demand && structural_.scoped();
    nd.stats.candidates = static_cast<std::int64_t>(structural_.size());
    r_candidates = structural_.TakeKind(CriticalKind::kR);
    if (on_demand) ray_points_ = structural_.ray_points();
    needed_ray_points_.clear();
    Walk(changes, change_candidate);
    if (!on_demand ||
        std::includes(listed.begin(), listed.end(), needed_ray_points_.begin(), needed_ray_points_.end())) {
      break;
    }
    listed.insert(needed_ray_points_.begin(), needed_ray_points_.end());
    scope.ray_points.clear();
    for (const size_t i : listed) scope.ray_points.push_back(ray_points_[i]);
    ++nd.stats.walks;
  }
  nd.stats.ray_points_listed = static_cast<std::int64_t>(listed.size());
  // Final slices.
  std::vector<std::pair<double, int>> order;
  for (size_t i = 0; i < changes.size(); ++i) order.push_back({changes[i], change_candidate[i]});
  std::sort(order.begin(), order.end());
  order.erase(std::unique(order.begin(), order.end(),
                          [](const auto& x, const auto& y) { return y.first - x.first <= kSameTheta; }),
              order.end());
  const size_t n = order.size();
  nd.slices.resize(n == 0 ? 1 : 2 * n);
  ParallelFor(nd.slices.size(), options_.threads, options_.progress, 0.85, 0.15, [&](size_t s) {
    if (n == 0) {
      nd.slices[0] = Evaluate(0.0, kSweepSlices);
      nd.slices[0].lo = -M_PI;
      nd.slices[0].hi = M_PI;
      return;
    }
    const size_t k = s / 2;
    const double lo = order[k].first;
    const double hi = k + 1 < n ? order[k + 1].first : order[0].first + 2 * M_PI;
    if (s % 2 == 0) {
      nd.slices[s] = Evaluate(lo, kSweepSlices);
      nd.slices[s].lo = nd.slices[s].hi = lo;
      nd.slices[s].critical = true;
    } else {
      // The interval checks swept its midpoint already when it was last probed.
      const auto cached = midpoints_.find({lo, hi});
      nd.slices[s] = cached != midpoints_.end() ? std::move(cached->second)
                                                : Evaluate(WrapAngle(lo + 0.5 * (hi - lo)), kSweepSlices);
      nd.slices[s].lo = lo;
      nd.slices[s].hi = hi;
    }
  });
  for (const auto& [theta, c] : order) {
    CriticalOrientation o;
    o.theta = theta;
    if (c >= 0) {
      o.kind = structural_.kind(static_cast<size_t>(c));
      o.refs = structural_.Refs(static_cast<size_t>(c));
      o.sliding = structural_.sliding(static_cast<size_t>(c));
    } else {
      o.kind = CriticalKind::kSelection;
      o.refs = selection_refs_[theta];
    }
    nd.orientations.push_back(o);
    ++nd.stats.changes;
    if (c < 0) ++nd.stats.selection;
  }
  // R-critical orientations of the start region where their sources are vertices of the regions there.
  for (int i = 0; i < kSweepPurposes; ++i) {
    nd.stats.sweeps[i] = sweeps_[i].load();
    nd.stats.sweep_seconds[i] = 1e-9 * static_cast<double>(sweep_ns_[i].load());
    nd.stats.backprojections += nd.stats.sweeps[i];
  }
  nd.stats.checked = checked_;
  nd.stats.events = static_cast<std::int64_t>(events_.size());
  nd.stats.unexplained = unexplained_;
  nd.stats.found_by_probes = found_by_probes_;
  nd.stats.rule_missed = rule_missed_;
  nd.stats.explained = explained_;
  nd.stats.updated = updated_.load();
  nd.stats.update_mismatches = update_mismatches_.load();
  nd.stats.rule_missed_sliding = rule_missed_sliding_;
  nd.stats.reused = reused_.load();
  nd.stats.unexplained_at = unexplained_at_;
  for (auto& c : r_candidates) {
    const Slice& s = SliceAt(nd, c.theta);
    if (!Relevant(c, EventPointsOf(s))) continue;
    c.sources.clear();
    nd.orientations.push_back(std::move(c));
    ++nd.stats.r_critical;
  }
  std::stable_sort(nd.orientations.begin(), nd.orientations.end(),
                   [](const CriticalOrientation& x, const CriticalOrientation& y) { return x.theta < y.theta; });
  for (auto& o : nd.orientations) o.sources.clear();
  swept_by_theta_.clear();
  return nd;
}

void KineticWalk::Walk(std::vector<double>& changes, std::vector<int>& change_candidate) {
  changes.clear();
  change_candidate.clear();
  events_.clear();
  checked_ = unexplained_ = found_by_probes_ = rule_missed_ = explained_ = rule_missed_sliding_ = 0;
  unexplained_at_.clear();
  selection_refs_.clear();
  midpoints_.clear();
  updated_ = 0;
  update_mismatches_ = 0;
  // Events: groups of structural candidates at (nearly) one θ.
  for (size_t i = 0; i < structural_.size();) {
    size_t j = i + 1;
    while (j < structural_.size() && structural_.theta(j) - structural_.theta(j - 1) <= kSameTheta) ++j;
    events_.push_back({static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j)});
    i = j;
  }
  // Interval k's structure is that of intervals[source[k]] (the last swept interval up to k).
  std::vector<std::uint32_t> source;
  const SweptSlices intervals = IntervalSlices(source);
  // Orientations where the interval structure changes.
  const size_t m = events_.size();
  for (size_t k = 0; k < m && m > 1; ++k) {
    const size_t b = source[(k + m - 1) % m], a = source[k];
    if (a == b) continue;  // no sweep in between: the same structure
    const Slice& before = intervals.at(b);
    const Slice& after = intervals.at(a);
    if (before.structure == after.structure) continue;
    if (const auto rays = RaySwitchInGap(k, before, after)) {
      AddSelection(*rays, changes, change_candidate);
      continue;
    }
    changes.push_back(EventTheta(k));
    change_candidate.push_back(PickCandidate(k, before, after));
    NoteRayPoints(EventPointsOf(before));  // PickCandidate's rule: every vertex
    NoteRayPoints(EventPointsOf(after));
    RaySwitchesBeside(k, before, after, changes, change_candidate);
    // The rule judged against the true structure before the event: a change it would skip was found only by the
    // walk's later sweeps (docs/planning_nondirectional.md argues there is none with the same chosen rays; a switch
    // of the rays can follow from an event in a ray's trial region, outside the regions the rule looks at).
    if (options_.method == SliceMethod::kKinetic && before.structure.active_rays == after.structure.active_rays &&
        !EventRelevant(k, WalkPointsOf(before), before)) {
      ++rule_missed_;
      bool sliding = false;
      for (size_t i = events_[k].begin; i < events_[k].end; ++i) {
        sliding = sliding || structural_.kind(i) == CriticalKind::kSliding;
      }
      if (sliding) ++rule_missed_sliding_;
    }
  }
  Verify(changes, change_candidate, intervals, source);
}

Slice KineticWalk::Evaluate(double theta, SweepPurpose purpose) {
  if (options_.stop != nullptr && options_.stop->load(std::memory_order_relaxed)) throw NondirectionalStopped();
  if (!ray_points_.empty()) {  // an earlier walk may have swept here
    std::unique_lock<std::mutex> lock(swept_mutex_);
    if (const auto it = swept_by_theta_.find(theta); it != swept_by_theta_.end()) {
      Slice s = it->second;
      lock.unlock();
      ++reused_;
      NoteRayPoints(WalkPointsOf(s));
      return s;
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  BackprojectionProblem p = pr_;
  p.theta = theta;
  Slice s;
  s.theta = theta;
  s.lo = s.hi = theta;
  s.vc = VcEnlargedBackprojection(p, options_.selection);
  s.structure.classic = RegionStructure(s.vc.classic);
  s.structure.vc = RegionStructure(s.vc.region);
  s.structure.active_rays = s.vc.active_rays;
  ++sweeps_[purpose];
  sweep_ns_[purpose] +=
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count();
  if (!ray_points_.empty()) {
    NoteRayPoints(WalkPointsOf(s));
    const std::lock_guard<std::mutex> lock(swept_mutex_);
    swept_by_theta_.emplace(theta, s);
  }
  return s;
}

void KineticWalk::RaySwitchesBeside(size_t k, const Slice& before, const Slice& after, std::vector<double>& changes,
                                    std::vector<int>& change_candidate) {
  if (before.structure.active_rays == after.structure.active_rays) return;
  const double at = EventTheta(k);
  const double dt = StepBeside(k);  // as RaySwitchInGap (the slices there are reused or swept again)
  if (!(dt > 0)) return;
  const SliceStructure left = Evaluate(WrapAngle(at - dt), kSweepBisect).structure;
  const SliceStructure right = Evaluate(WrapAngle(at + dt), kSweepBisect).structure;
  std::vector<Switch> found;
  if (left.active_rays != before.structure.active_rays) {
    found.push_back(Bisect(Unwrap(before.theta, at - 2 * M_PI), at - dt, before.structure));
  }
  if (right.active_rays != after.structure.active_rays) {
    found.push_back(Bisect(at + dt, Unwrap(after.theta, at), right));
  }
  for (const Switch& s : found) {
    if (s.before.active_rays != s.after.active_rays) AddSelection(s, changes, change_candidate);
  }
}

void KineticWalk::NoteRayPoints(const std::vector<EventPoint>& points) const {
  if (ray_points_.empty()) return;
  const double tol = 1e-9 * size_;  // IsEventPoint's match in Relevant
  std::vector<size_t> found;
  for (const EventPoint& e : points) {
    for (auto it = std::lower_bound(ray_points_.begin(), ray_points_.end(), e.p.x() - tol,
                                    [](const Vector2d&r, double x) { return r.x() < x; });
         it != ray_points_.end() && it->x() <= e.p.x() + tol; ++it) {
      if ((*it - e.p).norm() <= tol) found.push_back(static_cast<size_t>(it - ray_points_.begin()));
    }
  }
  if (found.empty()) return;
  const std::lock_guard<std::mutex> lock(ray_points_mutex_);
  needed_ray_points_.insert(found.begin(), found.end());
}

std::optional<Slice> KineticWalk::Updated(size_t k, const Slice& last, const std::vector<EventPoint>& ends) const {
  CarriedAt carried(last, EventTheta(k), pr_.velocity_cone);
  const CriticalOrientation* only = nullptr;
  CriticalOrientation c, one;
  for (size_t i = events_[k].begin; i < events_[k].end; ++i) {
    structural_.Get(i, c, false);
    if (!CanChange(c, ends, last, carried)) continue;
    if (only != nullptr) return std::nullopt;  // several events at once
    std::swap(one, c);
    only = &one;
  }
  if (only == nullptr || (only->kind != CriticalKind::kVertex && only->kind != CriticalKind::kVgraph)) {
    return std::nullopt;
  }
  const double theta = IntervalTheta(k);
  const RegionUpdater updater(statics_, crossed_, kOnBoundary * size_, pr_.velocity_cone);
  Slice s;
  s.theta = s.lo = s.hi = theta;
  s.vc.active_rays = last.vc.active_rays;
  s.vc.rejected_rays = last.vc.rejected_rays;
  s.vc.unreliable_rays = last.vc.unreliable_rays;
  s.vc.selection = last.vc.selection;
  s.vc.candidates = last.vc.candidates;
  bool edited = false;
  for (int r = 0; r < 2; ++r) {
    const Region& region = r == 0 ? last.vc.classic : last.vc.region;
    Region& out = r == 0 ? s.vc.classic : s.vc.region;
    switch (updater.Apply(*only, region, carried.Get()[static_cast<size_t>(r)], theta,
                          r == 0 ? std::vector<std::array<Vector2d, 2>>{} : ray_segments_, out)) {
      case Update::kUnknown:
        return std::nullopt;
      case Update::kUnchanged:
        out = CarryRegion(region, theta, pr_.velocity_cone);
        break;
      case Update::kEdited:
        edited = true;
        break;
    }
  }
  if (!edited) return std::nullopt;
  s.structure.classic = RegionStructure(s.vc.classic);
  s.structure.vc = RegionStructure(s.vc.region);
  s.structure.active_rays = s.vc.active_rays;
  NoteRayPoints(WalkPointsOf(s));
  return s;
}

bool KineticWalk::ExplainedAt(size_t k, const Slice& before, const Slice& after) const {
  if (before.structure.active_rays != after.structure.active_rays) return false;
  const double tol = 1e-9 * size_;
  for (const bool vc : {false, true}) {
    const auto& sb = vc ? before.structure.vc : before.structure.classic;
    const auto& sa = vc ? after.structure.vc : after.structure.classic;
    if (sb == sa) continue;
    const auto edit =
        OneRingChanged(vc ? before.vc.region : before.vc.classic, vc ? after.vc.region : after.vc.classic, sb, sa);
    if (!edit) return false;
    bool made = false;
    CriticalOrientation c;
    for (size_t i = events_[k].begin; i < events_[k].end && !made; ++i) {
      structural_.Get(i, c, false);
      made = MakesEdit(c, *edit, tol);
    }
    if (!made) return false;
  }
  return true;
}

std::pair<double, double> KineticWalk::EventInterval(size_t k) const {
  return {EventTheta(k), k + 1 < events_.size() ? EventTheta(k + 1) : EventTheta(0) + 2 * M_PI};
}

double KineticWalk::IntervalTheta(size_t k) const {
  const auto [lo, hi] = EventInterval(k);
  return WrapAngle(0.5 * (lo + hi));
}

KineticWalk::SweptSlices KineticWalk::IntervalSlices(std::vector<std::uint32_t>& source) {
  const size_t m = events_.size();
  source.resize(m);
  for (size_t k = 0; k < m; ++k) source[k] = static_cast<std::uint32_t>(k);
  SweptSlices all;
  if (m <= 1) {
    if (m == 1) all.emplace(0, Evaluate(IntervalTheta(0), kSweepWalk));
    return all;
  }
  if (options_.method == SliceMethod::kBaseline) {
    checked_ = static_cast<std::int64_t>(m);
    std::vector<Slice> out(m);
    ParallelFor(m, options_.threads, options_.progress, 0.0, 0.7,
                [&](size_t k) { out[k] = Evaluate(IntervalTheta(k), kSweepWalk); });
    for (size_t k = 0; k < m; ++k) all.emplace(k, std::move(out[k]));
    return all;
  }
  // Chunks of events walked independently (one per thread), each starting from a swept interval. An event is
  // swept again when it is relevant, and every `resweep_period` events anyway; when the structure differs from the
  // last swept interval's, the skipped events in between are bisected for where it changed (an event whose free
  // edges are the region's only after it is found that way).
  const size_t period = options_.resweep_period > 0 ? static_cast<size_t>(options_.resweep_period) : m;
  const size_t chunks = std::clamp<size_t>(static_cast<size_t>(std::max(1, options_.threads)), 1, m);
  std::vector<std::int64_t> checked(chunks, 0), explained(chunks, 0);
  std::vector<char> swept(m, 0);
  std::vector<SweptSlices> chunk_slices(chunks);
  ParallelFor(chunks, options_.threads, options_.progress, 0.0, 0.7, [&](size_t c) {
    const size_t begin = m * c / chunks, end = m * (c + 1) / chunks;
    SweptSlices& out = chunk_slices[c];  // a chunk reads and sweeps only its own events
    auto sweep = [&](size_t k, SweepPurpose purpose) {
      out[k] = Evaluate(IntervalTheta(k), purpose);
      swept[k] = 1;
      ++checked[c];
    };
    // The slice after relevant event k, from the last one: computed where the update knows the event's edit, else
    // swept. With check_updates it is swept as well, and the walk goes on with the sweep.
    auto advance = [&](size_t k, size_t last, const std::vector<EventPoint>& ends) {
      if (options_.computed_updates && !statics_.empty()) {
        if (auto updated = Updated(k, out[last], ends)) {
          ++updated_;
          if (!options_.check_updates) {
            out[k] = std::move(*updated);
            swept[k] = 1;
            return;
          }
          sweep(k, kSweepWalk);
          const double tol = 1e-9 * size_ * size_;
          if (!(updated->structure == out[k].structure) ||
              std::abs(updated->vc.classic.area - out[k].vc.classic.area) > tol ||
              std::abs(updated->vc.region.area - out[k].vc.region.area) > tol) {
            ++update_mismatches_;
          }
          return;
        }
      }
      sweep(k, kSweepWalk);
    };
    // Finds every change between swept intervals lo < hi whose structures differ.
    std::function<void(size_t, size_t)> bisect = [&](size_t lo, size_t hi) {
      if (hi - lo <= 1) return;
      const size_t mid = lo + (hi - lo) / 2;
      sweep(mid, kSweepLocate);
      if (!(out[mid].structure == out[lo].structure)) bisect(lo, mid);
      if (!(out[mid].structure == out[hi].structure)) bisect(mid, hi);
    };
    // Most changes are at the event just swept (it was swept because it is relevant): the interval before it
    // tells at once, instead of a bisection of the whole gap.
    auto locate = [&](size_t lo, size_t hi) {
      if (hi - lo >= 2 && options_.local_edits && ExplainedAt(hi, out[lo], out[hi])) {
        ++explained[c];
        return;  // the change is event hi's own local edit
      }
      if (hi - lo <= 2) return bisect(lo, hi);
      sweep(hi - 1, kSweepLocate);
      if (out[hi - 1].structure == out[lo].structure) return;  // the change is at event hi alone
      bisect(lo, hi - 1);
    };
    // Where the structure differs between swept intervals lo < hi: the changes located, then every stretch between
    // two swept intervals walked again with the free edges of the slice that begins it. The events there were
    // skipped for the free edges of the slice at lo; a change found in between can give the region free edges
    // (and so relevant events) it did not have at lo, and a bisection alone misses a structure that comes and
    // goes again between two equal ends (VISCO_SEED_OFFSET=19507001, strategy seed 11: free edges appeared at
    // 54.2°, their free vertex crossed the bounds at 78.3° and back at 152.2°, and the walk, which had skipped
    // those events before the free edges were found, never swept between them).
    std::function<void(size_t, size_t)> walk;
    auto resolve = [&](size_t lo, size_t hi) {
      locate(lo, hi);
      size_t p = lo;
      for (size_t q = lo + 1; q <= hi; ++q) {
        if (!swept[q]) continue;
        if (q - p > 1) walk(p, q);
        p = q;
      }
    };
    // The events strictly between swept intervals lo < hi, under the free edges of each last swept slice.
    walk = [&](size_t lo, size_t hi) {
      size_t last = lo;
      std::vector<EventPoint> ends = WalkPointsOf(out[lo]);
      for (size_t k = lo + 1; k < hi; ++k) {
        if (swept[k] || !EventRelevant(k, ends, out[last])) continue;
        advance(k, last, ends);
        if (!(out[k].structure == out[last].structure)) resolve(last, k);
        last = k;
        ends = WalkPointsOf(out[k]);
      }
      if (last != lo && !(out[hi].structure == out[last].structure)) resolve(last, hi);
    };
    sweep(begin, kSweepWalk);
    std::vector<EventPoint> ends = WalkPointsOf(out[begin]);
    size_t last = begin;
    for (size_t k = begin + 1; k < end; ++k) {
      if (!EventRelevant(k, ends, out[last]) && k - last < period && k + 1 < end) continue;
      advance(k, last, ends);
      if (!(out[k].structure == out[last].structure)) resolve(last, k);
      last = k;
      ends = WalkPointsOf(out[k]);
    }
    // Intervals not swept have the structure of the last swept one before them (not copied: at thousands of
    // events the copies of large structures cost more memory and time than the sweeps).
    size_t from = begin;
    for (size_t k = begin + 1; k < end; ++k) {
      if (swept[k]) from = k;
      source[k] = static_cast<std::uint32_t>(from);
    }
  });
  for (auto c : checked) checked_ += c;
  for (auto c : explained) explained_ += c;
  for (auto& slices : chunk_slices) all.merge(slices);
  return all;
}

}  // namespace visco::planning::internal

namespace visco::planning {

const char* SweepPurposeName(SweepPurpose purpose) {
  static const char* const kNames[kSweepPurposes] = {"walk", "locate", "checks", "bisect", "slices"};
  return purpose < kSweepPurposes ? kNames[purpose] : "?";
}

NondirectionalBackprojection ComputeNondirectional(const BackprojectionProblem& problem, const NamedPolygon* start,
                                                   const NondirectionalOptions& options) {
  // Every sweep of the walk (hundreds, at as many θ) maps one overlay of the statics instead of building its own.
  BackprojectionProblem prepared = problem;
  PrepareStaticOverlay(prepared);
  return internal::KineticWalk(prepared, start, options).Run();
}
}  // namespace visco::planning
