#pragma once
// `visco plan` (docs/formats.md): the strategy JSON, its picture, and the LCM motion_strategy_t.

#include "planning/scene.h"
#include "planning/strategy.h"

namespace CLI {
class App;
}

namespace visco {
class motion_strategy_t;
}

namespace visco::planning {

/// Registers `visco plan` on `app`.
void RegisterPlanCommand(CLI::App& app);

/// The strategy as the LCM message `visco run` also accepts (speed in m/s, the JSON's time-outs).
motion_strategy_t StrategyToLcm(const Scene& scene, const Strategy& strategy, double speed);

}  // namespace visco::planning
