// The lean multi-step search (planning/strategy.h SearchMode::kLean: children computed side by side, keeping only
// what the next level reads) against the search before it (kBaseline) on seeded random scenes of the kind users bring
// (tests/planning/multistep_scenes.h): wherever the baseline finds a strategy within --max-steps the lean search finds
// one with no more steps (here: the same strategy, byte for byte, after the same number of backprojections), and
// every strategy passes the adversarial simulator. CI runs a few small scenes with two steps; VISCO_FULL_PROPERTY=1
// runs many, with three.

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "planning/cspace.h"
#include "planning/strategy.h"
#include "planning/vc_rays.h"
#include "tests/planning/multistep_scenes.h"
#include "tests/planning/scene_json.h"

namespace visco::planning {
namespace {

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif

bool FullProperty() { return std::getenv("VISCO_FULL_PROPERTY") != nullptr; }

struct Tally {
  int scenes = 0, feasible = 0, multi_step = 0;
};

void Compare(const Scene& s, int max_steps, int budget, bool use_camera, Tally& t) {
  PlanOptions o;
  o.max_steps = max_steps;
  o.max_nondirectional = budget;
  o.use_camera = use_camera;
  o.threads = 2;
  o.search = SearchMode::kBaseline;
  const Strategy before = PlanStrategy(s, o);
  o.search = SearchMode::kLean;
  const Strategy lean = PlanStrategy(s, o);
  const std::string what = s.name + (use_camera ? "" : " (no camera)");
  ++t.scenes;
  if (before.feasible) {
    EXPECT_TRUE(lean.feasible) << what << ": " << lean.reason << " " << testing::DumpScene(s, "multistep_" + s.name);
  }
  if (before.feasible && lean.feasible) {
    EXPECT_LE(lean.steps.size(), before.steps.size()) << what;
  }
  // The lean search meets the same children in the same order and computes the same backprojections.
  EXPECT_EQ(StrategyToJson(s, lean), StrategyToJson(s, before)) << what;
  EXPECT_EQ(lean.nondirectional, before.nondirectional) << what;
  EXPECT_LT(lean.peak_memory_mib, 1e6);
  if (!lean.feasible) return;
  ++t.feasible;
  t.multi_step += lean.steps.size() > 1;
  const CSpace cspace(s);
  VcRays rays;
  if (s.camera && use_camera) rays = ComputeVcRays(s, cspace);
  const int samples = kSanitized ? 6 : 16;
  const StrategyCheck c = CheckStrategy(s, cspace, rays, lean, samples, 11);
  EXPECT_EQ(c.successes, c.starts) << what << ": " << (c.failures.empty() ? "" : c.failures[0]) << " "
                                   << testing::DumpScene(s, "multistep_" + s.name);
  std::printf("%s: %zu step(s), %lld nondirectional, checked %d of %d\n", what.c_str(), lean.steps.size(),
              static_cast<long long>(lean.nondirectional), c.successes, c.starts);
}

TEST(MultiStepProperty, LeanSearchFindsWhatTheBaselineFinds) {
  const std::uint64_t last = FullProperty() ? 40 : kSanitized ? 2 : 6;
  const int max_steps = FullProperty() ? 3 : 2;
  const int budget = FullProperty() ? 30 : 6;
  const std::size_t vertices = FullProperty() ? 40 : 16;
  Tally t;
  for (std::uint64_t seed = 1; seed <= last; ++seed) {
    Scene s;
    if (!testing::MultiStepScene(seed, vertices, s)) continue;
    Compare(s, max_steps, budget, /*use_camera=*/true, t);
    if (FullProperty()) Compare(s, max_steps, budget, /*use_camera=*/false, t);
  }
  std::printf("%d plans, %d with a strategy, %d of them multi-step\n", t.scenes, t.feasible, t.multi_step);
  EXPECT_GE(t.scenes, static_cast<int>(last) / 2);
}

}  // namespace
}  // namespace visco::planning
