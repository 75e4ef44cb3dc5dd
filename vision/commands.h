#pragma once
// The vision subcommands of the `visco` program: `detect` (one image, docs/formats.md), `track` (streaming)
// and `capture` (a V4L2 camera onto the bus).

namespace CLI {
class App;
}

namespace visco::vision {

/// Registers `visco detect`, `visco track` and `visco capture` on `app`.
void RegisterCommands(CLI::App& app);
/// Registers `visco capture` (the V4L2 camera process; vision/capture_command.cc).
void RegisterCaptureCommand(CLI::App& app);

}  // namespace visco::vision
