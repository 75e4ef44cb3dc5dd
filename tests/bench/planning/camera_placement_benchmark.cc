// Viewing cells (planning/camera_placement.h) on seeded random scenes of k x k cells of obstacles (star-shaped,
// some touching, lattice-aligned; the generator of the property tests), k = 2 ... 4: the time of the exact
// arrangement and its counts next to the bound (mn)^2 the paper's argument gives, for n obstacle vertices and m robot
// hull vertices. Counters: n, m, mn2 = (mn)^2, lines (distinct event lines in the bounds), faces, cells (outside the
// obstacles), views (distinct views among them). Scaling: compare faces with lines^2 / 2 and with mn2.

#include <benchmark/benchmark.h>

#include "planning/camera_placement.h"
#include "tests/planning/random_vc_scenes.h"

namespace visco::planning {
namespace {

void BM_ViewingCells(benchmark::State& state) {
  testing::RandomSceneOptions o;
  o.cells_x = o.cells_y = static_cast<int>(state.range(0));
  o.cell = 3.0;
  o.fill = 0.5;
  o.max_vertices = 5;
  const Scene scene = testing::RandomScene(11, o);
  ViewingCells cells;
  for (auto _ : state) {
    cells = ComputeViewingCells(scene, scene.bounds.min, scene.bounds.max);
    benchmark::DoNotOptimize(cells.cells.data());
  }
  const double mn = static_cast<double>(cells.obstacle_vertices) * cells.robot_vertices;
  state.counters["n"] = cells.obstacle_vertices;
  state.counters["m"] = cells.robot_vertices;
  state.counters["mn2"] = mn * mn;
  state.counters["lines"] = cells.event_lines;
  state.counters["faces"] = cells.faces;
  state.counters["cells"] = static_cast<double>(cells.cells.size());
  state.counters["views"] = cells.views;
}
BENCHMARK(BM_ViewingCells)->DenseRange(2, 4)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace
}  // namespace visco::planning

BENCHMARK_MAIN();
