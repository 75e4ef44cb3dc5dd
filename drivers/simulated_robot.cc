#include "drivers/simulated_robot.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "common/error.h"

namespace visco::drivers {

SimulatedRobot::SimulatedRobot(const SimulatedRobotConfig& config) : config_(config) {
  if (!(config.max_acceleration > 0.0) || !(config.quick_stop_deceleration > 0.0)) {
    throw InputError("command line", "--max-acceleration",
                     "must be positive, not " + std::to_string(config.max_acceleration));
  }
  if (config.walls) {
    for (int i = 0; i < 2; ++i) {
      if (!(config.bounds_min[i] < config.bounds_max[i])) {
        throw InputError("command line", "--bounds", "the bounds are empty (min must be below max on both axes)");
      }
      if (config.start[i] < config.bounds_min[i] || config.start[i] > config.bounds_max[i]) {
        throw InputError("command line", "--start", "the start position lies outside the bounds");
      }
    }
  }
  if (config.workspace) {
    for (int i = 0; i < 2; ++i) {
      if (!(config.workspace_min[i] < config.workspace_max[i])) {
        throw InputError("command line", "--workspace", "the workspace is empty (min must be below max on both axes)");
      }
      if (config.start[i] < config.workspace_min[i] || config.start[i] > config.workspace_max[i]) {
        throw InputError("command line", "--start", "the start position lies outside the workspace");
      }
    }
  }
  state_.position[0] = config.start[0];
  state_.position[1] = config.start[1];
}

void SimulatedRobot::SetVelocity(const double velocity[2]) {
  command_[0] = std::isfinite(velocity[0]) ? velocity[0] : 0.0;
  command_[1] = std::isfinite(velocity[1]) ? velocity[1] : 0.0;
  quick_stop_ = false;
}

void SimulatedRobot::QuickStop() {
  command_[0] = 0.0;
  command_[1] = 0.0;
  quick_stop_ = true;
}

void SimulatedRobot::Step(double dt) {
  if (!(dt > 0.0)) return;
  const double max_dv = (quick_stop_ ? config_.quick_stop_deceleration : config_.max_acceleration) * dt;
  state_.contact = false;
  for (int i = 0; i < 2; ++i) {
    // Velocity follows the command within the acceleration limit, then the position integrates (semi-implicit).
    const double dv = std::clamp(command_[i] - state_.velocity[i], -max_dv, max_dv);
    state_.velocity[i] += dv;
    state_.position[i] += state_.velocity[i] * dt;
    state_.contact_force[i] = 0.0;
  }
  if (config_.workspace) {
    state_.out_of_bounds = false;
    for (int i = 0; i < 2; ++i) {
      state_.out_of_bounds |=
          state_.position[i] < config_.workspace_min[i] || state_.position[i] > config_.workspace_max[i];
    }
  }
  if (!config_.walls) return;
  for (int i = 0; i < 2; ++i) {
    const bool below = state_.position[i] <= config_.bounds_min[i];
    const bool above = state_.position[i] >= config_.bounds_max[i];
    if (!below && !above) continue;
    state_.position[i] = std::clamp(state_.position[i], config_.bounds_min[i], config_.bounds_max[i]);
    state_.velocity[i] = 0.0;
    // Pushing into the wall: the wall pushes back.
    const double into = below ? -command_[i] : command_[i];
    if (into >= 0.0) {
      state_.contact = true;
      state_.contact_force[i] = (below ? 1.0 : -1.0) * config_.wall_damping * into;
    }
  }
}

}  // namespace visco::drivers
