#pragma once
// The calibration subcommands of the `visco` program: `extrinsics` (the camera's pose from a tag on the table) and
// `robot-frame` (the robot's command frame in the world). docs/camera.md.

namespace CLI {
class App;
}

namespace visco::vision {

/// Registers `visco extrinsics` and `visco robot-frame` on `app`.
void RegisterCalibrationCommands(CLI::App& app);

}  // namespace visco::vision
