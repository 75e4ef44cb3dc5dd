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
#include <vector>

#include "planning/backproject_command.h"
#include "planning/backprojection.h"
#include "planning/cspace.h"
#include "planning/motion_model.h"
#include "planning/vc_rays.h"
#include "tests/planning/random_scenes.h"
#include "tests/planning/random_vc_scenes.h"

namespace visco::planning {
namespace {

using Eigen::Vector2d;

struct Counts {
  int scenes = 0, with_active = 0, open_active = 0, forced = 0, samples = 0, failures = 0;
};

// A random scene: 3 x 3 cells of 4 m, star-shaped (non-convex) obstacles, some overlapping; the camera on the edge
// of the bounds for two seeds in three, anywhere otherwise; a small goal in free space; θ and ε_v random.
bool MakeScene(std::uint64_t seed, Scene& s, double& theta) {
  testing::RandomSceneOptions o;
  o.cells_x = 3;
  o.cells_y = 3;
  o.fill = 0.45;
  o.lattice = seed % 3 == 0 ? 0.0 : 0.5;
  o.overlap = seed % 4 == 0 ? 0.4 : 0.0;
  s = testing::RandomScene(seed, o);
  std::mt19937_64 rng(seed * 7919 + 1);
  std::uniform_real_distribution<double> unit(0, 1);
  const CSpace probe(s);
  if (seed % 3 != 0) {
    // On one side of the bounds, facing inwards.
    const int side = static_cast<int>(seed % 4);
    const double t = unit(rng);
    const Vector2d lo = s.bounds.min, hi = s.bounds.max;
    const Vector2d c = side == 0   ? Vector2d(lo.x() + t * (hi.x() - lo.x()), lo.y())
                       : side == 1 ? Vector2d(hi.x(), lo.y() + t * (hi.y() - lo.y()))
                       : side == 2 ? Vector2d(lo.x() + t * (hi.x() - lo.x()), hi.y())
                                   : Vector2d(lo.x(), lo.y() + t * (hi.y() - lo.y()));
    bool inside = false;
    for (const Obstacle& ob : s.obstacles) inside |= Locate(ob.shape.polygon, c) == Location::kInside;
    if (!inside) {
      const double first = 90.0 * side + 5.0;  // a 170° view into the box
      s.camera->center = c;
      s.camera->fov_first_rad = first * M_PI / 180;
      s.camera->fov_second_rad = (first + 170.0) * M_PI / 180;
      s.camera->fov_first = {std::cos(s.camera->fov_first_rad), std::sin(s.camera->fov_first_rad)};
      s.camera->fov_second = {std::cos(s.camera->fov_second_rad), std::sin(s.camera->fov_second_rad)};
    }
  }
  // A goal rectangle whose corners are free (the region may still graze CB; the sweep clips it).
  for (int attempt = 0; attempt < 200; ++attempt) {
    const double w = 0.4 + unit(rng), h = 0.3 + 0.6 * unit(rng);
    const double x = s.bounds.min.x() + unit(rng) * (s.bounds.max.x() - s.bounds.min.x() - w);
    const double y = s.bounds.min.y() + unit(rng) * (s.bounds.max.y() - s.bounds.min.y() - h);
    Polygon g{{{x, y}, {x + w, y}, {x + w, y + h}, {x, y + h}}};
    bool free = true;
    for (const Point& v : g.vertices) free &= probe.Locate(v) == Location::kOutside;
    free &= probe.Locate(Point(x + w / 2, y + h / 2)) == Location::kOutside;
    if (!free) continue;
    s.goal.polygon = g;
    s.goal.source_index = {0, 1, 2, 3};
    s.uncertainty.velocity_cone_rad = (2.0 + 18.0 * unit(rng)) * M_PI / 180;
    s.friction_cone_rad = (5.0 + 30.0 * unit(rng)) * M_PI / 180;
    theta = (-180.0 + 360.0 * unit(rng)) * M_PI / 180;
    return true;
  }
  return false;
}

// Simulates from points of `region` (its bounding box, and just beside the active rays, where trajectories engage
// them) with `active` as walls; counts and reports every failure.
void CheckRegion(std::uint64_t seed, const CSpace& cspace, const BackprojectionProblem& pr, const Region& region,
                 const std::vector<std::string>& active, const char* what, Counts& counts) {
  const MotionModel model(ToMotionWorld(cspace, pr, active));  // as the product's simulated robot
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
    const SimulationResult r = SimulateAdversarially(model, p, pr.theta, pr.velocity_cone, seed * 1000 + i,
                                                     /*greedy=*/i % 4 == 0);
    if (r.outcome != Outcome::kReachedGoal) {
      ++counts.failures;
      ADD_FAILURE() << "seed " << seed << " θ = " << pr.theta * 180 / M_PI << ", " << what << " (" << active.size()
                    << " active): (" << p.x() << ", " << p.y() << ") is inside but fails: " << OutcomeName(r.outcome);
    }
  }
}

void CheckScene(std::uint64_t seed, Counts& counts) {
  Scene s;
  double theta = 0;
  if (!MakeScene(seed, s, theta)) return;
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
  EXPECT_GT(c.with_active, 5);
  EXPECT_GT(c.forced, 20);
  EXPECT_GT(c.samples, 300);
}

TEST(VcSoundnessProperty, RandomWholeScenesFirstHalf) {
  Counts c;
  for (std::uint64_t seed = 1; seed <= 60; ++seed) CheckScene(seed, c);
  Report(c);
}

TEST(VcSoundnessProperty, RandomWholeScenesSecondHalf) {
  Counts c;
  for (std::uint64_t seed = 61; seed <= 120; ++seed) CheckScene(seed, c);
  Report(c);
}

}  // namespace
}  // namespace visco::planning
