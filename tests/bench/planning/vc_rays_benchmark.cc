// Scaling of the unoccluded-vertex sweep (with CM vertices) against the O(n^2) reference, and of the C-space and
// CVC-ray pipeline, on seeded random scenes of n obstacle vertices (octagon-like star polygons on a grid, camera at a
// free grid corner with a 150-degree field of view).
//
//   build/bin/planning_vc_rays_benchmark                 # all sizes (the reference stops at 10k)
//   build/bin/planning_vc_rays_benchmark --benchmark_filter=Sweep

#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <random>

#include "planning/cspace.h"
#include "planning/vc_rays.h"
#include "tests/planning/random_vc_scenes.h"

namespace visco::planning {
namespace {

// A scene with exactly n obstacle vertices in 8-vertex star polygons (the last one may be smaller, >= 3).
Scene BenchScene(int n) {
  static std::map<int, Scene> cache;
  if (auto it = cache.find(n); it != cache.end()) return it->second;
  std::mt19937_64 rng(4242 + n);
  const int obstacles = (n + 7) / 8;
  const int side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(obstacles))));
  const double cell = 4.0;
  Scene s;
  s.name = "bench" + std::to_string(n);
  s.bounds = {{0, 0}, {side * cell, side * cell}};
  int remaining = n;
  for (int k = 0; k < obstacles; ++k) {
    const int count = std::min(8, remaining);
    if (count < 3) break;
    const Point c((k % side + 0.5) * cell, (k / side + 0.5) * cell);
    Polygon p;
    std::uniform_real_distribution<double> jitter(-0.25, 0.25), radius(0.8, 1.7);
    for (int i = 0; i < count; ++i) {
      const double a = (i + 0.5 + jitter(rng)) * 2 * M_PI / count;
      const double r = radius(rng);
      p.vertices.push_back(c + r * Point(std::cos(a), std::sin(a)));
    }
    ScenePolygon sp{p, {}};
    for (int i = 0; i < count; ++i) sp.source_index.push_back(i);
    s.obstacles.push_back({"o" + std::to_string(k), sp, std::nullopt});
    remaining -= count;
  }
  s.robot = {Polygon{{{0, 0}, {0.6, 0}, {0.6, 0.4}, {0.3, 0.7}, {0, 0.4}}}, {0, 1, 2, 3, 4}};
  s.goal = {Polygon{{{0, 0}, {0.1, 0}, {0.1, 0.1}, {0, 0.1}}}, {0, 1, 2, 3}};
  Camera cam;
  cam.center = Point(std::floor(side / 2.0) * cell, std::floor(side / 2.0) * cell);  // a free grid corner
  cam.fov_first_rad = -0.3;
  cam.fov_second_rad = cam.fov_first_rad + 150 * M_PI / 180;
  cam.fov_first = Vector(std::cos(cam.fov_first_rad), std::sin(cam.fov_first_rad));
  cam.fov_second = Vector(std::cos(cam.fov_second_rad), std::sin(cam.fov_second_rad));
  s.camera = cam;
  cache.emplace(n, s);
  return s;
}

void Sweep(benchmark::State& state) {
  const Scene scene = BenchScene(static_cast<int>(state.range(0)));
  std::size_t visible = 0;
  for (auto _ : state) {
    const auto result = FindUnoccludedVertices(scene);
    visible = result.size();
    benchmark::DoNotOptimize(result.data());
  }
  state.counters["visible"] = static_cast<double>(visible);
  state.SetComplexityN(state.range(0));
}

void Reference(benchmark::State& state) {
  const Scene scene = BenchScene(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    const auto result = FindUnoccludedVerticesReference(scene);
    benchmark::DoNotOptimize(result.data());
  }
  state.SetComplexityN(state.range(0));
}

void CSpaceBuild(benchmark::State& state) {
  const Scene scene = BenchScene(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    const CSpace cspace(scene);
    benchmark::DoNotOptimize(&cspace);
  }
  state.SetComplexityN(state.range(0));
}

void CvcRays(benchmark::State& state) {
  const Scene scene = BenchScene(static_cast<int>(state.range(0)));
  const CSpace cspace(scene);
  std::size_t cvc = 0, crossings = 0;
  for (auto _ : state) {
    const VcRays rays = ComputeVcRays(scene, cspace);
    cvc = rays.cvc_rays.size();
    crossings = rays.crossings.size();
    benchmark::DoNotOptimize(rays.cvc_rays.data());
  }
  state.counters["cvc_rays"] = static_cast<double>(cvc);
  state.counters["crossings"] = static_cast<double>(crossings);
  state.SetComplexityN(state.range(0));
}

BENCHMARK(Sweep)
    ->Arg(1000)
    ->Arg(3000)
    ->Arg(10000)
    ->Arg(30000)
    ->Arg(100000)
    ->Unit(benchmark::kMillisecond)
    ->Complexity(benchmark::oNLogN);
BENCHMARK(Reference)->Arg(1000)->Arg(3000)->Arg(10000)->Unit(benchmark::kMillisecond)->Complexity(benchmark::oNSquared);
BENCHMARK(CSpaceBuild)->Arg(1000)->Arg(10000)->Arg(100000)->Unit(benchmark::kMillisecond)->Iterations(1);
BENCHMARK(CvcRays)->Arg(1000)->Arg(10000)->Arg(100000)->Unit(benchmark::kMillisecond)->Iterations(1);

}  // namespace
}  // namespace visco::planning

BENCHMARK_MAIN();
