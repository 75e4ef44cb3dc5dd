#pragma once
// `visco sim`: the simulated robot and camera (visco::sim).

namespace CLI {
class App;
}

namespace visco::sim {

/// Registers `sim`. Not real-time safe.
void RegisterCommands(CLI::App& app);

}  // namespace visco::sim
