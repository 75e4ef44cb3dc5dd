#pragma once
// `visco backproject SCENE --theta DEG [--kernel] [--out FILE] [--svg FILE]` (docs/formats.md).

namespace CLI {
class App;
}

namespace visco::planning {

/// Registers `visco backproject` on `app`.
void RegisterBackprojectCommand(CLI::App& app);

}  // namespace visco::planning
