// The VC-enlarged backprojection's choice of active rays against a slow, obvious reference: on seeded random small
// scenes (at most 8 candidate rays), sweep the region of EVERY subset of the rays, keep the subsets whose region
// contains B_θ(G) (checked by vertical slabs in double precision, independently of the planner's exact polygon
// difference), and compare the largest area with the planner's. The chosen sets are also run through the motion
// model (soundness), and the exact choice is compared with the greedy one.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "common/motion_model.h"
#include "planning/backprojection.h"
#include "tests/planning/random_scenes.h"

namespace visco::planning {
namespace {

using Eigen::Vector2d;

struct Edge {
  Vector2d a, b;
};

std::vector<Edge> Edges(const Region& r) {
  std::vector<Edge> out;
  auto add = [&](const RegionRing& ring) {
    for (size_t i = 0; i < ring.vertices.size(); ++i) {
      out.push_back({ring.vertices[i], ring.vertices[(i + 1) % ring.vertices.size()]});
    }
  };
  for (const auto& poly : r.polygons) {
    add(poly.outer);
    for (const auto& h : poly.holes) add(h);
  }
  return out;
}

// The region's intersection with the vertical line at x, as sorted disjoint intervals (even-odd rule).
std::vector<std::pair<double, double>> Intervals(const std::vector<Edge>& edges, double x) {
  std::vector<double> ys;
  for (const Edge& e : edges) {
    if ((e.a.x() > x) == (e.b.x() > x)) continue;
    ys.push_back(e.a.y() + (x - e.a.x()) * (e.b.y() - e.a.y()) / (e.b.x() - e.a.x()));
  }
  std::sort(ys.begin(), ys.end());
  std::vector<std::pair<double, double>> out;
  for (size_t i = 0; i + 1 < ys.size(); i += 2) out.emplace_back(ys[i], ys[i + 1]);
  return out;
}

// True if `inner` is contained in `outer` up to `tol` (length). Between consecutive x-coordinates of vertices and of
// edge crossings the edges of both regions keep their vertical order, so one vertical line per slab decides it.
bool ContainedIn(const Region& inner, const Region& outer, double tol) {
  const std::vector<Edge> ei = Edges(inner), eo = Edges(outer);
  std::vector<double> xs;
  for (const auto* es : {&ei, &eo}) {
    for (const Edge& e : *es) xs.push_back(e.a.x());
  }
  for (const Edge& p : ei) {
    for (const Edge& q : eo) {
      const Vector2d d = p.b - p.a, f = q.b - q.a, w = q.a - p.a;
      const double den = d.x() * f.y() - d.y() * f.x();
      if (std::abs(den) < 1e-18) continue;
      const double t = (w.x() * f.y() - w.y() * f.x()) / den;
      const double s = (w.x() * d.y() - w.y() * d.x()) / den;
      if (t >= 0 && t <= 1 && s >= 0 && s <= 1) xs.push_back(p.a.x() + t * d.x());
    }
  }
  std::sort(xs.begin(), xs.end());
  for (size_t i = 0; i + 1 < xs.size(); ++i) {
    if (xs[i + 1] - xs[i] < tol) continue;
    const double x = 0.5 * (xs[i] + xs[i + 1]);
    const auto in = Intervals(ei, x), out = Intervals(eo, x);
    for (const auto& [lo, hi] : in) {
      // [lo, hi] must be covered by the union of `out`'s intervals (gaps up to tol forgiven).
      double covered = lo;
      for (const auto& [olo, ohi] : out) {
        if (olo > covered + tol) break;
        covered = std::max(covered, ohi);
      }
      if (covered < hi - tol) return false;
    }
  }
  return true;
}

// A random scene (random_scenes.h) with 3 to 8 random candidate rays (some unreliable for θ).
BackprojectionProblem SceneWithRays(std::uint64_t seed) {
  BackprojectionProblem pr = RandomScene(seed);
  SceneRng r(seed * 31 + 7);
  const int nr = r.Int(3, 8);
  for (int i = 0; i < nr; ++i) {
    CvcRayInput ray = RandomRay(pr, r, "ray" + std::to_string(i), -160, -20, 9);
    ray.group = "vc" + std::to_string(i / 2);
    if (!ray.segments.empty()) pr.rays.push_back(ray);
  }
  return pr;
}

int SimulationFailures(const BackprojectionProblem& pr, const VcBackprojection& vc, std::uint64_t seed, int samples,
                       int& inside) {
  const MotionModel model(ToMotionWorld(pr, vc.active_rays));
  std::mt19937_64 rng(seed);
  auto u = [&]() { return static_cast<double>(rng() >> 11) * (1.0 / 9007199254740992.0); };
  Vector2d lo(1e300, 1e300), hi = -lo;
  for (const auto& poly : vc.region.polygons) {
    for (const auto& v : poly.outer.vertices) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
  }
  int failures = 0;
  for (int i = 0; i < samples && !vc.region.polygons.empty(); ++i) {
    const Vector2d p(lo.x() + u() * (hi.x() - lo.x()), lo.y() + u() * (hi.y() - lo.y()));
    if (!vc.region.Contains(p) || vc.region.BoundaryDistance(p) < 1e-6 || model.InObstacleInterior(p)) continue;
    ++inside;
    const SimulationResult res = SimulateAdversarially(model, p, pr.theta, pr.velocity_cone, seed + i, true);
    if (res.outcome != Outcome::kReachedGoal) {
      ++failures;
      ADD_FAILURE() << "seed " << seed << ": (" << p.x() << ", " << p.y()
                    << ") is in B_vc but fails: " << OutcomeName(res.outcome);
    }
  }
  return failures;
}

// Runs the comparison on scenes first, first + step, … ≤ last (two interleaved sets, two CTest entries: each stays well
// inside the timeout under ASan).
void CheckSeeds(std::uint64_t first, std::uint64_t last, std::uint64_t step) {
  int scenes = 0, with_candidates = 0, enlarged = 0, better_than_greedy = 0, subsets = 0, inside = 0, failures = 0;
  int max_candidates = 0;
  for (std::uint64_t seed = first; seed <= last; seed += step) {
    const BackprojectionProblem pr = SceneWithRays(seed);
    ++scenes;
    VcSelectionOptions exact_options;
    exact_options.method = RaySelection::kExact;
    const VcBackprojection vc = VcEnlargedBackprojection(pr, exact_options);
    const int n = static_cast<int>(pr.rays.size());
    ASSERT_LE(vc.candidates, 8);
    ASSERT_EQ(vc.candidates + static_cast<int>(vc.unreliable_rays.size()), n) << "seed " << seed;
    max_candidates = std::max(max_candidates, vc.candidates);
    if (vc.candidates > 0) {
      ++with_candidates;
      EXPECT_EQ(vc.selection, RaySelection::kExact) << "seed " << seed;
      EXPECT_EQ(vc.sweeps, 1 << vc.candidates) << "seed " << seed;
    }

    // The reference: every subset of the rays, without the unreliable ones (which may never be active).
    const Region classic = ClassicBackprojection(pr);
    std::vector<bool> reliable(n);
    for (int i = 0; i < n; ++i) reliable[i] = IsReliableRay(pr.rays[i], pr.theta, pr.velocity_cone);
    double best = classic.area;
    std::vector<std::string> best_set;
    for (int mask = 1; mask < (1 << n); ++mask) {
      std::vector<std::string> set;
      bool all_reliable = true;
      for (int i = 0; i < n; ++i) {
        if (!(mask >> i & 1)) continue;
        set.push_back(pr.rays[i].id);
        all_reliable = all_reliable && reliable[i];
      }
      if (!all_reliable) continue;
      ++subsets;
      const Region r = BackprojectionWithActiveRays(pr, set);
      if (r.area <= best) continue;
      if (!ContainedIn(classic, r, 1e-7)) continue;
      best = r.area;
      best_set = set;
    }
    EXPECT_NEAR(vc.region.area, best, 1e-9 * std::max(1.0, best))
        << "seed " << seed << ": the planner's set has area " << vc.region.area << ", the best subset " << best << " ("
        << best_set.size() << " rays)";
    EXPECT_TRUE(ContainedIn(classic, vc.region, 1e-7)) << "seed " << seed;
    // The reported region is the sweep of the reported set.
    EXPECT_EQ(BackprojectionWithActiveRays(pr, vc.active_rays).area, vc.region.area) << "seed " << seed;
    enlarged += vc.region.area > classic.area * (1 + 1e-9);

    // Exact is never worse than greedy (the greedy set is admissible).
    VcSelectionOptions greedy_options;
    greedy_options.method = RaySelection::kGreedy;
    const VcBackprojection greedy = VcEnlargedBackprojection(pr, greedy_options);
    if (vc.candidates > 0) {
      EXPECT_EQ(greedy.selection, RaySelection::kGreedy);
    }
    EXPECT_GE(vc.region.area, greedy.region.area * (1 - 1e-12)) << "seed " << seed;
    better_than_greedy += vc.region.area > greedy.region.area * (1 + 1e-9);

    failures += SimulationFailures(pr, vc, seed, 60, inside);
  }
  std::printf(
      "vc selection, seeds %llu-%llu step %llu: %d scenes (%d with reliable candidates, at most %d), %d "
      "admissible-candidate subsets swept by the reference; %d enlarged; exact strictly better than greedy on %d; "
      "%d configurations simulated inside the chosen regions, %d failures\n",
      static_cast<unsigned long long>(first), static_cast<unsigned long long>(last),
      static_cast<unsigned long long>(step), scenes, with_candidates, max_candidates, subsets, enlarged,
      better_than_greedy, inside, failures);
  EXPECT_EQ(failures, 0);
  if (testing::DesignedSeeds()) {  // not vacuous
    EXPECT_GE(enlarged, 2);
    EXPECT_GT(inside, 100);
    EXPECT_GE(max_candidates, 6);
  }
}

// The default (track-pruned) choice against the exact search on seeded random scenes with at most 8 candidates:
// never unsound (simulated), never smaller than B_θ(G), equal area on at least 95 % of the scenes with candidates.
void CompareTrackWithExact(std::uint64_t first, std::uint64_t last) {
  int with_candidates = 0, equal = 0, inside = 0, failures = 0, track_sweeps = 0, exact_sweeps = 0;
  double worst = 1.0;
  std::uint64_t worst_seed = 0;
  for (std::uint64_t seed = first; seed <= last; ++seed) {
    const BackprojectionProblem pr = SceneWithRays(seed);
    const VcBackprojection track = VcEnlargedBackprojection(pr);
    if (track.candidates == 0) continue;
    ++with_candidates;
    EXPECT_EQ(track.selection, RaySelection::kTrack);
    EXPECT_LE(track.sweeps, 3 * track.candidates + 1) << "seed " << seed;
    VcSelectionOptions exact_options;
    exact_options.method = RaySelection::kExact;
    const VcBackprojection exact = VcEnlargedBackprojection(pr, exact_options);
    const Region classic = ClassicBackprojection(pr);
    EXPECT_EQ(track.classic.area, classic.area) << "seed " << seed;  // the no-ray sweep it reports is B_θ(G)
    EXPECT_TRUE(ContainedIn(classic, track.region, 1e-7)) << "seed " << seed;
    EXPECT_EQ(BackprojectionWithActiveRays(pr, track.active_rays).area, track.region.area) << "seed " << seed;
    track_sweeps += track.sweeps;
    exact_sweeps += exact.sweeps;
    const double ratio = exact.region.area > 0 ? track.region.area / exact.region.area : 1.0;
    EXPECT_LE(ratio, 1 + 1e-9) << "seed " << seed << ": the exact search is a maximum";
    if (ratio >= 1 - 1e-9) {
      ++equal;
    } else if (ratio < worst) {
      worst = ratio;
      worst_seed = seed;
    }
    failures += SimulationFailures(pr, track, seed, 40, inside);
  }
  std::printf(
      "track vs exact, seeds %llu-%llu: %d scenes with candidates, equal area on %d (%.1f %%), worst ratio %.4f "
      "(seed %llu); sweeps %d against %d; %d configurations simulated, %d failures\n",
      static_cast<unsigned long long>(first), static_cast<unsigned long long>(last), with_candidates, equal,
      100.0 * equal / std::max(1, with_candidates), worst, static_cast<unsigned long long>(worst_seed), track_sweeps,
      exact_sweeps, inside, failures);
  EXPECT_EQ(failures, 0);
  EXPECT_GE(equal, 0.95 * with_candidates);
  EXPECT_GT(with_candidates, 20);
}

TEST(VcSelectionProperty, TrackChoiceAgainstTheExactSearch) { CompareTrackWithExact(1, 40); }
TEST(VcSelectionProperty, TrackChoiceAgainstTheExactSearchMore) { CompareTrackWithExact(41, 80); }

TEST(VcSelectionProperty, ExactChoiceHasTheLargestAdmissibleAreaOverAllSubsets) { CheckSeeds(201, 217, 2); }
TEST(VcSelectionProperty, ExactChoiceHasTheLargestAdmissibleAreaOverAllSubsetsMore) { CheckSeeds(202, 218, 2); }

}  // namespace
}  // namespace visco::planning
