// Cost of the nondirectional backprojection (planning/nondirectional.h) and of the planner built on it.
//
// BM_Candidates/search/n: the candidate critical orientations of the pentagon grid with n obstacle vertices (closed
//   forms over the static arrangement: the number grows with the pairs of visible features), found through the grid
//   index (search 0, the default) or by scanning every segment (search 1, the reference). Scaling exponent: compare
//   two sizes, log(t2 / t1) / log(n2 / n1); the counters give the count by kind next to the time.
// BM_Nondirectional/method/n: the whole nondirectional backprojection, kinetic (method 0, the default: a sweep only
//   where an event involves the regions' free edges, or a sliding or along-a-segment event's edge or vertex meets a
//   region) against the critical-slice baseline (method 1: a sweep in every interval between candidates) and the
//   kinetic walk with its broad rule (method 2: also every event at any vertex of the regions) and with its sources
//   rule alone (method 3: an event's point need not lie on the regions' boundary) and without its computed updates
//   (method 4: every relevant event swept, none of the slices after one computed from its local edit), same problem,
//   same run: the ratio to the baseline is the kinetic method's gain; the counters give the candidates swept by the
//   walk (checked), the slices it computed instead (updated), all sweeps (backprojections) by purpose (sweeps_*, with
//   their time *_s) and the orientations found (equal for all methods).
// BM_RegionAt/method/n: the region at a θ inside an open interval, carried from the slice (method 0) or swept
//   (method 1), in the same run: the ratio is what the carried regions save the queries and the --svg curves.
// Every benchmark but BM_Plan reports its peak resident memory (`peak_MiB`).
// BM_Plan/scene: `visco plan` on the example scenes (one thread), with the nondirectional backprojections it needed.

#include <benchmark/benchmark.h>

#include <cmath>
#include <ctime>
#include <fstream>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "planning/critical.h"
#include "planning/cspace.h"
#include "planning/nondirectional.h"
#include "planning/scene.h"
#include "planning/scene_file.h"
#include "planning/scene_problem.h"
#include "planning/strategy.h"
#include "planning/threads.h"
#include "planning/vc_rays.h"
#include "tests/bench/planning/pentagon_grid.h"
#include "tests/bench/planning/process_stats.h"
#include "tests/planning/random_vc_scenes.h"

#ifndef VISCO_SOURCE_DIR
#define VISCO_SOURCE_DIR "."
#endif

namespace visco::planning {
namespace {

using bench::PeakMemoryMiB;
using bench::ProcessCpuSeconds;
using bench::ResetPeakMemory;

void BM_Candidates(benchmark::State& state) {
  const BackprojectionProblem pr = bench::PentagonGrid(static_cast<int>(state.range(1)) / 5);
  const CandidateSearch search = state.range(0) == 0 ? CandidateSearch::kIndexed : CandidateSearch::kScan;
  CriticalCounts counts;
  size_t n = 0;
  ResetPeakMemory();
  for (auto _ : state) {
    const auto c = CriticalCandidates(pr, nullptr, &counts, search);
    n = c.size();
    benchmark::DoNotOptimize(c.data());
  }
  state.SetLabel(state.range(0) == 0 ? "indexed" : "scan");
  state.counters["peak_MiB"] = PeakMemoryMiB();
  state.counters["vertices"] = bench::Vertices(pr);
  state.counters["candidates"] = static_cast<double>(n);
  state.counters["visible_pairs"] = static_cast<double>(counts.visible_pairs);
  for (int k = 0; k < 6; ++k) {
    state.counters[CriticalKindName(static_cast<CriticalKind>(k))] = static_cast<double>(counts.by_kind[k]);
  }
}
// Indexed (the default) at n = 20 ... 2000 vertices, and the scan over every segment (the reference) up to 320.
BENCHMARK(BM_Candidates)
    ->ArgsProduct({{0}, {20, 40, 80, 160, 320, 640, 1280, 2000}})
    ->ArgsProduct({{1}, {20, 40, 80, 160, 320}})
    ->Unit(benchmark::kMillisecond);

// The candidates of a whole scene through the real pipeline (scene -> C-space -> CVC rays), counted by kind: n =
// C-obstacle vertices, rays = CVC ray segments, points = points of the static arrangement.
void CountCandidates(benchmark::State& state, const Scene& scene, double theta) {
  const CSpace cspace(scene);
  const VcRays rays = ComputeVcRays(scene, cspace);
  const BackprojectionProblem pr = ProblemFromScene(scene, cspace, &rays, theta, /*kernel=*/false);
  CriticalCounts counts;
  ResetPeakMemory();
  for (auto _ : state) {
    const auto c = CriticalCandidates(pr, nullptr, &counts);
    benchmark::DoNotOptimize(c.data());
  }
  double n = 0, segments = 0;
  for (const auto& o : pr.obstacles) n += static_cast<double>(o.vertices.size());
  for (const auto& r : pr.rays) segments += static_cast<double>(r.segments.size());
  state.counters["peak_MiB"] = PeakMemoryMiB();
  state.counters["n"] = n;
  state.counters["rays"] = segments;
  state.counters["points"] = static_cast<double>(counts.points);
  state.counters["visible_pairs"] = static_cast<double>(counts.visible_pairs);
  for (int kind = 0; kind < 6; ++kind) {
    state.counters[CriticalKindName(static_cast<CriticalKind>(kind))] = static_cast<double>(counts.by_kind[kind]);
  }
}

// Candidate counts by kind on growing whole random scenes with a camera (k x k cells of 4 m, star-shaped obstacles,
// some overlapping, the camera on the bounds; the real pipeline scene -> C-space -> CVC rays): the table against the
// papers' bounds in docs/planning_nondirectional.md. n = C-obstacle vertices, rays = CVC ray segments.
void BM_CandidateCounts(benchmark::State& state) {
  const int k = static_cast<int>(state.range(0));
  Scene scene;
  double theta = 0;
  std::uint64_t seed = 2;  // the camera on the bounds (seed % 3 != 0)
  while (!testing::RandomWholeScene(seed, scene, theta, k, k)) seed += 3;
  CountCandidates(state, scene, theta);
}
BENCHMARK(BM_CandidateCounts)->DenseRange(2, 12, 2)->Unit(benchmark::kMillisecond)->Iterations(1);

void BM_Nondirectional(benchmark::State& state) {
  const BackprojectionProblem pr = bench::PentagonGrid(static_cast<int>(state.range(1)) / 5);
  NondirectionalOptions o;
  o.method = state.range(0) == 1 ? SliceMethod::kBaseline : SliceMethod::kKinetic;
  if (state.range(0) == 2) o.vertex_events = true;     // the walk's broad rule: an event at any vertex of the regions
  if (state.range(0) == 3) o.boundary_events = false;  // the sources rule alone, wherever the event's point lies
  if (state.range(0) == 4) o.computed_updates = false;
  NondirectionalStats stats;
  size_t orientations = 0;
  ResetPeakMemory();
  for (auto _ : state) {
    const auto nd = ComputeNondirectional(pr, nullptr, o);
    stats = nd.stats;
    orientations = nd.orientations.size();
    benchmark::DoNotOptimize(nd.slices.data());
  }
  static const char* const kLabels[] = {"kinetic", "baseline", "kinetic, broad rule (every vertex of the regions)",
                                        "kinetic, sources rule (the event's point anywhere)",
                                        "kinetic, no computed updates (every relevant event swept)"};
  state.SetLabel(kLabels[state.range(0)]);
  state.counters["peak_MiB"] = PeakMemoryMiB();
  state.counters["vertices"] = bench::Vertices(pr);
  state.counters["candidates"] = static_cast<double>(stats.candidates);
  state.counters["events"] = static_cast<double>(stats.events);
  state.counters["checked"] = static_cast<double>(stats.checked);
  // What the baseline would cost on this problem, for the sizes where it is too slow to run: a slice per event (the
  // midpoint of the interval after it), plus the same interval checks and critical slices (4 per orientation), at the
  // mean time of 128 of the baseline's own slices (every events/128-th interval midpoint) timed here. CPU time of the
  // process, like the benchmark's CPU column (one thread): other work on a shared machine does not inflate it.
  std::vector<double> event_theta;  // the candidates grouped as ComputeNondirectional groups them
  for (const auto& c : CriticalCandidates(pr, nullptr)) {
    if (c.kind == CriticalKind::kR) continue;
    if (event_theta.empty() || c.theta - event_theta.back() > 1e-10) event_theta.push_back(c.theta);
  }
  constexpr int kSamples = 128;
  const double s0 = ProcessCpuSeconds();
  for (int i = 0; i < kSamples && !event_theta.empty(); ++i) {
    const size_t m = event_theta.size(), k = m * static_cast<size_t>(i) / kSamples;
    const double hi = k + 1 < m ? event_theta[k + 1] : event_theta[0] + 2 * M_PI;
    BackprojectionProblem p = pr;
    p.theta = WrapAngle(0.5 * (event_theta[k] + hi));
    const VcBackprojection vc = VcEnlargedBackprojection(p, o.selection);  // and its structure, as each slice has
    benchmark::DoNotOptimize(RegionStructure(vc.classic).size() + RegionStructure(vc.region).size());
  }
  const double per_sweep_s = (ProcessCpuSeconds() - s0) / kSamples;
  state.counters["baseline_estimate_s"] =
      per_sweep_s * static_cast<double>(stats.events + 4 * static_cast<std::int64_t>(orientations));
  state.counters["backprojections"] = static_cast<double>(stats.backprojections);
  state.counters["orientations"] = static_cast<double>(orientations);
  state.counters["explained"] = static_cast<double>(stats.explained);
  state.counters["updated"] = static_cast<double>(stats.updated);
  for (int i = 0; i < kSweepPurposes; ++i) {
    const std::string name = std::string("sweeps_") + SweepPurposeName(static_cast<SweepPurpose>(i));
    state.counters[name] = static_cast<double>(stats.sweeps[i]);
    state.counters[name + "_s"] = stats.sweep_seconds[i];
  }
}
BENCHMARK(BM_Nondirectional)
    ->ArgsProduct({{0, 1, 2, 3, 4}, {10, 20, 40, 80}})
    ->ArgsProduct({{0, 3, 4}, {160, 320}})
    ->ArgsProduct({{0}, {500, 640, 1280, 2000}})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

// The region at a θ inside an open slice's interval: the slice's region carried there (method 0, RegionAt: free edges
// turned about their sources, O(region size)) against a sweep at θ with the slice's active rays (method 1, what the
// queries did before), both regions (classic and VC), at the midpoints of up to 64 open slices. The nondirectional
// backprojection is computed once per size, outside the timing.
void BM_RegionAt(benchmark::State& state) {
  static std::map<int, std::pair<BackprojectionProblem, NondirectionalBackprojection>> cache;
  const int n = static_cast<int>(state.range(1));
  if (!cache.count(n)) {
    BackprojectionProblem pr = bench::PentagonGrid(n / 5);
    NondirectionalOptions o;
    o.threads = MachineThreads();
    auto nd = ComputeNondirectional(pr, nullptr, o);
    cache.emplace(n, std::make_pair(std::move(pr), std::move(nd)));
  }
  const auto& [pr, nd] = cache.at(n);
  std::vector<double> thetas;
  for (size_t s = 1; s < nd.slices.size(); s += 2) thetas.push_back(nd.slices[s].theta);
  if (thetas.size() > 64) {
    std::vector<double> every;
    for (size_t i = 0; i < 64; ++i) every.push_back(thetas[i * thetas.size() / 64]);
    thetas.swap(every);
  }
  double area = 0;
  for (auto _ : state) {
    for (double theta : thetas) {
      // A point of the interval other than the slice's own θ (a quarter of the way from its midpoint to its end).
      const Slice& sl = SliceAt(nd, theta);
      const double t = WrapAngle(theta + 0.25 * (sl.hi - sl.lo) / 2);
      if (state.range(0) == 0) {
        area += RegionAt(nd, t, false).area + RegionAt(nd, t, true).area;
      } else {
        BackprojectionProblem p = pr;
        p.theta = t;
        area += ClassicBackprojection(p).area + BackprojectionWithActiveRays(p, sl.vc.active_rays).area;
      }
    }
  }
  benchmark::DoNotOptimize(area);
  state.SetLabel(state.range(0) == 0 ? "carried" : "swept");
  state.counters["vertices"] = bench::Vertices(pr);
  state.counters["thetas"] = static_cast<double>(thetas.size());
  // Seconds per θ (both regions).
  state.counters["per_theta"] = benchmark::Counter(
      static_cast<double>(thetas.size()), benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_RegionAt)->ArgsProduct({{0, 1}, {20, 80, 320}})->Unit(benchmark::kMillisecond);

void BM_Plan(benchmark::State& state) {
  static const char* const kScenes[] = {"slot", "fig13", "corner"};
  const char* name = kScenes[state.range(0)];
  const Scene scene = LoadScene(std::string(VISCO_SOURCE_DIR) + "/data/scenes/" + name + ".json");
  Strategy st;
  for (auto _ : state) {
    st = PlanStrategy(scene, {});
    benchmark::DoNotOptimize(st.steps.data());
  }
  state.SetLabel(name);
  state.counters["steps"] = static_cast<double>(st.steps.size());
  state.counters["nondirectional"] = static_cast<double>(st.nondirectional);
}
BENCHMARK(BM_Plan)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->Iterations(1);

// Plan synthesis as the scene grows: the demo's slot (its camera looking left and down) in a room whose right part
// holds m convex pentagons on a jittered grid, behind the camera (so they add C-obstacles, not rays). n, the number of
// C-obstacle vertices, grows by 9 per pentagon (a pentagon swept by the square robot): m = 4 ... 110 gives
// n = 50 ... 1 000. Counters: n, steps, whether a strategy was found, nondirectional backprojections, peak memory.
Scene ClutteredSlot(int m) {
  Scene scene = DefaultScene();
  std::mt19937_64 rng(777);
  std::uniform_real_distribution<double> unit(0, 1);
  const int rows = 3, columns = (m + rows - 1) / rows;
  scene.bounds.max = {12.0 + 2.0 * columns, 8.0};
  for (int i = 0; i < m; ++i) {
    const double cx = 13.0 + 2.0 * (i / rows) + 0.3 * (unit(rng) - 0.5);
    const double cy = 1.5 + 2.5 * (i % rows) + 0.3 * (unit(rng) - 0.5);
    Obstacle o;
    o.id = "clutter" + std::to_string(i);
    const double a0 = 2 * M_PI * unit(rng);
    for (int k = 0; k < 5; ++k) {
      const double a = a0 + 2 * M_PI * (k + 0.3 * unit(rng)) / 5;
      o.shape.polygon.vertices.emplace_back(cx + 0.6 * std::cos(a), cy + 0.6 * std::sin(a));
      o.shape.source_index.push_back(k);
    }
    scene.obstacles.push_back(std::move(o));
  }
  return scene;
}

void BM_PlanSynthesis(benchmark::State& state) {
  const Scene scene = ClutteredSlot(static_cast<int>(state.range(0)));
  const CSpace cspace(scene);
  std::size_t vertices = 0;
  for (std::size_t i = 0; i < cspace.num_c_obstacles(); ++i) {
    for (const PolygonWithHoles& p : cspace.c_obstacle(i)) vertices += p.outer.size();
  }
  Strategy st;
  ResetPeakMemory();
  for (auto _ : state) {
    st = PlanStrategy(scene, {});
    benchmark::DoNotOptimize(st.steps.data());
  }
  state.counters["n"] = static_cast<double>(vertices);
  state.counters["feasible"] = st.feasible ? 1 : 0;
  state.counters["steps"] = static_cast<double>(st.steps.size());
  state.counters["nondirectional"] = static_cast<double>(st.nondirectional);
  state.counters["peak_MiB"] = PeakMemoryMiB();
}
BENCHMARK(BM_PlanSynthesis)->Arg(4)->Arg(12)->Arg(30)->Arg(60)->Arg(110)->Unit(benchmark::kSecond)->Iterations(1);

// Candidate counts by kind against the papers' bounds up to n = 2 000 on a scene with a camera: the cluttered slot
// above (its camera gives the CVC rays; the m random pentagons behind it add C-obstacle vertices, not rays), through
// the real pipeline scene -> C-space -> CVC rays. The counts where the rays grow with n are BM_CandidateCounts'.
void BM_CandidateCountsCluttered(benchmark::State& state) {
  CountCandidates(state, ClutteredSlot(static_cast<int>(state.range(0))), 0.0);
}
BENCHMARK(BM_CandidateCountsCluttered)
    ->Arg(2)
    ->Arg(8)
    ->Arg(24)
    ->Arg(55)
    ->Arg(110)
    ->Arg(220)
    ->Arg(250)
    ->Unit(benchmark::kSecond)
    ->Iterations(1);

}  // namespace
}  // namespace visco::planning

BENCHMARK_MAIN();
