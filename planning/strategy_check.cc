// The adversarial check of a strategy (strategy.h, CheckStrategy): the motion model run from sampled starts.

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "common/motion_model.h"
#include "planning/cspace.h"
#include "planning/scene_problem.h"
#include "planning/strategy.h"
#include "planning/vc_rays.h"

namespace visco::planning {

using Eigen::Vector2d;

StrategyCheck CheckStrategy(const Scene& scene, const CSpace& cspace, const VcRays& rays, const Strategy& strategy,
                            int samples, std::uint64_t seed) {
  StrategyCheck out;
  if (!scene.start || !strategy.feasible) return out;
  const BackprojectionProblem base = ProblemFromScene(scene, cspace, &rays, 0.0, true);
  // The simulated world of each step: one solid polygon per C-obstacle part, the step's target as its goal; three
  // of each, complying exactly and with the servo's tracking error to either side of a ray's line (start i uses
  // models[i % 3]).
  std::vector<MotionModel> models[3];
  for (const auto& s : strategy.steps) {
    MotionWorld w;
    for (std::size_t i = 0; i < cspace.num_c_obstacles(); ++i) {
      for (const PolygonWithHoles& part : cspace.c_obstacle(i)) w.obstacles.push_back(part.outer.vertices);
    }
    // A guarded step stops wherever the ray is reached first (the executor's event); only its target piece succeeds.
    // A contact step has no goal region: it ends where the motion stops (and succeeds only at its feature).
    if (s.terminate != Termination::kContact) {
      for (const auto& g : s.terminate == Termination::kVisualGuarded ? s.triggers : s.target)
        w.goal.push_back(g.vertices);
    }
    w.bounds_min = base.bounds_min;
    w.bounds_max = base.bounds_max;
    w.friction_cone = base.friction_cone;
    for (const auto& id : s.active_rays) {
      for (const auto& ray : base.rays) {
        if (ray.id != id) continue;
        for (size_t k = 0; k < ray.segments.size(); ++k) {
          w.active_rays.push_back(ray.segments[k]);
          w.active_ray_open_ends.push_back(k < ray.open_ends.size() ? ray.open_ends[k] : std::array<bool, 2>{});
        }
      }
    }
    for (int side = 0; side < 3; ++side) {
      w.ray_landing_offset = (side == 0 ? 0.0 : side == 1 ? 1.0 : -1.0) * base.ray_tracking_error;
      models[side].emplace_back(w);
    }
  }
  const auto& r = scene.start->polygon.vertices;
  Vector2d lo = r[0], hi = r[0];
  for (const auto& v : r) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < samples; ++i) {
    Vector2d q;
    if (i % 2 == 0) {  // on the boundary
      const size_t e = rng() % r.size();
      q = r[e] + u(rng) * (r[(e + 1) % r.size()] - r[e]);
    } else {
      for (int attempt = 0; attempt < 1000; ++attempt) {
        q = {lo.x() + u(rng) * (hi.x() - lo.x()), lo.y() + u(rng) * (hi.y() - lo.y())};
        if (InsideEvenOdd(r, q)) break;
      }
    }
    ++out.starts;
    Vector2d pos = q;
    bool ok = true;
    for (size_t k = 0; k < strategy.steps.size() && ok; ++k) {
      const auto& s = strategy.steps[k];
      const SimulationResult res =
          SimulateAdversarially(models[i % 3][k], pos, s.theta, scene.uncertainty.velocity_cone_rad,
                                seed * 7919 + i * 31 + k, /*greedy=*/i % 3 == 0);
      bool reached = res.outcome == Outcome::kReachedGoal;
      const char* why = OutcomeName(res.outcome);
      if (s.terminate == Termination::kContact) {
        // Stuck where the step may end: on the face's piece, or near the corner.
        const Vector2d d = s.end_b - s.end_a, p = res.final_state.position;
        const double t = d.squaredNorm() > 0 ? std::clamp((p - s.end_a).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
        reached = res.outcome == Outcome::kStopped &&
                  (s.end_a + t * d - p).norm() <= s.end_radius + 1e-9 * (base.bounds_max - base.bounds_min).norm();
        why = res.outcome == Outcome::kStopped ? "stuck outside the feature's places" : why;
      } else if (reached && s.terminate == Termination::kVisualGuarded) {
        // Where on the ray it stopped: inside the target piece's strip (a hair of slack for the stop's rounding)?
        const Vector2d d = s.end_b - s.end_a;
        const double t = std::clamp((res.final_state.position - s.end_a).dot(d) / d.squaredNorm(), 0.0, 1.0);
        reached = (s.end_a + t * d - res.final_state.position).norm() <= kVcStripHalfWidth * (1 + 1e-6);
      }
      if (!reached) {
        ok = false;
        if (out.failures.size() < 20) {
          out.failures.push_back(
              fmt::format("start ({:.4f}, {:.4f}): step {}: {} at ({:.4f}, {:.4f})", q.x(), q.y(), k,
                          res.outcome == Outcome::kReachedGoal && s.terminate == Termination::kVisualGuarded
                              ? "reached the ray outside the target piece"
                              : why,
                          res.final_state.position.x(), res.final_state.position.y()));
        }
      }
      pos = res.final_state.position;
    }
    out.successes += ok;
  }
  return out;
}

}  // namespace visco::planning
