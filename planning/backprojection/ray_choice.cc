// The ray choice of B_vcθ(G) (ray_choice.h; backprojection.h, VcEnlargedBackprojection).

#include "planning/backprojection/ray_choice.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace visco::planning::internal {

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
bool LargerArea(const SweepResult& a, const SweepResult& b) {
  return a.region.area > b.region.area * (1 + 1e-12) + 1e-15;
}

bool ContainsSet(const PolygonSet& set, const std::vector<ExactRing>& rings) {
  PolygonSet diff = set;
  diff.difference(ToPolygonSet(rings));
  return diff.is_empty();
}

bool AdoptIfLarger(const BackprojectionProblem& problem, SweepFrame& frame, const std::vector<int>& set,
                   SweepResult& current, PolygonSet& current_set, int& sweeps) {
  SweepResult trial = RunSweep(problem, set, frame);
  ++sweeps;
  if (!LargerArea(trial, current) || !ContainsSet(current_set, trial.rings)) return false;
  current = std::move(trial);
  current_set = ToPolygonSet(current.rings);
  return true;
}

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

namespace {
// The end of ray segment `s` that complying down it leads to (the end further along θ).
int Destination(const std::array<Vector2d, 2>& s, double theta) {
  return (s[1] - s[0]).dot(Vector2d(std::cos(theta), std::sin(theta))) > 0 ? 1 : 0;
}

// True if no segment of ray c meets the goal (boxes: conservative) or an active ray: complying down it runs to the
// segment's destination end.
bool MeetsOnlyItsEnds(const BackprojectionProblem& problem, int c, const std::vector<int>& active) {
  const CvcRayInput& ray = problem.rays[c];
  for (const auto& s : ray.segments) {
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
}  // namespace

bool LeadsOnlyToOpenEnds(const BackprojectionProblem& problem, int c, const std::vector<int>& active) {
  const CvcRayInput& ray = problem.rays[c];
  for (size_t k = 0; k < ray.segments.size(); ++k) {
    if (k >= ray.open_ends.size() || !ray.open_ends[k][Destination(ray.segments[k], problem.theta)]) return false;
  }
  return MeetsOnlyItsEnds(problem, c, active);
}

bool LandsOnlyOutside(const BackprojectionProblem& problem, int c, const std::vector<int>& active,
                      const Region& region) {
  const CvcRayInput& ray = problem.rays[c];
  const double margin = kLandingMargin * (problem.bounds_max - problem.bounds_min).norm();
  for (size_t k = 0; k < ray.segments.size(); ++k) {
    const int destination = Destination(ray.segments[k], problem.theta);
    if (k < ray.open_ends.size() && ray.open_ends[k][destination]) continue;
    const Vector2d& end = ray.segments[k][destination];
    if (region.Contains(end) || region.BoundaryDistance(end) <= margin) return false;
  }
  return MeetsOnlyItsEnds(problem, c, active);
}

std::vector<int> TrackSelection(const BackprojectionProblem& problem, SweepFrame& frame,
                                const std::vector<int>& candidates, SweepResult& current, int& sweeps,
                                bool skip_open_ended, bool skip_outside_landings) {
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
    // Its sweep could not be adopted: with c active no point joins the region.
    if (skip_open_ended && LeadsOnlyToOpenEnds(problem, c, active)) continue;
    if (skip_outside_landings && LandsOnlyOutside(problem, c, active, current.region)) continue;
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

}  // namespace visco::planning::internal

namespace visco::planning {

using namespace internal;  // NOLINT(google-build-using-namespace): the ray choice's own internals

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
    active = TrackSelection(problem, frame, candidates, result, out.sweeps, options.skip_open_ended,
                            options.skip_outside_landings);
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

}  // namespace visco::planning
