// The lean multi-step search (planning/strategy.h SearchMode::kLean: children computed side by side, keeping only
// what the next level reads) against the search before it (kBaseline) on seeded random scenes of the kind users bring
// (tests/planning/multistep_scenes.h): wherever the baseline finds a strategy within --max-steps the lean search finds
// one with no more steps (here: the same strategy, byte for byte, after the same number of backprojections), and
// every strategy passes the adversarial simulator.

#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "planning/cspace.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "planning/strategy.h"
#include "planning/vc_rays.h"
#include "tests/planning/corner_rooms.h"
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

// CI: random corner rooms (two steps, a contact step first, cheap) and the example scenes whose strategies have two
// steps; VISCO_FULL_PROPERTY=1 adds many more corner rooms and the random scenes users bring (tests/planning/
// multistep_scenes.h, 40 obstacle vertices, three steps, with and without the camera: minutes each).
TEST(MultiStepProperty, LeanSearchFindsWhatTheBaselineFinds) {
  Tally t;
  const std::uint64_t rooms = FullProperty() ? 40 : kSanitized ? 2 : 5;
  for (std::uint64_t seed = 1; seed <= rooms; ++seed) {
    Scene s;
    if (RandomCornerRoom(seed, s)) Compare(s, 2, 60, /*use_camera=*/false, t);
  }
  if (!kSanitized) {
    Compare(LoadScene("data/scenes/corner.json"), 3, 60, /*use_camera=*/true, t);
    Compare(LoadScene("data/scenes/slot.json"), 3, 60, /*use_camera=*/false, t);
  }
  if (FullProperty()) {
    for (std::uint64_t seed = 1; seed <= 40; ++seed) {
      Scene s;
      if (!testing::MultiStepScene(seed, 40, s)) continue;
      Compare(s, 3, 30, /*use_camera=*/true, t);
      Compare(s, 3, 30, /*use_camera=*/false, t);
    }
  }
  std::printf("%d plans, %d with a strategy, %d of them multi-step\n", t.scenes, t.feasible, t.multi_step);
  EXPECT_GE(t.multi_step, kSanitized ? 1 : 3);
}

// The memory limit stops the search where it is, with what was explored in the reason. The memory the limit reads
// is the test's: none until the search starts on the children of level 2 (the corner needs two steps: the goal's
// backprojection, then the children), then more than the limit.
TEST(MultiStep, MemoryLimitStopsWithWhatWasExplored) {
  const Scene s = LoadScene("data/scenes/corner.json");
  std::atomic<double> in_use{0.0};
  PlanOptions o;
  o.threads = 2;
  o.max_memory_mib = 100;
  o.resident_memory_mib = [&] { return in_use.load(); };
  o.search_progress = [&](const PlanProgress& p) {
    if (p.level == 2) in_use = 150;
  };
  const Strategy st = PlanStrategy(s, o);
  EXPECT_FALSE(st.feasible);
  EXPECT_TRUE(st.memory_limit_reached);
  EXPECT_EQ(st.levels, 2);
  EXPECT_EQ(st.nondirectional, 1);  // the goal's
  EXPECT_EQ(st.peak_memory_mib, 150);
  EXPECT_NE(st.reason.find("the search stopped at the memory limit (150 MiB in use, --max-memory 100 MiB)"),
            std::string::npos)
      << st.reason;
  EXPECT_NE(st.reason.find("while trying 2 steps (0 of that level's"), std::string::npos) << st.reason;
  EXPECT_NE(st.reason.find("no strategy within 1 step(s)"), std::string::npos) << st.reason;
  // Over the limit from the start: the goal's backprojection stops at its next sweep.
  in_use = 150;
  o.search_progress = nullptr;
  const Strategy none = PlanStrategy(s, o);
  EXPECT_FALSE(none.feasible);
  EXPECT_TRUE(none.memory_limit_reached);
  EXPECT_EQ(none.nondirectional, 0);
  EXPECT_NE(none.reason.find("while computing the goal's preimage"), std::string::npos) << none.reason;
  // The process's own memory and no limit: the corner has its two steps.
  o.resident_memory_mib = nullptr;
  o.max_memory_mib = 0;
  const Strategy full = PlanStrategy(s, o);
  EXPECT_TRUE(full.feasible) << full.reason;
  EXPECT_FALSE(full.memory_limit_reached);
  EXPECT_GT(full.peak_memory_mib, 0.0);
  EXPECT_GT(full.goal_seconds, 0.0);
  EXPECT_GT(full.children_seconds, 0.0);
  EXPECT_GT(full.goal_sweeps, 0);
  EXPECT_GT(full.children_sweeps, 0);
}

}  // namespace
}  // namespace visco::planning
