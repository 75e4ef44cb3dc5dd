#pragma once
// Subcommands of visco::control: `visco run` (the real-time strategy executor).

namespace CLI {
class App;
}

namespace visco::control {

/// Registers `run`. Not real-time safe.
void RegisterCommands(CLI::App& app);

}  // namespace visco::control
