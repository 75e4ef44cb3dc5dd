#pragma once
// `visco camera SCENE [--grid H | --candidates FILE] [--fov DEG] [--aim X Y] [--max-steps K] [--max-candidates N]
// [--max-backprojections N] [--threads N] [--out FILE] [--svg FILE]`: where to put the camera
// (docs/camera_placement.md).

namespace CLI {
class App;
}

namespace visco::planning {

/// Registers `visco camera` on `app`.
void RegisterCameraCommand(CLI::App& app);

}  // namespace visco::planning
