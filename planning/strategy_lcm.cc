// The strategy as the LCM message motion_strategy_t (strategy.h, StrategyToLcm).

#include <chrono>
#include <cstdint>

#include "planning/strategy.h"
#include "visco/motion_strategy_t.hpp"

namespace visco::planning {

motion_strategy_t StrategyToLcm(const Scene& scene, const Strategy& strategy, double speed) {
  motion_strategy_t m;
  m.utime = std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
                .count();
  m.scene = scene.name;
  m.feasible = strategy.feasible;
  m.speed = speed;
  for (const auto& s : strategy.steps) {
    motion_step_t step;
    step.theta = s.theta;
    step.active_rays = s.active_rays;
    step.num_active_rays = static_cast<int32_t>(s.active_rays.size());
    step.terminate_kind = s.terminate == Termination::kGoal            ? motion_step_t::TERMINATE_GOAL
                          : s.terminate == Termination::kVisualGuarded ? motion_step_t::TERMINATE_VC
                                                                       : motion_step_t::TERMINATE_CONTACT;
    step.terminate_ref = s.terminate_ref;
    step.timeout_s = StepTimeout(scene, speed);  // as in the JSON: `visco run` times a step out the same way
    m.steps.push_back(step);
  }
  m.num_steps = static_cast<int32_t>(m.steps.size());
  return m;
}

}  // namespace visco::planning
