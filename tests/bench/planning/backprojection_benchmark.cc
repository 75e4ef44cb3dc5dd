// Cost of the classic directional backprojection B_θ(G) (exact plane sweep) from 1k to 100k C-obstacle vertices,
// against the slow obvious reference measured in the same run: classifying a 10 x 10 grid of configurations with
// the motion model (three fixed extreme/central adversaries per configuration, each event scanning every edge).
//
// Scaling exponent: compare BM_Classic at 1k and 100k vertices (log(t100k / t1k) / log(100)); the ratio: the
// reference's time per classified configuration against the sweep's time for the whole region.
//
// BM_RaySelection: the VC-enlarged backprojection's choice of active rays, the default track-pruned choice (at most
// 3k + 1 sweeps) against exact (every subset of the reliable candidates) and greedy (single rays, then pairs) on the
// same scenes in the same run: the example scenes
// (data/scenes) at a commanded direction with candidates, and random scenes with 4, 8 and 12 candidate rays.

#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "common/motion_model.h"
#include "planning/backprojection.h"
#include "planning/cspace.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "planning/scene_problem.h"
#include "planning/vc_rays.h"
#include "tests/bench/planning/pentagon_grid.h"
#include "tests/planning/random_scenes.h"

namespace visco::planning {
namespace {

BackprojectionProblem Scene(int m) { return bench::PentagonGrid(m); }
using bench::Vertices;

void BM_Classic(benchmark::State& state) {
  const BackprojectionProblem pr = Scene(static_cast<int>(state.range(0)) / 5);
  double area = 0;
  for (auto _ : state) {
    const Region r = ClassicBackprojection(pr);
    benchmark::DoNotOptimize(r.polygons.data());  // (DoNotOptimize on a double garbles it with this benchmark)
    area = r.area;
  }
  state.counters["vertices"] = Vertices(pr);
  state.counters["area"] = area;
  state.SetComplexityN(Vertices(pr));
}

void BM_ReferenceGrid(benchmark::State& state) {
  const BackprojectionProblem pr = Scene(static_cast<int>(state.range(0)) / 5);
  MotionWorld world;
  for (const auto& o : pr.obstacles) world.obstacles.push_back(o.vertices);
  for (const auto& g : pr.goal) world.goal.push_back(g.vertices);
  world.bounds_min = pr.bounds_min;
  world.bounds_max = pr.bounds_max;
  world.friction_cone = pr.friction_cone;
  const MotionModel model(world);
  constexpr int kGrid = 10;
  int reached = 0;
  for (auto _ : state) {
    reached = 0;
    for (int i = 0; i < kGrid; ++i) {
      for (int j = 0; j < kGrid; ++j) {
        const Eigen::Vector2d p(pr.bounds_min.x() + (i + 0.5) * (pr.bounds_max.x() - pr.bounds_min.x()) / kGrid,
                                pr.bounds_min.y() + (j + 0.5) * (pr.bounds_max.y() - pr.bounds_min.y()) / kGrid);
        bool ok = true;
        for (double off : {-pr.velocity_cone, 0.0, pr.velocity_cone}) {
          FixedAdversary a(off);
          ok = ok && Simulate(model, p, pr.theta, pr.velocity_cone, a).outcome == Outcome::kReachedGoal;
        }
        reached += ok;
      }
    }
    benchmark::DoNotOptimize(reached);
  }
  state.counters["vertices"] = Vertices(pr);
  state.counters["configurations"] = kGrid * kGrid;
  state.counters["per_configuration_s"] =
      benchmark::Counter(kGrid * kGrid, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.SetComplexityN(Vertices(pr));
}

struct SelectionCase {
  std::string name;
  BackprojectionProblem problem;
};

// Example scenes through the real pipeline, and random scenes (random_scenes.h) with n random reliable rays.
const std::vector<SelectionCase>& SelectionCases() {
  static const std::vector<SelectionCase> cases = [] {
    std::vector<SelectionCase> out;
    const std::pair<const char*, double> figures[] = {
        {"fig13.json", -90}, {"fig13.json", -60}, {"slot.json", -90}, {"fig5.json", -90}, {"ledge.json", -90}};
    for (const auto& [file, deg] : figures) {
      const auto scene = LoadScene(std::string(VISCO_SOURCE_DIR) + "/data/scenes/" + file);
      const CSpace cspace(scene);
      const VcRays rays = ComputeVcRays(scene, cspace);
      out.push_back({std::string(file) + "@" + std::to_string(static_cast<int>(deg)),
                     ProblemFromScene(scene, cspace, &rays, deg * M_PI / 180, false)});
    }
    for (int n : {4, 8, 12}) {
      BackprojectionProblem pr = RandomScene(4242 + n);
      SceneRng r(n);
      while (static_cast<int>(pr.rays.size()) < n) {
        const CvcRayInput ray = RandomRay(pr, r, "ray" + std::to_string(100 + pr.rays.size()), -160, -20, 9);
        if (IsReliableRay(ray, pr.theta, pr.velocity_cone)) pr.rays.push_back(ray);
      }
      out.push_back({"random" + std::to_string(n), pr});
    }
    return out;
  }();
  return cases;
}

// range(0): case index; range(1): 0 = greedy, 1 = exact, 2 = track (the default).
void BM_RaySelection(benchmark::State& state) {
  const SelectionCase& c = SelectionCases().at(state.range(0));
  VcSelectionOptions options;
  const RaySelection methods[] = {RaySelection::kGreedy, RaySelection::kExact, RaySelection::kTrack};
  options.method = methods[state.range(1)];
  options.exact_limit = 64;
  VcBackprojection vc;
  for (auto _ : state) {
    vc = VcEnlargedBackprojection(c.problem, options);
    benchmark::DoNotOptimize(vc.region.polygons.data());
  }
  state.SetLabel(c.name + " " + RaySelectionName(options.method));
  state.counters["candidates"] = vc.candidates;
  state.counters["sweeps"] = vc.sweeps;
  state.counters["active"] = static_cast<double>(vc.active_rays.size());
  state.counters["area"] = vc.region.area;
}

void SelectionArgs(benchmark::internal::Benchmark* b) {
  for (int i = 0; i < static_cast<int>(SelectionCases().size()); ++i) {
    for (int method : {0, 1, 2}) b->Args({i, method});
  }
}

BENCHMARK(BM_RaySelection)->Apply(SelectionArgs)->Unit(benchmark::kMillisecond);

BENCHMARK(BM_Classic)
    ->Arg(1000)
    ->Arg(4000)
    ->Arg(16000)
    ->Arg(64000)
    ->Arg(100000)
    ->Unit(benchmark::kMillisecond)
    ->Complexity();
BENCHMARK(BM_ReferenceGrid)
    ->Arg(1000)
    ->Arg(4000)
    ->Arg(16000)
    ->Arg(64000)
    ->Arg(100000)
    ->Unit(benchmark::kMillisecond)
    ->Complexity();

}  // namespace
}  // namespace visco::planning

BENCHMARK_MAIN();
