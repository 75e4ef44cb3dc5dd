#pragma once
// `visco sim`: the simulated robot and camera (visco::control_sim).

namespace CLI {
class App;
}

namespace visco::control {

/// Registers `sim`. Not real-time safe.
void RegisterSimCommands(CLI::App& app);

}  // namespace visco::control
