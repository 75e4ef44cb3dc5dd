#pragma once
// The plugin seam: a robot of the user's own, in a shared library the driver loads at start-up (`visco driver
// --robot plugin --robot-plugin LIB.so --robot-config FILE`), the way ros2_control loads hardware components. The
// library implements visco::drivers::RobotInterface (drivers/robot_interface.h: the lifecycle, then SetVelocity,
// QuickStop, Reset, Step and Read in the loop) and exports three C functions:
//
//   int visco_robot_plugin_abi(void);                       // returns VISCO_ROBOT_PLUGIN_ABI it was built with
//   visco::drivers::RobotInterface* visco_robot_plugin_create(const char* config_json, char* error,
//                                                             size_t error_size);
//   void visco_robot_plugin_destroy(visco::drivers::RobotInterface* robot);
//
// create() receives the configuration file's text (a JSON document, "{}" without one); on bad configuration it
// writes a message naming the key and what is wrong into `error` and returns null. The driver then calls Configure()
// and Activate() (which may throw visco::InputError or visco::JobFailed: the library is built against the same
// headers and compiler), runs the loop, and at the end Deactivate() and destroy(). The robot is used by one thread,
// the driver's. Example: drivers/plugins/example_robot_plugin.cc; docs/your_own_robot.md.

#include <cstddef>

#include "drivers/robot_interface.h"

/// Bumped whenever RobotInterface or RobotFeedback change: the driver refuses a library built for another one.
#define VISCO_ROBOT_PLUGIN_ABI 1

extern "C" {
using visco_robot_plugin_abi_fn = int();
using visco_robot_plugin_create_fn = visco::drivers::RobotInterface*(const char* config_json, char* error,
                                                                     std::size_t error_size);
using visco_robot_plugin_destroy_fn = void(visco::drivers::RobotInterface* robot);
}
