#pragma once
// `visco plan` (docs/formats.md).

namespace CLI {
class App;
}

namespace visco::planning {

/// Registers `visco plan` on `app`.
void RegisterPlanCommand(CLI::App& app);

}  // namespace visco::planning
