#include "app/sim/world.h"

#include "planning/cspace.h"
#include "planning/scene.h"

namespace visco::sim {

MotionWorld MakeMotionWorld(const planning::Scene& scene) {
  MotionWorld world;
  const planning::CSpace cspace(scene);
  for (std::size_t i = 0; i < cspace.num_c_obstacles(); ++i) {
    for (const planning::PolygonWithHoles& part : cspace.c_obstacle(i)) {
      // Holes of a C-obstacle are pockets enclosed by it: unreachable from outside, so the outer boundary suffices.
      world.obstacles.push_back(part.outer.vertices);
    }
  }
  world.bounds_min = scene.bounds.min;
  world.bounds_max = scene.bounds.max;
  world.friction_cone = scene.friction_cone_rad;
  return world;
}

Eigen::Vector2d StartRegionCentroid(const planning::Scene& scene) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const auto& v : scene.start->polygon.vertices) c += v;
  return c / static_cast<double>(scene.start->polygon.vertices.size());
}

drivers::WorldFile MakeWorldFile(const planning::Scene& scene) {
  drivers::WorldFile file;
  file.world = MakeMotionWorld(scene);
  file.velocity_cone = scene.uncertainty.velocity_cone_rad;
  if (scene.start) {
    file.start = StartRegionCentroid(scene);
    file.have_start = true;
  }
  return file;
}

}  // namespace visco::sim
