// Soundness of B_vcθ(G) on whole random scenes that nobody designed, through the real pipeline (scene -> C-space ->
// VC rays -> backprojection): cameras anywhere, often on the edge of the bounds (so CVC rays run to the bounds and are
// clipped there), θ all around the circle, ε_v up to 20°, non-convex and overlapping obstacles. Points sampled inside
// the VC region are run through the adversarial simulator with the chosen rays active (open ray ends included);
// every one must reach the goal. B_θ(G) ⊆ B_vcθ(G) is checked on the classic region's vertices.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "common/motion_model.h"
#include "planning/backprojection.h"
#include "planning/cspace.h"
#include "planning/scene_problem.h"
#include "planning/vc_rays.h"
#include "tests/planning/random_scenes.h"
#include "tests/planning/random_vc_scenes.h"

namespace visco::planning {
namespace {

using Eigen::Vector2d;

struct Counts {
  int scenes = 0, with_active = 0, open_active = 0, forced = 0, samples = 0, failures = 0;
};

// Simulates from points of `region` (its bounding box, and just beside the active rays, where trajectories engage
// them) with `active` as walls; counts and reports every failure.
void CheckRegion(std::uint64_t seed, const CSpace& cspace, const BackprojectionProblem& pr, const Region& region,
                 const std::vector<std::string>& active, const char* what, Counts& counts) {
  // As the product's simulated robot, complying exactly and, for two samples in three, run the servo's tracking error
  // to either side of the ray's line (where a ray ends on CB, the motion meets CB beside the end).
  std::vector<MotionModel> models;
  for (const double side : {0.0, 1.0, -1.0}) {
    MotionWorld w = ToMotionWorld(cspace, pr, active);
    w.ray_landing_offset = side * pr.ray_tracking_error;
    models.emplace_back(std::move(w));
  }
  const MotionModel& model = models[0];
  std::mt19937_64 rng(seed);
  auto u = [&]() { return static_cast<double>(rng() >> 11) * (1.0 / 9007199254740992.0); };
  Vector2d lo(1e300, 1e300), hi = -lo;
  for (const auto& poly : region.polygons) {
    for (const auto& v : poly.outer.vertices) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
  }
  std::vector<Vector2d> points;
  for (int i = 0; i < 40; ++i) points.emplace_back(lo.x() + u() * (hi.x() - lo.x()), lo.y() + u() * (hi.y() - lo.y()));
  for (const auto& seg : model.world().active_rays) {
    const Vector2d d = seg[1] - seg[0];
    const Vector2d n = Vector2d(-d.y(), d.x()).normalized();
    for (int k = 0; k < 4; ++k) {
      const Vector2d on = seg[0] + u() * d;
      points.push_back(on + 1e-3 * n);
      points.push_back(on - 1e-3 * n);
    }
  }
  for (size_t i = 0; i < points.size(); ++i) {
    const Vector2d& p = points[i];
    if (!region.Contains(p) || region.BoundaryDistance(p) < 1e-6 || model.InObstacleInterior(p)) continue;
    ++counts.samples;
    const MotionModel& m = models[i % 3];
    const SimulationResult r = SimulateAdversarially(m, p, pr.theta, pr.velocity_cone, seed * 1000 + i,
                                                     /*greedy=*/i % 4 == 0);
    if (r.outcome != Outcome::kReachedGoal) {
      ++counts.failures;
      ADD_FAILURE() << "seed " << seed << " θ = " << pr.theta * 180 / M_PI << ", " << what << " (" << active.size()
                    << " active, landing offset " << m.world().ray_landing_offset << "): (" << p.x() << ", " << p.y()
                    << ") is inside but fails: " << OutcomeName(r.outcome);
    }
  }
}

// With `heights`, the camera stands 1-6 m above the plane and most obstacles are prisms 0.2-3 m high (2.5D
// visibility): rays see over low prisms, and break where a prism hides the robot, with open ends there.
// With `goal_on_cb`, the goal rests on a surface (around a point of CB's boundary, partly inside CB).
// `scene_offset` shifts the scene's seed as VISCO_SEED_OFFSET does (the rays forced and the points sampled stay
// those of `seed`), so that a failure found on shifted seeds can be kept as a test.
void CheckScene(std::uint64_t seed, Counts& counts, bool heights = false, bool goal_on_cb = false,
                std::uint64_t scene_offset = 0) {
  Scene s;
  double theta = 0;
  // RandomWholeScene shifts by VISCO_SEED_OFFSET itself: a scene_offset names one scene whatever it is.
  const std::uint64_t scene_seed = scene_offset == 0 ? seed : scene_offset + seed - testing::SeedOffset();
  if (!testing::RandomWholeScene(scene_seed, s, theta, 3, 3, goal_on_cb)) return;
  if (heights) {
    std::mt19937_64 rng(seed * 977 + 5);
    std::uniform_real_distribution<double> unit(0, 1);
    s.camera->height = 1 + 5 * unit(rng);
    for (Obstacle& o : s.obstacles) {
      if (unit(rng) < 0.8) o.height = 0.2 + 2.8 * unit(rng);
    }
  }
  const CSpace cspace(s);
  const VcRays rays = ComputeVcRays(s, cspace);
  const BackprojectionProblem pr = ProblemFromScene(s, cspace, &rays, theta, /*kernel=*/false);
  const VcBackprojection vc = VcEnlargedBackprojection(pr);
  const Region& classic = vc.classic;
  ++counts.scenes;
  EXPECT_GE(vc.region.area, classic.area * (1 - 1e-9)) << "seed " << seed;
  for (const auto& poly : classic.polygons) {
    for (const auto& v : poly.outer.vertices) {
      EXPECT_TRUE(vc.region.Contains(v) || vc.region.BoundaryDistance(v) < 1e-7) << "seed " << seed;
    }
  }
  // A region swept with any set of active rays is what that set guarantees (the choice relies on it): a random
  // subset of the reliable candidates, forced active, must be sound too, bad tracks and open ends included.
  std::vector<std::string> forced;
  std::mt19937_64 pick(seed * 3 + 1);
  for (const auto& ray : pr.rays) {
    if (IsReliableRay(ray, pr.theta, pr.velocity_cone) && pick() % 2 == 0) forced.push_back(ray.id);
  }
  if (!forced.empty()) {
    ++counts.forced;
    CheckRegion(seed, cspace, pr, BackprojectionWithActiveRays(pr, forced), forced, "forced subset", counts);
  }
  if (vc.active_rays.empty()) return;
  ++counts.with_active;
  for (const auto& ray : pr.rays) {
    if (std::find(vc.active_rays.begin(), vc.active_rays.end(), ray.id) == vc.active_rays.end()) continue;
    bool open = false;
    for (const auto& e : ray.open_ends) open |= e[0] || e[1];
    counts.open_active += open;
  }
  CheckRegion(seed, cspace, pr, vc.region, vc.active_rays, "chosen set", counts);
}

void Report(const Counts& c) {
  std::printf(
      "scenes %d, with active rays %d (active rays with an open end %d), forced subsets %d, samples %d, failures %d\n",
      c.scenes, c.with_active, c.open_active, c.forced, c.samples, c.failures);
  EXPECT_EQ(c.failures, 0);
  if (testing::DesignedSeeds()) {  // not vacuous
    EXPECT_GT(c.with_active, 5);
  }
  EXPECT_GT(c.forced, 20);
  EXPECT_GT(c.samples, 300);
}

TEST(VcSoundnessProperty, RandomWholeScenesFirstHalf) {
  Counts c;
  for (std::uint64_t seed = 1; seed <= 60; ++seed) CheckScene(seed, c);
  Report(c);
}

// The track choice skips sweeping again the dropped rays that only lead to open ends (VcSelectionOptions::
// skip_open_ended): on whole random scenes (cameras on the bounds: many rays end there; with and without heights) it
// chooses exactly what it chooses without the skip, with fewer sweeps.
TEST(VcSoundnessProperty, SkippingRaysThatOnlyLeadToOpenEndsChangesNothing) {
  int scenes = 0, saved = 0;
  for (std::uint64_t seed = 1; seed <= 80; ++seed) {
    Scene s;
    double theta = 0;
    if (!testing::RandomWholeScene(seed, s, theta)) continue;
    if (seed % 2 == 0) {
      s.camera->height = 3.0;
      for (Obstacle& o : s.obstacles) o.height = 1.0 + 0.25 * static_cast<double>(o.shape.polygon.size() % 4);
    }
    const CSpace cspace(s);
    const VcRays rays = ComputeVcRays(s, cspace);
    const BackprojectionProblem pr = ProblemFromScene(s, cspace, &rays, theta, /*kernel=*/false);
    // The skip alone (the one for landings outside the region skips these rays too).
    VcSelectionOptions skip;
    skip.skip_outside_landings = false;
    VcSelectionOptions reference = skip;
    reference.skip_open_ended = false;
    const VcBackprojection with_skip = VcEnlargedBackprojection(pr, skip);
    const VcBackprojection without = VcEnlargedBackprojection(pr, reference);
    ++scenes;
    EXPECT_EQ(with_skip.active_rays, without.active_rays) << "seed " << seed;
    EXPECT_EQ(with_skip.region.area, without.region.area) << "seed " << seed;
    EXPECT_LE(with_skip.sweeps, without.sweeps) << "seed " << seed;
    saved += without.sweeps - with_skip.sweeps;
  }
  std::printf("scenes %d, sweeps saved by the skip %d\n", scenes, saved);
  EXPECT_GE(scenes, 60);
  if (testing::DesignedSeeds()) {  // not vacuous
    EXPECT_GT(saved, 20);
  }
}

// The track choice skips sweeping again the dropped rays whose every piece ends open or lands on CB outside the current
// region (VcSelectionOptions::skip_outside_landings, LandsOnlyOutside): on whole random scenes (with and without
// heights, with and without the goal on CB, where rays land beside the region), at three θ each, it chooses exactly
// what it chooses without that skip, with fewer sweeps.
TEST(VcSoundnessProperty, SkippingRaysThatLandOutsideTheRegionChangesNothing) {
  int problems = 0, skipped_any = 0, saved = 0;
#if defined(__SANITIZE_ADDRESS__)
  const std::uint64_t seeds = 12;  // about ten times slower under the sanitizer
#else
  const std::uint64_t seeds = 60;
#endif
  for (std::uint64_t seed = 1; seed <= seeds; ++seed) {
    Scene s;
    double theta = 0;
    if (!testing::RandomWholeScene(seed, s, theta, 3, 3, /*goal_on_cb=*/seed % 3 == 0)) continue;
    if (seed % 2 == 0) {
      s.camera->height = 3.0;
      for (Obstacle& o : s.obstacles) o.height = 1.0 + 0.25 * static_cast<double>(o.shape.polygon.size() % 4);
    }
    const CSpace cspace(s);
    const VcRays rays = ComputeVcRays(s, cspace);
    for (const double turn : {0.0, 2.0 * M_PI / 3.0, 4.0 * M_PI / 3.0}) {
      const BackprojectionProblem pr = ProblemFromScene(s, cspace, &rays, theta + turn, /*kernel=*/false);
      VcSelectionOptions reference;
      reference.skip_outside_landings = false;
      const VcBackprojection with_skip = VcEnlargedBackprojection(pr);
      const VcBackprojection without = VcEnlargedBackprojection(pr, reference);
      ++problems;
      EXPECT_EQ(with_skip.active_rays, without.active_rays) << "seed " << seed << " turn " << turn;
      EXPECT_EQ(with_skip.region.area, without.region.area) << "seed " << seed << " turn " << turn;
      EXPECT_LE(with_skip.sweeps, without.sweeps) << "seed " << seed << " turn " << turn;
      saved += without.sweeps - with_skip.sweeps;
      skipped_any += with_skip.sweeps < without.sweeps;
    }
  }
  std::printf("problems %d, of which the skip saved sweeps in %d, sweeps saved %d\n", problems, skipped_any, saved);
  EXPECT_GE(problems, static_cast<int>(2 * seeds));
  if (testing::DesignedSeeds()) {  // not vacuous
    EXPECT_GT(skipped_any, static_cast<int>(seeds / 3));
  }
}

TEST(VcSoundnessProperty, RandomWholeScenesWithHeights) {
  Counts c;
  for (std::uint64_t seed = 1; seed <= 60; ++seed) CheckScene(seed, c, /*heights=*/true);
  Report(c);
}

// Goals resting on surfaces, as real goals do (a slot, a shelf): motions slide into them and rays land beside and in
// them, with the servo's tracking error.
TEST(VcSoundnessProperty, RandomWholeScenesWithTheGoalOnCB) {
  Counts c;
  for (std::uint64_t seed = 1; seed <= 60; ++seed) CheckScene(seed, c, /*heights=*/false, /*goal_on_cb=*/true);
  Report(c);
}

TEST(VcSoundnessProperty, RandomWholeScenesWithHeightsAndTheGoalOnCB) {
  Counts c;
  for (std::uint64_t seed = 1; seed <= 60; ++seed) CheckScene(seed, c, /*heights=*/true, /*goal_on_cb=*/true);
  Report(c);
}

// Scenes with the goal on CB where the checks found the planner or the simulator wrong (2026-12-06, offsets nobody
// had run: VISCO_SEED_OFFSET and the test's seed):
//   3247261 + 8: the simulator left an active ray it had just engaged at the ray's upper end on a C-obstacle edge
//     for another ray running along that edge (MotionModel::ResolveAt now ends a ray only at the end ahead);
//   6995588 + 31: an active ray running along a C-obstacle edge to the edge's convex corner, with the tracking
//     error (the overlay merged the ray into the edge and saw a sliding motion; now such an end counts as open);
//   5340517 + 33: a C-obstacle edge on the bounds' line, which the vertex rule at its corner may choose (it was taken
//     for a bounds edge only; now a motion sliding along it counts as failing);
//   5261327 + 51: the goal's corner 1 cm from an active ray, with CB within the tracking error of the ray there (the
//     ray's part beside CB ended open only at its lower cut, after the goal; now complying along it fails);
//   8372434 + 4: a ray converging on its landing edge at 9°, the robot joining it already within δ of the edge (the
//     simulator searched for the landing from further back, inside CB, and took the robot to stop; now the robot
//     meets a landing edge within the offset where it joins the ray, and the search starts there);
//   8636742 + 60: the goal entered 7 cm before a closed end whose landing edge comes within δ 10 cm before it (the
//     sweep stopped at the goal and never checked the landing; now such a part fails);
//   8636742 + 14: a ray starting on the bounds, the robot joining it 1 cm inside them with δ = 2.3 cm (the bounds
//     within δ of a ray now cut it like CB);
//   16255459 + 50 (with heights): a ray's open upper end, where the camera stops seeing the CM vertex, a few ulps
//     beside the C-obstacle edge it lies on: motions sliding down the edge passed it by, where the robot meets the
//     ray and complies to its open end (open ends are now moved onto CB like closed ones);
//   17064016 + 17: the simulator's robot, complying along a ray on a C-obstacle edge, met that edge "across" from the
//     line at distance 0 at every step and never moved on (an edge the robot is on no longer counts).
// Seed 29 of RandomWholeScenesWithTheGoalOnCB failed like 8636742 + 60 once the simulator met landing edges.
TEST(VcSoundnessProperty, ScenesWithTheGoalOnCBFoundWrongOnShiftedSeeds) {
  Counts c;
  const std::pair<std::uint64_t, std::uint64_t> found[] = {{3247261, 8},   {6995588, 31}, {5340517, 33}, {5261327, 51},
                                                           {8372434, 4},   {8636742, 60}, {8636742, 14}, {16255459, 50},
                                                           {17064016, 17}, {16155279, 52}};
  for (const auto& [offset, seed] : found) {
    CheckScene(seed, c, /*heights=*/offset == 16255459, /*goal_on_cb=*/true, offset);
  }
  std::printf("scenes %d, samples %d, failures %d\n", c.scenes, c.samples, c.failures);
  EXPECT_EQ(c.scenes, 10);
  EXPECT_EQ(c.failures, 0);
  EXPECT_GT(c.samples, 100);
}

TEST(VcSoundnessProperty, RandomWholeScenesSecondHalf) {
  Counts c;
  for (std::uint64_t seed = 61; seed <= 120; ++seed) CheckScene(seed, c);
  Report(c);
}

}  // namespace
}  // namespace visco::planning
