#pragma once
// `visco replay` (replayer.h).

namespace CLI {
class App;
}

namespace visco::replay {

/// Adds `visco replay`. Not real-time safe.
void RegisterCommands(CLI::App& app);

}  // namespace visco::replay
