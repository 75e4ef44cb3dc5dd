#pragma once
// The vision subcommands of the `visco` program: `detect` (one image, docs/formats.md) and `track` (streaming).

namespace CLI {
class App;
}

namespace visco::vision {

/// Registers `visco detect` and `visco track` on `app`.
void RegisterCommands(CLI::App& app);

}  // namespace visco::vision
