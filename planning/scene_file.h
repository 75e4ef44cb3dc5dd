#pragma once
// Scene files (docs/formats.md): reading and validating one, and the default demo scene. Above the C-space in the
// dependency order: validation checks that the goal and start regions are not entirely inside the C-obstacles.

#include <string>
#include <string_view>

#include "planning/scene.h"

namespace visco::planning {

/// Reads and validates a scene file. Not real-time safe.
/// @throws visco::InputError naming the file, the object (e.g. "obstacles[1] (left).polygon") and what is wrong:
///   unreadable file, invalid JSON, unknown or missing fields, non-finite numbers, polygons with fewer than 3
///   distinct vertices or self-intersections, a goal or start region entirely inside the C-obstacles, a camera
///   centre inside an obstacle, an empty or reflex field of view, negative uncertainty, cone or friction angles
///   outside [0, 90) degrees, bounds with min >= max. Obstacles may touch and overlap (their union is the obstacle
///   region).
Scene LoadScene(const std::string& path);

/// As LoadScene, from JSON text; `source` names it in messages.
Scene ParseScene(std::string_view json_text, const std::string& source);

/// The default demo scene (data/scenes/slot.json, compiled into the program) as JSON text.
std::string_view DefaultSceneJson();

/// Loads the default demo scene. @throws visco::InputError only if the embedded file is broken (a build bug).
Scene DefaultScene();

}  // namespace visco::planning
