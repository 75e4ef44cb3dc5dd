#pragma once
// `visco driver`: the robot driver process.

namespace CLI {
class App;
}

namespace visco::drivers {

/// Registers `visco driver`. Not real-time safe.
void RegisterCommands(CLI::App& app);

}  // namespace visco::drivers
