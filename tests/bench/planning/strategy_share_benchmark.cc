// The strategy-share figure: over seeded random scenes with a start region (the planner tests' generator: 8 m x 4 m,
// star-shaped and overlapping obstacles, a camera on the edge of the bounds or anywhere, ε_v 2-8°), the share that has
// a strategy within two steps with visual constraints and without, and the step counts.
//
// BM_StrategyShare/hard/N plans seeds 1..N both ways (counters: scenes, with_1, with_2, with_none, without_1,
// without_2, without_none, only_with: a strategy only with the camera). hard = 0: the start 1-2.5 m from the goal,
// ε_v 2-8° (the planner tests' scenes); hard = 1: 2.5-4 m, ε_v 8-16° (where the classic backprojection runs out).
// With VISCO_FIGURE_SVG=PREFIX it also draws PREFIX<hard>.svg (docs/figures/strategy_share0.svg and 1:
// `VISCO_FIGURE_SVG=docs/figures/strategy_share build/bin/planning_strategy_share_benchmark
// --benchmark_filter=/40/`).

#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include <array>
#include <cstdlib>
#include <string>

#include "planning/strategy.h"
#include "planning/svg.h"
#include "tests/planning/random_vc_scenes.h"

namespace visco::planning {
namespace {

struct Tally {
  int scenes = 0;
  std::array<int, 3> with{};     // 1 step, 2 steps, none
  std::array<int, 3> without{};  // 1 step, 2 steps, none
  int only_with = 0;
};

int Bucket(const Strategy& s) { return !s.feasible ? 2 : s.steps.size() == 1 ? 0 : 1; }

std::string Figure(const Tally& t, bool hard) {
  SvgCanvas c({0, -0.15}, {1.0, 1.1}, 520);
  c.TextPx(12, 20,
           fmt::format("{} random scenes, start {} m from the goal, ε_v {}°: a strategy within two steps", t.scenes,
                       hard ? "2.5-4" : "1-2.5", hard ? "8-16" : "2-8"),
           13, "fill=\"black\"");
  const char* colours[] = {"#1a9850", "#a6d96a", "#bbbbbb"};
  const char* names[] = {"1 step", "2 steps", "none"};
  const std::array<const std::array<int, 3>*, 2> bars = {&t.with, &t.without};
  const char* labels[] = {"with visual constraints", "without (no camera)"};
  for (int b = 0; b < 2; ++b) {
    const double x0 = 0.12 + 0.45 * b, x1 = x0 + 0.3;
    double y = 0;
    for (int k = 0; k < 3; ++k) {
      const double h = t.scenes > 0 ? static_cast<double>((*bars[b])[k]) / t.scenes : 0;
      if (h > 0) {
        c.Polygon(Polygon{{{x0, y}, {x1, y}, {x1, y + h}, {x0, y + h}}},
                  fmt::format("class=\"bar\" fill=\"{}\" stroke=\"white\"", colours[k]));
        c.Text({(x0 + x1) / 2, y + h / 2}, fmt::format("{} ({})", names[k], (*bars[b])[k]), 12,
               "fill=\"black\" text-anchor=\"middle\"", 0, 4);
      }
      y += h;
    }
    c.Text({(x0 + x1) / 2, 0}, labels[b], 12, "fill=\"black\" text-anchor=\"middle\"", 0, 16);
  }
  for (int k = 0; k <= 4; ++k) {
    c.Line({0.08, k / 4.0}, {0.1, k / 4.0}, "stroke=\"black\"");
    c.Text({0.08, k / 4.0}, fmt::format("{}%", 25 * k), 11, "fill=\"black\" text-anchor=\"end\"", -3, 4);
  }
  c.TextPx(12, c.height_px() - 30, fmt::format("{} of them have a strategy only with the camera", t.only_with), 12,
           "fill=\"black\"");
  return c.Finish();
}

void BM_StrategyShare(benchmark::State& state) {
  const bool hard = state.range(0) != 0;
  const auto last = static_cast<std::uint64_t>(state.range(1));
  Tally t;
  for (auto _ : state) {
    t = Tally{};
    for (std::uint64_t seed = 1; seed <= last; ++seed) {
      Scene s;
      double theta = 0;
      if (!testing::RandomWholeScene(seed, s, theta, 2, 1)) continue;
      if (!(hard ? testing::PlaceStartRegion(seed, s, 2.5, 4.0, 8.0, 16.0) : testing::PlaceStartRegion(seed, s)))
        continue;
      ++t.scenes;
      PlanOptions o;
      o.max_steps = 2;
      o.threads = 2;
      const Strategy with = PlanStrategy(s, o);
      o.use_camera = false;
      const Strategy without = PlanStrategy(s, o);
      ++t.with[static_cast<std::size_t>(Bucket(with))];
      ++t.without[static_cast<std::size_t>(Bucket(without))];
      t.only_with += with.feasible && !without.feasible;
    }
  }
  state.counters["scenes"] = t.scenes;
  state.counters["with_1"] = t.with[0];
  state.counters["with_2"] = t.with[1];
  state.counters["with_none"] = t.with[2];
  state.counters["without_1"] = t.without[0];
  state.counters["without_2"] = t.without[1];
  state.counters["without_none"] = t.without[2];
  state.counters["only_with"] = t.only_with;
  if (const char* prefix = std::getenv("VISCO_FIGURE_SVG")) {
    std::FILE* f = std::fopen((std::string(prefix) + (hard ? "1" : "0") + ".svg").c_str(), "w");
    if (f != nullptr) {
      const std::string svg = Figure(t, hard);
      std::fwrite(svg.data(), 1, svg.size(), f);
      std::fclose(f);
    }
  }
}
BENCHMARK(BM_StrategyShare)->ArgsProduct({{0, 1}, {3, 40}})->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace
}  // namespace visco::planning

BENCHMARK_MAIN();
