#pragma once
// The simulated robot's options, declared once for every command that runs it (`visco-rt driver`, `visco sim`), and
// its world file: the C-space it moves in (docs/formats.md "World file"), which `visco sim` and the demo write from
// a scene so that a driver process needs no planner to simulate the scene's physics.

#include <string>
#include <vector>

#include "drivers/simulated_robot.h"

namespace CLI {
class App;
}

namespace visco::drivers {

/// Flag-friendly values (degrees, lists); ToConfig turns them into a SimulatedRobotConfig.
struct SimulatedRobotOptions {
  std::string world_path;         // a world file (C-obstacles, bounds, friction, velocity cone); "" = free plane
  std::vector<double> start;      // X Y; empty: the world's start, else the origin
  std::vector<double> walls;      // XMIN YMIN XMAX YMAX: walls around this box (C-obstacles added to the world)
  std::vector<double> workspace;  // XMIN YMIN XMAX YMAX: the bounds (overrides the world's)
  double friction_deg = -1;       // φ; < 0: the world's (0 without a world)
  double velocity_cone_deg = -1;  // ε_v; < 0: the world's (0 without a world)
  SimulatedRobotConfig robot;     // seed, hold, fixed offset, rates (defaults from SimulatedRobotConfig)
};

/// Registers the options on `cmd`. `with_world`: also --world, --start, --walls, --workspace, --friction-deg and
/// --velocity-cone-deg (a command whose scene gives these, like `visco sim`, leaves them out).
void AddSimulatedRobotOptions(CLI::App& cmd, SimulatedRobotOptions& options, bool with_world);

/// The configuration the options describe (loads the world file).
/// @throws visco::InputError naming the file or option and what is wrong.
SimulatedRobotConfig ToConfig(const SimulatedRobotOptions& options);

/// The world file's contents (docs/formats.md "World file").
struct WorldFile {
  MotionWorld world;  // obstacles, bounds, friction
  double velocity_cone = 0.0;
  bool have_start = false;
  Eigen::Vector2d start{0.0, 0.0};
};

/// @throws visco::InputError for a missing file, bad JSON, an unknown key or a bad value (with its JSON path).
WorldFile LoadWorldFile(const std::string& path);
/// The JSON text of a world file (round-trips through LoadWorldFile exactly: doubles printed to 17 digits).
std::string WorldFileJson(const WorldFile& world);

}  // namespace visco::drivers
