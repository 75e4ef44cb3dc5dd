// The interval checks (kinetic_walk.h): every interval between consecutive changes checked at more orientations,
// and a change found there located by bisection (a switch of the chosen rays, or a change the walk skipped).

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
#include "planning/nondirectional/kinetic_walk.h"
#include "planning/threads.h"

namespace visco::planning::internal {

double KineticWalk::Unwrap(double theta, double from) {
  while (theta < from) theta += 2 * M_PI;
  while (theta - 2 * M_PI >= from) theta -= 2 * M_PI;
  return theta;
}

KineticWalk::Switch KineticWalk::Bisect(double x, double y, const SliceStructure& sx) {
  for (int it = 0; it < 60 && y - x > 1e-12; ++it) {
    const double mid = 0.5 * (x + y);
    if (Evaluate(WrapAngle(mid), kSweepBisect).structure == sx) {
      x = mid;
    } else {
      y = mid;
    }
  }
  return {WrapAngle(0.5 * (x + y)), sx, Evaluate(WrapAngle(y), kSweepBisect).structure};
}

double KineticWalk::StepBeside(size_t k) const {
  const size_t m = events_.size();
  const double at = EventTheta(k);
  const double gap = std::min(at - EventTheta((k + m - 1) % m) + (k == 0 ? 2 * M_PI : 0.0),
                              EventTheta((k + 1) % m) - at + (k + 1 == m ? 2 * M_PI : 0.0));
  return std::min(1e-9, 0.25 * gap);
}

std::optional<KineticWalk::Switch> KineticWalk::RaySwitchInGap(size_t k, const Slice& before, const Slice& after) {
  if (before.structure.active_rays == after.structure.active_rays) return std::nullopt;
  const double at = EventTheta(k);
  const double dt = StepBeside(k);
  if (!(dt > 0)) return std::nullopt;
  const SliceStructure right = Evaluate(WrapAngle(at + dt), kSweepBisect).structure;
  if (!(Evaluate(WrapAngle(at - dt), kSweepBisect).structure == right)) return std::nullopt;
  const Switch s = right == after.structure ? Bisect(Unwrap(before.theta, at - 2 * M_PI), at - dt, before.structure)
                                            : Bisect(at + dt, Unwrap(after.theta, at), right);
  if (s.before.active_rays == s.after.active_rays) return std::nullopt;
  return s;
}

void KineticWalk::AddSelection(const Switch& s, std::vector<double>& changes, std::vector<int>& change_candidate) {
  changes.push_back(s.theta);
  change_candidate.push_back(-1);
  std::vector<std::string> refs;
  std::set_symmetric_difference(s.before.active_rays.begin(), s.before.active_rays.end(), s.after.active_rays.begin(),
                                s.after.active_rays.end(), std::back_inserter(refs));
  selection_refs_[s.theta] = refs;
}

int KineticWalk::NearestCandidate(double theta, double tolerance) const {
  int best = -1;
  double best_d = tolerance;
  for (size_t i = 0; i < structural_.size(); ++i) {
    const double d = std::abs(WrapAngle(structural_.theta(i) - theta));
    if (d <= best_d) {
      best_d = d;
      best = static_cast<int>(i);
    }
  }
  return best;
}

size_t KineticWalk::EventIntervalAt(double theta) const {
  theta = WrapAngle(theta);
  const auto first_not_before = std::partition_point(
      events_.begin(), events_.end(), [&](const Event& e) { return structural_.theta(e.begin) < theta; });
  // Before the first event: the wrapping interval after the last.
  const size_t after = static_cast<size_t>(first_not_before - events_.begin());
  return (after == 0 ? events_.size() : after) - 1;
}

void KineticWalk::AddFound(const Switch& s, std::vector<double>& changes, std::vector<int>& change_candidate) {
  const int c = NearestCandidate(s.theta, 1e-7);
  if (s.before.active_rays != s.after.active_rays) {
    AddSelection(s, changes, change_candidate);
    return;
  }
  changes.push_back(c >= 0 ? structural_.theta(static_cast<size_t>(c)) : s.theta);
  change_candidate.push_back(c >= 0 ? c : (structural_.empty() ? -1 : 0));
  if (c >= 0) ++found_by_probes_;
  if (c < 0) {
    ++unexplained_;
    unexplained_at_.push_back(s.theta);
  }
}

void KineticWalk::Verify(std::vector<double>& changes, std::vector<int>& change_candidate, const SweptSlices& intervals,
                         const std::vector<std::uint32_t>& source) {
  for (int round = 0; round < 4; ++round) {
    std::vector<std::pair<double, int>> order;
    for (size_t i = 0; i < changes.size(); ++i) order.push_back({changes[i], change_candidate[i]});
    std::sort(order.begin(), order.end());
    const size_t n = std::max<size_t>(order.size(), 1);
    struct Probe {
      double lo, hi;
      Slice s[3];
      bool disagreed = false;
    };
    std::vector<Probe> probes(n);
    const double fractions[3] = {0.3, 0.5, 0.7};
    ParallelFor(3 * n, options_.threads, options_.progress, 0.7 + 0.04 * round, 0.04, [&](size_t t) {
      const size_t k = t / 3;
      const double lo = order.empty() ? -M_PI : order[k].first;
      const double hi = order.empty() ? M_PI : (k + 1 < order.size() ? order[k + 1].first : order[0].first + 2 * M_PI);
      probes[k].lo = lo;
      probes[k].hi = hi;
      probes[k].s[t % 3] = Evaluate(WrapAngle(lo + fractions[t % 3] * (hi - lo)), kSweepChecks);
    });
    bool found = false;
    for (auto& p : probes) {
      // First round: each probe against the structure the walk gave its event interval (the walk swept there or
      // at an earlier event of the same stretch). A difference is a change the walk missed between that sweep and
      // the probe.
      for (int a = 0; a < 3 && round == 0 && !p.disagreed && events_.size() > 1; ++a) {
        const double theta = p.lo + fractions[a] * (p.hi - p.lo);
        const size_t k = EventIntervalAt(theta);
        // A switch of the chosen rays found inside this event interval: the walk's one structure for it holds
        // on one side of the switch only.
        const auto [event_lo, event_hi] = EventInterval(k);
        const double from = Unwrap(event_lo, theta - 2 * M_PI), to = from + (event_hi - event_lo);
        if (Unwrap(p.lo, from) < to || Unwrap(p.hi, from) < to) continue;
        const Slice& walk = intervals.at(source[k]);
        if (walk.structure == p.s[a].structure) continue;
        const double swept = Unwrap(walk.theta, p.lo);
        AddFound(swept < theta ? Bisect(swept, theta, walk.structure) : Bisect(theta, swept, p.s[a].structure), changes,
                 change_candidate);
        p.disagreed = true;
        found = true;
      }
      if (p.disagreed) continue;
      for (int a = 0; a < 2; ++a) {
        if (p.s[a].structure == p.s[a + 1].structure) continue;
        // Bisect between the two probes for where the structure changes.
        AddFound(Bisect(p.lo + fractions[a] * (p.hi - p.lo), p.lo + fractions[a + 1] * (p.hi - p.lo), p.s[a].structure),
                 changes, change_candidate);
        found = true;
        break;  // the rest of this interval is probed again next round
      }
    }
    // The midpoints, for the final open slices of the intervals that do not change any more.
    midpoints_.clear();
    for (auto& p : probes) midpoints_.emplace(std::make_pair(p.lo, p.hi), std::move(p.s[1]));
    if (!found) return;
  }
}

}  // namespace visco::planning::internal
