// Multi-step plan synthesis (`visco plan SCENE --max-steps 3`) on seeded random scenes of n = 50 ... 500 obstacle
// vertices (tests/planning/multistep_scenes.h: non-convex obstacles, the goal on a surface, a start region, a camera
// on the edge of the bounds or anywhere).
//
// BM_MultiStep/n/seed/search: one scene, planned with at most 3 steps on two threads, by the lean search (search = 0,
// the default) or the search before it (1, SearchMode::kBaseline; run up to n = 100, where it finishes), both with a
// memory limit of 4 GiB (a search that reaches it stops: memory_stop = 1). Counters: the scene's obstacle vertices (n)
// and C-obstacle vertices (cn), whether a strategy was found and its steps, the levels reached, the child targets
// computed (children; each one nondirectional backprojection, as is the goal's: nondirectional), the CPU seconds of the
// process and its peak resident memory (peak_MiB, reset before each benchmark); where the time went (wall clock): the
// goal's nondirectional backprojection (goal_s) and its VC-enlarged backprojections (goal_sweeps), the children's
// summed over the threads (children_s, children_sweeps) and the slowest child (slowest_child_s).
//
// With VISCO_SCENE_DUMP=DIR each benchmark writes its scene to DIR/multistep_n<n>_s<seed>.json instead of planning
// (for `visco plan` under /usr/bin/time -v or heaptrack).

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <fstream>
#include <string>

#include "planning/cspace.h"
#include "planning/strategy.h"
#include "tests/bench/planning/process_stats.h"
#include "tests/planning/multistep_scenes.h"
#include "tests/planning/scene_json.h"

namespace visco::planning {
namespace {

using bench::PeakMemoryMiB;
using bench::ProcessCpuSeconds;
using bench::ResetPeakMemory;

void BM_MultiStep(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto seed = static_cast<std::uint64_t>(state.range(1));
  Scene scene;
  if (!testing::MultiStepScene(seed, n, scene)) {
    state.SkipWithError("the seed gives no goal or start region");
    return;
  }
  if (const char* dir = std::getenv("VISCO_SCENE_DUMP")) {
    std::ofstream(std::string(dir) + "/" + scene.name + ".json") << testing::SceneToJson(scene);
    state.SkipWithError("scene written");
    return;
  }
  std::size_t c_vertices = 0;
  {
    const CSpace cspace(scene);
    for (std::size_t i = 0; i < cspace.num_c_obstacles(); ++i) {
      for (const PolygonWithHoles& p : cspace.c_obstacle(i)) c_vertices += p.outer.size();
    }
  }
  PlanOptions options;
  options.max_steps = 3;
  options.threads = 2;
  options.max_memory_mib = 4096;
  options.search = state.range(2) == 0 ? SearchMode::kLean : SearchMode::kBaseline;
  Strategy st;
  ResetPeakMemory();
  const double cpu0 = ProcessCpuSeconds();
  for (auto _ : state) {
    st = PlanStrategy(scene, options);
    benchmark::DoNotOptimize(st.steps.data());
  }
  state.counters["cpu_s"] = ProcessCpuSeconds() - cpu0;
  state.counters["peak_MiB"] = PeakMemoryMiB();
  state.counters["n"] = static_cast<double>(testing::ObstacleVertices(scene));
  state.counters["cn"] = static_cast<double>(c_vertices);
  state.counters["feasible"] = st.feasible ? 1 : 0;
  state.counters["steps"] = static_cast<double>(st.steps.size());
  state.counters["nondirectional"] = static_cast<double>(st.nondirectional);
  state.counters["children"] = static_cast<double>(st.children);
  state.counters["levels"] = st.levels;
  state.counters["memory_stop"] = st.memory_limit_reached ? 1 : 0;
  state.counters["goal_s"] = st.goal_seconds;
  state.counters["goal_sweeps"] = static_cast<double>(st.goal_sweeps);
  state.counters["children_s"] = st.children_seconds;
  state.counters["slowest_child_s"] = st.slowest_child_seconds;
  state.counters["children_sweeps"] = static_cast<double>(st.children_sweeps);
}
// The lean search on every size, the search before it beside it up to 100 vertices.
void Sizes(benchmark::internal::Benchmark* b) {
  for (int n : {20, 50, 60, 80, 100, 200, 500}) {
    for (int seed = 1; seed <= 5; ++seed) {
      b->Args({n, seed, 0});
      if (n <= 100) b->Args({n, seed, 1});
    }
  }
}
BENCHMARK(BM_MultiStep)->Apply(Sizes)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace
}  // namespace visco::planning

BENCHMARK_MAIN();
