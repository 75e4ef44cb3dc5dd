#pragma once
// The demo's pictures: run.svg (the executed trajectory over the plan) and montecarlo.svg (every run's trajectory,
// histograms of the motion time and the commands sent).

#include <string>
#include <vector>

#include "app/demo/closed_loop.h"
#include "app/demo/trace.h"
#include "planning/cspace.h"
#include "planning/scene.h"
#include "planning/strategy.h"

namespace visco::app::demo {

/// The plan's picture underneath, the executed trajectory over it, with a legend.
std::string RunSvg(const planning::Scene& scene, const planning::CSpace& cspace, const planning::Strategy& strategy,
                   const Trace& trace);

/// The Monte Carlo figure: every run's trajectory over the plan (green: reached the goal, red: did not; dots: starts),
/// and histograms of the motion time and the commands sent.
std::string MonteCarloSvg(const Setup& su, const std::vector<RunOutcome>& outcomes);

}  // namespace visco::app::demo
