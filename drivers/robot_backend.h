#pragma once
// Which robot the driver drives, chosen by configuration (`visco driver --robot`): the simulated robot (default),
// CiA 402 drives over CAN, or a plugin (drivers/robot_plugin.h). Not real-time: everything here runs before the loop.

#include <memory>
#include <string>

#include "drivers/robot_interface.h"

namespace visco::drivers {

struct SimulatedRobotOptions;
class SimulatedRobot;

struct RobotBackendOptions {
  std::string kind = "simulated";  // simulated | cia402 | plugin
  std::string config_path;         // cia402: the drives' configuration (JSON); plugin: passed to it as text
  std::string plugin_path;         // plugin: the shared library
  double max_speed = 1.0;          // the driver's speed limit (m/s): a drive that cannot reach it is refused
  int driver_node = 1;             // the driver's own node id (drives must not share it when on its bus)
  std::string driver_interface;    // the driver's CAN interface ("" on LCM)
  double heartbeat_ms = 100.0;     // the driver's heartbeat period
};

/// The robot the options choose, constructed but not configured (its lifecycle is the caller's).
/// `simulated`: the robot built from `sim` (returned also through `simulated`, for the truth publisher).
/// @throws visco::InputError naming the option or file and what is wrong (an unknown kind, a plugin that cannot be
///         loaded or lacks a symbol, a configuration the backend refuses).
std::unique_ptr<RobotInterface> MakeRobot(const RobotBackendOptions& options, const SimulatedRobotOptions& sim,
                                          SimulatedRobot** simulated);

/// A plugin loaded from `library` (dlopen) and created with `config_json`. The returned robot unloads the library
/// when it is destroyed. @throws visco::InputError naming the library and what is wrong.
std::unique_ptr<RobotInterface> LoadRobotPlugin(const std::string& library, const std::string& config_json);

}  // namespace visco::drivers
