#pragma once
// Seeded random scenes for multi-step planning, sized by their number of obstacle vertices: the property tests'
// whole random scenes (star-shaped, non-convex obstacles in 4 m cells, some overlapping, a camera on the edge of the
// bounds or anywhere) with the goal resting on a surface (around a point of CB's boundary) and a start region 1-2.5 m
// from it, on a grid of cells just large enough to hold `vertices` obstacle vertices. These are the scenes a user
// brings: nobody designed them to have a strategy.

#include <cstddef>
#include <cstdint>

#include "planning/scene.h"
#include "tests/planning/random_vc_scenes.h"

namespace visco::planning::testing {

/// The obstacle vertices of the scene (the workspace polygons' vertices, as a user counts them).
inline std::size_t ObstacleVertices(const Scene& s) {
  std::size_t n = 0;
  for (const Obstacle& o : s.obstacles) n += o.shape.polygon.vertices.size();
  return n;
}

/// A scene for seed `seed` with at least `vertices` obstacle vertices (the smallest grid of cells, square or one column
/// wider, that holds them), a goal on CB and a start region. False if the seed gives no goal or no start region.
inline bool MultiStepScene(std::uint64_t seed, std::size_t vertices, Scene& s) {
  for (int cells = 2; cells <= 40; ++cells) {
    for (int extra = 0; extra <= 1; ++extra) {
      double theta = 0;
      if (!RandomWholeScene(seed, s, theta, cells + extra, cells, /*goal_on_cb=*/true)) continue;
      if (ObstacleVertices(s) < vertices) continue;
      if (!PlaceStartRegion(seed, s)) return false;
      s.name = "multistep_n" + std::to_string(vertices) + "_s" + std::to_string(seed);
      s.source = s.name;
      return true;
    }
  }
  return false;
}

}  // namespace visco::planning::testing
