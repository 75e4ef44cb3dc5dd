#pragma once
// The planner's subcommands of the `visco` program: `vcrays` (CONTRACT.md).

namespace CLI {
class App;
}

namespace visco::planning {

/// Registers the planner's subcommands (`visco vcrays`) on `app`.
void RegisterCommands(CLI::App& app);

}  // namespace visco::planning
