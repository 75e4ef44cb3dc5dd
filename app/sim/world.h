#pragma once
// The world of a scene as the simulated robot (drivers/simulated_robot.h) sees it: the C-obstacles (outer boundaries
// of CB_i), the bounds, friction and the velocity cone. The planner's C-space computes it; the world file carries it
// to a driver process that links no planner. Part of visco::sim. Not real-time safe.

#include "common/motion_model.h"
#include "drivers/simulated_robot_options.h"

namespace visco::planning {
struct Scene;
}

namespace visco::sim {

/// C-obstacles, bounds and friction of a scene; no goal, no rays (visual compliance is the controller's job).
MotionWorld MakeMotionWorld(const planning::Scene& scene);

/// The mean of the start region's vertices: where a simulated run starts by default. The scene must have one.
Eigen::Vector2d StartRegionCentroid(const planning::Scene& scene);

/// The scene's world file: MakeMotionWorld, ε_v, and the start region's centroid as the start (if it has one).
drivers::WorldFile MakeWorldFile(const planning::Scene& scene);

}  // namespace visco::sim
